//! # Diagnosis: which effects does the model lack?
//!
//! `backlash diagnose FILE [--na N --nb N --delay D]` answers with the ids of the catalogue the record shows,
//! in the order they were found (or `null`), and the evidence for each. The procedure ([`diagnose`]):
//!
//! 1. **Split.** The first 70% of the record fit the models; the last 30% are held out and only judge them.
//!    Every model is simulated over the whole record from rest, so the held-out part starts from the state
//!    the fit part left (nothing is re-initialised at the split). Every error called "held-out RMSE" below
//!    is this free-run simulation error.
//! 2. **Structure.** Declared orders and delay win; without them `structure::select` chooses them
//!    on the fit part only (see there).
//! 3. **Fit the linear model and the backlash model.** The best linear output-error model of the structure
//!    (backlash replaced by a straight line through an offset, which is the backlash with c1 = -c2 and
//!    m2 = m1) is fitted first; the backlash model (m1 = 1) is fitted by Levenberg-Marquardt ([`super::fit`])
//!    on the simulated output from MRGIA (recommended setting), from an equation-error least-squares fit,
//!    from the linear model, and from a start without dynamics; then 3 perturbed restarts. Its fit-part cost
//!    is never above the linear model's (the linear model is one of its points; if the fit ends higher, the
//!    linear model is taken). Parameters whose simulation is not a valid plant are refused: an unstable
//!    linear block, m2 <= 0, or a backlash whose memory zone is inverted where the record takes it (there
//!    the contract's rule flips between the borders every sample, a chatter a fit would otherwise exploit).
//!    Whether the data support the backlash is said plainly: its play c1 + c2 with a standard error from the
//!    fit's information matrix, and its held-out error against the linear model's.
//! 4. **Test the residual** e = y - y_model **of the fit part** with the tests of [`super::residual`].
//!    Each test that rejects points to the effects of [`EffectId::pointing_tests`]; those are the
//!    **candidates**. A residual spectrum peak at a frequency the input carries
//!    ([`super::statistics::input_line_ratio`] above [`super::statistics::INPUT_LINE_RATIO`]) is model error
//!    driven by the input, not a disturbance: it then does not make `periodic-disturbance` a candidate.
//! 5. **Fit each candidate extension** (current model + the effect's own parameters, all fitted jointly on
//!    the fit part, from the starts of [`super::starts`]), on all cores; the result does not depend on the
//!    number of threads.
//! 6. **Decide** by [`super::decision`]: supported when the held-out error falls by at least 1%,
//!    significantly (Diebold-Mariano), and BIC on the fit part is lower; the lowest BIC among supported
//!    deterministic extensions wins, coloured-noise only when none is supported. If the winner's own base
//!    part fits the plain model better than the plain fit did (that fit stopped in a local minimum), the
//!    plain model refitted from there becomes "before" (at most twice), so that it is an honest optimum, and
//!    the round is judged again against it (the candidates already fitted are judged as they are).
//!
//! 7. **Loop**: the winner becomes the current model and steps 4 to 6 repeat on its residual:
//!    the candidates are fitted on top of it (all parameters, the earlier effects' too, jointly: the last
//!    round's fit is the joint refit of every effect found), judged against it by the same rule, and the
//!    lowest BIC among the supported ones is kept. Each effect is added at most once; a noise model ends
//!    the loop (it describes what the deterministic part leaves); friction with the play inside its spring
//!    and curved borders are never combined (that element has straight borders). The loop stops when no
//!    candidate is supported, after `max_effects` effects (default 3) or when the time budget is spent.
//!    On a clean record the first round finds nothing, so the loop adds no false positive there; on a
//!    single-effect record the second round judges a residual that has no structure left, as the first
//!    round does on a clean record.
//!
//! "before" is the declared model's held-out RMSE, "after" the final model's simulation RMSE (equal to
//! "before" for `null`). **coloured-noise is judged by prediction:** its evidence is the one-step-ahead
//! prediction error `y(k) - [s(k) + sum_i phi_i (y(k-i) - s(k-i))]` (s the simulated output) against the
//! plain model's, whose predictor is its simulation; those two numbers are reported as `one_step` beside
//! the simulation errors, never in their place.
//!
//! ## Cost and bounds
//!
//! Exploration (screening a grid of starts, short runs from each) uses the first [`EXPLORE_SAMPLES`]
//! samples of the fit part; only the best start is refined on the whole fit part, and that refinement stops
//! when its step is below 0.1 standard errors (as `identify oe` does) or after a few iterations, so a long
//! record costs a few simulations of its whole length per candidate. A candidate with several structures
//! (longer delays, higher orders, friction's two forms) refines only the best of them on the window. Every
//! fit is bounded in iterations and simulations, and the whole diagnosis by a time budget ([`DiagnoseConfig::time_budget`]): candidates not fitted when it is
//! spent are listed as not tried.
//!
//! ## Why no constant offset
//!
//! A constant output offset d is not in the catalogue: with straight borders it is absorbed exactly into
//! the gaps, m1 (x - c1) + d = m1 (x - (c1 - d/m1)) and m2 (x + c2) + d = m2 (x + (c2 + d/m2)), so the
//! declared model already contains it and no data can show it (test
//! `constant_offset_is_absorbed_into_the_gaps`). An input offset passes the linear block as a constant and
//! is absorbed the same way. This is also why the fitted gaps may be negative: only c1 + c2 (the play)
//! must not be.

use std::time::{Duration, Instant};

use rayon::prelude::*;
use serde::Serialize;

use super::catalogue::{EffectId, test_names};
use super::decision::{self, Evidence};
use super::fit::{LmOptions, bic, cost_of};
use super::model::{BaseModel, EffectModel, Objective, Simulation};
pub use super::problem::EXPLORE_SAMPLES;
use super::problem::{Problem, fit_linear, fit_plain, sim_limit};
use super::residual::{self, Verdict};
use super::starts::{self, StartContext};
use super::statistics::{INPUT_LINE_RATIO, diebold_mariano, input_line_ratio};
use super::structure::{self, InitialState, Structure, StructureChoice};
use crate::plant::{MAX_DELAY, MAX_ORDER};
use crate::stats::{below_by, rms, rms_diff, std_dev};

/// The error kind of a candidate judged by its free-run simulation.
const SIMULATION: &str = "simulation";
/// The fraction by which a refit of the plain model must lower its cost to replace it.
const REFIT_GAIN: f64 = 1e-6;

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
    #[error("the most effects to add ({0}) must be between 1 and {max}", max = EffectId::ALL.len())]
    MaxEffects(usize),
}

/// The fewest samples a structure needs: 100 plus 20 per order and delay sample.
pub fn min_samples(s: &Structure) -> usize {
    100 + 20 * (s.na + s.nb + s.delay)
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

/// The result of [`diagnose`].
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

// ---------------------------------------------------------------------------------------------------------
// The diagnosis

/// Diagnose the record (u, y): choose or take the structure, fit, test, extend, decide.
pub fn diagnose(u: &[f64], y: &[f64], cfg: &DiagnoseConfig) -> Result<Diagnosis, DiagnoseError> {
    diagnose_with_progress(u, y, cfg, &|_| {})
}

/// [`diagnose`], telling `progress` what it is doing at each stage (a sentence such as "fitting the
/// candidates of round 1 (3 of 8 done)"); `progress` may be called from any thread.
pub fn diagnose_with_progress(
    u: &[f64],
    y: &[f64],
    cfg: &DiagnoseConfig,
    progress: &(dyn Fn(&str) + Sync),
) -> Result<Diagnosis, DiagnoseError> {
    check_record(u, y, cfg)?;
    let n = u.len();
    let smallest = Structure {
        na: 0,
        nb: 0,
        delay: 1,
    };
    let needed = cfg.structure.as_ref().unwrap_or(&smallest);
    if n < min_samples(needed) {
        return Err(DiagnoseError::TooShort {
            n,
            min: min_samples(needed),
        });
    }
    let deadline = Instant::now() + cfg.time_budget;
    let lm = LmOptions {
        deadline: Some(deadline),
        ..cfg.lm
    };
    let n_fit = ((n as f64 * cfg.fit_fraction).round() as usize).clamp(1, n - 1);
    let mut problem = Problem {
        progress,
        ..Problem::new(u, y, n_fit, lm)
    };
    progress("choosing the initial state");
    let initial = structure::initial_state(
        &problem,
        &match cfg.structure {
            Some(s) => vec![s],
            None => structure::grid(cfg.max_delay, n_fit, n),
        },
    );
    problem.rest = initial.rest_for(u[0]);
    let choice = match cfg.structure {
        Some(s) => StructureChoice::declared(s),
        None => {
            progress("choosing the structure (orders and delay)");
            structure::select(&problem, cfg.max_delay, n)
        }
    };
    let s = choice.chosen;
    progress(&format!("fitting the linear model ({s})"));
    let linear = fit_linear(&problem, s).ok_or(DiagnoseError::NoFit)?;
    progress(&format!("fitting the backlash model ({s})"));
    let mut base =
        fit_plain(&problem, s, cfg.restarts, cfg.seed, &linear).ok_or(DiagnoseError::NoFit)?;
    let mut fitted: Vec<Candidate> = Vec::new();
    let mut rounds = 0;
    loop {
        rounds += 1;
        let mut d = diagnose_from(
            &mut problem,
            cfg,
            base.0.clone(),
            &linear,
            choice.clone(),
            &initial,
            (rounds, &fitted),
        )?;
        // A winner whose own base part fits the plain model better means the plain fit stopped in a local
        // minimum: the plain model refitted from there (at most twice) becomes "before", so that it is an
        // honest optimum, and the round is judged again against it. The candidates already fitted are
        // fits of their own structures whatever the plain model is: they are judged again as they are, not
        // refitted.
        if let Some(start) = refit_start(rounds, d.effect())
            && let Some((polished, cost)) =
                problem.fit(&start, std::slice::from_ref(&start), Objective::Simulation)
            // Lower by more than one part in a million: a refit that only matches the plain model up to the
            // optimiser's tolerance is no better.
            && below_by(cost, base.1, REFIT_GAIN)
        {
            base = (polished, cost);
            fitted = std::mem::take(&mut d.candidates);
            continue;
        }
        extend(&problem, cfg, &mut d);
        return Ok(d);
    }
}

/// Refits of the plain model from a winner's base part, at most.
const MAX_REFITS: usize = 2;

/// The plain model to refit from after round `rounds` (counted from 1): the winner's own base part, when it
/// extends the plain model and fewer than [`MAX_REFITS`] refits have run.
fn refit_start(rounds: usize, winner: Option<&Candidate>) -> Option<EffectModel> {
    let c = winner.filter(|c| rounds <= MAX_REFITS && !c.model.exts.is_empty())?;
    Some(EffectModel::plain(c.model.base.clone()))
}

/// The loop after the first round: while the last round kept an effect, the extended model becomes the
/// current one; its residual is tested, the candidates it points to are fitted on top of it (every
/// parameter, old and new, jointly) and judged by the same rule. Stops when nothing is supported, after
/// `max_effects` effects, after a noise model (it describes what the deterministic part leaves) or when
/// the time budget is spent.
fn extend(p: &Problem, cfg: &DiagnoseConfig, d: &mut Diagnosis) {
    let Some(first) = d.effect() else {
        d.stopped = "no effect is supported by the plain model's residual".into();
        return;
    };
    let mut kept = vec![first.id];
    let mut last = first.clone();
    loop {
        if kept.len() >= cfg.max_effects {
            d.stopped = format!(
                "{} effects found: the most allowed (--max-effects)",
                kept.len()
            );
            return;
        }
        if last.model.noise().is_some() {
            d.stopped =
                "a noise model was kept: it describes what the deterministic part leaves".into();
            return;
        }
        if p.out_of_time() {
            d.stopped = "the time budget is spent".into();
            return;
        }
        let penalty: f64 = kept.iter().map(|&id| decision::structure_penalty(id)).sum();
        let e: Vec<f64> = p.y.iter().zip(&last.sim.y).map(|(a, b)| a - b).collect();
        let cost = cost_of(&e[..p.n_fit]);
        let found = find(
            p,
            cfg,
            Current {
                model: &last.model,
                sim: &last.sim,
                e: &e,
                cost,
                bic: last.bic,
                penalty,
                exclude: &kept,
                fitted: &[],
            },
        );
        let next = found.chosen.map(|i| found.candidates[i].clone());
        d.later.push(Round {
            current: last.model.clone(),
            current_heldout_rmse: last.heldout_rmse,
            current_bic: last.bic,
            found,
        });
        match next {
            Some(c) => {
                kept.push(c.id);
                last = c;
            }
            None => {
                d.stopped = format!(
                    "no further effect is supported by the residual of the model with {}",
                    kept.iter()
                        .map(|id| id.as_str())
                        .collect::<Vec<_>>()
                        .join(" + ")
                );
                return;
            }
        }
    }
}

fn check_record(u: &[f64], y: &[f64], cfg: &DiagnoseConfig) -> Result<(), DiagnoseError> {
    if u.len() != y.len() {
        return Err(DiagnoseError::Length {
            u: u.len(),
            y: y.len(),
        });
    }
    if let Some(k) = u
        .iter()
        .zip(y)
        .position(|(a, b)| !a.is_finite() || !b.is_finite())
    {
        return Err(DiagnoseError::NonFinite(k));
    }
    if let Some(s) = &cfg.structure {
        if s.na > MAX_ORDER || s.nb > MAX_ORDER {
            return Err(DiagnoseError::Structure(format!(
                "na = {}, nb = {}: each must be between 0 and {MAX_ORDER}",
                s.na, s.nb
            )));
        }
        if s.delay < 1 || s.delay > MAX_DELAY {
            return Err(DiagnoseError::Structure(format!(
                "delay = {}: must be between 1 and {MAX_DELAY}",
                s.delay
            )));
        }
    }
    if cfg.max_delay < 1 || cfg.max_delay > MAX_DELAY {
        return Err(DiagnoseError::Structure(format!(
            "the longest delay to try ({}) must be between 1 and {MAX_DELAY}",
            cfg.max_delay
        )));
    }
    if !(0.3..=0.95).contains(&cfg.fit_fraction) {
        return Err(DiagnoseError::Fraction(cfg.fit_fraction));
    }
    if cfg.time_budget.is_zero() {
        return Err(DiagnoseError::Budget);
    }
    if !(1..=EffectId::ALL.len()).contains(&cfg.max_effects) {
        return Err(DiagnoseError::MaxEffects(cfg.max_effects));
    }
    Ok(())
}

/// The linear model's fit and held-out errors over the record.
fn linear_fit(p: &Problem, linear: &(BaseModel, f64)) -> LinearFit {
    let n = p.u.len();
    let output = EffectModel::plain(linear.0.clone())
        .simulate(p.u, p.rest, n, p.limit)
        .map_or_else(|| vec![f64::NAN; n], |s| s.y);
    LinearFit {
        model: linear.0.clone(),
        fit_rmse: (linear.1 / p.n_fit as f64).sqrt(),
        heldout_rmse: rms_diff(&p.y[p.n_fit..], &output[p.n_fit..]),
        output,
    }
}

/// The standard error of the sum of parameters `j` and `k` from their covariance matrix:
/// `sqrt(var_j + var_k + 2 cov_jk)` (0 where rounding makes the variance negative).
fn sum_std_error(cov: &nalgebra::DMatrix<f64>, j: usize, k: usize) -> f64 {
    (cov[(j, j)] + cov[(k, k)] + 2.0 * cov[(j, k)])
        .max(0.0)
        .sqrt()
}

/// The plain model's play with its standard error, and the verdict against the linear model.
fn backlash_support(
    p: &Problem,
    base: &BaseModel,
    base_heldout: f64,
    linear: &LinearFit,
) -> BacklashSupport {
    let cov = p.plain_covariance(base);
    let i = base.na + base.nb + 1;
    let se = |j: usize| cov.as_ref().map(|c| c[(j, j)].max(0.0).sqrt());
    let play = base.c1 + base.c2;
    let play_se = cov.as_ref().map(|c| sum_std_error(c, i + 1, i + 2));
    let significant = play_se.is_some_and(|s| play > residual::Z95 * s);
    let better = base_heldout < linear.heldout_rmse;
    let play_text = match play_se {
        Some(s) => format!("play c1 + c2 = {play:.4e} +/- {s:.2e} (standard error)"),
        None => format!(
            "play c1 + c2 = {play:.4e} (no standard error: the record does not determine the gaps)"
        ),
    };
    let errors = format!(
        "held-out error {base_heldout:.4e} with backlash against {:.4e} for the linear model",
        linear.heldout_rmse
    );
    let verdict = match (significant, better) {
        (true, true) => format!("backlash is supported by the data: {play_text}, {errors}"),
        (false, _) => format!(
            "backlash is not supported by the data: the {play_text} is not significantly above zero ({errors})"
        ),
        (true, false) => format!(
            "backlash is not supported by the data: the {play_text} is significant on the fit part but the \
             {errors} (a straight line predicts as well)"
        ),
    };
    BacklashSupport {
        play,
        play_se,
        c1_se: se(i + 1),
        c2_se: se(i + 2),
        m2_se: se(i),
        supported: significant && better,
        verdict,
    }
}

fn diagnose_from(
    p: &mut Problem,
    cfg: &DiagnoseConfig,
    base: EffectModel,
    linear: &(BaseModel, f64),
    structure: StructureChoice,
    initial: &InitialState,
    (rounds, fitted): (usize, &[Candidate]),
) -> Result<Diagnosis, DiagnoseError> {
    let (u, y, n_fit) = (p.u, p.y, p.n_fit);
    let n = u.len();
    let base_sim = base
        .simulate(u, p.rest, n, p.limit)
        .ok_or(DiagnoseError::NoFit)?;
    p.x_scale = std_dev(&base_sim.x[..n_fit]).max(1e-12);
    let e: Vec<f64> = y.iter().zip(&base_sim.y).map(|(a, b)| a - b).collect();
    let base_cost = cost_of(&e[..n_fit]);
    let base_k = base.n_estimated();
    let base_bic = bic(base_cost, n_fit, base_k);
    let base_heldout_rmse = rms(e[n_fit..].iter().copied());
    let linear = linear_fit(p, linear);
    let backlash = backlash_support(p, &base.base, base_heldout_rmse, &linear);

    let found = find(
        p,
        cfg,
        Current {
            model: &base,
            sim: &base_sim,
            e: &e,
            cost: base_cost,
            bic: base_bic,
            penalty: 0.0,
            exclude: &[],
            fitted,
        },
    );
    Ok(Diagnosis {
        config: *cfg,
        n,
        n_fit,
        structure,
        initial: initial.clone(),
        linear,
        base_k,
        base_fit_rmse: (base_cost / n_fit as f64).sqrt(),
        base_bic,
        base_heldout_rmse,
        base,
        base_sim,
        backlash,
        tests: found.tests,
        set_aside: found.set_aside,
        candidates: found.candidates,
        not_tried: found.not_tried,
        chosen: found.chosen,
        base_rounds: rounds,
        later: Vec::new(),
        stopped: String::new(),
    })
}

/// The model a round extends, its simulation and residual over the whole record, its fit-part cost and BIC
/// (with the structure penalties of the effects it has), the effects not to try again, and candidates
/// already fitted on the same record (judged again against this model instead of being refitted).
struct Current<'a> {
    model: &'a EffectModel,
    sim: &'a Simulation,
    e: &'a [f64],
    cost: f64,
    bic: f64,
    penalty: f64,
    exclude: &'a [EffectId],
    fitted: &'a [Candidate],
}

/// One round: test the current model's residual on the fit part, fit every candidate it points to on top
/// of the model (on all cores; the result does not depend on the number of threads), judge them, choose.
fn find(p: &Problem, cfg: &DiagnoseConfig, cur: Current) -> Found {
    let (u, y, n_fit) = (p.u, p.y, p.n_fit);
    let e = cur.e;
    let findings = residual_tests(
        &e[..n_fit],
        &u[..n_fit],
        &y[..n_fit],
        cur.sim,
        n_fit,
        cfg.lags,
    );
    let mut set_aside = Vec::new();
    let input_ratio = input_line_ratio(&u[..n_fit], findings.omega);
    let rejected = |name: &str| {
        findings
            .tests
            .iter()
            .any(|t| t.verdict.name == name && t.verdict.rejects)
    };
    if rejected(test_names::SPECTRUM_PEAK) && input_ratio > INPUT_LINE_RATIO {
        set_aside.push(format!(
            "periodic-disturbance: the residual's spectrum peak at {:.4} rad/sample is a frequency the input \
             carries (its periodogram there is {:.0} times its median): model error driven by the input, not \
             a disturbance",
            findings.omega, input_ratio
        ));
    }
    let pointed: Vec<(EffectId, Vec<&'static str>)> = EffectId::ALL
        .into_iter()
        .filter(|id| *id != EffectId::PeriodicDisturbance || set_aside.is_empty())
        .filter(|id| !cur.exclude.contains(id) && cur.model.can_add(*id))
        .map(|id| {
            let by = id
                .pointing_tests()
                .iter()
                .copied()
                .filter(|t| rejected(t))
                .collect::<Vec<_>>();
            (id, by)
        })
        .filter(|(_, by)| !by.is_empty())
        .collect();

    let held = e[n_fit..].to_vec();
    let round = cur.exclude.len() + 1;
    let total = pointed.len();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let tell = |k: usize| {
        (p.progress)(&format!(
            "round {round}: fitting the candidates the residual points to ({k} of {total} done)"
        ))
    };
    tell(0);
    let mrgia = |na: usize, nb: usize, delay: usize| p.mrgia_start(Structure { na, nb, delay });
    let ctx = Context {
        p,
        cfg,
        base_cost: cur.cost,
        base_bic: cur.bic,
        penalty: cur.penalty,
        base_heldout: &held,
        starts: StartContext {
            current: cur.model,
            u: &u[..n_fit],
            y: &y[..n_fit],
            residual: &e[..n_fit],
            y_scale: p.y_scale,
            omega: findings.omega,
            lattice: findings.lattice,
            clip: findings.clip,
            mrgia: &mrgia,
        },
    };
    let results: Vec<Result<Option<Candidate>, EffectId>> = pointed
        .into_par_iter()
        .map(|(id, by)| {
            let again = judged_as_is(cur.fitted, id);
            let result = match again {
                Some(c) => {
                    Ok(ctx.judge(id, by, (c.model.clone(), c.fit_cost, Objective::Simulation)))
                }
                None if p.out_of_time() => Err(id),
                None => Ok(ctx.fit_candidate(id).and_then(|f| ctx.judge(id, by, f))),
            };
            tell(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1);
            result
        })
        .collect();
    let mut candidates = Vec::new();
    let mut not_tried = Vec::new();
    for r in results {
        match r {
            Ok(Some(c)) => candidates.push(c),
            Ok(None) => {}
            Err(id) => not_tried.push(id),
        }
    }
    let judged: Vec<(EffectId, bool, f64)> = candidates
        .iter()
        .map(|c| (c.id, c.supported, c.bic))
        .collect();
    let chosen = decision::choose(&judged);
    Found {
        tests: findings.tests,
        set_aside,
        candidates,
        not_tried,
        chosen,
    }
}

/// The residual tests' verdicts and what the starts need from them.
struct Findings {
    tests: Vec<TestResult>,
    omega: f64,
    lattice: Option<f64>,
    clip: (f64, f64),
}

/// The lags of the autocorrelation tests and of the report's correlation figures: those asked for, at most a
/// fifth of the fit part, at least one.
pub(crate) fn usable_lags(lags: usize, n_fit: usize) -> usize {
    lags.min(n_fit / 5).max(1)
}

/// Run every residual test on the fit part.
fn residual_tests(
    e: &[f64],
    u: &[f64],
    y: &[f64],
    sim: &Simulation,
    n_fit: usize,
    lags: usize,
) -> Findings {
    let x = &sim.x[..n_fit];
    let modes = &sim.mode[..n_fit];
    let lags = usable_lags(lags, n_fit);
    let (_, by_mode) = residual::by_mode(e, modes);
    let (_, since) = residual::since_reversal(e, x);
    let (omega, peak) = residual::spectrum_peak(e);
    let (lattice, lat) = residual::lattice(y);
    let (lo, hi, clip) = residual::clipping(y);
    let verdicts = vec![
        residual::ljung_box(e, lags),
        residual::cross_correlation(e, u, lags).verdict,
        residual::billings(e, u, lags.min(10)).verdict,
        by_mode,
        since,
        residual::against_x(e, x, modes),
        residual::drift(e, modes),
        peak,
        lat,
        clip,
        residual::extreme_increments(e, &sim.y[..n_fit]),
    ];
    Findings {
        tests: verdicts
            .into_iter()
            .map(|v| TestResult {
                points_to: EffectId::pointed_by(v.name),
                verdict: v,
            })
            .collect(),
        omega,
        lattice,
        clip: (lo, hi),
    }
}

struct Context<'a, 'b> {
    p: &'a Problem<'b>,
    cfg: &'a DiagnoseConfig,
    base_cost: f64,
    base_bic: f64,
    /// Structure penalties of the effects the current model already has.
    penalty: f64,
    base_heldout: &'a [f64],
    starts: StartContext<'a>,
}

impl Context<'_, '_> {
    /// Fit every structure of the candidate's plan; the lowest cost wins.
    fn fit_candidate(&self, id: EffectId) -> Option<(EffectModel, f64, Objective)> {
        let plan = starts::plan(id, &self.starts)?;
        if plan.objective == Objective::Prediction {
            // A noise model is fitted on the current model's residual with the deterministic part kept (its
            // start is that least-squares fit): the simulation, and so the free-run error, stay the current
            // model's, and the gain shows in the one-step prediction only.
            let m = plan.alternatives.first()?.starts.first()?.clone();
            let cost = self.p.cost(&m, Objective::Prediction)?;
            return Some((m, cost, Objective::Prediction));
        }
        let alternatives: Vec<(&EffectModel, &[EffectModel])> = plan
            .alternatives
            .iter()
            .map(|alt| (&alt.template, alt.starts.as_slice()))
            .collect();
        let (m, c) = self.p.fit_alternatives(&alternatives, plan.objective)?;
        Some((m, c, plan.objective))
    }

    /// Judge one fitted candidate (its model, fit-part cost and objective) against the current model.
    fn judge(
        &self,
        id: EffectId,
        pointed_by: Vec<&'static str>,
        (model, cost, obj): (EffectModel, f64, Objective),
    ) -> Option<Candidate> {
        let p = self.p;
        let n = p.u.len();
        let k = model.n_estimated();
        let sim = model.simulate(p.u, p.rest, n, p.limit)?;
        let sim_held: Vec<f64> = p.y[p.n_fit..]
            .iter()
            .zip(&sim.y[p.n_fit..])
            .map(|(a, b)| a - b)
            .collect();
        let heldout_rmse = rms(sim_held.iter().copied());
        let before = rms(self.base_heldout.iter().copied());
        // A noise model is judged by its one-step prediction; everything else by simulation.
        let (judged, one_step) = match obj {
            Objective::Prediction => {
                let pred = model.predict_from(&sim.y, p.y);
                let e: Vec<f64> = p.y[p.n_fit..]
                    .iter()
                    .zip(&pred[p.n_fit..])
                    .map(|(a, b)| a - b)
                    .collect();
                let after = rms(e.iter().copied());
                (e, Some(OneStep { before, after }))
            }
            Objective::Simulation => (sim_held, None),
        };
        let heldout_z = diebold_mariano(self.base_heldout, &judged);
        let bic_value = bic(cost, p.n_fit, k) + self.penalty + decision::structure_penalty(id);
        let delta_bic = bic_value - self.base_bic;
        let judgement = decision::judge(&Evidence {
            before,
            after: one_step.map_or(heldout_rmse, |o| o.after),
            z: heldout_z,
            z_threshold: self.cfg.z_threshold,
            delta_bic,
        });
        let stuck = (cost - self.base_cost).abs() <= 1e-12 * self.base_cost.max(f64::MIN_POSITIVE)
            && obj == Objective::Simulation;
        let reason = if stuck {
            format!(
                "{} (the fit found no valid step away from the current model: it sits on the edge of the \
                 valid region, where nearby parameters would invert the backlash's memory zone, or the \
                 extension's start has no effect on the output)",
                judgement.reason
            )
        } else {
            judgement.reason
        };
        Some(Candidate {
            id,
            pointed_by,
            k,
            fit_rmse: (cost / p.n_fit as f64).sqrt(),
            fit_cost: cost,
            bic: bic_value,
            delta_bic,
            heldout_rmse,
            heldout_z,
            error_kind: match obj {
                Objective::Prediction => "one-step prediction",
                Objective::Simulation => SIMULATION,
            },
            one_step,
            supported: judgement.supported,
            reason,
            model,
            output: sim.y.clone(),
            sim,
        })
    }
}

/// The earlier fit of effect `id` that is judged again as it is when the plain model changed: its simulation
/// fit (a fit of its own structure, whatever the plain model is); a noise model's prediction fit depends on
/// the plain model's residual and is fitted again.
fn judged_as_is(fitted: &[Candidate], id: EffectId) -> Option<&Candidate> {
    fitted
        .iter()
        .find(|c| c.id == id && c.error_kind == SIMULATION)
}

#[cfg(test)]
mod mutation_tests;
