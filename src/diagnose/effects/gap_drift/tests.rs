use super::*;
use crate::diagnose::fit::starts::tests::{context, paper};

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

/// The rates start at zero, on the current model; they pack scaled by the time scale (a total drift).
#[test]
fn starts_at_the_current_model_and_packs_a_total_drift() {
    let m = paper();
    let y = vec![0.0; 10];
    let p = GapDrift.plan(&context(&m, &y, &y, &y)).unwrap();
    assert_eq!(p.alternatives[0].starts[0].exts, vec![extension(0.0, 0.0)]);
    let e = extension(1e-4, -2e-4);
    assert_eq!(e.pack(1000.0), vec![0.1, -0.2]);
    let back = e.unpack(&[0.1, -0.2], 1000.0);
    assert!((back.theta[0] - 1e-4).abs() < 1e-18 && (back.theta[1] + 2e-4).abs() < 1e-18);
}

/// The fitted drift as reported: the rates, the gaps at the first and at the last sample (c + rate (n - 1)),
/// and the rates per second when the sample period is known. Rates of 2^-10 and -2^-12 per sample over
/// 1025 samples at 0.5 s move c1 = 0.5 to 1.5 and c2 = 1 to 0.75.
#[test]
fn parameters_report_the_gaps_at_both_ends() {
    let plain = paper();
    let m = plain.with(extension(2f64.powi(-10), -(2f64.powi(-12))));
    let fitted = |ts| Fitted {
        n: 1025,
        ts,
        ..Fitted::on(&m, &plain)
    };
    let p = GapDrift.parameters(&fitted(Some(0.5)));
    let got = |name: &str| p.get(name).and_then(serde_json::Value::as_f64);
    assert_eq!(got("c1_rate"), Some(2f64.powi(-10)));
    assert_eq!(got("c2_rate"), Some(-(2f64.powi(-12))));
    assert_eq!((got("c1_start"), got("c2_start")), (Some(0.5), Some(1.0)));
    assert_eq!((got("c1_end"), got("c2_end")), (Some(1.5), Some(0.75)));
    assert_eq!(got("c1_rate_per_s"), Some(2f64.powi(-9)));
    assert_eq!(got("c2_rate_per_s"), Some(-(2f64.powi(-11))));
    let per_sample = GapDrift.parameters(&fitted(None));
    assert_eq!(per_sample.get("c1_rate_per_s"), None);
    assert_eq!(
        GapDrift.parameters(&Fitted {
            model: &plain,
            ..fitted(None)
        }),
        Parameters::new()
    );
}
