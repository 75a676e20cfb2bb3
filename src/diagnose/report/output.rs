//! The diagnosis as the contract's JSON object: typed structures, serialised by serde.

use serde::Serialize;

use crate::diagnose::effects::{EffectId, Fitted, Parameters};
use crate::diagnose::fit::model::{BaseModel, EffectModel};
use crate::diagnose::fit::structure::{InitialState, StructureChoice};
use crate::diagnose::search::decision::DECISION_RULE;
use crate::diagnose::search::engine::{
    BacklashSupport, Candidate, Diagnosis, Explained, OneStep, OperatingPoint, TestResult,
};

/// The parameters of `id` fitted as `m` over `n` samples, against the `current` model, as the effect reports
/// them; `ts` (sample period, when known) adds per-second forms of per-sample parameters.
pub fn parameters_of(
    id: EffectId,
    m: &EffectModel,
    current: &EffectModel,
    n: usize,
    ts: Option<f64>,
    output_level: f64,
) -> Parameters {
    id.effect().parameters(&Fitted {
        model: m,
        current,
        n,
        ts,
        output_level,
    })
}

/// The plain model before any extension.
#[derive(Debug, Serialize)]
pub struct Before<'a> {
    /// Held-out free-run RMSE.
    pub rmse: f64,
    pub fit_rmse: f64,
    pub bic: f64,
    pub k: usize,
    pub model: &'a BaseModel,
}

/// The first effect kept (all fields but `id`, `parameters`, `pointed_by` absent for `null`).
#[derive(Debug, Serialize)]
pub struct Effect<'a> {
    pub id: Option<EffectId>,
    pub parameters: Parameters,
    pub pointed_by: Option<&'static str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub description: Option<&'static str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pointing_tests_rejected: Option<&'a [&'static str]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub heldout_rmse: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub heldout_z: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error_kind: Option<&'static str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub one_step: Option<OneStep>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bic: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub delta_bic: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub model: Option<&'a BaseModel>,
}

/// One step of the loop: an effect added on top of the previous ones, the test that pointed to it, the
/// held-out error after it.
#[derive(Debug, Serialize)]
pub struct Step<'a> {
    pub id: EffectId,
    pub parameters: Parameters,
    pub pointed_by: Option<&'static str>,
    /// Held-out free-run RMSE after this step.
    pub after_rmse: f64,
    /// Held-out free-run RMSE of the model this step extended.
    pub before_rmse: f64,
    pub fit_rmse: f64,
    pub bic: f64,
    pub delta_bic: f64,
    pub heldout_z: f64,
    pub error_kind: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub one_step: Option<OneStep>,
    pub reason: &'a str,
}

/// A round of the loop after the first: the effects the model it extended had, and what its residual
/// showed.
#[derive(Debug, Serialize)]
pub struct RoundOut<'a> {
    pub extends: Vec<EffectId>,
    /// Held-out free-run RMSE of the model it extended.
    pub before_rmse: f64,
    /// The residual tests that rejected.
    pub rejected: Vec<&'static str>,
    pub set_aside: &'a [String],
    pub candidates: Vec<CandidateOut<'a>>,
    pub not_tried: &'a [EffectId],
    pub chosen: Option<EffectId>,
}

/// The final model.
#[derive(Debug, Serialize)]
pub struct After {
    /// Held-out free-run RMSE (always a simulation error, comparable with `before.rmse`).
    pub rmse: f64,
    /// The same error as a normalised fit, percent (see [`Explained`]).
    pub fit_percent: f64,
    /// The held-out error of predicting the fit part's mean.
    pub constant_rmse: f64,
    pub error_kind: &'static str,
    /// With a noise model: the one-step prediction errors on the held-out part before and after it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub one_step: Option<OneStep>,
}

/// The best linear model of the structure.
#[derive(Debug, Serialize)]
pub struct Linear<'a> {
    /// Held-out free-run RMSE.
    pub rmse: f64,
    pub fit_rmse: f64,
    pub a: &'a [f64],
    pub b: &'a [f64],
    pub offset: f64,
}

/// A candidate in the JSON.
#[derive(Debug, Serialize)]
pub struct CandidateOut<'a> {
    pub id: EffectId,
    pub pointed_by: &'a [&'static str],
    pub parameters: Parameters,
    pub k: usize,
    pub fit_rmse: f64,
    /// Held-out free-run RMSE.
    pub heldout_rmse: f64,
    pub heldout_z: f64,
    pub error_kind: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub one_step: Option<OneStep>,
    pub bic: f64,
    pub delta_bic: f64,
    pub supported: bool,
    pub reason: &'a str,
}

/// The whole object.
#[derive(Debug, Serialize)]
pub struct DiagnosisOut<'a> {
    pub before: Before<'a>,
    pub effect: Effect<'a>,
    pub effects: Vec<Step<'a>>,
    /// The loop's rounds after the first, and why it stopped.
    pub rounds: Vec<RoundOut<'a>>,
    pub stopped: &'a str,
    pub after: After,
    pub linear: Linear<'a>,
    pub backlash: &'a BacklashSupport,
    pub structure: &'a StructureChoice,
    /// The input level the models rest at before the first sample, and why.
    pub initial_state: &'a InitialState,
    pub na: usize,
    pub nb: usize,
    pub delay: usize,
    pub tests: &'a [TestResult],
    pub tests_on: String,
    pub set_aside: &'a [String],
    pub candidates: Vec<CandidateOut<'a>>,
    pub not_tried: &'a [EffectId],
    pub decision: &'static str,
    pub samples: usize,
    pub fit_samples: usize,
    pub heldout_samples: usize,
    /// The levels every fit worked about (the fit part's mean input, the first output).
    pub operating_point: OperatingPoint,
    /// The final model's held-out fit, percent, and the constant predictor's error (also in `after`).
    pub fit_percent: f64,
    pub constant_rmse: f64,
    /// How much the final model explains and how well the held-out part is excited.
    pub explained: Explained,
}

impl<'a> DiagnosisOut<'a> {
    pub fn new(d: &'a Diagnosis, ts: Option<f64>) -> Self {
        let effect = Effect::of(d, ts);
        let effects = steps_of(d, ts);
        let rounds = rounds_of(d, ts);
        let lin = &d.linear.model;
        Self {
            before: Before {
                rmse: d.base_heldout_rmse,
                fit_rmse: d.base_fit_rmse,
                bic: d.base_bic,
                k: d.base_k,
                model: &d.base.base,
            },
            effect,
            effects,
            rounds,
            stopped: &d.stopped,
            after: After {
                rmse: d.after_rmse(),
                fit_percent: d.explained.fit_percent,
                constant_rmse: d.explained.constant_rmse,
                error_kind: "simulation",
                one_step: d.steps().last().and_then(|c| c.one_step),
            },
            linear: Linear {
                rmse: d.linear.heldout_rmse,
                fit_rmse: d.linear.fit_rmse,
                a: &lin.a,
                b: &lin.b,
                offset: lin.c2,
            },
            backlash: &d.backlash,
            structure: &d.structure,
            initial_state: &d.initial,
            na: d.structure.chosen.na,
            nb: d.structure.chosen.nb,
            delay: d.structure.chosen.delay,
            tests: &d.tests,
            tests_on: format!(
                "residual y - y_model of the plain model's simulation on the fit part (samples 0..{})",
                d.n_fit
            ),
            set_aside: &d.set_aside,
            candidates: d
                .candidates
                .iter()
                .map(|c| candidate_out(c, &d.base, d.n, (ts, d.operating_point.y)))
                .collect(),
            not_tried: &d.not_tried,
            decision: DECISION_RULE,
            samples: d.n,
            fit_samples: d.n_fit,
            heldout_samples: d.n - d.n_fit,
            operating_point: d.operating_point,
            fit_percent: d.explained.fit_percent,
            constant_rmse: d.explained.constant_rmse,
            explained: d.explained,
        }
    }
}

impl<'a> Effect<'a> {
    /// The first effect kept, or the `null` object.
    fn of(d: &'a Diagnosis, ts: Option<f64>) -> Self {
        let params =
            |c: &Candidate| parameters_of(c.id, &c.model, &d.base, d.n, ts, d.operating_point.y);
        match d.effect() {
            Some(c) => Effect {
                id: Some(c.id),
                parameters: params(c),
                pointed_by: d.pointing_test(),
                description: Some(c.id.describe()),
                pointing_tests_rejected: Some(&c.pointed_by),
                heldout_rmse: Some(c.heldout_rmse),
                heldout_z: Some(c.heldout_z),
                error_kind: Some(c.error_kind),
                one_step: c.one_step,
                bic: Some(c.bic),
                delta_bic: Some(c.delta_bic),
                model: Some(&c.model.base),
            },
            None => Effect {
                id: None,
                parameters: Parameters::new(),
                pointed_by: None,
                description: None,
                pointing_tests_rejected: None,
                heldout_rmse: None,
                heldout_z: None,
                error_kind: None,
                one_step: None,
                bic: None,
                delta_bic: None,
                model: None,
            },
        }
    }
}

/// Every step of the loop, each against the model it extended.
fn steps_of(d: &Diagnosis, ts: Option<f64>) -> Vec<Step<'_>> {
    let mut currents: Vec<&EffectModel> = vec![&d.base];
    currents.extend(d.later.iter().map(|r| &r.current));
    let mut befores = vec![d.base_heldout_rmse];
    befores.extend(d.later.iter().map(|r| r.current_heldout_rmse));
    d.steps()
        .into_iter()
        .zip(currents.iter().zip(&befores))
        .map(|(c, (cur, &before_rmse))| Step {
            id: c.id,
            parameters: parameters_of(c.id, &c.model, cur, d.n, ts, d.operating_point.y),
            pointed_by: c.pointed_by.first().copied(),
            after_rmse: c.heldout_rmse,
            before_rmse,
            fit_rmse: c.fit_rmse,
            bic: c.bic,
            delta_bic: c.delta_bic,
            heldout_z: c.heldout_z,
            error_kind: c.error_kind,
            one_step: c.one_step,
            reason: &c.reason,
        })
        .collect()
}

/// The rounds after the first.
fn rounds_of(d: &Diagnosis, ts: Option<f64>) -> Vec<RoundOut<'_>> {
    let kept: Vec<EffectId> = d.steps().iter().map(|c| c.id).collect();
    d.later
        .iter()
        .enumerate()
        .map(|(i, r)| RoundOut {
            // Round i + 2 extends the model with the first i + 1 effects.
            extends: kept[..=i].to_vec(),
            before_rmse: r.current_heldout_rmse,
            rejected: r
                .found
                .tests
                .iter()
                .filter(|t| t.verdict.rejects)
                .map(|t| t.verdict.name)
                .collect(),
            set_aside: &r.found.set_aside,
            candidates: r
                .found
                .candidates
                .iter()
                .map(|c| candidate_out(c, &r.current, d.n, (ts, d.operating_point.y)))
                .collect(),
            not_tried: &r.found.not_tried,
            chosen: r.found.chosen.map(|i| r.found.candidates[i].id),
        })
        .collect()
}

/// A candidate fitted on top of `current`, for the JSON.
fn candidate_out<'a>(
    c: &'a Candidate,
    current: &EffectModel,
    n: usize,
    (ts, output_level): (Option<f64>, f64),
) -> CandidateOut<'a> {
    CandidateOut {
        id: c.id,
        pointed_by: &c.pointed_by,
        parameters: parameters_of(c.id, &c.model, current, n, ts, output_level),
        k: c.k,
        fit_rmse: c.fit_rmse,
        heldout_rmse: c.heldout_rmse,
        heldout_z: c.heldout_z,
        error_kind: c.error_kind,
        one_step: c.one_step,
        bic: c.bic,
        delta_bic: c.delta_bic,
        supported: c.supported,
        reason: &c.reason,
    }
}

impl Diagnosis {
    /// The contract's JSON object. `ts`, when known, adds per-second forms of per-sample parameters.
    pub fn to_json(&self, ts: Option<f64>) -> serde_json::Value {
        serde_json::to_value(DiagnosisOut::new(self, ts)).expect("plain data serialises")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::effects::{gap_drift, linear_order, periodic};
    use crate::diagnose::fit::model::tests::paper_base;

    fn number(p: &Parameters, name: &str) -> f64 {
        p.get(name).and_then(|v| v.as_f64()).expect(name)
    }

    /// linear-order names the coefficient it added: a3 when na grew from 2 to 3 (its value the new a),
    /// b1 when nb grew from 0 to 1.
    #[test]
    fn linear_order_names_the_added_coefficient() {
        let current = EffectModel::plain(paper_base());
        let mut more_a = paper_base().with_orders(3, 0, 1);
        more_a.a[2] = 0.125;
        let mut more_b = paper_base().with_orders(2, 1, 1);
        more_b.b[1] = -0.25;
        let named = |b: BaseModel| {
            let p = parameters_of(
                linear_order::ID,
                &EffectModel::plain(b),
                &current,
                100,
                None,
                0.0,
            );
            (p.get("added").cloned(), number(&p, "value"))
        };
        assert_eq!(named(more_a), (Some(serde_json::json!("a3")), 0.125));
        assert_eq!(named(more_b), (Some(serde_json::json!("b1")), -0.25));
    }

    /// A periodic disturbance in the JSON: omega pi/10 rad/sample is a 20-sample period, 2.5 Hz at 0.02 s per
    /// sample; a_sin 3, a_cos 4 make amplitude 5 and phase atan2(4, 3); no sample time, no frequency in Hz.
    #[test]
    fn periodic_parameters_in_every_unit() {
        let omega = std::f64::consts::PI / 10.0;
        let m = EffectModel::plain(paper_base()).with(periodic::extension(omega, 3.0, 4.0));
        let current = EffectModel::plain(paper_base());
        let of = |ts| parameters_of(periodic::ID, &m, &current, 100, ts, 0.0);
        let p = of(Some(0.02));
        assert_eq!(number(&p, "omega"), omega);
        assert!((number(&p, "period_samples") - 20.0).abs() < 1e-12);
        assert!((number(&p, "amplitude") - 5.0).abs() < 1e-12);
        assert!((number(&p, "phase") - 4.0f64.atan2(3.0)).abs() < 1e-12);
        assert!((number(&p, "frequency_hz") - 2.5).abs() < 1e-12);
        assert!(of(None).get("frequency_hz").is_none());
        let keys: Vec<String> = serde_json::to_value(&p)
            .unwrap()
            .as_object()
            .unwrap()
            .keys()
            .cloned()
            .collect();
        assert_eq!(keys.len(), 6, "{keys:?}");
    }

    /// A gap drift in the JSON: over 101 samples (100 sample periods) the borders move from c1, c2 by 100
    /// times their rates; at 0.01 s per sample the per-second rates are 100 times the per-sample ones.
    #[test]
    fn gap_drift_ends_and_rates_per_second() {
        let base = paper_base();
        let (c1, c2) = (base.c1, base.c2);
        let m = EffectModel::plain(base).with(gap_drift::extension(1e-3, -2e-3));
        let current = EffectModel::plain(paper_base());
        let p = parameters_of(gap_drift::ID, &m, &current, 101, Some(0.01), 0.0);
        assert_eq!((number(&p, "c1_start"), number(&p, "c2_start")), (c1, c2));
        assert!((number(&p, "c1_end") - (c1 + 0.1)).abs() < 1e-12);
        assert!((number(&p, "c2_end") - (c2 - 0.2)).abs() < 1e-12);
        assert!((number(&p, "c1_rate_per_s") - 0.1).abs() < 1e-12);
        assert!((number(&p, "c2_rate_per_s") + 0.2).abs() < 1e-12);
    }
}
