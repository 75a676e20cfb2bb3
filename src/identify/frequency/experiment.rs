//! Paper 003's experiment on a simulated plant: the plant of [`crate::plant::Plant`] with a continuous
//! linear block and polynomial borders (the same code as BacklashPlant.fmu with `linear = 1`,
//! `border = 1`), driven by sines; each record identified, and the estimate compared with the truth.
//!
//! Two designs:
//! - [`run_sines`]: one record per frequency, sampled at a fixed number of samples per period, starting
//!   from rest (the transient is left in the record for the estimator to drop);
//! - [`run_stepped`]: one record through all frequencies at one sample period, each step ramped in and out
//!   (as test rigs do), identified by [`analyse_steps`]; beside it, for each frequency, a single-frequency
//!   record of the same length (the same step alone, from rest) identified the same way, so that the
//!   stepped record's accuracy is compared with like.
//!
//! # The truth
//!
//! The samples carry the zero-order-hold response of the sampled block, not `G(j omega)`: the truth is
//! [`ContinuousLinear::sampled_response`], normalised by eqs. (29)-(30a) at the estimator's degree, and its
//! dual (6)-(7), normalised in turn. An estimate is matched with the member whose phase is nearer.

use std::f64::consts::{PI, TAU};

use serde::{Deserialize, Serialize};

use super::analysis::{AnalysisOptions, SteppedAnalysis, analyse_steps, analyse_window};
use super::window::SineWindow;
use super::{
    FrequencyError, FrequencyEstimate, FrequencyOptions, SineRecord, dual_borders, estimate,
    normalize,
};
use crate::plant::continuous::gain_phase_of;
use crate::plant::{
    ContinuousLinear, ParamError, Plant, PlantExtensions, PlantParams, PolyBacklashParams,
    TransferFunction,
};

/// The simulated plant and its excitation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExperimentPlant {
    /// Numerator of G(s), descending powers of s.
    pub num: Vec<f64>,
    /// Denominator of G(s), descending powers of s (stable, degree at most 4, above the numerator's).
    pub den: Vec<f64>,
    /// Ascending border, lowest power first (degree at most 3).
    pub fa: Vec<f64>,
    /// Descending border, lowest power first.
    pub fd: Vec<f64>,
    /// Sine amplitude U.
    pub amplitude: f64,
    /// Standard deviation of the white output noise.
    pub noise_std: f64,
    /// Noise seed of the first record (record i uses seed + i).
    pub seed: u64,
}

impl Default for ExperimentPlant {
    /// G(s) = 1/(s^2 + 0.6 s + 1), cubic borders, U = 3, noise std 0.01, seed 1.
    fn default() -> Self {
        Self {
            num: vec![1.0],
            den: vec![1.0, 0.6, 1.0],
            fa: vec![-0.25, 0.9, 0.1, 0.05],
            fd: vec![0.3, 0.85, 0.1, 0.05],
            amplitude: 3.0,
            noise_std: 0.01,
            seed: 1,
        }
    }
}

/// Why an experiment could not run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ExperimentError {
    #[error(transparent)]
    Plant(#[from] ParamError),
    #[error(transparent)]
    Frequency(#[from] FrequencyError),
    #[error("invalid experiment setting {name} = {value}: {reason}")]
    Setting {
        name: &'static str,
        value: f64,
        reason: &'static str,
    },
    #[error(
        "the true ascending or descending border is constant (degree {degree}): nothing to normalise"
    )]
    ConstantBorder { degree: usize },
}

/// A simulated record.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Record {
    pub t: Vec<f64>,
    pub u: Vec<f64>,
    pub x: Vec<f64>,
    pub w: Vec<f64>,
    pub y: Vec<f64>,
}

impl Record {
    pub fn as_sine_record(&self) -> SineRecord<'_> {
        SineRecord {
            time: &self.t,
            u: Some(&self.u),
            y: &self.y,
        }
    }
}

impl ExperimentPlant {
    pub fn transfer_function(&self) -> Result<TransferFunction, ParamError> {
        TransferFunction::new(&self.num, &self.den)
    }

    pub fn borders(&self) -> Result<PolyBacklashParams, ParamError> {
        PolyBacklashParams::new(&self.fa, &self.fd)
    }

    /// The library plant for sample period `ts` and noise seed `seed`.
    pub fn plant(&self, ts: f64, seed: u64) -> Result<Plant, ParamError> {
        let params = PlantParams {
            noise_std: self.noise_std,
            noise_seed: seed,
            ..PlantParams::PAPER
        };
        let ext = PlantExtensions {
            borders: Some(self.borders()?),
            continuous: Some((self.transfer_function()?, ts)),
            ..Default::default()
        };
        Plant::with_extensions(params, &ext)
    }

    /// The plant's response to the samples `u` (held over `ts`), from rest; sample k of the record is the
    /// plant's output before it reads `u[k]`, at `t = k ts`.
    pub fn simulate(&self, u: &[f64], ts: f64, seed: u64) -> Result<Record, ParamError> {
        let mut plant = self.plant(ts, seed)?;
        let mut r = Record::default();
        for (k, &uk) in u.iter().enumerate() {
            let o = plant.output();
            r.t.push(k as f64 * ts);
            r.u.push(uk);
            r.x.push(o.x);
            r.w.push(o.w);
            r.y.push(o.y);
            plant.advance(uk);
        }
        Ok(r)
    }

    fn check(&self) -> Result<(), ExperimentError> {
        let bad = |name, value, reason| {
            Err(ExperimentError::Setting {
                name,
                value,
                reason,
            })
        };
        if !(self.amplitude.is_finite() && self.amplitude > 0.0) {
            return bad(
                "amplitude",
                self.amplitude,
                "must be a positive finite number",
            );
        }
        if !(self.noise_std.is_finite() && self.noise_std >= 0.0) {
            return bad("noise_std", self.noise_std, "must be a finite number >= 0");
        }
        self.plant(1.0, 0)?;
        Ok(())
    }
}

/// `U cos(omega k ts)`, `k = 0..n`.
pub fn sine_input(amplitude: f64, omega: f64, ts: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|k| amplitude * (omega * k as f64 * ts).cos())
        .collect()
}

/// Periods of `2 pi / omega` for the slowest pole's transient to decay by `e^-25` (at least 1, at most 400).
pub fn transient_periods(tf: &TransferFunction, omega: f64) -> usize {
    let slowest = tf
        .poles()
        .iter()
        .map(|p| -p.re)
        .fold(f64::INFINITY, f64::min);
    if slowest.is_finite() && slowest > 0.0 {
        ((25.0 / slowest / (TAU / omega)).ceil() as usize).clamp(1, 400)
    } else {
        1
    }
}

/// A model in the estimator's terms.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelView {
    pub phase: f64,
    pub gain: f64,
    pub fa: Vec<f64>,
    pub fd: Vec<f64>,
}

impl From<&FrequencyEstimate> for ModelView {
    fn from(e: &FrequencyEstimate) -> Self {
        Self {
            phase: e.phase,
            gain: e.gain,
            fa: e.fa.clone(),
            fd: e.fd.clone(),
        }
    }
}

/// The normalised truth (model, dual) for a frequency response `g` and degree `n` (module documentation).
pub fn truth_pair(
    g: nalgebra::Complex<f64>,
    fa: &[f64],
    fd: &[f64],
    n: usize,
) -> Result<(ModelView, ModelView), ExperimentError> {
    let constant = ExperimentError::ConstantBorder { degree: n };
    let (gain, phase) = gain_phase_of(g);
    let (mg, ma, md) = normalize(gain, fa, fd, n).ok_or(constant.clone())?;
    let (da, dd) = dual_borders(&ma, &md);
    let (dg, da, dd) = normalize(mg, &da, &dd, n).ok_or(constant)?;
    Ok((
        ModelView {
            phase,
            gain: mg,
            fa: ma,
            fd: md,
        },
        ModelView {
            phase: (phase + PI).rem_euclid(TAU),
            gain: dg,
            fa: da,
            fd: dd,
        },
    ))
}

/// Distance of two phases modulo `2 pi`.
pub fn phase_error(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(TAU);
    d.min(TAU - d)
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// Errors of an estimate against the member of the truth it estimates.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Errors {
    pub phase: f64,
    pub gain: f64,
    pub fa: f64,
    pub fd: f64,
}

/// An estimate matched with the truth.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Matched {
    /// "model" or "dual": which member of the pair the estimate is.
    pub reported: String,
    /// The estimate in the true model's convention (converted with the dual map if needed).
    pub as_model: ModelView,
    pub errors: Errors,
}

/// Match an estimate with the nearer member of `(truth, dual)` and measure its errors.
pub fn match_truth(est: &FrequencyEstimate, truth: &ModelView, dual: &ModelView) -> Matched {
    let is_model = phase_error(est.phase, truth.phase) <= phase_error(est.phase, dual.phase);
    let reference = if is_model { truth } else { dual };
    let view = if is_model { est.clone() } else { est.dual() };
    Matched {
        reported: if is_model { "model" } else { "dual" }.to_string(),
        as_model: ModelView::from(&view),
        errors: Errors {
            phase: phase_error(est.phase, reference.phase),
            gain: (est.gain - reference.gain).abs(),
            fa: max_abs_diff(&est.fa, &reference.fa),
            fd: max_abs_diff(&est.fd, &reference.fd),
        },
    }
}

/// One frequency of [`run_sines`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SineRow {
    pub omega: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub estimate: Option<FrequencyEstimate>,
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub matched: Option<Matched>,
    /// The truth for the sampled data: the zero-order-hold response, normalised (29)-(30a).
    pub truth: ModelView,
    /// |G(jw)|/K and -arg G(jw) of the continuous-time block, for reference.
    pub gain_continuous: f64,
    pub phase_continuous: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// The simulated record.
    #[serde(skip)]
    pub record: Record,
}

/// Settings of [`run_sines`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SineDesign {
    pub omegas: Vec<f64>,
    /// Estimator degree (the borders' degree if `None`).
    pub degree: Option<usize>,
    /// Steady periods recorded per frequency.
    pub periods: usize,
    pub samples_per_period: usize,
    /// Periods added at the start for the transient; default: [`transient_periods`].
    pub transient_periods: Option<usize>,
}

fn check_omegas(omegas: &[f64]) -> Result<(), ExperimentError> {
    match omegas.iter().find(|w| !(w.is_finite() && **w > 0.0)) {
        Some(w) => Err(ExperimentError::Setting {
            name: "omega",
            value: *w,
            reason: "every frequency must be a positive finite number (rad/s)",
        }),
        None if omegas.is_empty() => Err(ExperimentError::Setting {
            name: "omegas",
            value: 0.0,
            reason: "list at least one frequency",
        }),
        None => Ok(()),
    }
}

/// The estimator's degree: declared, or the borders'.
pub fn design_degree(
    plant: &ExperimentPlant,
    degree: Option<usize>,
) -> Result<usize, ExperimentError> {
    Ok(degree.unwrap_or(plant.borders()?.degree().max(1)))
}

/// One record per frequency, each identified (module documentation).
pub fn run_sines(
    plant: &ExperimentPlant,
    design: &SineDesign,
) -> Result<Vec<SineRow>, ExperimentError> {
    plant.check()?;
    check_omegas(&design.omegas)?;
    if design.periods == 0 || design.samples_per_period < 8 {
        return Err(ExperimentError::Setting {
            name: "samples_per_period",
            value: design.samples_per_period as f64,
            reason: "needs at least 1 period and at least 8 samples per period",
        });
    }
    let tf = plant.transfer_function()?;
    let degree = design_degree(plant, design.degree)?;
    let mut rows = Vec::new();
    for (i, &omega) in design.omegas.iter().enumerate() {
        let spp = design.samples_per_period;
        let ts = TAU / omega / spp as f64;
        let transient = design
            .transient_periods
            .unwrap_or_else(|| transient_periods(&tf, omega));
        let u = sine_input(
            plant.amplitude,
            omega,
            ts,
            (transient + design.periods) * spp,
        );
        let record = plant.simulate(&u, ts, plant.seed.wrapping_add(i as u64))?;
        let sampled = ContinuousLinear::new(tf.clone(), ts)?;
        let (truth, dual) = truth_pair(
            sampled.sampled_response(omega),
            &plant.fa,
            &plant.fd,
            degree,
        )?;
        let (gc, pc) = gain_phase_of(tf.response(omega));
        let k = truth.gain / gain_phase_of(sampled.sampled_response(omega)).0;
        let result = estimate(
            &record.as_sine_record(),
            &FrequencyOptions {
                omega,
                amplitude: plant.amplitude,
                degree,
                transient: None,
            },
        );
        let (estimate, matched, error) = match result {
            Ok(e) => {
                let m = match_truth(&e, &truth, &dual);
                (Some(e), Some(m), None)
            }
            Err(e) => (None, None, Some(e.to_string())),
        };
        rows.push(SineRow {
            omega,
            estimate,
            matched,
            truth,
            gain_continuous: gc * k,
            phase_continuous: pc,
            error,
            record,
        });
    }
    Ok(rows)
}

/// Settings of [`run_stepped`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SteppedDesign {
    pub omegas: Vec<f64>,
    /// Estimator degree; `None`: chosen by the data.
    pub degree: Option<usize>,
    /// Sample period (s), common to all steps.
    pub ts: f64,
    /// Periods of each step at full amplitude.
    pub hold_periods: usize,
    /// Periods of each step's ramp in and of its ramp out.
    pub ramp_periods: usize,
    /// Rest between steps (s): the input is 0.
    pub pause: f64,
}

/// Where a step lies in the stepped input.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepPlan {
    pub omega: f64,
    /// First sample of the step (its ramp in).
    pub first: usize,
    /// Samples of the step (ramps and hold).
    pub samples: usize,
}

/// One step: `U sin(omega s)` ramped in linearly over `ramp_periods`, held `hold_periods`, ramped out, then
/// `pause` s of rest; `s` is the time since the step's start.
fn step_input(amplitude: f64, omega: f64, design: &SteppedDesign) -> Vec<f64> {
    let period = TAU / omega;
    let ramp = design.ramp_periods as f64 * period;
    let hold = design.hold_periods as f64 * period;
    let length = 2.0 * ramp + hold;
    let n = ((length + design.pause) / design.ts).round() as usize;
    (0..n)
        .map(|k| {
            let s = k as f64 * design.ts;
            let envelope = if s >= length {
                0.0
            } else if s < ramp {
                s / ramp
            } else if s > ramp + hold {
                (length - s) / ramp
            } else {
                1.0
            };
            amplitude * envelope * (omega * s).sin()
        })
        .collect()
}

/// The stepped input through `design.omegas` in order, and where each step lies.
pub fn stepped_input(amplitude: f64, design: &SteppedDesign) -> (Vec<f64>, Vec<StepPlan>) {
    let mut u = Vec::new();
    let mut plan = Vec::new();
    for &omega in &design.omegas {
        let step = step_input(amplitude, omega, design);
        plan.push(StepPlan {
            omega,
            first: u.len(),
            samples: step.len(),
        });
        u.extend(step);
    }
    (u, plan)
}

/// One frequency of [`run_stepped`]: the stepped record's step and the single-frequency record of the
/// same length, both against the truth.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SteppedRow {
    pub omega: f64,
    pub truth: ModelView,
    /// The stepped record's step (matched by frequency), if it was identified.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stepped: Option<Matched>,
    /// The single-frequency record's estimate.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub single: Option<Matched>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub single_window: Option<SineWindow>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// The stepped experiment's result.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SteppedResult {
    pub plan: Vec<StepPlan>,
    pub analysis: SteppedAnalysis,
    pub rows: Vec<SteppedRow>,
    #[serde(skip)]
    pub record: Record,
}

/// Simulate a stepped-sine record and identify it; beside each step, a single-frequency record of the same
/// length identified at the same degree (module documentation).
pub fn run_stepped(
    plant: &ExperimentPlant,
    design: &SteppedDesign,
) -> Result<SteppedResult, ExperimentError> {
    plant.check()?;
    check_omegas(&design.omegas)?;
    if !(design.ts.is_finite() && design.ts > 0.0) || design.hold_periods < 2 {
        return Err(ExperimentError::Setting {
            name: "ts",
            value: design.ts,
            reason: "needs a sample period > 0 and at least 2 held periods per step",
        });
    }
    let (u, plan) = stepped_input(plant.amplitude, design);
    let record = plant.simulate(&u, design.ts, plant.seed)?;
    let analysis = analyse_steps(&record.as_sine_record(), design.degree, None)?;
    let degree = analysis.degree;
    let sampled = ContinuousLinear::new(plant.transfer_function()?, design.ts)?;
    let mut rows = Vec::new();
    for (i, step) in plan.iter().enumerate() {
        let omega = step.omega;
        let (truth, dual) = truth_pair(
            sampled.sampled_response(omega),
            &plant.fa,
            &plant.fd,
            degree,
        )?;
        let stepped = analysis
            .steps
            .iter()
            .filter_map(|s| s.analysis.as_ref())
            .find(|a| (a.estimate.omega / omega - 1.0).abs() < 0.01)
            .map(|a| match_truth(&a.estimate, &truth, &dual));
        // The same step alone, from rest, with its own noise.
        let single_u = &u[step.first..step.first + step.samples];
        let single = plant.simulate(single_u, design.ts, plant.seed.wrapping_add(1 + i as u64))?;
        let single_rec = single.as_sine_record();
        let opts = AnalysisOptions {
            degree: Some(degree),
            ..Default::default()
        };
        let result = super::analysis::select_window(&single_rec, &opts)
            .and_then(|w| analyse_window(&single_rec, w, &opts));
        let (single, single_window, error) = match result {
            Ok(a) => (
                Some(match_truth(&a.estimate, &truth, &dual)),
                Some(a.window),
                None,
            ),
            Err(e) => (None, None, Some(e.to_string())),
        };
        rows.push(SteppedRow {
            omega,
            truth,
            stepped,
            single,
            single_window,
            error,
        });
    }
    Ok(SteppedResult {
        plan,
        analysis,
        rows,
        record,
    })
}

/// The continuous block's `|G(j omega)|/K` and phase lag (rad, continued along the grid) on a log grid
/// from `lo` to `hi`, in the scale of the borders normalised at `degree`.
pub fn bode_curve(
    plant: &ExperimentPlant,
    degree: usize,
    lo: f64,
    hi: f64,
    points: usize,
) -> Result<Vec<(f64, f64, f64)>, ExperimentError> {
    let tf = plant.transfer_function()?;
    let (kinv, _, _) = normalize(1.0, &plant.fa, &plant.fd, degree)
        .ok_or(ExperimentError::ConstantBorder { degree })?;
    let mut prev: Option<f64> = None;
    Ok((0..=points)
        .map(|i| {
            let w = lo * (hi / lo).powf(i as f64 / points as f64);
            let (g, mut p) = gain_phase_of(tf.response(w));
            if let Some(q) = prev {
                p += ((q - p) / TAU).round() * TAU;
            }
            prev = Some(p);
            (w, g * kinv, p)
        })
        .collect())
}
