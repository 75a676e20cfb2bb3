//! The sampling rate a record is fitted at: a record sampled far faster than its dynamics is decimated
//! (block means, as `--decimate` does) before anything is fitted.
//!
//! **Why.** At a rate far above the dynamics the linear block's poles crowd towards 1: its coefficients are
//! nearly collinear, least-squares starts are biased towards one-step prediction, the delay spans tens of
//! samples (beyond the delays the structure search tries) and every fit simulates tens of thousands of
//! samples that carry little more than a few hundred would.
//!
//! **The criterion.** A probe model, the linear output-error model with two poles, one zero and delay 1
//! (`linear_oe`), is fitted on the first [`PROBE_SAMPLES`] samples (at most) of the
//! fit part. Its slowest pole `p` (radius r, angle theta) gives the dynamics' time constant
//! `tau = -1 / ln r` samples and, when it oscillates, `2 pi / theta` samples per period. The record is
//! oversampled when `tau` spans more than [`SAMPLES_PER_TAU`] samples at a coarser rate: the factor is
//! `D = floor(tau / SAMPLES_PER_TAU)`, at most `pi / (4 theta)` (eight samples per period of an
//! oscillation stay), at most the record's length over [`MIN_SAMPLES`] and at most [`MAX_FACTOR`];
//! below [`MIN_FACTOR`] the record is kept at its rate. The user's `--decimate` always wins.

use serde::Serialize;

use crate::diagnose::fit::linear_oe::{self, LinearOe};

/// The probe is fitted on at most this many samples of the fit part.
pub const PROBE_SAMPLES: usize = 20_000;

/// At the chosen rate, the slowest time constant spans about this many samples. Block means of a backlash
/// output are not the backlash of block means, so every factor costs some model error as well as samples:
/// with 4, records of a slow first-order block with backlash (time constant 33 samples) were decimated by 5
/// and their held-out error rose from the noise level to 2-3 times the decimated record's; with 10, the
/// test bench's plant sampled 30 times faster than its own rate was decimated by 8 and ended 1.29 times the
/// true model's error there, by 3 at 1.04 times.
pub const SAMPLES_PER_TAU: f64 = 25.0;

/// Factors below this keep the record's rate.
pub const MIN_FACTOR: usize = 2;

/// The decimated record keeps at least this many samples.
pub const MIN_SAMPLES: usize = 600;

/// The largest factor chosen from the data.
pub const MAX_FACTOR: usize = 1000;

/// Probe iterations (the probe only needs its slowest pole).
const PROBE_ITER: usize = 30;

/// The rate a record is fitted at, and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Rate {
    /// Block-mean decimation factor (1: every sample).
    pub decimate: usize,
    /// `user` (`--decimate` / `decimate=` given), or `data` (this module's criterion).
    pub chosen_by: &'static str,
    /// The probe's slowest time constant in samples of the record as given (`None`: not probed).
    pub time_constant: Option<f64>,
    pub reason: String,
}

impl Rate {
    /// The user's factor.
    pub fn user(decimate: usize) -> Self {
        Self {
            decimate,
            chosen_by: "user",
            time_constant: None,
            reason: if decimate > 1 {
                format!("decimated by {decimate} as asked (block means)")
            } else {
                "every sample, as asked".into()
            },
        }
    }
}

/// The slowest pole of `1 + a1 z^-1 + a2 z^-2` as (radius, angle in radians).
fn slowest_pole(a: &[f64]) -> (f64, f64) {
    let (a1, a2) = (a[0], a.get(1).copied().unwrap_or(0.0));
    let disc = a1 * a1 - 4.0 * a2;
    if disc >= 0.0 {
        let s = disc.sqrt();
        let r = ((-a1 + s) / 2.0).abs().max(((-a1 - s) / 2.0).abs());
        // A negative real pole alternates every sample: an angle of pi.
        let angle = if (-a1 - s).abs() > (-a1 + s).abs() && (-a1 - s) < 0.0 {
            std::f64::consts::PI
        } else {
            0.0
        };
        (r, angle)
    } else {
        (a2.sqrt(), ((-disc).sqrt()).atan2(-a1).abs())
    }
}

/// The factor for a slowest pole (radius r, angle theta) on a record of `n` samples (module docs).
fn factor_for(r: f64, theta: f64, n: usize) -> (usize, f64) {
    let tau = if r > 0.0 && r < 1.0 {
        -1.0 / r.ln()
    } else {
        0.0
    };
    let mut d = (tau / SAMPLES_PER_TAU).floor();
    if theta > 0.0 {
        d = d.min((std::f64::consts::PI / (4.0 * theta)).floor());
    }
    let d = (d.max(1.0) as usize)
        .min((n / MIN_SAMPLES).max(1))
        .min(MAX_FACTOR);
    (if d < MIN_FACTOR { 1 } else { d }, tau)
}

/// The rate for a record (u, y) whose first `n_fit` samples are fitted (see the module's documentation).
pub fn choose(u: &[f64], y: &[f64], n_fit: usize) -> Rate {
    let n = u.len().min(y.len());
    let m = n_fit.min(n).min(PROBE_SAMPLES);
    let keep = |reason: String| Rate {
        decimate: 1,
        chosen_by: "data",
        time_constant: None,
        reason,
    };
    if m < 50 || n < MIN_FACTOR * MIN_SAMPLES {
        return keep(format!(
            "every sample: {n} samples are too few to decimate (at least {} are kept)",
            MIN_SAMPLES
        ));
    }
    let u0 = u[0];
    let v: Vec<f64> = u[..m].iter().map(|x| x - u0).collect();
    let mean_y = crate::stats::mean(&y[..m]);
    let start = LinearOe {
        a: vec![-1.5, 0.56],
        b: vec![0.0, 0.0],
        c: mean_y,
    };
    let d = linear_oe::Data {
        v: &v,
        y,
        delay: 1,
        n: m,
    };
    let Some((probe, _)) = linear_oe::fit(start, &d, PROBE_ITER) else {
        return keep("every sample: the probe model could not be fitted".into());
    };
    let (r, theta) = slowest_pole(&probe.a);
    let (factor, tau) = factor_for(r, theta, n);
    let rate = Rate {
        decimate: factor,
        chosen_by: "data",
        time_constant: Some(tau),
        reason: String::new(),
    };
    let reason = if factor > 1 {
        format!(
            "decimated by {factor} (block means): the slowest pole of a two-pole linear output-error probe, \
             radius {r:.4}, gives a time constant of {tau:.1} samples, so the record is sampled far faster than \
             its dynamics; about {SAMPLES_PER_TAU} samples per time constant are kept"
        )
    } else {
        format!(
            "every sample: the slowest pole of a two-pole linear output-error probe, radius {r:.4}, gives a time \
             constant of {tau:.1} samples (decimation needs at least {} samples per time constant)",
            SAMPLES_PER_TAU * MIN_FACTOR as f64
        )
    };
    Rate { reason, ..rate }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn poles_and_factors_by_hand() {
        // (1 - 0.9 z^-1)(1 - 0.5 z^-1) = 1 - 1.4 z^-1 + 0.45 z^-2: slowest radius 0.9.
        let (r, th) = slowest_pole(&[-1.4, 0.45]);
        assert!((r - 0.9).abs() < 1e-12 && th == 0.0);
        // Complex pair 0.8 e^{+-i 0.3}: a1 = -1.6 cos 0.3, a2 = 0.64.
        let (r, th) = slowest_pole(&[-1.6 * 0.3f64.cos(), 0.64]);
        assert!((r - 0.8).abs() < 1e-12 && (th - 0.3).abs() < 1e-12);
        // tau = -1/ln 0.995 = 199.5 samples: factor 7; an oscillation of angle 0.2 caps it at 3.
        assert_eq!(factor_for(0.995, 0.0, 1_000_000).0, 7);
        assert_eq!(factor_for(0.995, 0.2, 1_000_000).0, 3);
        // The record's length caps it; below 2 the rate is kept (a fast plant, a time constant of 33).
        assert_eq!(factor_for(0.995, 0.0, 3000).0, 5);
        assert_eq!(factor_for(0.97, 0.0, 1_000_000).0, 1);
        assert_eq!(factor_for(0.7, 0.0, 1_000_000).0, 1);
    }

    /// A first-order block with pole 0.995 (time constant 200 samples) driven by a slow square wave: the
    /// record is decimated, by a factor near 200 / 25; the paper-like fast block is kept at its rate.
    #[test]
    fn a_slow_record_is_decimated_and_a_fast_one_is_not() {
        let n = 40_000;
        let u: Vec<f64> = (0..n)
            .map(|k| if (k / 700) % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let first_order = |pole: f64| {
            let mut y = vec![0.0; n];
            for k in 1..n {
                y[k] = pole * y[k - 1] + (1.0 - pole) * u[k - 1];
            }
            y
        };
        let rate = choose(&u, &first_order(0.995), 28_000);
        assert!((6..=10).contains(&rate.decimate), "{rate:?}");
        assert_eq!(rate.chosen_by, "data");
        let white: Vec<f64> = (0..n)
            .map(|k| ((k * 7919 % 101) as f64 / 50.0) - 1.0)
            .collect();
        let mut y = vec![0.0; n];
        for k in 2..n {
            y[k] = 0.45 * y[k - 1] - 0.2 * y[k - 2] + white[k - 1];
        }
        assert_eq!(choose(&white, &y, 28_000).decimate, 1);
    }
}
