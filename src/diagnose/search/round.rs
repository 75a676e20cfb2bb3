//! One round of the loop: the residual tests on the current model, the candidates they point to, each
//! fitted on top of the model from its effect's plan and judged by the decision rule, and the winner.

use rayon::prelude::*;

use crate::diagnose::effects::{CATALOGUE, EffectId, Screening};
use crate::diagnose::fit::lm::bic;
use crate::diagnose::fit::model::{EffectModel, Objective, Simulation};
use crate::diagnose::fit::problem::Problem;
use crate::diagnose::fit::starts::StartContext;
use crate::diagnose::fit::structure::Structure;
use crate::diagnose::residual;
use crate::diagnose::residual::statistics::diebold_mariano;
use crate::diagnose::search::decision::{self, Evidence};
use crate::diagnose::search::diagnosis::{
    Candidate, DiagnoseConfig, Found, OneStep, SIMULATION, TestResult,
};
use crate::stats::rms;

/// The model a round extends, its simulation and residual over the whole record, its fit-part cost and BIC
/// (with the structure penalties of the effects it has), the effects not to try again, and candidates
/// already fitted on the same record (judged again against this model instead of being refitted).
pub(super) struct Current<'a> {
    pub(super) model: &'a EffectModel,
    pub(super) sim: &'a Simulation,
    pub(super) e: &'a [f64],
    pub(super) cost: f64,
    pub(super) bic: f64,
    pub(super) penalty: f64,
    pub(super) exclude: &'a [EffectId],
    pub(super) fitted: &'a [Candidate],
}

/// One round: test the current model's residual on the fit part, fit every candidate it points to on top
/// of the model (on all cores; the result does not depend on the number of threads), judge them, choose.
pub(super) fn find(p: &Problem, cfg: &DiagnoseConfig, cur: Current) -> Found {
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
    let (set_aside, pointed) = candidates_pointed_to(&findings, &u[..n_fit], &cur);
    let held = e[n_fit..].to_vec();
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
    let (candidates, not_tried) = ctx.fit_all(pointed, cur.fitted, cur.exclude.len() + 1);
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

/// The effects the rejecting tests point to, each with the tests that point to it (in its pointing order),
/// that the current model can still take; and why a rejecting test did not make an effect a candidate
/// (each effect says so for itself, [`crate::diagnose::effects::Effect::set_aside`]).
fn candidates_pointed_to(
    findings: &Findings,
    u: &[f64],
    cur: &Current,
) -> (Vec<String>, Vec<(EffectId, Vec<&'static str>)>) {
    let rejected: Vec<&'static str> = findings
        .tests
        .iter()
        .filter(|t| t.verdict.rejects)
        .map(|t| t.verdict.name)
        .collect();
    let screen = Screening {
        u,
        omega: findings.omega,
        rejected: &rejected,
    };
    let mut set_aside = Vec::new();
    let mut pointed = Vec::new();
    for effect in CATALOGUE {
        if let Some(why) = effect.set_aside(&screen) {
            set_aside.push(why);
            continue;
        }
        let id = effect.id();
        if cur.exclude.contains(&id) || !cur.model.can_add(id) {
            continue;
        }
        let by: Vec<&'static str> = effect
            .pointing_tests()
            .iter()
            .copied()
            .filter(|t| rejected.contains(t))
            .collect();
        if !by.is_empty() {
            pointed.push((id, by));
        }
    }
    (set_aside, pointed)
}

/// The residual tests' verdicts and what the starts need from them.
pub(super) struct Findings {
    pub(super) tests: Vec<TestResult>,
    pub(super) omega: f64,
    pub(super) lattice: Option<f64>,
    pub(super) clip: (f64, f64),
}

/// The lags of the autocorrelation tests and of the report's correlation figures: those asked for, at most a
/// fifth of the fit part, at least one.
pub fn usable_lags(lags: usize, n_fit: usize) -> usize {
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

pub(super) struct Context<'a, 'b> {
    pub(super) p: &'a Problem<'b>,
    pub(super) cfg: &'a DiagnoseConfig,
    pub(super) base_cost: f64,
    pub(super) base_bic: f64,
    /// Structure penalties of the effects the current model already has.
    pub(super) penalty: f64,
    pub(super) base_heldout: &'a [f64],
    pub(super) starts: StartContext<'a>,
}

impl Context<'_, '_> {
    /// Fit and judge every candidate `pointed` to (on all cores), telling the progress display of each;
    /// an earlier simulation fit of the same effect in `fitted` is judged again as it is. Returns the
    /// candidates and the effects not tried because the time budget was spent.
    fn fit_all(
        &self,
        pointed: Vec<(EffectId, Vec<&'static str>)>,
        fitted: &[Candidate],
        round: usize,
    ) -> (Vec<Candidate>, Vec<EffectId>) {
        let p = self.p;
        let total = pointed.len();
        let done = std::sync::atomic::AtomicUsize::new(0);
        let tell = |k: usize| {
            (p.progress)(&crate::progress::part(
                &format!("round {round}: fitting the candidates the residual points to"),
                k,
                total,
            ))
        };
        tell(0);
        let results: Vec<Result<Option<Candidate>, EffectId>> = pointed
            .into_par_iter()
            .map(|(id, by)| {
                let result = match judged_as_is(fitted, id) {
                    Some(c) => Ok(self.judge(
                        id,
                        by,
                        (c.model.clone(), c.fit_cost, Objective::Simulation),
                    )),
                    None if p.out_of_time() => Err(id),
                    None => Ok(self.fit_candidate(id).and_then(|f| self.judge(id, by, f))),
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
        (candidates, not_tried)
    }

    /// Fit every structure of the candidate's plan; the lowest cost wins.
    fn fit_candidate(&self, id: EffectId) -> Option<(EffectModel, f64, Objective)> {
        let plan = id
            .effect()
            .plan(&self.starts)
            .filter(|plan| !plan.alternatives.is_empty())?;
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
    pub(super) fn judge(
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
pub(super) fn judged_as_is(fitted: &[Candidate], id: EffectId) -> Option<&Candidate> {
    fitted
        .iter()
        .find(|c| c.id == id && c.error_kind == SIMULATION)
}
