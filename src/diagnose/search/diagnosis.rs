//! What a diagnosis finds: its settings, the fitted candidates, the rounds of the loop and the result.

use std::time::Duration;

use serde::Serialize;

use crate::diagnose::effects::{CATALOGUE, EffectId};
use crate::diagnose::fit::lm::LmOptions;
use crate::diagnose::fit::model::{BaseModel, EffectModel, Simulation};
use crate::diagnose::fit::problem::sim_limit;
use crate::diagnose::fit::structure::{InitialState, Structure, StructureChoice};
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
    #[error("the fit fraction {0} must be between 0.3 and 0.95")]
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

/// Whether the data support a backlash rather than a straight line.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BacklashSupport {
    /// c1 + c2: the width of the play in the linear block's output units.
    pub play: f64,
    /// Standard errors from the fit's information matrix (`None`: the record does not determine them).
    pub play_se: Option<f64>,
    pub c1_se: Option<f64>,
    pub c2_se: Option<f64>,
    pub m2_se: Option<f64>,
    pub supported: bool,
    pub verdict: String,
}

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
}

impl Diagnosis {
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
        let limit = sim_limit(u, y);
        let rest = self.initial.rest_for(u.first().copied().unwrap_or(0.0));
        let before = self.base.simulate(u, rest, n, limit)?;
        let after = self.final_model().simulate(u, rest, n, limit)?.y;
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
