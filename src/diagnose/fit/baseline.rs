//! The linear baseline: the best ARX model with an intercept a user fits first, at the record's own rate
//! (issue 45's peer recipe), held against the diagnosis's final model.
//!
//! Every structure with na and nb in 1..=[`BASELINE_ORDER`] and delay in 1..=[`BASELINE_DELAY`] (48) is
//! fitted by least squares (`y(k) = -sum a_i y(k-i) + sum_{j=0..nb} b_j u(k-d-j) + c`) on the fit part
//! (its first [`LS_SAMPLES`] at most), simulated free-run over the whole record with its past held at the
//! first output and input, and the one with the lowest free-run RMSE on the fit part is the baseline
//! (nothing of the held-out part is seen). The fits work about the diagnosis's operating point, so a record
//! shifted by constants gets the same baseline. A block a little beyond stability (a least-squares fit of a
//! position record sampled fast often is) still simulates; a free run that leaves [`DIVERGED`] fit-part
//! standard deviations is not eligible.
//!
//! [`check`] compares the final model's free-run error on the fit part with the baseline's, at the record's
//! own samples. It reports; it does not replace the answer: on the measured records a final model behind the
//! baseline on the fit part was as often far ahead of it held out (a damper under an earthquake record:
//! 0.039 against 0.344) as behind it (a servo: 6.41 against 5.23).

use rayon::prelude::*;
use serde::Serialize;

use crate::diagnose::fit::lm::LmOptions;
use crate::diagnose::fit::operating_point::OperatingPoint;
use crate::diagnose::fit::orders::Structure;
use crate::diagnose::fit::problem::Problem;
use crate::stats::rms_diff;

/// The highest na and nb of the baseline's grid.
pub const BASELINE_ORDER: usize = 4;
/// The longest delay of the baseline's grid.
pub const BASELINE_DELAY: usize = 3;

/// The linear baseline of a record.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LinearBaseline {
    #[serde(flatten)]
    pub structure: Structure,
    /// `y(k) = -sum a_i y(k-i) + sum b_j v(k-delay-j) + constant`, y in the record's units and v the input
    /// about the operating point's input (the fit part's mean).
    pub a: Vec<f64>,
    pub b: Vec<f64>,
    pub constant: f64,
    /// Free-run RMSE on the fit part (what chose it) and on the held-out part, in the record's units.
    pub fit_rmse: f64,
    pub heldout_rmse: f64,
    /// Structures of the grid whose fit or free run was not eligible.
    pub not_eligible: usize,
    /// Its free-run output over the whole record, in the record's units.
    #[serde(skip)]
    pub output: Vec<f64>,
}

/// The least-squares fits use at most this many samples of the fit part (the first): a QR of the regressors
/// of a record of 10^6 samples would cost more than the rest of the diagnosis; the free runs, which choose
/// and score, cover every sample.
pub const LS_SAMPLES: usize = 100_000;

/// A free run farther than this many fit-part standard deviations from the first output has diverged.
pub const DIVERGED: f64 = 1e3;

/// The free run of the ARX model `(a, b, c)` of structure `s` (`y(k) = -sum a_i y(k-i) + sum b_j
/// u(k-delay-j) + c`) over `u`, its past held at the first output `y0` and the first input, as a user starts
/// a simulation from the measured initial condition; `None` when it leaves `limit` about `y0` or is not
/// finite.
fn free_run(
    s: Structure,
    (a, b, c): (&[f64], &[f64], f64),
    u: &[f64],
    y0: f64,
    limit: f64,
) -> Option<Vec<f64>> {
    let u0 = u.first().copied().unwrap_or(0.0);
    let mut y: Vec<f64> = Vec::with_capacity(u.len());
    for k in 0..u.len() {
        let past: f64 = a
            .iter()
            .enumerate()
            .map(|(i, ai)| ai * if k > i { y[k - 1 - i] } else { y0 })
            .sum();
        let input: f64 = b
            .iter()
            .enumerate()
            .map(|(j, bj)| bj * k.checked_sub(s.delay + j).map_or(u0, |i| u[i]))
            .sum();
        let v = input - past + c;
        if !(v.is_finite() && (v - y0).abs() <= limit) {
            return None;
        }
        y.push(v);
    }
    Some(y)
}

/// The ARX model with an intercept of `s` by least squares on the fit part of `p` (Householder QR of the
/// regressors, each column scaled to unit norm: a record sampled far faster than its dynamics makes the
/// normal equations too ill-conditioned): `(a, b, c)` with `c` the equation's constant; `None` when the
/// fit part is too short for the structure or the regressors are singular.
fn least_squares(p: &Problem, s: Structure) -> Option<(Vec<f64>, Vec<f64>, f64)> {
    use nalgebra::{DMatrix, DVector};
    let (k0, cols) = (Problem::arx_start(s), s.na + s.nb + 2);
    let end = p.n_fit.min(LS_SAMPLES);
    let rows = end.checked_sub(k0).filter(|r| *r > cols + 2)?;
    let mut phi = DMatrix::<f64>::zeros(rows, cols);
    let mut row = vec![0.0; cols];
    for (r, k) in (k0..end).enumerate() {
        p.arx_row(s, k, &mut row);
        phi.row_mut(r).copy_from_slice(&row);
    }
    let target = DVector::from_column_slice(&p.y[k0..end]);
    let norms: Vec<f64> = phi.column_iter().map(|c| c.norm()).collect();
    if norms.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
        return None;
    }
    for (mut c, v) in phi.column_iter_mut().zip(&norms) {
        c /= *v;
    }
    let qr = phi.qr();
    let rhs = qr.q().transpose() * target;
    let th = qr.r().solve_upper_triangular(&rhs)?;
    let th: Vec<f64> = th.iter().zip(&norms).map(|(t, v)| t / v).collect();
    th.iter().all(|v| v.is_finite()).then(|| {
        let (a, rest) = th.split_at(s.na);
        (a.to_vec(), rest[..=s.nb].to_vec(), rest[s.nb + 1])
    })
}

/// One structure's least-squares fit `(structure, a, b, c)` and its fit-part free-run RMSE.
type Scored = (Structure, Vec<f64>, Vec<f64>, f64, f64);

/// The baseline of (u, y) with the first `n_fit` samples fitted; `None` when no structure of the grid can be
/// fitted and simulated (a record too short for every one, or all diverge).
pub fn linear_baseline(u: &[f64], y: &[f64], n_fit: usize) -> Option<LinearBaseline> {
    let n = u.len().min(y.len());
    if n_fit == 0 || n_fit >= n {
        return None;
    }
    let op = OperatingPoint::of(&u[..n], &y[..n], n_fit);
    let (ud, yd) = (op.deviations(&u[..n], op.u), op.deviations(&y[..n], op.y));
    let p = Problem::new(&ud, &yd, n_fit, LmOptions::default());
    let limit = DIVERGED * crate::stats::std_dev(&yd[..n_fit]).max(f64::MIN_POSITIVE);
    let grid: Vec<Structure> = (1..=BASELINE_DELAY)
        .flat_map(|delay| {
            (1..=BASELINE_ORDER)
                .flat_map(move |na| (1..=BASELINE_ORDER).map(move |nb| Structure { na, nb, delay }))
        })
        .collect();
    // Each structure's free run is scored and dropped (48 outputs of a long record at once would cost more
    // memory than the diagnosis); the best one's is run again.
    let fits: Vec<Option<Scored>> = grid
        .par_iter()
        .map(|&s| {
            let (a, b, c) = least_squares(&p, s)?;
            let out = free_run(s, (&a, &b, c), &ud, yd[0], limit)?;
            let fit_rmse = rms_diff(&yd[..n_fit], &out[..n_fit]);
            fit_rmse.is_finite().then_some((s, a, b, c, fit_rmse))
        })
        .collect();
    let not_eligible = fits.iter().filter(|f| f.is_none()).count();
    // The lowest fit-part error; a tie goes to the first in the grid (shorter delay, then fewer a's and b's).
    let (s, a, b, c, fit_rmse) = fits
        .into_iter()
        .flatten()
        .reduce(|m, f| if f.4 < m.4 { f } else { m })?;
    let out = free_run(s, (&a, &b, c), &ud, yd[0], limit)?;
    Some(LinearBaseline {
        structure: s,
        constant: c + op.y * (1.0 + a.iter().sum::<f64>()),
        a,
        b,
        fit_rmse,
        heldout_rmse: rms_diff(&yd[n_fit..], &out[n_fit..n]),
        not_eligible,
        output: out.iter().map(|v| v + op.y).collect(),
    })
}

/// The baseline held against a diagnosis's final model on the fit part, at the record's own samples.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BaselineCheck {
    #[serde(flatten)]
    pub baseline: LinearBaseline,
    /// The fit-part samples both are compared on (the fit part, less a partial block of a decimated record).
    pub compared_samples: usize,
    /// The baseline's and the final model's free-run RMSE on those samples, the final model's output held
    /// over the samples each of its (decimated) samples stands for.
    pub baseline_compared_rmse: f64,
    pub final_fit_rmse: f64,
    /// The final model's fit-part error is above the baseline's.
    pub final_behind: bool,
    pub reason: String,
}

/// The baseline of (u, y) (the first `n_fit` samples fitted) held against `final_output`, the final model's
/// free run at `decimate` times fewer samples (in the record's units), with `final_heldout` its held-out
/// error; `None` without a baseline.
pub fn check(
    (u, y): (&[f64], &[f64]),
    n_fit: usize,
    (final_output, final_heldout): (&[f64], f64),
    decimate: usize,
) -> Option<BaselineCheck> {
    let baseline = linear_baseline(u, y, n_fit)?;
    let d = decimate.max(1);
    let held: Vec<f64> = final_output
        .iter()
        .flat_map(|&v| std::iter::repeat_n(v, d))
        .collect();
    let m = n_fit.min(held.len());
    let final_fit_rmse = rms_diff(&y[..m], &held[..m]);
    let baseline_compared_rmse = rms_diff(&y[..m], &baseline.output[..m]);
    let final_behind = final_fit_rmse > baseline_compared_rmse || final_fit_rmse.is_nan();
    let s = baseline.structure;
    let compared = format!(
        "the final model's free-run RMSE on the fit part is {final_fit_rmse:.4e} (at the record's own \
         samples), the best ARX model with an intercept at the record's own rate ({s}) has {:.4e}",
        baseline_compared_rmse
    );
    let reason = if final_behind {
        format!(
            "the final model is behind the best linear model on the data it was fitted to: {compared}, so \
             the catalogue explains nothing there that a linear model does not; held out, the final model \
             has {final_heldout:.4e} and the linear model {:.4e}",
            baseline.heldout_rmse
        )
    } else {
        format!("{compared}: the final model is not behind it")
    };
    Some(BaselineCheck {
        baseline,
        compared_samples: m,
        baseline_compared_rmse,
        final_fit_rmse,
        final_behind,
        reason,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::effects::rig::Draw;
    use rand_chacha::ChaCha8Rng;
    use rand_core::SeedableRng;

    /// A first-order ARX record with a constant (x(k) = 0.8 x(k-1) + 0.5 u(k-2), y = x + 3, small noise):
    /// the baseline fits it to the noise, and a shift of u and y by constants changes neither its structure
    /// nor its errors (its constant moves with y).
    #[test]
    fn the_baseline_finds_a_linear_record_and_ignores_offsets() {
        let mut d = Draw(ChaCha8Rng::seed_from_u64(3));
        let n = 1500;
        let u: Vec<f64> = (0..n).map(|_| d.uniform(-1.0, 1.0)).collect();
        let mut x = vec![0.0; n];
        for k in 2..n {
            x[k] = 0.8 * x[k - 1] + 0.5 * u[k - 2];
        }
        let y: Vec<f64> = x.iter().map(|v| v + 3.0 + d.uniform(-0.02, 0.02)).collect();
        let n_fit = 1050;
        let b = linear_baseline(&u, &y, n_fit).expect("a baseline");
        // At the noise level (uniform +-0.02: RMSE 0.0115), whatever structure reads lag 2.
        let errors = |m: &LinearBaseline| (m.structure, m.fit_rmse, m.heldout_rmse);
        assert!(
            b.fit_rmse < 0.02 && b.heldout_rmse < 0.02,
            "{:?}",
            errors(&b)
        );
        let us: Vec<f64> = u.iter().map(|v| v - 3.0).collect();
        let ys: Vec<f64> = y.iter().map(|v| v + 7.0).collect();
        let s = linear_baseline(&us, &ys, n_fit).expect("a baseline");
        assert_eq!(s.structure, b.structure);
        assert!(
            (s.fit_rmse / b.fit_rmse - 1.0).abs() < 1e-6,
            "{:?} {:?}",
            errors(&s),
            errors(&b)
        );
        assert!((s.heldout_rmse / b.heldout_rmse - 1.0).abs() < 1e-6);
        let gain = 1.0 + b.a.iter().sum::<f64>();
        assert!(
            (s.constant - b.constant - 7.0 * gain).abs() < 1e-6,
            "{s:?} {b:?}"
        );
    }

    /// The check holds a decimated output over its blocks and finds the final model behind only when it is
    /// worse on the fit part.
    #[test]
    fn the_check_holds_the_final_output_and_judges_on_the_fit_part() {
        let mut d = Draw(ChaCha8Rng::seed_from_u64(5));
        let n = 1200;
        let u: Vec<f64> = (0..n)
            .map(|k| if (k / 40) % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let mut y = vec![0.0; n];
        for k in 1..n {
            y[k] = 0.9 * y[k - 1] + 0.1 * u[k - 1];
        }
        let y: Vec<f64> = y.iter().map(|v| v + d.uniform(-0.01, 0.01)).collect();
        let n_fit = 840;
        // A perfect final output at half the rate (block means) beats nothing worse than its own hold.
        let means: Vec<f64> = y
            .chunks(2)
            .map(|c| c.iter().sum::<f64>() / c.len() as f64)
            .collect();
        let good = check((&u, &y), n_fit, (&means, 0.0), 2).expect("a check");
        assert_eq!(good.compared_samples, n_fit);
        let held_err = rms_diff(
            &y[..n_fit],
            &means.iter().flat_map(|&v| [v, v]).collect::<Vec<_>>()[..n_fit],
        );
        assert!((good.final_fit_rmse - held_err).abs() < 1e-12);
        // A constant is worse than the first-order ARX: behind it, said so; the record itself is not.
        let flat = vec![0.0; n / 2];
        let bad = check((&u, &y), n_fit, (&flat, 1.0), 2).expect("a check");
        assert!(bad.final_behind, "{}", bad.reason);
        assert!(
            bad.reason.contains("behind the best linear model"),
            "{}",
            bad.reason
        );
        let exact = check((&u, &y), n_fit, (&y, 0.0), 1).expect("a check");
        assert!(!exact.final_behind, "{}", exact.reason);
        assert!(exact.reason.contains("not behind"), "{}", exact.reason);
    }

    /// Nothing to fit: no baseline.
    #[test]
    fn a_record_too_short_has_no_baseline() {
        assert!(linear_baseline(&[1.0, 2.0], &[1.0, 2.0], 1).is_none());
        assert!(linear_baseline(&[1.0; 10], &[1.0; 10], 10).is_none());
    }
}
