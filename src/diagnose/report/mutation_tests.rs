//! Tests that pin behaviour a mutation sample found unchecked.

use super::*;

/// The figures' curves pair each x with its y, in order, one point per sample (a curve of one point would
/// draw nothing the reader can check).
#[test]
fn points_pair_every_sample_in_order() {
    let got = pts(&[0.5, 1.5, 2.5], &[-1.0, 4.0, 9.0]);
    assert_eq!(got, vec![(0.5, -1.0), (1.5, 4.0), (2.5, 9.0)]);
}

/// A border's fitted curve spans exactly the x its samples cover, in 100 equal steps, with the curvature's
/// value at each x; no samples, no curve.
#[test]
fn border_curve_spans_the_samples() {
    let samples = [(3.0, 0.1), (-1.0, 0.2), (1.0, -0.3)];
    let got = border_curve(&[2.0, 0.5], 1.0, &samples);
    assert_eq!(got.len(), 101);
    assert_eq!(got[0].0, -1.0);
    assert_eq!(got[50].0, 1.0);
    assert_eq!(got[100].0, 3.0);
    assert!(
        got.windows(2)
            .all(|w| (w[1].0 - w[0].0 - 0.04).abs() < 1e-12)
    );
    // At x = 1: s = 2, s^2 (2 + 0.5 s) = 4 * 3 = 12.
    assert!((got[50].1 - 12.0).abs() < 1e-12);
    assert!(border_curve(&[2.0, 0.5], 1.0, &[]).is_empty());
}

/// Running means over windows of the given samples, at the middle sample's time: windows of 8 step by 2.
#[test]
fn running_means_by_hand() {
    let t: Vec<f64> = (0..20).map(|k| 0.5 * k as f64).collect();
    let e: Vec<f64> = (0..20).map(|k| k as f64).collect();
    let idx: Vec<usize> = (0..20).filter(|k| k % 2 == 0).collect();
    let got = running_means(&t, &e, &idx, 8);
    // Windows of idx: [0, 2, .., 14] (mean 7, middle sample 8 at t 4), then [4, .., 18] (mean 11, t 6).
    assert_eq!(got, vec![(4.0, 7.0), (6.0, 11.0)]);
}

/// The fitted drift as a line over time: slope times the sample index, at every (n / 200)-th sample.
#[test]
fn drift_line_by_hand() {
    let t: Vec<f64> = (0..1000).map(|k| 0.01 * k as f64).collect();
    let line = drift_line(&t, -0.5);
    assert_eq!(line.len(), 200);
    assert_eq!(line[0], (0.0, 0.0));
    assert_eq!(line[1], (0.05, -2.5));
    assert_eq!(line[199], (t[995], -497.5));
    assert_eq!(
        drift_line(&t[..3], 2.0),
        vec![(0.0, 0.0), (0.01, 2.0), (0.02, 4.0)]
    );
}

/// The fitted drift's lines: the upper border falls by c1_rate per sample, the lower rises by m2 c2_rate;
/// centring moves a line to the data's mean level without changing its slope.
#[test]
fn border_drift_lines_and_centring_by_hand() {
    let t: Vec<f64> = (0..4).map(f64::from).collect();
    let [up, dn] = border_drift_lines(&t, 0.5, 0.25, 3.0);
    assert_eq!(up, vec![(0.0, 0.0), (1.0, -0.5), (2.0, -1.0), (3.0, -1.5)]);
    assert_eq!(dn, vec![(0.0, 0.0), (1.0, 0.75), (2.0, 1.5), (3.0, 2.25)]);
    // Line mean -0.75, data mean 10: every point up by 10.75.
    let c = centred_on(up, &[(0.0, 9.0), (5.0, 11.0)]);
    assert_eq!(
        c,
        vec![(0.0, 10.75), (1.0, 10.25), (2.0, 9.75), (3.0, 9.25)]
    );
}
