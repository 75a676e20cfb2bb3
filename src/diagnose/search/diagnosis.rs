//! What a diagnosis finds: its settings, the fitted candidates, the rounds of the loop and the result.

use std::time::Duration;

use serde::Serialize;

use crate::diagnose::effects::{CATALOGUE, EffectId};
use crate::diagnose::fit::lm::LmOptions;
use crate::diagnose::fit::model::{BaseModel, EffectModel, Simulation};
use crate::diagnose::fit::problem::sim_limit;
use crate::diagnose::fit::structure::{InitialState, Structure, StructureChoice};
use crate::diagnose::record::{POOR_EXCITATION, excitation};
use crate::diagnose::residual::Verdict;
use crate::diagnose::search::decision;
use crate::stats::{rms_diff, std_dev};

/// The error kind of a candidate judged by its free-run simulation.
pub(crate) const SIMULATION: &str = "simulation";

/// Settings of a diagnosis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiagnoseConfig {
    /// The declared structure; `None`: chosen from the data (`structure::select`).
    pub structure: Option<Structure>,
    /// The longest delay the structure selection tries (it also stays below a tenth of the fit part).
    pub max_delay: usize,
    /// Share of the record used for fitting (the rest is held out). Default 0.7.
    pub fit_fraction: f64,
    /// Lags of the correlation tests. Default 20.
    pub lags: usize,
    /// Perturbed restarts of the plain model's fit, besides its other starts. Default 3.
    pub restarts: usize,
    /// Seed of the perturbations (the diagnosis is deterministic for a given seed).
    pub seed: u64,
    /// One-sided z threshold of the held-out comparison (Diebold-Mariano). Default 1.645 (5%).
    pub z_threshold: f64,
    pub lm: LmOptions,
    /// Wall-clock budget of the whole diagnosis; candidates not fitted when it is spent are listed as not
    /// tried. Default 300 s.
    pub time_budget: Duration,
    /// The most effects the loop adds (1: the first round only). Default 3.
    pub max_effects: usize,
}

impl DiagnoseConfig {
    /// A declared structure.
    pub fn new(na: usize, nb: usize, delay: usize) -> Self {
        Self {
            structure: Some(Structure { na, nb, delay }),
            ..Self::auto()
        }
    }

    /// The structure chosen from the data.
    pub fn auto() -> Self {
        Self {
            structure: None,
            max_delay: 10,
            fit_fraction: 0.7,
            lags: 20,
            restarts: 3,
            seed: 0,
            z_threshold: decision::Z_THRESHOLD,
            lm: LmOptions::default(),
            time_budget: Duration::from_secs(300),
            max_effects: 3,
        }
    }
}

/// Why a diagnosis could not run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DiagnoseError {
    #[error("u has {u} samples and y {y}: they must be the same length")]
    Length { u: usize, y: usize },
    #[error(
        "{n} samples: at least {min} are needed for this structure (fit part and held-out part)"
    )]
    TooShort { n: usize, min: usize },
    #[error("invalid model structure: {0}")]
    Structure(String),
    #[error(
        "the fit fraction {0} must be between {lo} and {hi}",
        lo = FIT_FRACTIONS.start(),
        hi = FIT_FRACTIONS.end()
    )]
    Fraction(f64),
    #[error("the declared model could not be fitted: no start point gives a valid simulation")]
    NoFit,
    #[error("the record contains a non-finite value at sample {0}")]
    NonFinite(usize),
    #[error("the time budget must be positive")]
    Budget,
    #[error("the most effects to add ({0}) must be between 1 and {max}", max = CATALOGUE.len())]
    MaxEffects(usize),
}

/// A residual test's verdict and the effects it points to.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TestResult {
    #[serde(flatten)]
    pub verdict: Verdict,
    pub points_to: Vec<EffectId>,
}

/// One-step-ahead prediction errors on the held-out part, before and after a noise model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct OneStep {
    pub before: f64,
    pub after: f64,
}

/// A rejected candidate with a lower held-out error than the chosen model ([`Diagnosis::closest_alternative`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClosestAlternative {
    pub id: EffectId,
    /// Its held-out free-run RMSE.
    pub heldout_rmse: f64,
    /// The chosen (final) model's.
    pub chosen_heldout_rmse: f64,
    /// Why the decision rejected it.
    pub reason: String,
}

/// One fitted candidate extension.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Candidate {
    pub id: EffectId,
    /// The rejecting tests that made it a candidate (pointing order).
    pub pointed_by: Vec<&'static str>,
    pub model: EffectModel,
    /// Parameters estimated (base + extension) for the information criterion.
    pub k: usize,
    pub fit_rmse: f64,
    /// Its fit-part cost (sum of squared errors of what it is judged by).
    #[serde(skip)]
    pub fit_cost: f64,
    pub bic: f64,
    /// BIC of the extension minus BIC of the current model (negative favours the extension).
    pub delta_bic: f64,
    /// Held-out free-run simulation RMSE.
    pub heldout_rmse: f64,
    /// Diebold-Mariano z of the held-out squared-error reduction (positive: the extension is better), on
    /// the errors the candidate is judged by.
    pub heldout_z: f64,
    /// What the candidate is judged by: "simulation" or "one-step prediction" (a noise model).
    pub error_kind: &'static str,
    /// For a noise model: the one-step prediction errors it is judged by.
    pub one_step: Option<OneStep>,
    pub supported: bool,
    pub reason: String,
    /// The extension's simulated output over the whole record.
    #[serde(skip)]
    pub output: Vec<f64>,
    #[serde(skip)]
    pub sim: Simulation,
}

/// The best linear output-error model of the structure (backlash replaced by a straight line with an
/// offset: c1 = -c2, m2 = m1 = 1).
#[derive(Debug, Clone, PartialEq)]
pub struct LinearFit {
    pub model: BaseModel,
    pub fit_rmse: f64,
    pub heldout_rmse: f64,
    /// Its simulated output over the whole record.
    pub output: Vec<f64>,
}

pub use crate::diagnose::fit::operating_point::OperatingPoint;
pub use crate::diagnose::search::presence::{BacklashSupport, Presence};

/// One round of the loop after the first: the model it started from (the previous round's winner) and what
/// its residual showed.
#[derive(Debug, Clone, PartialEq)]
pub struct Round {
    /// The model this round extends, with its held-out free-run RMSE and BIC.
    pub current: EffectModel,
    pub current_heldout_rmse: f64,
    pub current_bic: f64,
    pub found: Found,
}

/// What a round found: the residual tests on the current model, the candidates they pointed to, fitted on
/// top of it and judged, and the winner.
#[derive(Debug, Clone, PartialEq)]
pub struct Found {
    pub tests: Vec<TestResult>,
    pub set_aside: Vec<String>,
    pub candidates: Vec<Candidate>,
    pub not_tried: Vec<EffectId>,
    pub chosen: Option<usize>,
}

/// The result of [`diagnose`](super::engine::diagnose).
#[derive(Debug, Clone, PartialEq)]
pub struct Diagnosis {
    pub config: DiagnoseConfig,
    pub n: usize,
    pub n_fit: usize,
    /// The structure used and how it was chosen.
    pub structure: StructureChoice,
    /// The state the record starts from (the input level the model rests at) and why.
    pub initial: InitialState,
    pub linear: LinearFit,
    /// The plain backlash model fitted on the fit part.
    pub base: EffectModel,
    pub base_k: usize,
    pub base_fit_rmse: f64,
    pub base_bic: f64,
    pub base_heldout_rmse: f64,
    /// The plain model's simulation over the whole record.
    pub base_sim: Simulation,
    pub backlash: BacklashSupport,
    /// The residual tests, on the fit part of the plain model's residual.
    pub tests: Vec<TestResult>,
    /// Why a rejecting test did not make an effect a candidate (evidence that belongs to the input).
    pub set_aside: Vec<String>,
    pub candidates: Vec<Candidate>,
    /// Candidates pointed to but not fitted because the time budget was spent.
    pub not_tried: Vec<EffectId>,
    /// Index into `candidates` of the chosen effect.
    pub chosen: Option<usize>,
    /// Number of fits of the plain model needed (a winner whose base part fitted the plain model better
    /// triggers a refit from there).
    pub base_rounds: usize,
    /// The rounds after the first (each extends the previous round's winner), in order; the last one found
    /// nothing, unless the loop stopped at `max_effects`, after a noise model or at the time budget.
    pub later: Vec<Round>,
    /// Why the loop stopped.
    pub stopped: String,
    /// The levels every fit worked about: the models see `u - operating_point.u` and `y - operating_point.y`
    /// (their simulated outputs are given back in the record's units).
    pub operating_point: OperatingPoint,
    /// How much the final model explains on the held-out part, against a constant.
    pub explained: Explained,
}

/// How much the final model explains of the held-out part, and whether that part can judge it.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Explained {
    /// 100 (1 - |y - y_hat| / |y - mean(y)|) over the held-out part (MATLAB's NRMSE fit; the mean is the
    /// held-out part's own): 100 is a perfect model, 0 no better than that mean, negative worse.
    pub fit_percent: f64,
    /// The held-out RMSE of predicting the fit part's mean (the first baseline a user tries).
    pub constant_rmse: f64,
    /// The input's standard deviation on the held-out part over the fit part's.
    pub heldout_input_std_ratio: f64,
    /// The input's range (max - min) on the held-out part over the fit part's.
    pub heldout_input_range_ratio: f64,
    /// The split that excites the held-out part best (see [`best_split`]): its fit fraction ...
    pub best_fit_fraction: f64,
    /// ... and how alike its two parts are excited (see [`best_split`]; 1: alike).
    pub best_heldout_excitation: f64,
}

/// The fit fractions a diagnosis accepts (`--fit-fraction`).
pub const FIT_FRACTIONS: std::ops::RangeInclusive<f64> = 0.3..=0.95;

/// The steps between the fit fractions [`best_split`] tries (every one of [`FIT_FRACTIONS`] that is a
/// multiple of 1/20).
const SPLIT_STEPS: f64 = 20.0;

/// The fit fraction (of [`FIT_FRACTIONS`], by 0.05) whose two parts' inputs are excited most alike, and how alike:
/// the smallest of the two ratios (held-out input over fit input: standard deviation, range) and their
/// inverses (1: alike; a quiet held-out part judges the models on little, a quiet fit part asks them to
/// extrapolate). Where the record's excitation sits in one short stretch no split is fair.
pub fn best_split(u: &[f64]) -> (f64, f64) {
    let steps = |f: f64| (f * SPLIT_STEPS).round() as u32;
    (steps(*FIT_FRACTIONS.start())..=steps(*FIT_FRACTIONS.end()))
        .map(|k| f64::from(k) / SPLIT_STEPS)
        .filter_map(|f| {
            let n_fit = crate::diagnose::fit::structure::fit_len(u.len(), f);
            let (s, r) = excitation(u, n_fit);
            let alike = s.min(r).min(1.0 / s).min(1.0 / r);
            alike.is_finite().then_some((f, alike))
        })
        .fold((f64::NAN, f64::NAN), |best, c| {
            if best.1.is_nan() || c.1 > best.1 {
                c
            } else {
                best
            }
        })
}

/// Below this fit (percent) the final model explains little of the held-out part.
pub const LOW_FIT_PERCENT: f64 = 20.0;
/// A final held-out error above this share of the constant predictor's is no better than a constant.
pub const NEAR_CONSTANT: f64 = 0.9;

impl Explained {
    /// The final output `y_hat` against the record `y` about the fit part's mean (`y` here is already a
    /// deviation from it), and the input `u`'s excitation on both parts.
    pub fn of(u: &[f64], y: &[f64], y_hat: &[f64], n_fit: usize) -> Self {
        let (held, model) = (&y[n_fit..], &y_hat[n_fit..]);
        let err = crate::stats::rms_diff(held, model);
        let spread = std_dev(held);
        let (std_ratio, range_ratio) = excitation(u, n_fit);
        let (best_fit_fraction, best_heldout_excitation) = best_split(u);
        Self {
            fit_percent: if spread > 0.0 {
                100.0 * (1.0 - err / spread)
            } else {
                f64::NAN
            },
            constant_rmse: {
                let level = crate::stats::mean(&y[..n_fit]);
                crate::stats::rms(held.iter().map(|a| a - level))
            },
            heldout_input_std_ratio: std_ratio,
            heldout_input_range_ratio: range_ratio,
            best_fit_fraction,
            best_heldout_excitation,
        }
    }

    /// What a user must know before trusting the held-out numbers, in sentences.
    pub fn warnings(&self, after_rmse: f64) -> Vec<String> {
        let mut w = Vec::new();
        if self.fit_percent < LOW_FIT_PERCENT || after_rmse > NEAR_CONSTANT * self.constant_rmse {
            w.push(format!(
                "the final model explains little of the held-out part: fit {:.1}% (below {LOW_FIT_PERCENT:.0}% \
                 or within {:.0}% of a constant), held-out error {:.4e} against {:.4e} for predicting the fit \
                 part's mean. Likely reasons: the input does not drive the output much, a second (unmeasured) \
                 input or set-point moves it, it drifts, or the model class is wrong for this record",
                self.fit_percent,
                100.0 * (1.0 - NEAR_CONSTANT),
                after_rmse,
                self.constant_rmse
            ));
        }
        let (s, r) = (self.heldout_input_std_ratio, self.heldout_input_range_ratio);
        if s < POOR_EXCITATION || r < POOR_EXCITATION {
            w.push(format!(
                "the held-out part is poorly excited: its input's standard deviation is {:.0}% and its range \
                 {:.0}% of the fit part's, so its errors judge the models on little (a quiet tail); {}",
                100.0 * s,
                100.0 * r,
                self.fairer_split()
            ));
        }
        w
    }

    /// What to do about a poorly excited held-out part: the split that excites it, or that none does.
    fn fairer_split(&self) -> String {
        let (f, e) = (self.best_fit_fraction, self.best_heldout_excitation);
        let (lo, hi) = (FIT_FRACTIONS.start(), FIT_FRACTIONS.end());
        if e >= POOR_EXCITATION {
            format!(
                "--fit-fraction {f:.2} excites the two parts most alike (each part's input has at least {:.0}% of \
                 the other's standard deviation and range; the best split from {lo:.2} to {hi:.2})",
                100.0 * e
            )
        } else {
            format!(
                "no split from --fit-fraction {lo:.2} to {hi:.2} gives each part's input a quarter of the other's \
                 standard deviation and range (the best, {f:.2}, gives {:.0}%): no held-out test on this record \
                 is fair; record more excitation, spread over the record",
                100.0 * e
            )
        }
    }
}

impl Diagnosis {
    /// Adds the operating point's output level back to every simulated output the diagnosis keeps (they were
    /// computed about it), so that they compare with the record as it is.
    pub(crate) fn restore_outputs(&mut self) {
        let level = self.operating_point.y;
        let shift = |v: &mut Vec<f64>| v.iter_mut().for_each(|a| *a += level);
        shift(&mut self.base_sim.y);
        shift(&mut self.linear.output);
        let later = self
            .later
            .iter_mut()
            .flat_map(|r| r.found.candidates.iter_mut());
        for c in self.candidates.iter_mut().chain(later) {
            shift(&mut c.output);
            shift(&mut c.sim.y);
        }
    }

    pub fn effect(&self) -> Option<&Candidate> {
        self.chosen.map(|i| &self.candidates[i])
    }

    pub fn effect_id(&self) -> Option<EffectId> {
        self.effect().map(|c| c.id)
    }

    /// The effects kept, in order: the first round's winner, then each later round's.
    pub fn steps(&self) -> Vec<&Candidate> {
        self.effect()
            .into_iter()
            .chain(
                self.later
                    .iter()
                    .filter_map(|r| r.found.chosen.map(|i| &r.found.candidates[i])),
            )
            .collect()
    }

    /// The final model: the last effect kept on top of the others, or the plain model.
    pub fn final_model(&self) -> &EffectModel {
        self.steps().last().map_or(&self.base, |c| &c.model)
    }

    /// Held-out free-run RMSE after: the final model's (the plain model's for `null`).
    pub fn after_rmse(&self) -> f64 {
        self.steps()
            .last()
            .map_or(self.base_heldout_rmse, |c| c.heldout_rmse)
    }

    /// A candidate the decision rejected (in any round) whose held-out free-run error is lower than the
    /// final model's by at least [`decision::MIN_FALL`] (the fall the decision itself asks of a candidate):
    /// the lowest such one, so that the user can judge (`None` when no rejected candidate is that much
    /// lower; noise models, judged by prediction, are not compared).
    pub fn closest_alternative(&self) -> Option<ClosestAlternative> {
        let after = self.after_rmse();
        let kept: Vec<&Candidate> = self.steps();
        self.candidates
            .iter()
            .chain(self.later.iter().flat_map(|r| r.found.candidates.iter()))
            .filter(|c| !kept.iter().any(|k| std::ptr::eq(*k, *c)))
            .filter(|c| {
                c.error_kind == SIMULATION && c.heldout_rmse < after * (1.0 - decision::MIN_FALL)
            })
            .min_by(|a, b| a.heldout_rmse.total_cmp(&b.heldout_rmse))
            .map(|c| ClosestAlternative {
                id: c.id,
                heldout_rmse: c.heldout_rmse,
                chosen_heldout_rmse: after,
                reason: c.reason.clone(),
            })
    }

    /// The test that points to the chosen effect: the first of its pointing tests (most specific first, see
    /// [`EffectId::pointing_tests`]) that rejected.
    pub fn pointing_test(&self) -> Option<&'static str> {
        self.effect()?.pointed_by.first().copied()
    }

    /// Simulate the plain model and the chosen extension (both as fitted here) over another record, from
    /// the same kind of initial state as this record (rest at 0, or at that record's first input):
    /// cross-record validation (free-run errors both).
    pub fn cross_validate(&self, u: &[f64], y: &[f64]) -> Option<CrossValidation> {
        let n = u.len().min(y.len());
        let op = self.operating_point;
        let (u, y_dev) = (&op.deviations(u, op.u)[..], op.deviations(y, op.y));
        let limit = sim_limit(u, &y_dev);
        let rest = self.initial.rest_for(u.first().copied().unwrap_or(0.0));
        let mut before = self.base.simulate(u, rest, n, limit)?;
        let mut after = self.final_model().simulate(u, rest, n, limit)?.y;
        before
            .y
            .iter_mut()
            .chain(after.iter_mut())
            .for_each(|a| *a += op.y);
        Some(CrossValidation {
            samples: n,
            y_std: std_dev(&y[..n]),
            rmse_before: rms_diff(y, &before.y),
            rmse_after: rms_diff(y, &after),
            before: before.y,
            after,
        })
    }
}

/// The result of [`Diagnosis::cross_validate`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CrossValidation {
    pub samples: usize,
    /// Standard deviation of the measured output (the RMSE of predicting its mean).
    pub y_std: f64,
    pub rmse_before: f64,
    pub rmse_after: f64,
    #[serde(skip)]
    pub before: Vec<f64>,
    #[serde(skip)]
    pub after: Vec<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An input of `n` samples excited (a deterministic spread over -1..1) where `loud` says, nearly still
    /// (a thousandth of that) elsewhere.
    fn input(n: usize, loud: impl Fn(f64) -> bool) -> Vec<f64> {
        (0..n)
            .map(|k| {
                let v = ((k * 7919) % 1000) as f64 / 500.0 - 1.0;
                if loud(k as f64 / n as f64) {
                    v
                } else {
                    1e-3 * v
                }
            })
            .collect()
    }

    fn warned(u: &[f64], fraction: f64) -> Vec<String> {
        let n_fit = crate::diagnose::fit::structure::fit_len(u.len(), fraction);
        let y = vec![0.0; u.len()];
        let e = Explained::of(u, &y, &y, n_fit);
        e.warnings(0.0)
            .into_iter()
            .filter(|w| w.contains("poorly excited"))
            .collect()
    }

    /// A record excited in its first half and its last tenth: the split at 0.85 excites both parts alike
    /// (the held-out part then holds the loud tail and a little of the still stretch).
    #[test]
    fn the_best_split_excites_both_parts_alike() {
        let u = input(4000, |t| !(0.5..0.9).contains(&t));
        let (f, alike) = best_split(&u);
        assert!((f - 0.85).abs() < 1e-9, "split {f}, alike {alike}");
        assert!(alike > 0.8, "alike {alike}");
    }

    /// A quiet tail after the default split: the warning names the split that excites both parts best; an
    /// excitation in one short stretch: the warning says that no split is fair.
    #[test]
    fn a_quiet_held_out_part_is_told_where_to_split_or_that_no_split_is_fair() {
        let tail = warned(&input(4000, |t| t < 0.65), 0.7);
        assert_eq!(tail.len(), 1, "{tail:?}");
        assert!(
            tail[0].contains("--fit-fraction 0.30 excites the two parts most alike"),
            "{tail:?}"
        );
        let burst = warned(&input(4000, |t| (0.51..0.54).contains(&t)), 0.7);
        assert_eq!(burst.len(), 1, "{burst:?}");
        assert!(
            burst[0].contains("no held-out test on this record is fair"),
            "{burst:?}"
        );
        assert!(warned(&input(4000, |_| true), 0.7).is_empty());
    }
}
