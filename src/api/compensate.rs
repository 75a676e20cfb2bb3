//! `backlash compensate` and Python's `compensate`: the adaptive loop of [`crate::compensate::adaptive`] on a
//! simulated paper plant for a reference, every mode or one, as one JSON object.

use super::{ApiError, check_record};
use crate::compensate::adaptive::{LoopRun, LoopSettings, Mode, Wear, simulate};
use crate::plant::PlantParams;
use serde_json::{Value, json};

/// What `compensate` simulates: the plant's noise, its wear, the loop's settings and the modes to run.
#[derive(Debug, Clone, PartialEq)]
pub struct CompensateOptions {
    pub noise_std: f64,
    pub noise_seed: u64,
    pub wear: Wear,
    /// The estimator's memory in samples (None: no forgetting).
    pub memory: Option<f64>,
    pub smoothing: f64,
    /// Samples by which the estimate the adaptive inverses use lags the latest: 0 or 1
    /// ([`LoopSettings::estimate_lag`]).
    pub estimate_lag: usize,
    pub modes: Vec<Mode>,
}

impl Default for CompensateOptions {
    fn default() -> Self {
        Self {
            noise_std: 0.0,
            noise_seed: 0,
            wear: Wear::None,
            memory: Some(500.0),
            smoothing: 0.0,
            estimate_lag: 0,
            modes: Mode::ALL.to_vec(),
        }
    }
}

/// The mode of a name (`none`, `fixed`, `adaptive`, `no-play`).
pub fn mode_named(name: &str) -> Result<Mode, ApiError> {
    Mode::ALL
        .into_iter()
        .find(|m| m.name() == name)
        .ok_or_else(|| {
            ApiError::Setting(format!(
                "mode '{name}' is unknown: one of none, fixed, adaptive, no-play"
            ))
        })
}

/// Runs the loop of every mode asked for on the paper plant for the reference `r`; the runs (for plots and
/// the input sequences) and the JSON answer.
pub fn compensate(r: &[f64], o: &CompensateOptions) -> Result<(Vec<LoopRun>, Value), ApiError> {
    check_record(&[("r", r)], 1)?;
    if !(o.noise_std.is_finite() && o.noise_std >= 0.0) {
        return Err(ApiError::Setting(format!(
            "noise_std {} is invalid: must be a finite number of 0 or more",
            o.noise_std
        )));
    }
    let plant = PlantParams {
        noise_std: o.noise_std,
        noise_seed: o.noise_seed,
        ..PlantParams::PAPER
    };
    let a = &plant.arx;
    let s = LoopSettings {
        estimate_lag: o.estimate_lag,
        ..LoopSettings::for_structure(a, o.memory, o.smoothing)
    };
    let runs = o
        .modes
        .iter()
        .map(|&m| simulate(r, &plant, o.wear, m, &s))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| ApiError::Setting(e.to_string()))?;
    let modes: serde_json::Map<String, Value> = runs
        .iter()
        .map(|run| (run.mode.name().to_string(), run_json(run)))
        .collect();
    let out = json!({
        "samples": r.len(),
        "plant": "paper",
        "noise_std": o.noise_std,
        "wear": o.wear,
        "memory": o.memory,
        "rho_min": o.memory.map(|n| 1.0 / n),
        "smoothing": o.smoothing,
        "estimate_lag": o.estimate_lag,
        "modes": modes,
    });
    Ok((runs, out))
}

fn run_json(run: &LoopRun) -> Value {
    json!({
        "rmse": run.rmse,
        "rmse_last_quarter": run.rmse_last_quarter,
        "degenerate_samples": run.degenerate,
        "refused_linear_samples": run.refused_linear,
        "backlash": run.backlash,
    })
}
