//! The diagnosis as the contract's JSON object: typed structures, serialised by serde.

use serde::Serialize;

use super::catalogue::EffectId;
use super::decision::DECISION_RULE;
use super::engine::{BacklashSupport, Candidate, Diagnosis, OneStep, TestResult};
use super::model::{BaseModel, EffectModel, Extension};
use super::structure::{InitialState, StructureChoice};
use crate::plant::effects::FrictionForm;

/// An effect's parameters in the report's units.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum EffectParams {
    ExtraDelay {
        delay: usize,
        declared_delay: usize,
        extra: usize,
    },
    LinearOrder {
        na: usize,
        nb: usize,
        added: String,
        value: f64,
    },
    GapDrift {
        c1_rate: f64,
        c2_rate: f64,
        c1_start: f64,
        c2_start: f64,
        c1_end: f64,
        c2_end: f64,
        rate_unit: &'static str,
        #[serde(skip_serializing_if = "Option::is_none")]
        c1_rate_per_s: Option<f64>,
        #[serde(skip_serializing_if = "Option::is_none")]
        c2_rate_per_s: Option<f64>,
    },
    CurvedBorders {
        upper_s2: f64,
        upper_s3: f64,
        lower_s2: f64,
        lower_s3: f64,
    },
    Saturation {
        lo: f64,
        hi: f64,
    },
    Periodic {
        omega: f64,
        omega_unit: &'static str,
        period_samples: f64,
        amplitude: f64,
        phase: f64,
        #[serde(skip_serializing_if = "Option::is_none")]
        frequency_hz: Option<f64>,
    },
    Quantization {
        step: f64,
        offset: f64,
        noise_before_rounding: f64,
    },
    Friction {
        k_e: f64,
        f_plus: f64,
        f_minus: f64,
        form: FrictionForm,
        note: &'static str,
    },
    ColouredNoise {
        ar_order: usize,
        phi: Vec<f64>,
    },
    DirectionDependent {
        a_rise: Vec<f64>,
        b_rise: Vec<f64>,
        a_fall: Vec<f64>,
        b_fall: Vec<f64>,
        note: &'static str,
    },
    None {},
}

impl EffectParams {
    /// The parameters of `id` fitted as `m` over `n` samples, against the `current` model; `ts` (sample
    /// period, when known) adds per-second forms of per-sample parameters.
    pub fn of(
        id: EffectId,
        m: &EffectModel,
        current: &EffectModel,
        n: usize,
        ts: Option<f64>,
    ) -> Self {
        let b = &m.base;
        match (id, m.extension(id).unwrap_or(&Extension::None)) {
            (EffectId::ExtraDelay, _) => EffectParams::ExtraDelay {
                delay: b.delay,
                declared_delay: current.base.delay,
                extra: b.delay.saturating_sub(current.base.delay),
            },
            (EffectId::LinearOrder, _) => {
                let (added, value) = if b.na > current.base.na {
                    (format!("a{}", b.na), b.a[b.na - 1])
                } else {
                    (format!("b{}", b.nb), b.b[b.nb])
                };
                EffectParams::LinearOrder {
                    na: b.na,
                    nb: b.nb,
                    added,
                    value,
                }
            }
            (_, Extension::GapDrift { c1_rate, c2_rate }) => {
                let end = n.saturating_sub(1) as f64;
                EffectParams::GapDrift {
                    c1_rate: *c1_rate,
                    c2_rate: *c2_rate,
                    c1_start: b.c1,
                    c2_start: b.c2,
                    c1_end: b.c1 + c1_rate * end,
                    c2_end: b.c2 + c2_rate * end,
                    rate_unit: "per sample",
                    c1_rate_per_s: ts.map(|t| c1_rate / t),
                    c2_rate_per_s: ts.map(|t| c2_rate / t),
                }
            }
            (_, Extension::CurvedBorders { upper, lower }) => EffectParams::CurvedBorders {
                upper_s2: upper[0],
                upper_s3: upper[1],
                lower_s2: lower[0],
                lower_s3: lower[1],
            },
            (_, Extension::Saturation { lo, hi }) => EffectParams::Saturation { lo: *lo, hi: *hi },
            (
                _,
                Extension::Periodic {
                    omega,
                    a_sin,
                    a_cos,
                },
            ) => EffectParams::Periodic {
                omega: *omega,
                omega_unit: "rad/sample",
                period_samples: 2.0 * std::f64::consts::PI / omega.abs().max(f64::MIN_POSITIVE),
                amplitude: a_sin.hypot(*a_cos),
                phase: a_cos.atan2(*a_sin),
                frequency_hz: ts.map(|t| omega.abs() / (2.0 * std::f64::consts::PI * t)),
            },
            (
                _,
                Extension::Quantization {
                    step,
                    offset,
                    sigma,
                },
            ) => EffectParams::Quantization {
                step: *step,
                offset: *offset,
                noise_before_rounding: *sigma,
            },
            (
                _,
                Extension::Friction {
                    f_plus,
                    f_minus,
                    form,
                },
            ) => EffectParams::Friction {
                k_e: 1.0,
                f_plus: *f_plus,
                f_minus: *f_minus,
                form: *form,
                note: match form {
                    FrictionForm::Series => {
                        "series: f(k) = clamp(f(k-1) + (w(k) - w(k-1)), -f_minus, f_plus) after the backlash; k_e = 1 is the normalisation (the stiffness is carried by b, as m1 = 1 is)"
                    }
                    FrictionForm::Contact => {
                        "contact: the play c1, c2 inside the spring: f = (x - z) - c1 beyond c1, m2 ((x - z) + c2) beyond -c2, 0 between, slider z moves at the slip levels; k_e = 1 is the normalisation"
                    }
                },
            },
            (_, Extension::ColouredNoise { phi }) => EffectParams::ColouredNoise {
                ar_order: phi.len(),
                phi: phi.clone(),
            },
            (_, Extension::DirectionDependent { a, b: bf }) => EffectParams::DirectionDependent {
                a_rise: b.a.clone(),
                b_rise: b.b.clone(),
                a_fall: a.clone(),
                b_fall: bf.clone(),
                note: "x(k) = -sum a_rise_i x(k-i) + sum b_rise_j u(k-delay-j) unless that is below x(k-1); then the same with a_fall, b_fall",
            },
            (_, Extension::None) => EffectParams::None {},
        }
    }
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
    pub parameters: EffectParams,
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
    pub parameters: EffectParams,
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
    pub parameters: EffectParams,
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
}

impl<'a> DiagnosisOut<'a> {
    pub fn new(d: &'a Diagnosis, ts: Option<f64>) -> Self {
        let params = |c: &Candidate| EffectParams::of(c.id, &c.model, &d.base, d.n, ts);
        let effect = match d.effect() {
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
                parameters: EffectParams::None {},
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
        };
        let mut currents: Vec<&EffectModel> = vec![&d.base];
        currents.extend(d.later.iter().map(|r| &r.current));
        let mut befores = vec![d.base_heldout_rmse];
        befores.extend(d.later.iter().map(|r| r.current_heldout_rmse));
        let effects = d
            .steps()
            .into_iter()
            .zip(currents.iter().zip(&befores))
            .map(|(c, (cur, &before_rmse))| Step {
                id: c.id,
                parameters: EffectParams::of(c.id, &c.model, cur, d.n, ts),
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
            .collect();
        let kept: Vec<EffectId> = d.steps().iter().map(|c| c.id).collect();
        let rounds = d
            .later
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
                    .map(|c| candidate_out(c, &r.current, d.n, ts))
                    .collect(),
                not_tried: &r.found.not_tried,
                chosen: r.found.chosen.map(|i| r.found.candidates[i].id),
            })
            .collect();
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
                .map(|c| candidate_out(c, &d.base, d.n, ts))
                .collect(),
            not_tried: &d.not_tried,
            decision: DECISION_RULE,
            samples: d.n,
            fit_samples: d.n_fit,
            heldout_samples: d.n - d.n_fit,
        }
    }
}

/// A candidate fitted on top of `current`, for the JSON.
fn candidate_out<'a>(
    c: &'a Candidate,
    current: &EffectModel,
    n: usize,
    ts: Option<f64>,
) -> CandidateOut<'a> {
    CandidateOut {
        id: c.id,
        pointed_by: &c.pointed_by,
        parameters: EffectParams::of(c.id, &c.model, current, n, ts),
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
    use crate::diagnose::model::tests::paper_base;

    /// linear-order names the coefficient it added: a3 when na grew from 2 to 3 (its value the new a),
    /// b1 when nb grew from 0 to 1.
    #[test]
    fn linear_order_names_the_added_coefficient() {
        let current = EffectModel::plain(paper_base());
        let mut more_a = paper_base().with_orders(3, 0, 1);
        more_a.a[2] = 0.125;
        let mut more_b = paper_base().with_orders(2, 1, 1);
        more_b.b[1] = -0.25;
        let named = |b: BaseModel| match EffectParams::of(
            EffectId::LinearOrder,
            &EffectModel::plain(b),
            &current,
            100,
            None,
        ) {
            EffectParams::LinearOrder { added, value, .. } => (added, value),
            e => panic!("{e:?}"),
        };
        assert_eq!(named(more_a), ("a3".to_string(), 0.125));
        assert_eq!(named(more_b), ("b1".to_string(), -0.25));
    }

    /// A periodic disturbance in the JSON: omega pi/10 rad/sample is a 20-sample period, 2.5 Hz at 0.02 s per
    /// sample; a_sin 3, a_cos 4 make amplitude 5 and phase atan2(4, 3); no sample time, no frequency in Hz.
    #[test]
    fn periodic_parameters_in_every_unit() {
        let omega = std::f64::consts::PI / 10.0;
        let m = EffectModel::plain(paper_base()).with(Extension::Periodic {
            omega,
            a_sin: 3.0,
            a_cos: 4.0,
        });
        let current = EffectModel::plain(paper_base());
        let of = |ts| EffectParams::of(EffectId::PeriodicDisturbance, &m, &current, 100, ts);
        match of(Some(0.02)) {
            EffectParams::Periodic {
                omega: w,
                period_samples,
                amplitude,
                phase,
                frequency_hz,
                ..
            } => {
                assert_eq!(w, omega);
                assert!((period_samples - 20.0).abs() < 1e-12);
                assert!((amplitude - 5.0).abs() < 1e-12);
                assert!((phase - 4.0f64.atan2(3.0)).abs() < 1e-12);
                assert!((frequency_hz.unwrap() - 2.5).abs() < 1e-12);
            }
            e => panic!("{e:?}"),
        }
        assert!(matches!(
            of(None),
            EffectParams::Periodic {
                frequency_hz: None,
                ..
            }
        ));
    }

    /// A gap drift in the JSON: over 101 samples (100 sample periods) the borders move from c1, c2 by 100
    /// times their rates; at 0.01 s per sample the per-second rates are 100 times the per-sample ones.
    #[test]
    fn gap_drift_ends_and_rates_per_second() {
        let base = paper_base();
        let (c1, c2) = (base.c1, base.c2);
        let m = EffectModel::plain(base).with(Extension::GapDrift {
            c1_rate: 1e-3,
            c2_rate: -2e-3,
        });
        let current = EffectModel::plain(paper_base());
        match EffectParams::of(EffectId::GapDrift, &m, &current, 101, Some(0.01)) {
            EffectParams::GapDrift {
                c1_start,
                c2_start,
                c1_end,
                c2_end,
                c1_rate_per_s,
                c2_rate_per_s,
                ..
            } => {
                assert_eq!((c1_start, c2_start), (c1, c2));
                assert!((c1_end - (c1 + 0.1)).abs() < 1e-12, "{c1_end}");
                assert!((c2_end - (c2 - 0.2)).abs() < 1e-12, "{c2_end}");
                assert!((c1_rate_per_s.unwrap() - 0.1).abs() < 1e-12);
                assert!((c2_rate_per_s.unwrap() + 0.2).abs() < 1e-12);
            }
            e => panic!("{e:?}"),
        }
    }
}
