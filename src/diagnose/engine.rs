//! # Diagnosis: which effect does the declared model lack?
//!
//! `backlash diagnose FILE --na N --nb N --delay D` answers with one id of the catalogue (or `null`) and the
//! evidence for it. The procedure ([`diagnose`]):
//!
//! 1. **Split.** The first 70% of the record fit the models; the last 30% are held out and only judge them.
//!    Every model is simulated over the whole record from rest, so the held-out part starts from the state
//!    the fit part left (nothing is re-initialised at the split).
//! 2. **Fit the declared model** (pseudo-Wiener with backlash, m1 = 1): output-error least squares by
//!    Levenberg-Marquardt ([`super::fit`]) on the simulated output, started from MRGIA (recommended
//!    setting) on the fit part, from an equation-error least-squares fit, and from a start without
//!    dynamics; then 3 perturbed restarts. Steps are accepted only if the cost falls. Parameters whose
//!    simulation is not a valid plant are refused: an unstable linear block, m2 <= 0, or a backlash whose
//!    memory zone is inverted where the record takes it (there the contract's rule flips between the
//!    borders every sample, a chatter that a fit would otherwise exploit).
//! 3. **Test the residual** e = y - y_model **of the fit part** with the tests of [`super::residual`]
//!    (Ljung-Box, residual-input cross-correlation, Billings' higher-order correlations, residual by
//!    backlash mode, by time since reversal, against x_hat, drift, spectrum peak, value lattice, clipping,
//!    incremental gain at the output extremes). Each test that rejects points to the effects of
//!    [`EffectId::pointing_tests`]; those are the **candidates**.
//! 4. **Fit each candidate extension** (declared model + the effect's own parameters, all fitted jointly
//!    on the fit part, started from the declared fit; grids of starts where the cost has many minima).
//! 5. **Decide.** A candidate is *supported* when
//!    - its held-out RMSE is at least 1% lower than the declared model's **and** the fall is significant:
//!      one-sided Diebold-Mariano test on the held-out squared errors, z > 1.645, with a Newey-West
//!      variance over n^(1/3) lags ([`diebold_mariano`]), **and**
//!    - its BIC on the fit part is lower: BIC = N ln(RSS / N) + k ln N + ln M, k the estimated parameters,
//!      M the number of alternative structures the candidate searched (extra-delay 3, linear-order 2,
//!      otherwise 1: a discrete choice costs its log-count).
//!
//!    Among supported deterministic extensions the lowest BIC wins; `coloured-noise` wins only when no
//!    deterministic extension is supported (a noise model improves the prediction of any misfit, a
//!    deterministic extension explains it); otherwise the answer is `null`. The report names the test that
//!    pointed to the winner: the first of its pointing tests, most specific first, that rejected.
//!    If the winner's own base part fits the declared model better than the declared fit did (the declared
//!    fit stopped in a local minimum), the declared model is refitted from there and the diagnosis is
//!    repeated (at most twice), so that "before" is an honest optimum.
//!
//! "before" is the declared model's held-out RMSE, "after" the chosen extension's (equal to "before" for
//! `null`).
//!
//! ## The catalogue
//!
//! | id | extension fitted | its parameters | pointed to by |
//! | --- | --- | --- | --- |
//! | `gap-drift` | c1(k) = c1 + r1 k, c2(k) = c2 + r2 k | r1, r2 (per sample) | drift, by mode |
//! | `curved-borders` | upper = s + p2 s^2 + p3 s^3 (s = x - c1), lower = m2 s + q2 s^2 + q3 s^3 (s = x + c2) | p2, p3, q2, q3 | against x_hat, Billings, extremes |
//! | `extra-delay` | delay + 1, + 2 or + 3 (each fitted, the best kept) | the delay | cross-correlation |
//! | `linear-order` | na + 1 or nb + 1 (each fitted, the best kept) | the new coefficient | cross-correlation, Ljung-Box |
//! | `coloured-noise` | AR(p) noise model on the output error, p = 1..3 by BIC, refitted jointly | phi_1..phi_p | Ljung-Box |
//! | `saturation` | model output clipped to [lo, hi] | lo, hi | clipping, extremes, against x_hat, Billings |
//! | `periodic-disturbance` | a_s sin(w k) + a_c cos(w k) on the output; w from the spectrum peak, a_s, a_c by least squares, then all refined | w, amplitude, phase | spectrum peak, Ljung-Box |
//! | `quantization` | the sensor rounds to offset + q Z; the model gives the expected reading for Gaussian noise of std sigma before the rounding | q and offset (from the value lattice), sigma (fitted) | value lattice |
//! | `friction` | elasto-plastic Coulomb element with the backlash, slip levels F+ and -F-, in two arrangements: *series* (after the backlash output, f(k) = clamp(f(k-1) + w(k) - w(k-1), -F-, F+)) or *contact* (the play inside the element's spring: after a reversal the force unloads, crosses the play at zero, reloads); both are fitted and the better kept | F+, F-, form (k_e = 1: the stiffness is carried by b, as m1 = 1) | extremes, since reversal, by mode, Billings, drift, Ljung-Box |
//!
//! **coloured-noise is judged by prediction.** Its held-out error is the one-step-ahead prediction error
//! of the model with its noise model, `y(k) - [s(k) + sum_i phi_i (y(k-i) - s(k-i))]` with s the simulated
//! output; the declared (output-error) model's one-step predictor is its simulation, so "before" is its
//! simulation error, and the comparison is between the two predictors. Its BIC uses the same prediction
//! errors (the Gaussian likelihood of a model with a noise model).
//!
//! ## Why no constant offset
//!
//! A constant output offset d is not in the catalogue: with straight borders it is absorbed exactly into
//! the gaps, m1 (x - c1) + d = m1 (x - (c1 - d/m1)) and m2 (x + c2) + d = m2 (x + (c2 + d/m2)), so the
//! declared model already contains it and no data can show it (test
//! `constant_offset_is_absorbed_into_the_gaps`: an offset of 0.7 on a clean record gives `null` and moves
//! the fitted gaps by -0.7 and +0.7/m2). An input offset passes the linear block as a constant and is
//! absorbed the same way. This is also why the fitted gaps may be negative: only c1 + c2 (the play) must
//! not be.

use std::cell::RefCell;

use rand_chacha::ChaCha8Rng;
use rand_core::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use serde::Serialize;
use serde_json::{Value, json};

use super::catalogue::EffectId;
use super::fit::{LmOptions, bic, levenberg_marquardt};
use super::model::{BaseModel, Extension, Model, Simulation};
use super::residual::{self, Verdict};
use crate::identify::mrgia::{Mrgia, MrgiaConfig};
use crate::plant::effects::FrictionForm;
use crate::plant::{MAX_DELAY, MAX_ORDER, Mode};

/// Settings of a diagnosis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiagnoseConfig {
    pub na: usize,
    pub nb: usize,
    pub delay: usize,
    /// Share of the record used for fitting (the rest is held out). Default 0.7.
    pub fit_fraction: f64,
    /// Lags of the correlation tests. Default 20.
    pub lags: usize,
    /// Perturbed restarts of the declared model's fit, besides the MRGIA and least-squares starts. Default 3.
    pub restarts: usize,
    /// Seed of the perturbations (the diagnosis is deterministic for a given seed).
    pub seed: u64,
    /// One-sided z threshold of the held-out comparison (Diebold-Mariano). Default 1.645 (5%).
    pub z_threshold: f64,
    pub lm: LmOptions,
}

impl DiagnoseConfig {
    pub fn new(na: usize, nb: usize, delay: usize) -> Self {
        Self {
            na,
            nb,
            delay,
            fit_fraction: 0.7,
            lags: 20,
            restarts: 3,
            seed: 0,
            z_threshold: 1.645,
            lm: LmOptions::default(),
        }
    }
}

/// Why a diagnosis could not run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DiagnoseError {
    #[error("u has {u} samples and y {y}: they must be the same length")]
    Length { u: usize, y: usize },
    #[error("{n} samples: at least {min} are needed (fit part and held-out part)")]
    TooShort { n: usize, min: usize },
    #[error("invalid model structure: {0}")]
    Structure(String),
    #[error("fit_fraction {0} must be in [0.3, 0.95]")]
    Fraction(f64),
    #[error("the declared model could not be fitted: no start point gives a valid simulation")]
    NoFit,
    #[error("the record contains a non-finite value at sample {0}")]
    NonFinite(usize),
}

/// A residual test's verdict and the effects it points to.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TestResult {
    #[serde(flatten)]
    pub verdict: Verdict,
    pub points_to: Vec<EffectId>,
}

/// One fitted candidate extension.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Candidate {
    pub id: EffectId,
    /// The rejecting tests that made it a candidate (pointing order).
    pub pointed_by: Vec<&'static str>,
    pub model: Model,
    /// Parameters estimated (base + extension) for the information criterion.
    pub k: usize,
    pub fit_rmse: f64,
    pub bic: f64,
    /// BIC of the extension minus BIC of the declared model (negative favours the extension).
    pub delta_bic: f64,
    pub heldout_rmse: f64,
    /// Diebold-Mariano z of the held-out squared-error reduction (positive: the extension is better).
    pub heldout_z: f64,
    /// "simulation" or "one-step prediction".
    pub error_kind: &'static str,
    pub supported: bool,
    pub reason: String,
    /// The extension's output over the whole record (simulation, or one-step prediction for a noise model).
    #[serde(skip)]
    pub output: Vec<f64>,
    /// The extension's simulation over the whole record.
    #[serde(skip)]
    pub sim: Simulation,
}

/// The result of [`diagnose`].
#[derive(Debug, Clone, PartialEq)]
pub struct Diagnosis {
    pub config: DiagnoseConfig,
    pub n: usize,
    pub n_fit: usize,
    /// The declared model fitted on the fit part.
    pub base: Model,
    pub base_k: usize,
    pub base_fit_rmse: f64,
    pub base_bic: f64,
    pub base_heldout_rmse: f64,
    /// The declared model's simulation over the whole record.
    pub base_sim: Simulation,
    /// The residual tests, on the fit part of the declared model's residual.
    pub tests: Vec<TestResult>,
    pub candidates: Vec<Candidate>,
    /// Index into `candidates` of the chosen effect.
    pub chosen: Option<usize>,
    /// Number of fits of the declared model needed (a winner whose base part fitted the plain model better
    /// triggers a refit from there).
    pub base_rounds: usize,
}

impl Diagnosis {
    pub fn effect(&self) -> Option<&Candidate> {
        self.chosen.map(|i| &self.candidates[i])
    }

    pub fn effect_id(&self) -> Option<EffectId> {
        self.effect().map(|c| c.id)
    }

    /// Held-out RMSE after: the chosen extension's, or the declared model's when nothing is supported.
    pub fn after_rmse(&self) -> f64 {
        self.effect()
            .map_or(self.base_heldout_rmse, |c| c.heldout_rmse)
    }

    /// The test that points to the chosen effect: the first of its pointing tests (most specific first, see
    /// [`EffectId::pointing_tests`]) that rejected.
    pub fn pointing_test(&self) -> Option<&'static str> {
        self.effect()?.pointed_by.first().copied()
    }

    /// Simulate the declared model and the chosen extension (both as fitted here) over another record,
    /// from zero initial state: cross-record validation. With a noise model the extension's error is its
    /// one-step prediction error, as in the held-out comparison.
    pub fn cross_validate(&self, u: &[f64], y: &[f64]) -> Option<CrossValidation> {
        let n = u.len().min(y.len());
        let ymax = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let umax = u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let limit = 1e4 * (1.0 + umax + ymax);
        let before = self.base.simulate(u, n, limit)?;
        let after = match self.effect() {
            Some(c) => {
                let s = c.model.simulate(u, n, limit)?;
                c.model.predict_from(&s.y, &y[..n])
            }
            None => before.y.clone(),
        };
        let err = |m: &[f64]| rms(y.iter().zip(m).map(|(a, b)| a - b));
        Some(CrossValidation {
            samples: n,
            y_std: std_dev(&y[..n]),
            rmse_before: err(&before.y),
            rmse_after: err(&after),
            before: before.y,
            after,
        })
    }

    /// The contract's JSON object. `ts`, when known, adds per-second forms of per-sample parameters.
    pub fn to_json(&self, ts: Option<f64>) -> Value {
        let effect = match self.effect() {
            Some(c) => json!({
                "id": c.id,
                "description": c.id.describe(),
                "parameters": parameters(c, &self.base, self.n, ts),
                "pointed_by": self.pointing_test(),
                "pointing_tests_rejected": c.pointed_by,
                "heldout_rmse": c.heldout_rmse,
                "heldout_z": c.heldout_z,
                "error_kind": c.error_kind,
                "bic": c.bic,
                "delta_bic": c.delta_bic,
                "model": base_json(&c.model.base),
            }),
            None => json!({"id": null, "parameters": {}, "pointed_by": null}),
        };
        let candidates: Vec<Value> = self
            .candidates
            .iter()
            .map(|c| {
                json!({
                    "id": c.id,
                    "pointed_by": c.pointed_by,
                    "parameters": parameters(c, &self.base, self.n, ts),
                    "k": c.k,
                    "fit_rmse": c.fit_rmse,
                    "heldout_rmse": c.heldout_rmse,
                    "heldout_z": c.heldout_z,
                    "error_kind": c.error_kind,
                    "bic": c.bic,
                    "delta_bic": c.delta_bic,
                    "supported": c.supported,
                    "reason": c.reason,
                })
            })
            .collect();
        json!({
            "before": {
                "rmse": self.base_heldout_rmse,
                "fit_rmse": self.base_fit_rmse,
                "bic": self.base_bic,
                "k": self.base_k,
                "model": base_json(&self.base.base),
            },
            "effect": effect,
            "after": {
                "rmse": self.after_rmse(),
                "error_kind": self.effect().map_or("simulation", |c| c.error_kind),
            },
            "tests": self.tests,
            "tests_on": format!(
                "residual y - y_model of the declared model's simulation on the fit part (samples 0..{})",
                self.n_fit
            ),
            "candidates": candidates,
            "decision": DECISION_RULE,
            "samples": self.n,
            "fit_samples": self.n_fit,
            "heldout_samples": self.n - self.n_fit,
            "na": self.config.na,
            "nb": self.config.nb,
            "delay": self.config.delay,
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

/// The smallest relative fall of the held-out RMSE that counts (besides its significance): a change of the
/// model that moves the error by less than 1% is no finding even when it is consistent.
pub const MIN_FALL: f64 = 0.01;

/// The decision rule, as written into every report.
pub const DECISION_RULE: &str = "an extension is supported when its held-out error is at least 1% lower than the \
declared model's with a one-sided Diebold-Mariano z above the threshold (5%) AND its BIC on the fit part is lower; \
among supported deterministic extensions the lowest BIC wins; coloured-noise (judged by one-step prediction) \
is chosen only when no deterministic extension is supported; otherwise the answer is null";

fn base_json(b: &BaseModel) -> Value {
    json!({
        "na": b.na, "nb": b.nb, "delay": b.delay,
        "a": b.a, "b": b.b, "m1": b.m1, "m2": b.m2, "c1": b.c1, "c2": b.c2,
    })
}

/// The extension's parameters in the report's units.
fn parameters(c: &Candidate, declared: &Model, n: usize, ts: Option<f64>) -> Value {
    let b = &c.model.base;
    match (&c.id, &c.model.ext) {
        (EffectId::ExtraDelay, _) => json!({
            "delay": b.delay, "declared_delay": declared.base.delay,
            "extra": b.delay - declared.base.delay,
        }),
        (EffectId::LinearOrder, _) => {
            let added = if b.na > declared.base.na {
                (format!("a{}", b.na), b.a[b.na - 1])
            } else {
                (format!("b{}", b.nb), b.b[b.nb])
            };
            json!({"na": b.na, "nb": b.nb, "added": added.0, "value": added.1})
        }
        (_, Extension::GapDrift { c1_rate, c2_rate }) => {
            let end = (n.saturating_sub(1)) as f64;
            let mut v = json!({
                "c1_rate": c1_rate, "c2_rate": c2_rate,
                "c1_start": b.c1, "c2_start": b.c2,
                "c1_end": b.c1 + c1_rate * end, "c2_end": b.c2 + c2_rate * end,
                "rate_unit": "per sample",
            });
            if let Some(ts) = ts {
                v["c1_rate_per_s"] = json!(c1_rate / ts);
                v["c2_rate_per_s"] = json!(c2_rate / ts);
            }
            v
        }
        (_, Extension::CurvedBorders { upper, lower }) => json!({
            "upper_s2": upper[0], "upper_s3": upper[1], "lower_s2": lower[0], "lower_s3": lower[1],
        }),
        (_, Extension::Saturation { lo, hi }) => json!({"lo": lo, "hi": hi}),
        (
            _,
            Extension::Periodic {
                omega,
                a_sin,
                a_cos,
            },
        ) => {
            let mut v = json!({
                "omega": omega, "omega_unit": "rad/sample",
                "period_samples": 2.0 * std::f64::consts::PI / omega.abs().max(f64::MIN_POSITIVE),
                "amplitude": a_sin.hypot(*a_cos), "phase": a_cos.atan2(*a_sin),
            });
            if let Some(ts) = ts {
                v["frequency_hz"] = json!(omega.abs() / (2.0 * std::f64::consts::PI * ts));
            }
            v
        }
        (
            _,
            Extension::Quantization {
                step,
                offset,
                sigma,
            },
        ) => json!({
            "step": step, "offset": offset, "noise_before_rounding": sigma,
        }),
        (
            _,
            Extension::Friction {
                f_plus,
                f_minus,
                form,
            },
        ) => json!({
            "k_e": 1.0, "f_plus": f_plus, "f_minus": f_minus, "form": form,
            "note": match form {
                FrictionForm::Series => "series: f(k) = clamp(f(k-1) + (w(k) - w(k-1)), -f_minus, f_plus) after the backlash; k_e = 1 is the normalisation (the stiffness is carried by b, as m1 = 1 is)",
                FrictionForm::Contact => "contact: the play c1, c2 inside the spring: f = (x - z) - c1 beyond c1, m2 ((x - z) + c2) beyond -c2, 0 between, slider z moves at the slip levels; k_e = 1 is the normalisation",
            },
        }),
        (_, Extension::ColouredNoise { phi }) => json!({"ar_order": phi.len(), "phi": phi}),
        (_, Extension::None) => json!({}),
    }
}

// ---------------------------------------------------------------------------------------------------------
// Fitting helpers

/// What the fit minimises.
#[derive(Clone, Copy, PartialEq)]
enum Objective {
    /// Output error: y - simulation.
    Simulation,
    /// One-step prediction error of the model with its noise model.
    Prediction,
}

struct Problem<'a> {
    u: &'a [f64],
    y: &'a [f64],
    n_fit: usize,
    limit: f64,
    time_scale: f64,
    y_scale: f64,
    x_scale: f64,
}

impl Problem<'_> {
    /// Residuals of `m` on the fit part into `out`.
    fn residuals(
        &self,
        m: &Model,
        obj: Objective,
        scratch: &mut Simulation,
        out: &mut Vec<f64>,
    ) -> bool {
        if !m.simulate_into(self.u, self.n_fit, self.limit, scratch) {
            return false;
        }
        let y = &self.y[..self.n_fit];
        match (obj, &m.ext) {
            (Objective::Prediction, Extension::ColouredNoise { phi }) => {
                if phi.iter().any(|p| !p.is_finite()) {
                    return false;
                }
                let e: Vec<f64> = y.iter().zip(&scratch.y).map(|(a, b)| a - b).collect();
                out.extend((0..e.len()).map(|k| {
                    let mut v = e[k];
                    for (i, p) in phi.iter().enumerate() {
                        if k > i {
                            v -= p * e[k - 1 - i];
                        }
                    }
                    v
                }));
            }
            _ => out.extend(y.iter().zip(&scratch.y).map(|(a, b)| a - b)),
        }
        true
    }

    /// Typical magnitudes of the packed parameters of `m`.
    fn typical(&self, m: &Model) -> Vec<f64> {
        let mut t = m.base.typical(self.y_scale);
        let ys = self.y_scale;
        let xs = self.x_scale.max(1e-12);
        t.extend(match &m.ext {
            Extension::None => vec![],
            Extension::Quantization { step, .. } => vec![0.1 * step],
            Extension::GapDrift { .. } => vec![0.1 * ys; 2],
            Extension::CurvedBorders { .. } => {
                vec![
                    0.1 * ys / (xs * xs),
                    0.1 * ys / (xs * xs * xs),
                    0.1 * ys / (xs * xs),
                    0.1 * ys / (xs * xs * xs),
                ]
            }
            Extension::Saturation { .. } | Extension::Friction { .. } => vec![ys; 2],
            Extension::Periodic { .. } => vec![1.0 / self.n_fit as f64, 0.1 * ys, 0.1 * ys],
            Extension::ColouredNoise { phi } => vec![0.5; phi.len()],
        });
        t
    }

    /// Fit `template`'s structure from the packed `starts`: a short run from each, then the best to
    /// convergence. Returns the model and its cost.
    fn fit(
        &self,
        template: &Model,
        starts: &[Vec<f64>],
        obj: Objective,
        lm: &LmOptions,
    ) -> Option<(Model, f64)> {
        let scratch = RefCell::new(Simulation::default());
        let f = |th: &[f64], out: &mut Vec<f64>| {
            let m = template.unpack(th, self.time_scale);
            self.residuals(&m, obj, &mut scratch.borrow_mut(), out)
        };
        let typ = self.typical(template);
        let short = LmOptions {
            max_iter: lm.max_iter.min(8),
            ..*lm
        };
        let mut best: Option<(Vec<f64>, f64)> = None;
        // Many starts (a grid): screen them by their cost and refine only the best few.
        let mut screened: Vec<(f64, &Vec<f64>)> = Vec::new();
        let starts: Vec<&Vec<f64>> = if starts.len() > SCREEN_KEEP {
            let mut r = Vec::new();
            for s in starts {
                r.clear();
                if f(s, &mut r) {
                    let c: f64 = r.iter().map(|v| v * v).sum();
                    if c.is_finite() {
                        screened.push((c, s));
                    }
                }
            }
            screened.sort_by(|a, b| a.0.total_cmp(&b.0));
            screened.iter().take(SCREEN_KEEP).map(|(_, s)| *s).collect()
        } else {
            starts.iter().collect()
        };
        if starts.len() > 1 {
            for s in starts.iter().copied() {
                if let Ok(fit) = levenberg_marquardt(&f, s, &typ, &[], &short)
                    && best.as_ref().is_none_or(|b| fit.cost < b.1)
                {
                    best = Some((fit.theta, fit.cost));
                }
            }
        } else if let Some(s) = starts.first() {
            best = Some(((*s).clone(), f64::INFINITY));
        }
        let (start, _) = best?;
        let fit = levenberg_marquardt(&f, &start, &typ, &[], lm).ok()?;
        Some((template.unpack(&fit.theta, self.time_scale), fit.cost))
    }
}

fn mrgia_start(p: &Problem, na: usize, nb: usize, delay: usize) -> Option<BaseModel> {
    let mut est = Mrgia::new(MrgiaConfig::recommended(na, nb, delay)).ok()?;
    for k in 0..p.n_fit {
        est.update(p.u[k], p.y[k]);
    }
    let e = est.estimate();
    let ok =
        e.a.iter()
            .chain(&e.b)
            .chain([&e.m2, &e.c1, &e.c2])
            .all(|v| v.is_finite());
    ok.then(|| BaseModel {
        na,
        nb,
        delay,
        a: e.a.clone(),
        b: e.b.clone(),
        m1: 1.0,
        m2: if e.m2 > 1e-3 { e.m2 } else { 1.0 },
        c1: e.c1,
        c2: e.c2,
    })
}

/// Equation-error least squares of y on its past and the delayed inputs, with a constant: the linear
/// block, unit slopes, and the constant turned into gaps around a small play.
fn ls_start(p: &Problem, na: usize, nb: usize, delay: usize) -> Option<BaseModel> {
    use nalgebra::{DMatrix, DVector};
    let k0 = na.max(delay + nb);
    if p.n_fit <= k0 + na + nb + 3 {
        return None;
    }
    let cols = na + nb + 2;
    let mut h = DMatrix::<f64>::zeros(cols, cols);
    let mut g = DVector::<f64>::zeros(cols);
    let mut row = vec![0.0; cols];
    for k in k0..p.n_fit {
        for (i, r) in row.iter_mut().take(na).enumerate() {
            *r = -p.y[k - 1 - i];
        }
        for j in 0..=nb {
            row[na + j] = p.u[k - delay - j];
        }
        row[cols - 1] = 1.0;
        for a in 0..cols {
            g[a] += row[a] * p.y[k];
            for b in 0..cols {
                h[(a, b)] += row[a] * row[b];
            }
        }
    }
    let ridge = 1e-9 * (0..cols).map(|i| h[(i, i)]).fold(0.0, f64::max);
    for i in 0..cols {
        h[(i, i)] += ridge;
    }
    let th = h.cholesky()?.solve(&g);
    let o = th[cols - 1];
    let gap = 0.05 * p.y_scale;
    Some(BaseModel {
        na,
        nb,
        delay,
        a: th.iter().take(na).copied().collect(),
        b: th.iter().skip(na).take(nb + 1).copied().collect(),
        m1: 1.0,
        m2: 1.0,
        c1: -o + gap,
        c2: o + gap,
    })
}

/// With more starts than this, [`Problem::fit`] ranks them by cost and refines only this many.
const SCREEN_KEEP: usize = 6;

/// Pull an unstable start's poles inside the unit circle: a_i -> a_i r^i (every root scaled by r = 0.9)
/// until stable.
fn stabilize(a: &mut [f64]) {
    for _ in 0..200 {
        if super::model::is_stable(a) {
            return;
        }
        let mut r = 1.0;
        for v in a.iter_mut() {
            r *= 0.9;
            *v *= r;
        }
    }
    a.iter_mut().for_each(|v| *v = 0.0);
}

fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    if n == 0 { 0.0 } else { (s / n as f64).sqrt() }
}

fn std_dev(v: &[f64]) -> f64 {
    let n = v.len().max(1) as f64;
    let m = v.iter().sum::<f64>() / n;
    (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / n).sqrt()
}

/// Diebold-Mariano statistic for "e1 has smaller squared errors than e0": the mean of
/// d = e0^2 - e1^2 over its standard error, with a Bartlett (Newey-West) long-run variance over
/// floor(n^(1/3)) lags so that autocorrelated errors do not inflate it.
pub fn diebold_mariano(e0: &[f64], e1: &[f64]) -> f64 {
    let d: Vec<f64> = e0.iter().zip(e1).map(|(a, b)| a * a - b * b).collect();
    let n = d.len();
    if n < 2 {
        return 0.0;
    }
    let nf = n as f64;
    let mean = d.iter().sum::<f64>() / nf;
    let c: Vec<f64> = d.iter().map(|v| v - mean).collect();
    let lags = (nf.cbrt().floor() as usize).min(n - 1);
    let gamma = |l: usize| (l..n).map(|k| c[k] * c[k - l]).sum::<f64>() / nf;
    let mut v = gamma(0);
    for l in 1..=lags {
        v += 2.0 * (1.0 - l as f64 / (lags + 1) as f64) * gamma(l);
    }
    if v <= 0.0 {
        return if mean > 0.0 { f64::INFINITY } else { 0.0 };
    }
    mean / (v / nf).sqrt()
}

// ---------------------------------------------------------------------------------------------------------
// The diagnosis

/// Diagnose the record (u, y) against the declared model of `cfg`.
pub fn diagnose(u: &[f64], y: &[f64], cfg: &DiagnoseConfig) -> Result<Diagnosis, DiagnoseError> {
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
    if cfg.na > MAX_ORDER || cfg.nb > MAX_ORDER {
        return Err(DiagnoseError::Structure(format!(
            "na = {}, nb = {}: each must be in 0..=4",
            cfg.na, cfg.nb
        )));
    }
    if cfg.delay < 1 || cfg.delay > MAX_DELAY {
        return Err(DiagnoseError::Structure(format!(
            "delay = {}: must be in 1..=64",
            cfg.delay
        )));
    }
    if !(0.3..=0.95).contains(&cfg.fit_fraction) {
        return Err(DiagnoseError::Fraction(cfg.fit_fraction));
    }
    let n = u.len();
    let min = 100 + 20 * (cfg.na + cfg.nb + cfg.delay);
    if n < min {
        return Err(DiagnoseError::TooShort { n, min });
    }
    let n_fit = ((n as f64 * cfg.fit_fraction).round() as usize).clamp(1, n - 1);
    let y_fit = &y[..n_fit];
    let y_scale =
        std_dev(y_fit).max(1e-12 * (1.0 + y_fit.iter().fold(0.0f64, |m, v| m.max(v.abs()))));
    let umax = u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let ymax = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut problem = Problem {
        u,
        y,
        n_fit,
        limit: 1e4 * (1.0 + umax + ymax),
        time_scale: n_fit as f64,
        y_scale,
        x_scale: y_scale,
    };
    let mut extra_starts: Vec<BaseModel> = Vec::new();
    let mut rounds = 0;
    loop {
        rounds += 1;
        let base = fit_declared(&problem, cfg, &extra_starts)?;
        let d = diagnose_from(&mut problem, cfg, base, rounds)?;
        // A winner whose own base part fits the plain model better than the declared fit means the declared
        // fit stopped in a local minimum: refit from there (at most twice) so that "before" is honest.
        if rounds < 3
            && let Some(c) = d.effect()
            && matches!(
                c.id,
                EffectId::GapDrift
                    | EffectId::CurvedBorders
                    | EffectId::Saturation
                    | EffectId::PeriodicDisturbance
                    | EffectId::Friction
                    | EffectId::ColouredNoise
            )
        {
            let start = Model::plain(c.model.base.clone());
            if let Some((polished, cost)) = problem.fit(
                &start,
                &[start.pack(problem.time_scale)],
                Objective::Simulation,
                &cfg.lm,
            ) {
                let base_cost = d.base_fit_rmse.powi(2) * n_fit as f64;
                if cost < base_cost * (1.0 - 1e-6) {
                    extra_starts.push(polished.base);
                    continue;
                }
            }
        }
        return Ok(d);
    }
}

/// Fit the declared model: MRGIA and least-squares starts (and any `extra` ones), then perturbed restarts.
fn fit_declared(
    p: &Problem,
    cfg: &DiagnoseConfig,
    extra: &[BaseModel],
) -> Result<Model, DiagnoseError> {
    let (na, nb, d) = (cfg.na, cfg.nb, cfg.delay);
    let mut starts: Vec<BaseModel> = Vec::new();
    starts.extend(mrgia_start(p, na, nb, d));
    starts.extend(ls_start(p, na, nb, d));
    starts.extend(extra.iter().cloned());
    // Always one start without dynamics (stable whatever the data), with the least-squares gain if any.
    let b0 = starts.last().map_or(vec![1.0; nb + 1], |s| s.b.clone());
    starts.push(BaseModel {
        b: b0,
        ..BaseModel::zero(na, nb, d)
    });
    for s in &mut starts {
        stabilize(&mut s.a);
        // A start with an inverted memory zone is not a backlash: keep its offset, give it a small gap.
        let (offset, gap) = ((s.c2 - s.c1) / 2.0, (s.c1 + s.c2) / 2.0);
        if gap < 0.01 * p.y_scale {
            let gap = 0.01 * p.y_scale;
            s.c1 = gap - offset;
            s.c2 = gap + offset;
        }
    }
    let packed: Vec<Vec<f64>> = starts
        .iter()
        .map(|b| Model::plain(b.clone()).pack(p.time_scale))
        .collect();
    let template = Model::plain(starts[0].clone());
    let (mut best, mut cost) = p
        .fit(&template, &packed, Objective::Simulation, &cfg.lm)
        .ok_or(DiagnoseError::NoFit)?;
    // Perturbed restarts around the best.
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed ^ 0xD1A6_0000);
    let typ = best.base.typical(p.y_scale);
    for _ in 0..cfg.restarts {
        let th0 = best.pack(p.time_scale);
        let th: Vec<f64> = th0
            .iter()
            .zip(&typ)
            .enumerate()
            .map(|(j, (v, t))| {
                let z: f64 = StandardNormal.sample(&mut rng);
                if j < na {
                    v * (1.0 + 0.1 * z)
                } else {
                    v + 0.3 * t * z
                }
            })
            .collect();
        if let Some((m, c)) = p.fit(&best, &[th], Objective::Simulation, &cfg.lm)
            && c < cost
        {
            best = m;
            cost = c;
        }
    }
    Ok(best)
}

fn diagnose_from(
    p: &mut Problem,
    cfg: &DiagnoseConfig,
    base: Model,
    rounds: usize,
) -> Result<Diagnosis, DiagnoseError> {
    let (u, y, n_fit) = (p.u, p.y, p.n_fit);
    let n = u.len();
    let base_sim = base.simulate(u, n, p.limit).ok_or(DiagnoseError::NoFit)?;
    p.x_scale = std_dev(&base_sim.x[..n_fit]).max(1e-12);
    let e: Vec<f64> = y.iter().zip(&base_sim.y).map(|(a, b)| a - b).collect();
    let base_cost: f64 = e[..n_fit].iter().map(|v| v * v).sum();
    let base_k = base.n_estimated();
    let base_bic = bic(base_cost, n_fit, base_k);
    let base_heldout_rmse = rms(e[n_fit..].iter().copied());

    // Residual tests on the fit part.
    let ef = &e[..n_fit];
    let uf = &u[..n_fit];
    let xf = &base_sim.x[..n_fit];
    let mf = &base_sim.mode[..n_fit];
    let yf = &y[..n_fit];
    let lags = cfg.lags.min(n_fit / 5).max(1);
    let lb = residual::ljung_box(ef, lags);
    let cc = residual::cross_correlation(ef, uf, lags);
    let bil = residual::billings(ef, uf, lags.min(10));
    let (_, bm) = residual::by_mode(ef, mf);
    let (_, sr) = residual::since_reversal(ef, xf);
    let ax = residual::against_x(ef, xf, mf);
    let dr = residual::drift(ef, mf);
    let (omega, sp) = residual::spectrum_peak(ef);
    let (q, lat) = residual::lattice(yf);
    let (clip_lo, clip_hi, clip) = residual::clipping(yf);
    let ext = residual::extreme_increments(ef, &base_sim.y[..n_fit]);
    let verdicts = vec![
        lb,
        cc.verdict,
        bil.verdict,
        bm,
        sr,
        ax,
        dr,
        sp,
        lat,
        clip,
        ext,
    ];
    let tests: Vec<TestResult> = verdicts
        .into_iter()
        .map(|v| TestResult {
            points_to: EffectId::pointed_by(v.name),
            verdict: v,
        })
        .collect();
    let rejected = |name: &str| {
        tests
            .iter()
            .any(|t| t.verdict.name == name && t.verdict.rejects)
    };

    let held = e[n_fit..].to_vec();
    let ctx = Context {
        p: &*p,
        cfg,
        base: &base,
        base_cost,
        base_bic,
        base_heldout: &held,
        e,
        omega,
        q,
        clip: (clip_lo, clip_hi),
    };
    let mut candidates = Vec::new();
    for id in EffectId::ALL {
        let pointed: Vec<&'static str> = id
            .pointing_tests()
            .iter()
            .copied()
            .filter(|t| rejected(t))
            .collect();
        if pointed.is_empty() {
            continue;
        }
        if let Some(c) = ctx.candidate(id, pointed) {
            candidates.push(c);
        }
    }
    let best_of = |det: bool| {
        candidates
            .iter()
            .enumerate()
            .filter(|(_, c)| c.supported && (c.id != EffectId::ColouredNoise) == det)
            .min_by(|a, b| a.1.bic.total_cmp(&b.1.bic))
            .map(|(i, _)| i)
    };
    let chosen = best_of(true).or_else(|| best_of(false));
    Ok(Diagnosis {
        config: *cfg,
        n,
        n_fit,
        base_k,
        base_fit_rmse: (base_cost / n_fit as f64).sqrt(),
        base_bic,
        base_heldout_rmse,
        base,
        base_sim,
        tests,
        candidates,
        chosen,
        base_rounds: rounds,
    })
}

struct Context<'a, 'b> {
    p: &'a Problem<'b>,
    cfg: &'a DiagnoseConfig,
    base: &'a Model,
    base_cost: f64,
    base_bic: f64,
    base_heldout: &'a [f64],
    /// The declared model's residual over the whole record.
    e: Vec<f64>,
    omega: f64,
    q: Option<f64>,
    clip: (f64, f64),
}

impl Context<'_, '_> {
    /// Fit and judge one candidate.
    fn candidate(&self, id: EffectId, pointed_by: Vec<&'static str>) -> Option<Candidate> {
        let (model, cost, obj, k) = self.fit_candidate(id)?;
        let p = self.p;
        let n = p.u.len();
        let sim = model.simulate(p.u, n, p.limit)?;
        let output = model.predict_from(&sim.y, p.y);
        let held: Vec<f64> = p.y[p.n_fit..]
            .iter()
            .zip(&output[p.n_fit..])
            .map(|(a, b)| a - b)
            .collect();
        let heldout_rmse = rms(held.iter().copied());
        let heldout_z = diebold_mariano(self.base_heldout, &held);
        let b = bic(cost, p.n_fit, k) + structure_penalty(id);
        let delta_bic = b - self.base_bic;
        let falls = heldout_rmse < (1.0 - MIN_FALL) * rms(self.base_heldout.iter().copied())
            && heldout_z > self.cfg.z_threshold;
        let favours = delta_bic < 0.0;
        let reason = match (falls, favours) {
            (true, true) => {
                "held-out error falls significantly and BIC favours the extension".to_string()
            }
            (false, true) => format!(
                "BIC favours it (dBIC {delta_bic:.1}) but the held-out error does not fall significantly (z {heldout_z:.2})"
            ),
            (true, false) => format!(
                "held-out error falls (z {heldout_z:.2}) but BIC does not favour it (dBIC {delta_bic:+.1})"
            ),
            (false, false) => format!("neither: held-out z {heldout_z:.2}, dBIC {delta_bic:+.1}"),
        };
        let reason = if (cost - self.base_cost).abs()
            <= 1e-12 * self.base_cost.max(f64::MIN_POSITIVE)
            && obj == Objective::Simulation
        {
            format!(
                "{reason} (the fit found no valid step away from the declared model: it sits on the edge of \
                 the valid region, where nearby parameters would invert the backlash's memory zone, or the \
                 extension's start has no effect on the output)"
            )
        } else {
            reason
        };
        Some(Candidate {
            id,
            pointed_by,
            k,
            fit_rmse: (cost / p.n_fit as f64).sqrt(),
            bic: b,
            delta_bic,
            heldout_rmse,
            heldout_z,
            error_kind: if obj == Objective::Prediction {
                "one-step prediction"
            } else {
                "simulation"
            },
            supported: falls && favours,
            reason,
            model,
            output,
            sim,
        })
    }

    /// The fitted extension, its fit-part cost, the objective and the parameter count.
    fn fit_candidate(&self, id: EffectId) -> Option<(Model, f64, Objective, usize)> {
        let p = self.p;
        let lm = &self.cfg.lm;
        let base = self.base;
        let ts = p.time_scale;
        let bk = base.base.n_params();
        let with_ext = |ext: Extension| Model {
            base: base.base.clone(),
            ext,
        };
        let sim_fit = |m: Model, starts: Vec<Vec<f64>>| {
            p.fit(&m, &starts, Objective::Simulation, lm).map(|(m, c)| {
                let k = m.n_estimated();
                (m, c, Objective::Simulation, k)
            })
        };
        let y_fit = &p.y[..p.n_fit];
        match id {
            EffectId::GapDrift => {
                let m = with_ext(Extension::GapDrift {
                    c1_rate: 0.0,
                    c2_rate: 0.0,
                });
                let s = m.pack(ts);
                sim_fit(m, vec![s])
            }
            EffectId::CurvedBorders => {
                let m = with_ext(Extension::CurvedBorders {
                    upper: [0.0; 2],
                    lower: [0.0; 2],
                });
                let s = m.pack(ts);
                sim_fit(m, vec![s])
            }
            EffectId::Saturation => {
                let (lo0, hi0) = self.clip;
                let mut sorted = y_fit.to_vec();
                sorted.sort_by(f64::total_cmp);
                let qt = |f: f64| sorted[((sorted.len() - 1) as f64 * f) as usize];
                let starts: Vec<Vec<f64>> = [(lo0, hi0), (qt(0.02), qt(0.98)), (qt(0.1), qt(0.9))]
                    .iter()
                    .map(|&(lo, hi)| with_ext(Extension::Saturation { lo, hi }).pack(ts))
                    .collect();
                sim_fit(with_ext(Extension::Saturation { lo: lo0, hi: hi0 }), starts)
            }
            EffectId::PeriodicDisturbance => {
                let w = self.omega;
                let ef = &self.e[..p.n_fit];
                // Least squares of the residual on sin, cos at the spectrum's peak.
                let (mut ss, mut cc, mut sc, mut se, mut ce) = (0.0, 0.0, 0.0, 0.0, 0.0);
                for (k, v) in ef.iter().enumerate() {
                    let (s, c) = (w * k as f64).sin_cos();
                    ss += s * s;
                    cc += c * c;
                    sc += s * c;
                    se += s * v;
                    ce += c * v;
                }
                let det = ss * cc - sc * sc;
                let (a_sin, a_cos) = if det.abs() > 1e-12 {
                    ((se * cc - ce * sc) / det, (ce * ss - se * sc) / det)
                } else {
                    (0.0, 0.0)
                };
                let m = with_ext(Extension::Periodic {
                    omega: w,
                    a_sin,
                    a_cos,
                });
                let s = m.pack(ts);
                sim_fit(m, vec![s])
            }
            EffectId::Quantization => {
                let q = self.q?;
                // Offset: circular mean of the measured values' phase on the lattice.
                let (s, c) = y_fit.iter().fold((0.0, 0.0), |(s, c), v| {
                    let ph = 2.0 * std::f64::consts::PI * v / q;
                    (s + ph.sin(), c + ph.cos())
                });
                let offset = q * s.atan2(c) / (2.0 * std::f64::consts::PI);
                // The noise before the rounding: start from the declared model's residual level.
                let sigma = (self.base_cost / p.n_fit as f64).sqrt().min(q);
                let m = with_ext(Extension::Quantization {
                    step: q,
                    offset,
                    sigma,
                });
                let starts = [sigma, 0.3 * sigma, 0.05 * q]
                    .iter()
                    .map(|&s| {
                        with_ext(Extension::Quantization {
                            step: q,
                            offset,
                            sigma: s,
                        })
                        .pack(ts)
                    })
                    .collect();
                sim_fit(m, starts)
            }
            EffectId::Friction => {
                let hi = y_fit.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
                let lo = y_fit.iter().cloned().fold(f64::INFINITY, f64::min);
                // The elastic slope is the steepest part of the output against the input: scale the declared
                // model's static gain up to the 90th percentile of |dy / du| (moves of u above its median).
                let bb = &base.base;
                let gain = bb.b.iter().sum::<f64>() / (1.0 + bb.a.iter().sum::<f64>());
                let uf = &p.u[..p.n_fit];
                let mut du: Vec<f64> = uf.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
                du.sort_by(f64::total_cmp);
                let du_med = du[du.len() / 2];
                let mut slopes: Vec<f64> = (1..p.n_fit)
                    .filter(|&k| (uf[k] - uf[k - 1]).abs() > du_med && du_med > 0.0)
                    .map(|k| ((y_fit[k] - y_fit[k - 1]) / (uf[k] - uf[k - 1])).abs())
                    .collect();
                slopes.sort_by(f64::total_cmp);
                let steep = slopes.get(slopes.len() * 9 / 10).copied().unwrap_or(0.0);
                let r = if gain.abs() > 0.0 && steep.is_finite() {
                    steep / gain.abs()
                } else {
                    1.0
                };
                // A grid: gains from the declared one up to twice the steepest slope (factors of sqrt 2),
                // slip levels at fractions of the output's 1% / 99% quantiles, the declared gap or none.
                let mut sorted = y_fit.to_vec();
                sorted.sort_by(f64::total_cmp);
                let (q01, q99) = (sorted[sorted.len() / 100], sorted[sorted.len() * 99 / 100]);
                let mut scales = vec![1.0];
                while scales.len() < 40 && *scales.last().unwrap() < 2.0 * r.max(4.0) {
                    let next = scales.last().unwrap() * std::f64::consts::SQRT_2;
                    scales.push(next);
                }
                // Series form: the offset of the gaps sets the element's first output (w(0) jumps onto a
                // border when a gap is negative): try the declared one scaled, none, and +-1/8 of the
                // output's range.
                let spread = (q99 - q01) / 8.0;
                let mut series = Vec::new();
                let mut contact = Vec::new();
                let mut uq: Vec<f64> = uf.to_vec();
                uq.sort_by(f64::total_cmp);
                let u_range = uq[uq.len() * 99 / 100] - uq[uq.len() / 100];
                for &scale in &scales {
                    let base_offset = (bb.c2 - bb.c1) / 2.0 * scale;
                    let mut b = bb.clone();
                    b.b.iter_mut().for_each(|v| *v *= scale);
                    // Equal slopes: with a small gap, unequal ones invert the memory zone within the range
                    // (the element carries the asymmetry in its two slip levels).
                    b.m2 = 1.0;
                    let with = |b: &BaseModel, c1: f64, c2: f64, frac: f64, form: FrictionForm| {
                        Model {
                            base: BaseModel {
                                c1,
                                c2,
                                ..b.clone()
                            },
                            ext: Extension::Friction {
                                f_plus: frac * q99,
                                f_minus: -frac * q01,
                                form,
                            },
                        }
                        .pack(ts)
                    };
                    for offset in [base_offset, 0.0, spread, -spread] {
                        for frac in [1.0, 0.9, 0.8, 0.7] {
                            for keep_gap in [true, false] {
                                let gap = (bb.c1 + bb.c2) / 2.0 * scale;
                                let gap = if keep_gap {
                                    gap.max(0.01 * p.y_scale)
                                } else {
                                    0.01 * p.y_scale
                                };
                                series.push(with(
                                    &b,
                                    gap - offset,
                                    gap + offset,
                                    frac,
                                    FrictionForm::Series,
                                ));
                            }
                        }
                    }
                    // Contact form: the play, a few percent of the stroke of x, placed around the start.
                    let x_range = scale * gain.abs() * u_range;
                    for play in [0.02, 0.05, 0.1] {
                        let g = play * x_range;
                        for offset in [0.0, 0.5 * g, -0.5 * g] {
                            for frac in [1.0, 0.9, 0.8] {
                                contact.push(with(
                                    &b,
                                    g - offset,
                                    g + offset,
                                    frac,
                                    FrictionForm::Contact,
                                ));
                            }
                        }
                    }
                }
                let template = |form| {
                    with_ext(Extension::Friction {
                        f_plus: hi,
                        f_minus: -lo,
                        form,
                    })
                };
                // Both arrangements of the play; the better fit is the candidate (same parameter count).
                let a = sim_fit(template(FrictionForm::Series), series);
                let b = sim_fit(template(FrictionForm::Contact), contact);
                match (a, b) {
                    (Some(a), Some(b)) => Some(if b.1 < a.1 { b } else { a }),
                    (a, b) => a.or(b),
                }
            }
            EffectId::ColouredNoise => {
                let ef = &self.e[..p.n_fit];
                // AR order by BIC of the least-squares fit on the residual, then a joint refit.
                let mut best: Option<(Vec<f64>, f64)> = None;
                for order in 1..=3 {
                    let phi = ar_ls(ef, order)?;
                    let r: f64 = (0..ef.len())
                        .map(|k| {
                            let mut v = ef[k];
                            for (i, f) in phi.iter().enumerate() {
                                if k > i {
                                    v -= f * ef[k - 1 - i];
                                }
                            }
                            v * v
                        })
                        .sum();
                    let b = bic(r, ef.len(), order);
                    if best.as_ref().is_none_or(|x| b < x.1) {
                        best = Some((phi, b));
                    }
                }
                let (phi, _) = best?;
                let m = with_ext(Extension::ColouredNoise { phi });
                let s = m.pack(ts);
                p.fit(&m, &[s], Objective::Prediction, lm).map(|(m, c)| {
                    let k = m.n_estimated();
                    (m, c, Objective::Prediction, k)
                })
            }
            EffectId::ExtraDelay => {
                let mut best: Option<(Model, f64)> = None;
                for extra in 1..=3 {
                    let d = base.base.delay + extra;
                    if d > MAX_DELAY {
                        break;
                    }
                    let shifted =
                        Model::plain(base.base.with_orders(base.base.na, base.base.nb, d));
                    let mut starts = vec![shifted.pack(ts)];
                    if let Some(m) = mrgia_start(p, base.base.na, base.base.nb, d) {
                        starts.push(Model::plain(m).pack(ts));
                    }
                    if let Some((m, c)) = p.fit(&shifted, &starts, Objective::Simulation, lm)
                        && best.as_ref().is_none_or(|b| c < b.1)
                    {
                        best = Some((m, c));
                    }
                }
                best.map(|(m, c)| (m, c, Objective::Simulation, bk))
            }
            EffectId::LinearOrder => {
                let (na, nb, d) = (base.base.na, base.base.nb, base.base.delay);
                let mut best: Option<(Model, f64)> = None;
                for (na2, nb2) in [(na + 1, nb), (na, nb + 1)] {
                    if na2 > MAX_ORDER || nb2 > MAX_ORDER {
                        continue;
                    }
                    let padded = Model::plain(base.base.with_orders(na2, nb2, d));
                    let mut starts = vec![padded.pack(ts)];
                    if let Some(m) = mrgia_start(p, na2, nb2, d) {
                        starts.push(Model::plain(m).pack(ts));
                    }
                    if let Some((m, c)) = p.fit(&padded, &starts, Objective::Simulation, lm)
                        && best.as_ref().is_none_or(|b| c < b.1)
                    {
                        best = Some((m, c));
                    }
                }
                best.map(|(m, c)| {
                    let k = m.n_estimated();
                    (m, c, Objective::Simulation, k)
                })
            }
        }
    }
}

/// The log-count of the alternative structures a candidate searched (a uniform prior over them, the
/// model-prior term of BIC): extra-delay tries 3 delays, linear-order 2 orders; the others fit one structure.
/// The extra delay adds no continuous parameter, so without this term it would tie exactly with a longer b
/// polynomial whose leading terms are zero.
pub fn structure_penalty(id: EffectId) -> f64 {
    match id {
        EffectId::ExtraDelay => 3f64.ln(),
        EffectId::LinearOrder => 2f64.ln(),
        _ => 0.0,
    }
}

/// Least-squares AR(order) coefficients of e: e(k) = sum phi_i e(k-i) + v(k).
fn ar_ls(e: &[f64], order: usize) -> Option<Vec<f64>> {
    use nalgebra::{DMatrix, DVector};
    let mut h = DMatrix::<f64>::zeros(order, order);
    let mut g = DVector::<f64>::zeros(order);
    for k in order..e.len() {
        for a in 0..order {
            g[a] += e[k - 1 - a] * e[k];
            for b in 0..order {
                h[(a, b)] += e[k - 1 - a] * e[k - 1 - b];
            }
        }
    }
    let th = h.cholesky()?.solve(&g);
    th.iter()
        .all(|v| v.is_finite())
        .then(|| th.iter().copied().collect())
}

/// Modes as a small integer (for plotting): up 1, down -1, held 0.
pub fn mode_value(m: Mode) -> f64 {
    match m {
        Mode::Up => 1.0,
        Mode::Down => -1.0,
        Mode::Held => 0.0,
    }
}
