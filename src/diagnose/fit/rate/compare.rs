//! Candidate rates compared on the data: at each, the backlash models of the structure selection's first
//! stage are fitted on the estimation part of a window of the fit part, simulated, and their block means held
//! over the samples they stand for; the errors are taken against the record as given, on the same validation
//! samples (the window's last third), in the record's units. Nothing of the held-out part is seen.

use serde::Serialize;

use crate::diagnose::fit::lm::LmOptions;
use crate::diagnose::fit::problem::Problem;
use crate::diagnose::fit::structure::{grid, initial_state, rate_models};

/// The comparison uses at most this many samples of the fit part (as given).
pub const COMPARE_SAMPLES: usize = 12_000;

/// The longest delay of the structures fitted at each rate (the diagnosis's default `--max-delay`).
const MAX_DELAY: usize = 10;

/// A rate replaces the time-constant rule's only when its validation error is lower by more than this
/// fraction.
pub const MARGIN: f64 = 0.01;

/// One rate compared.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RateCandidate {
    /// Block-mean decimation factor.
    pub decimate: usize,
    /// Free-run RMSE of its best backlash model on the validation samples, block means held over the samples
    /// they stand for, against the record as given (`None`: nothing could be fitted at this rate).
    pub validation_rmse: Option<f64>,
}

/// The simulations at rate `d` on the window `0..n_w` of (u, y), each held at the samples as given, and the
/// first sample (as given) after its estimation part.
fn held_simulations(u: &[f64], y: &[f64], d: usize, n_w: usize) -> (Vec<Vec<f64>>, usize) {
    let mut cols = crate::stats::block_means(&[&u[..n_w], &y[..n_w]], d).into_iter();
    let (ud, yd) = (
        cols.next().unwrap_or_default(),
        cols.next().unwrap_or_default(),
    );
    let m = ud.len().min(yd.len());
    if m < 20 {
        return (Vec::new(), n_w);
    }
    let mut p = Problem::new(&ud[..m], &yd[..m], m, LmOptions::default());
    let initial = initial_state(&p, &grid(MAX_DELAY, m, m));
    p.rest = initial.rest_for(ud[0]);
    let (n_est, models) = rate_models(&p, MAX_DELAY);
    let sims = models
        .iter()
        .filter_map(|model| model.simulate(p.u, p.rest, m, p.limit))
        .map(|sim| {
            sim.y[..m]
                .iter()
                .flat_map(|&v| std::iter::repeat_n(v, d))
                .collect()
        })
        .collect();
    (sims, n_est * d)
}

/// Every factor of `factors` (the first is the time-constant rule's) scored on the same validation samples of
/// the fit part's first [`COMPARE_SAMPLES`] samples; the index of the chosen one (the rule's unless another
/// is more than [`MARGIN`] lower) and every score.
pub fn compare(
    u: &[f64],
    y: &[f64],
    n_fit: usize,
    factors: &[usize],
) -> (usize, Vec<RateCandidate>) {
    let n_w = n_fit.min(COMPARE_SAMPLES).min(u.len()).min(y.len());
    let runs: Vec<(Vec<Vec<f64>>, usize)> = factors
        .iter()
        .map(|&d| held_simulations(u, y, d, n_w))
        .collect();
    // Samples no rate estimated on and every rate simulated.
    let k0 = runs.iter().map(|r| r.1).max().unwrap_or(n_w);
    let k1 = factors.iter().map(|&d| n_w / d * d).min().unwrap_or(0);
    let scored: Vec<RateCandidate> = factors
        .iter()
        .zip(&runs)
        .map(|(&d, (sims, _))| RateCandidate {
            decimate: d,
            validation_rmse: (k0 < k1)
                .then(|| {
                    sims.iter()
                        .map(|s| crate::stats::rms_diff(&y[k0..k1], &s[k0..k1]))
                        .filter(|e| e.is_finite())
                        .min_by(f64::total_cmp)
                })
                .flatten(),
        })
        .collect();
    (pick(&scored), scored)
}

/// The first candidate (the rule's) unless another's error is more than [`MARGIN`] below it; among those,
/// the lowest.
fn pick(c: &[RateCandidate]) -> usize {
    let err = |i: usize| c[i].validation_rmse.unwrap_or(f64::INFINITY);
    let best = (0..c.len()).min_by(|&a, &b| err(a).total_cmp(&err(b)));
    match best {
        Some(b)
            if err(b) < err(0) * (1.0 - MARGIN) || (err(0).is_infinite() && err(b).is_finite()) =>
        {
            b
        }
        _ => 0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cand(decimate: usize, e: Option<f64>) -> RateCandidate {
        RateCandidate {
            decimate,
            validation_rmse: e,
        }
    }

    /// The rule's rate stays unless another is more than 1% better; a rule's rate that cannot be fitted
    /// yields to one that can.
    #[test]
    fn the_rules_rate_needs_a_clear_loser_to_yield() {
        assert_eq!(pick(&[cand(1, Some(1.0)), cand(2, Some(0.995))]), 0);
        assert_eq!(
            pick(&[cand(1, Some(1.0)), cand(2, Some(0.98)), cand(4, Some(0.9))]),
            2
        );
        assert_eq!(pick(&[cand(1, None), cand(2, Some(5.0))]), 1);
        assert_eq!(pick(&[cand(1, None), cand(2, None)]), 0);
    }
}
