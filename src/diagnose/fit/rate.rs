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
//! `tau = -1 / ln r` samples and, when it oscillates, `2 pi / theta` samples per period. The rule's factor
//! keeps about [`SAMPLES_PER_TAU`] samples per time constant: `D = floor(tau / SAMPLES_PER_TAU)`, at most
//! `pi / (4 theta)` (eight samples per period of an oscillation stay), at most the record's length over
//! [`MIN_SAMPLES`] and at most [`MAX_FACTOR`]; below [`MIN_FACTOR`] it is 1 (every sample).
//!
//! **The comparison.** The same bounds with about 12 and 6 samples per time constant ([`COARSER_PER_TAU`])
//! give coarser factors. When there are any, or when the rule's factor is above 1, every factor is judged on
//! the data (`compare`), and factor 1 (every sample, the record as given) is always among them: a rule that
//! asks for a coarser rate is checked against the record's own. At each factor, the
//! structure selection's first stage ranks the structures by their linear output-error models and the
//! backlash models of the best, of the smallest near it and of that one at delay 1 (the play's hold reads as a
//! delay to a linear model) are fitted on the first two thirds of a window
//! of the fit part ([`COMPARE_SAMPLES`]) at that rate; their free runs, each block mean held over the
//! samples it stands for, are compared with the record as given on the window's last third (the same
//! samples for every factor, in the record's units). The rule's factor stays unless another's error is more
//! than 1% lower. Judged at the record's samples, a coarser factor also pays for the output's variation
//! within its blocks, which no block mean follows: a record whose every-sample fit succeeds keeps every
//! sample, and the coarser rates win where that fit fails (poles crowding at 1, a delay beyond the search).
//! The cost is bounded by [`COMPARE_SAMPLES`]: at factor 1 the structures are ranked and at most three backlash models
//! fitted on at most that many samples. Why not the rule alone: a DC motor record with a time constant of 27 samples is fitted far
//! better at a quarter of its rate (its nonlinear fits converge there), while the test bench's plant with the
//! same time constant (input levels held for 10 samples) loses at every coarser rate; no threshold on tau
//! separates the two. A linear model alone cannot choose either: the backlash it lacks dominates its error
//! at every rate. The user's `--decimate` always wins.

use serde::Serialize;

use crate::diagnose::fit::linear_oe::{self, LinearOe};

mod compare;
pub use compare::{COMPARE_SAMPLES, RateCandidate};

/// The probe is fitted on at most this many samples of the fit part.
pub const PROBE_SAMPLES: usize = 20_000;

/// At the chosen rate, the slowest time constant spans about this many samples. Block means of a backlash
/// output are not the backlash of block means, so every factor costs some model error as well as samples:
/// with 4, records of a slow first-order block with backlash (time constant 33 samples) were decimated by 5
/// and their held-out error rose from the noise level to 2-3 times the decimated record's; with 10, the
/// test bench's plant sampled 30 times faster than its own rate was decimated by 8 and ended 1.29 times the
/// true model's error there, by 3 at 1.04 times.
pub const SAMPLES_PER_TAU: f64 = 25.0;

/// Coarser rates compared with the rule's: about this many samples per time constant (each kept only when
/// it is a factor of at least 2 and coarser than the rule's).
pub const COARSER_PER_TAU: [f64; 2] = [12.0, 6.0];

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
    /// The rates compared on the fit part (empty: none was compared), the time-constant rule's first, then
    /// every sample (when the rule's is coarser), then the coarser ones.
    pub candidates: Vec<RateCandidate>,
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
            candidates: Vec::new(),
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

/// The factor for a slowest pole (radius r, angle theta) on a record of `n` samples, keeping about
/// `per_tau` samples per time constant (module docs), and the time constant.
fn factor_for(r: f64, theta: f64, n: usize, per_tau: f64) -> (usize, f64) {
    let tau = if r > 0.0 && r < 1.0 {
        -1.0 / r.ln()
    } else {
        0.0
    };
    let mut d = (tau / per_tau).floor();
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
        candidates: Vec::new(),
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
    let (rule, tau) = factor_for(r, theta, n, SAMPLES_PER_TAU);
    let factors = candidate_factors(rule, r, theta, n);
    let mut probe_says = format!(
        "the slowest pole of a two-pole linear output-error probe, radius {r:.4}, gives a time constant of \
         {tau:.1} samples"
    );
    if theta > 0.0 {
        probe_says += &format!(
            " and oscillates with a period of {:.1} samples",
            std::f64::consts::TAU / theta
        );
    }
    if factors.len() == 1 {
        return Rate {
            decimate: 1,
            chosen_by: "data",
            time_constant: Some(tau),
            reason: rule_reason(&probe_says),
            candidates: Vec::new(),
        };
    }
    let (i, candidates) = compare::compare(u, y, n_fit, &factors);
    Rate {
        decimate: factors[i],
        chosen_by: "data",
        time_constant: Some(tau),
        reason: compared_reason(i, &candidates, &probe_says),
        candidates,
    }
}

/// The factors compared for a probe's slowest pole (radius r, angle theta) on a record of `n` samples: the
/// rule's factor `rule` first, then 1 (every sample, the record as given) when the rule's is coarser, then
/// the coarser factors of [`COARSER_PER_TAU`], each kept only when it is coarser than every factor before
/// it. A single factor (1) means nothing is compared.
fn candidate_factors(rule: usize, r: f64, theta: f64, n: usize) -> Vec<usize> {
    let mut factors = vec![rule];
    if rule > 1 {
        factors.push(1);
    }
    for per_tau in COARSER_PER_TAU {
        let d = factor_for(r, theta, n, per_tau).0;
        if factors.iter().all(|&f| d > f) {
            factors.push(d);
        }
    }
    factors
}

/// Why every sample was kept with nothing to compare.
fn rule_reason(probe_says: &str) -> String {
    format!(
        "every sample: {probe_says}; no factor of at least {MIN_FACTOR} keeps {} samples per time constant, \
         8 per period of an oscillation and {MIN_SAMPLES} samples",
        COARSER_PER_TAU[COARSER_PER_TAU.len() - 1]
    )
}

/// Why the compared factor `i` of `c` was chosen.
fn compared_reason(i: usize, c: &[RateCandidate], probe_says: &str) -> String {
    let list: Vec<String> = c
        .iter()
        .map(|c| match c.validation_rmse {
            Some(e) => format!("{} ({e:.4e})", c.decimate),
            None => format!("{} (not fitted)", c.decimate),
        })
        .collect();
    let what = match c[i].decimate {
        1 => "every sample".to_string(),
        d => format!("decimated by {d} (block means)"),
    };
    let why = if i == 0 {
        format!(
            "no other rate's error was more than {:.0}% lower than that of the rate keeping about \
             {SAMPLES_PER_TAU} samples per time constant",
            100.0 * compare::MARGIN
        )
    } else {
        format!(
            "the lowest error, more than {:.0}% below that of the rate keeping about {SAMPLES_PER_TAU} samples \
             per time constant",
            100.0 * compare::MARGIN
        )
    };
    format!(
        "{what}: {probe_says}; the backlash models fitted at each factor, held at the record's samples, gave \
         these free-run RMSEs on the last third of the fit part's first {COMPARE_SAMPLES} samples: {}; {why}",
        list.join(", ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::effects::rig::Draw;
    use rand_chacha::ChaCha8Rng;
    use rand_core::SeedableRng;

    #[test]
    fn poles_and_factors_by_hand() {
        // (1 - 0.9 z^-1)(1 - 0.5 z^-1) = 1 - 1.4 z^-1 + 0.45 z^-2: slowest radius 0.9.
        let (r, th) = slowest_pole(&[-1.4, 0.45]);
        assert!((r - 0.9).abs() < 1e-12 && th == 0.0);
        // Complex pair 0.8 e^{+-i 0.3}: a1 = -1.6 cos 0.3, a2 = 0.64.
        let (r, th) = slowest_pole(&[-1.6 * 0.3f64.cos(), 0.64]);
        assert!((r - 0.8).abs() < 1e-12 && (th - 0.3).abs() < 1e-12);
        // tau = -1/ln 0.995 = 199.5 samples: factor 7; an oscillation of angle 0.2 caps it at 3.
        assert_eq!(factor_for(0.995, 0.0, 1_000_000, SAMPLES_PER_TAU).0, 7);
        assert_eq!(factor_for(0.995, 0.2, 1_000_000, SAMPLES_PER_TAU).0, 3);
        // The record's length caps it; below 2 the rate is kept (a fast plant, a time constant of 33).
        assert_eq!(factor_for(0.995, 0.0, 3000, SAMPLES_PER_TAU).0, 5);
        assert_eq!(factor_for(0.97, 0.0, 1_000_000, SAMPLES_PER_TAU).0, 1);
        assert_eq!(factor_for(0.7, 0.0, 1_000_000, SAMPLES_PER_TAU).0, 1);
        // Compared: the rule's 7, every sample, then about 12 and 6 samples per time constant (16, 33); a
        // rule of 1 comes once; a fast plant compares nothing.
        assert_eq!(candidate_factors(7, 0.995, 0.0, 1_000_000), [7, 1, 16, 33]);
        assert_eq!(candidate_factors(1, 0.97, 0.0, 1_000_000), [1, 2, 5]);
        assert_eq!(candidate_factors(1, 0.7, 0.0, 1_000_000), [1]);
    }

    /// A first-order block with pole 0.995 (time constant 200 samples), no noise, driven by a slow square
    /// wave: the rule asks for a factor near 200 / 25; every sample is compared too and wins, its backlash
    /// model fitting the record exactly where block means held over their samples cannot follow the output's
    /// ramps. The paper-like fast block compares nothing and keeps its rate.
    #[test]
    fn a_slow_record_fitted_exactly_keeps_every_sample_and_a_fast_one_compares_nothing() {
        let n = 40_000;
        let u: Vec<f64> = (0..n)
            .map(|k| if (k / 700) % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let mut y = vec![0.0; n];
        for k in 1..n {
            y[k] = 0.995 * y[k - 1] + 0.005 * u[k - 1];
        }
        let rate = choose(&u, &y, 28_000);
        assert!((6..=10).contains(&rate.candidates[0].decimate), "{rate:?}");
        assert_eq!((rate.decimate, rate.chosen_by), (1, "data"), "{rate:?}");
        let every = rate.candidates.iter().find(|c| c.decimate == 1);
        assert!(
            every
                .and_then(|c| c.validation_rmse)
                .is_some_and(|e| e < 1e-6),
            "{rate:?}"
        );
        let white: Vec<f64> = (0..n)
            .map(|k| ((k * 7919 % 101) as f64 / 50.0) - 1.0)
            .collect();
        let mut y = vec![0.0; n];
        for k in 2..n {
            y[k] = 0.45 * y[k - 1] - 0.2 * y[k - 2] + white[k - 1];
        }
        let fast = choose(&white, &y, 28_000);
        assert!(fast.decimate == 1 && fast.candidates.is_empty(), "{fast:?}");
    }

    /// A second-order block (poles 0.965 +- 0.03i, time constant about 28 samples) followed by a play, its
    /// input a level held for 10 samples, a little noise. The play slows the linear probe (a time constant of
    /// about 62 samples), so the rule asks for a factor of 2, and every sample is judged too. There the
    /// structures ranked first by their linear error carry delays of 7 and 8 samples (the play's dead time
    /// read as a delay), and their backlash fits ended about 2.5 times the error at 2; the smallest one's
    /// twin at delay 1 (the plant's) is fitted too and ends 1.6 times below it: every sample wins, the
    /// comparison deciding, not the rule.
    #[test]
    fn a_record_the_rule_decimates_is_judged_at_every_sample_too() {
        let n = 6000;
        let mut draw = Draw(ChaCha8Rng::seed_from_u64(12345));
        let u: Vec<f64> = (0..n / 10)
            .flat_map(|_| std::iter::repeat_n(draw.uniform(-2.0, 2.0), 10))
            .collect();
        let (a1, a2) = (-2.0 * 0.965, 0.965f64.powi(2) + 0.03f64.powi(2));
        let (mut x, mut w) = (vec![0.0f64; n], vec![0.0f64; n]);
        for k in 2..n {
            x[k] = -a1 * x[k - 1] - a2 * x[k - 2] + (1.0 + a1 + a2) * u[k - 1];
            w[k] = w[k - 1].clamp(x[k] - 0.5, x[k] + 0.5);
        }
        let y: Vec<f64> = w.iter().map(|w| w + draw.uniform(-0.01, 0.01)).collect();
        let rate = choose(&u, &y, 4200);
        assert!(rate.reason.contains("free-run RMSEs"), "{}", rate.reason);
        let e = |i: usize| rate.candidates[i].validation_rmse.unwrap_or(f64::INFINITY);
        let every = rate.candidates.iter().position(|c| c.decimate == 1);
        let every = every.expect("every sample is among the compared rates");
        assert!(rate.candidates[0].decimate > 1 && every > 0, "{rate:?}");
        assert_eq!(rate.decimate, 1, "{rate:?}");
        assert!(e(every) < e(0) * (1.0 - compare::MARGIN), "{rate:?}");
        assert!(
            (0..rate.candidates.len()).all(|i| e(i) >= e(every)),
            "{rate:?}"
        );
    }
}
