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
//!    m2 = m1) is fitted first; the backlash model (m1 = 1) is fitted by Levenberg-Marquardt ([`crate::diagnose::fit::lm`])
//!    on the simulated output from MRGIA (recommended setting), from an equation-error least-squares fit,
//!    from the linear model, and from a start without dynamics; then 3 perturbed restarts. Its fit-part cost
//!    is never above the linear model's (the linear model is one of its points; if the fit ends higher, the
//!    linear model is taken). Parameters whose simulation is not a valid plant are refused: an unstable
//!    linear block, m2 <= 0, or a backlash whose output flips between the borders against x (the contract's
//!    rule does so where the memory zone is inverted and x holds or falls) while its zone is inverted on more
//!    than a tenth of the samples ([`crate::diagnose::fit::model::MAX_INVERTED_SHARE`]): a chatter a fit could
//!    tune to what the model lacks. The plant's own visits beyond its borders' crossing flip in the same way
//!    on a few samples, and are accepted.
//!    Whether the data support the backlash is said plainly: its play c1 + c2 with a standard error from the
//!    fit's information matrix, and its held-out error against the linear model's.
//! 4. **Test the residual** e = y - y_model **of the fit part** with the tests of [`crate::diagnose::residual`].
//!    Each test that rejects points to the effects of [`EffectId::pointing_tests`](crate::diagnose::id::EffectId::pointing_tests); those are the
//!    **candidates**. A residual spectrum peak at a frequency the input carries
//!    ([`crate::diagnose::residual::statistics::input_line_ratio`] above [`crate::diagnose::residual::statistics::INPUT_LINE_RATIO`]) is model error
//!    driven by the input, not a disturbance: it then does not make `periodic-disturbance` a candidate.
//! 5. **Fit each candidate extension** (current model + the effect's own parameters, all fitted jointly on
//!    the fit part, from the starts of [`crate::diagnose::fit::starts`]), on all cores; the result does not depend on the
//!    number of threads.
//! 6. **Decide** by [`crate::diagnose::search::decision`]: supported when the held-out error falls by at least 1%,
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

use std::time::Instant;

use crate::diagnose::effects::CATALOGUE;
use crate::diagnose::fit::lm::{LmOptions, bic, cost_of};
use crate::diagnose::fit::model::{BaseModel, EffectModel, Objective};
pub use crate::diagnose::fit::problem::EXPLORE_SAMPLES;
use crate::diagnose::fit::problem::{Problem, fit_linear, fit_plain};
use crate::diagnose::fit::structure::{
    self, InitialState, Structure, StructureChoice, min_samples,
};
use crate::diagnose::record::{POOR_EXCITATION, fairly_excited};
use crate::diagnose::search::decision;
pub use crate::diagnose::search::diagnosis::*;
pub use crate::diagnose::search::round::usable_lags;
use crate::diagnose::search::round::{Current, find};
use crate::diagnose::search::{presence, stability};
use crate::plant::{MAX_DELAY, MAX_ORDER};
use crate::stats::{below_by, rms, rms_diff, std_dev};

/// The fraction by which a refit of the plain model must lower its cost to replace it.
const REFIT_GAIN: f64 = 1e-6;

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
    let op = OperatingPoint::of(u, y, structure::fit_len(u.len(), cfg.fit_fraction));
    let (uc, yc) = (op.deviations(u, op.u), op.deviations(y, op.y));
    let (u, y) = (&uc[..], &yc[..]);
    let mut problem = problem_of(u, y, cfg, progress)?;
    let (initial, choice) = structure::choose(&mut problem, cfg.structure, cfg.max_delay);
    let s = choice.chosen;
    progress(&format!("fitting the linear model ({s})"));
    let linear = fit_linear(&problem, s).ok_or(DiagnoseError::NoFit)?;
    progress(&format!("fitting the backlash model ({s})"));
    let base =
        fit_plain(&problem, s, cfg.restarts, cfg.seed, &linear).ok_or(DiagnoseError::NoFit)?;
    let mut d = rounds_from(&mut problem, cfg, base, &linear, choice, &initial)?;
    extend(&problem, cfg, &mut d);
    d.backlash = judge_play(&problem, d.final_model(), cfg.fit_fraction);
    let explained = {
        let last = d.steps().last().map_or(&d.base_sim.y, |c| &c.output);
        Explained::of(u, y, last, d.n_fit)
    };
    d.explained = explained;
    d.operating_point = op;
    d.initial.input += op.u;
    d.restore_outputs();
    Ok(d)
}

/// The verdict on play for the final model `last` of `p` (split at the fit fraction `fraction`), checked at
/// the neighbouring splits. On a long record (fits explored on a window of the fit part) every model the
/// verdict compares is fitted on that window and scored on the whole held-out part ([`Problem::verdict_window`]),
/// `last` refitted there first from where it ended: the verdict's fits then cost a window's, not the whole fit
/// part's. Where that refit fails the verdict is judged on the whole fit part. Where the split's held-out
/// part is poorly excited, the verdict is judged at the split that excites both parts ([`excited_split`]).
fn judge_play(p: &Problem, last: &EffectModel, fraction: f64) -> presence::BacklashSupport {
    let Some((q, m, f, why)) = excited_split(p, last) else {
        return judge_on(p, last, fraction);
    };
    let mut s = judge_on(&q, &m, f);
    s.reasons.insert(0, why);
    s
}

/// Where the held-out part of `p`'s split is poorly excited (the input's standard deviation or range there
/// below [`POOR_EXCITATION`] of the fit part's: a quiet tail, on which every model predicts alike and no
/// claim is tested) and another split excites each part at least that much of the other ([`best_split`]):
/// the record split there, the final model `last` refitted on its fit part from where it ended (its
/// parameters keep their meaning, as at the neighbouring splits), that split's fit fraction and the
/// sentence that says so. `None` where the split is fair, where no split is, or where the refit fails (the
/// verdict then says that the held-out part tests nothing).
fn excited_split<'a>(
    p: &Problem<'a>,
    last: &EffectModel,
) -> Option<(Problem<'a>, EffectModel, f64, String)> {
    let (s, r) = p.held_out_excitation();
    if fairly_excited((s, r)) {
        return None;
    }
    // The best split of an unfair one is another: where it is the same, both its ratios reach the rule.
    // Where no split reaches it (`NaN` for an input that never moves), none is tried.
    let (best, alike) = best_split(p.u);
    if alike.is_nan() || alike < POOR_EXCITATION {
        return None;
    }
    let n_fit = structure::fit_len(p.u.len(), best);
    (p.progress)(&format!(
        "judging the play at fit fraction {best:.2}, where both parts are excited"
    ));
    let q = p.resplit(n_fit);
    let start = last.deterministic();
    let (m, _) = q.fit(&start, std::slice::from_ref(&start), Objective::Simulation)?;
    let why = format!(
        "the held-out part of the split asked for is poorly excited (its input's standard deviation is {:.0}% \
         and its range {:.0}% of the fit part's), so it tests no claim: the play is judged at the fit fraction \
         {best:.2}, which excites the two parts most alike (each part's input has at least {:.0}% of the \
         other's standard deviation and range), with the final model refitted on that fit part; the held-out \
         errors of the effects stay those of the split asked for",
        100.0 * s,
        100.0 * r,
        100.0 * alike
    );
    Some((q, m, best, why))
}

/// The verdict on play for the final model `last` of `p` (split at the fit fraction `fraction`), on the
/// long record's window where there is one (see [`judge_play`]), checked at the neighbouring splits.
fn judge_on(p: &Problem, last: &EffectModel, fraction: f64) -> presence::BacklashSupport {
    let v = p.verdict_window();
    let start = last.deterministic();
    let refit = (v.n_fit < p.n_fit)
        .then(|| v.fit(&start, std::slice::from_ref(&start), Objective::Simulation))
        .flatten();
    let Some((m, _)) = refit else {
        let first = presence::assess(p, last, presence::Depth::Full);
        return stability::over_splits(p, last, fraction, first);
    };
    let mut first = presence::assess(&v, &m, presence::Depth::Full);
    first.reasons.insert(
        0,
        format!(
            "the fit part has {} samples: every model compared here, the final model among them, is \
             fitted on its first {} (like with like, at a window's cost) and scored on the whole held-out \
             part ({} samples)",
            p.n_fit,
            v.n_fit,
            p.u.len() - v.held_from
        ),
    );
    stability::over_splits(&v, &m, fraction, first)
}

/// The record as a fitting problem: the fit part's length from the fit fraction, every fit bounded by the
/// time budget; refused when the record is too short for the declared structure (or the smallest one).
fn problem_of<'a>(
    u: &'a [f64],
    y: &'a [f64],
    cfg: &DiagnoseConfig,
    progress: &'a (dyn Fn(&str) + Sync),
) -> Result<Problem<'a>, DiagnoseError> {
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
    let lm = LmOptions {
        deadline: Some(Instant::now() + cfg.time_budget),
        ..cfg.lm
    };
    let n_fit = structure::fit_len(n, cfg.fit_fraction);
    Ok(Problem {
        progress,
        ..Problem::new(u, y, n_fit, lm)
    })
}

/// The first round from the plain fit `base` (model and fit-part cost). A winner whose own base part fits
/// the plain model better means the plain fit stopped in a local minimum: the plain model refitted from
/// there (at most twice) becomes "before", so that it is an honest optimum, and the round is judged again
/// against it. The candidates already fitted are fits of their own structures whatever the plain model is:
/// they are judged again as they are, not refitted.
fn rounds_from(
    problem: &mut Problem,
    cfg: &DiagnoseConfig,
    mut base: (EffectModel, f64),
    linear: &(BaseModel, f64),
    choice: StructureChoice,
    initial: &InitialState,
) -> Result<Diagnosis, DiagnoseError> {
    let mut fitted: Vec<Candidate> = Vec::new();
    let mut rounds = 0;
    loop {
        rounds += 1;
        let mut d = diagnose_from(
            problem,
            cfg,
            base.0.clone(),
            linear,
            choice.clone(),
            initial,
            (rounds, &fitted),
        )?;
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
    if !FIT_FRACTIONS.contains(&cfg.fit_fraction) {
        return Err(DiagnoseError::Fraction(cfg.fit_fraction));
    }
    if cfg.time_budget.is_zero() {
        return Err(DiagnoseError::Budget);
    }
    if !(1..=CATALOGUE.len()).contains(&cfg.max_effects) {
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
    let backlash =
        BacklashSupport::undetermined("not judged yet: the verdict is taken on the final model");

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
        operating_point: OperatingPoint::default(),
        explained: Explained::default(),
    })
}

#[cfg(test)]
mod mutation_tests;
