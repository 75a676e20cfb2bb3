//! A stepped-sine record: every step analysed at one degree for all (the smallest sum of the steps'
//! criteria, or the declared one), the Bode points in one convention, the spread of the borders over the steps.

use std::f64::consts::{PI, TAU};

use serde::{Deserialize, Serialize};

use super::super::window::{self, SineWindow};
use super::super::{FrequencyError, FrequencyEstimate, SineRecord};
use super::{
    Analysis, AnalysisOptions, bic, check_options, conclude, degrees_to_fit, fit_degrees,
    sub_record,
};

/// One step of a stepped-sine record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepAnalysis {
    pub window: SineWindow,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub analysis: Option<Analysis>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// A point of the measured Bode plot, all in the convention of the lowest-frequency step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BodePoint {
    pub omega: f64,
    pub gain: f64,
    /// Phase lag (rad), continued from step to step (not wrapped to `[0, pi)`).
    pub phase: f64,
    /// "reported" when the step's estimate is used as it is, "dual" when its dual is.
    pub member: String,
    pub fa: Vec<f64>,
    pub fd: Vec<f64>,
    pub explained: bool,
    /// The input amplitude `U` of the step (the borders are seen over `|x| <= U gain`).
    pub amplitude: f64,
}

/// Mean and standard deviation of the border coefficients over the steps.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BorderSpread {
    pub fa_mean: Vec<f64>,
    pub fa_std: Vec<f64>,
    pub fd_mean: Vec<f64>,
    pub fd_std: Vec<f64>,
}

/// The answer for a stepped-sine record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SteppedAnalysis {
    pub degree: usize,
    /// "declared", or "bic" (smallest sum over the steps).
    pub degree_rule: String,
    /// Per degree: the sum of the steps' criteria (`None` if some step cannot be fitted at it).
    pub degree_bic: Vec<(usize, Option<f64>)>,
    pub steps: Vec<StepAnalysis>,
    /// The steps that were identified, by increasing omega.
    pub bode: Vec<BodePoint>,
    /// Over the Bode points (at least two).
    pub border_spread: Option<BorderSpread>,
    /// Steps whose verdict is "explained".
    pub explained_steps: usize,
}

/// Every step of a stepped-sine record (module documentation): one degree for all, the Bode points in
/// one convention, the spread of the borders over the steps.
pub fn analyse_steps(
    rec: &SineRecord,
    degree: Option<usize>,
    transient: Option<f64>,
) -> Result<SteppedAnalysis, FrequencyError> {
    let opts = AnalysisOptions {
        degree,
        transient,
        ..Default::default()
    };
    check_options(&opts)?;
    let u = rec.u.ok_or(FrequencyError::Missing {
        name: "u",
        why: "the steps are found from the input column",
    })?;
    let windows = window::detect(rec.time, u);
    if windows.is_empty() {
        return Err(FrequencyError::NoSteps);
    }
    let per_step: Vec<_> = windows
        .iter()
        .map(|w| {
            let sub = sub_record(rec, w.range());
            let amplitude = w.input_amplitude.unwrap_or(0.0);
            fit_degrees(&sub, w.omega, amplitude, degree, transient)
        })
        .collect();
    let degree_bic = summed_bic(&per_step, degree);
    let (chosen, rule) = match degree {
        Some(n) => (n, "declared"),
        None => degree_bic
            .iter()
            .filter_map(|(n, b)| b.map(|b| (*n, b)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map_or((1, "bic"), |(n, _)| (n, "bic")),
    };
    let steps: Vec<StepAnalysis> = windows
        .into_iter()
        .zip(per_step)
        .map(|(w, fits)| conclude_step(rec, w, fits, chosen, rule))
        .collect();
    let bode = bode_points(&steps);
    let border_spread = spread(&bode);
    let explained_steps = steps
        .iter()
        .filter(|s| s.analysis.as_ref().is_some_and(|a| a.verdict.explained))
        .count();
    Ok(SteppedAnalysis {
        degree: chosen,
        degree_rule: rule.to_string(),
        degree_bic,
        steps,
        bode,
        border_spread,
        explained_steps,
    })
}

/// Each degree's BIC summed over the steps (`None` when a step could not be fitted at that degree).
fn summed_bic(
    per_step: &[Vec<(usize, Result<FrequencyEstimate, FrequencyError>)>],
    declared: Option<usize>,
) -> Vec<(usize, Option<f64>)> {
    degrees_to_fit(declared)
        .into_iter()
        .map(|n| {
            let sum: Option<f64> = per_step
                .iter()
                .map(|fits| {
                    fits.iter()
                        .find(|(d, _)| *d == n)
                        .and_then(|(_, r)| r.as_ref().ok().map(bic))
                })
                .sum();
            (n, sum)
        })
        .collect()
}

/// One step's analysis at the chosen degree, or the reason it has none.
fn conclude_step(
    rec: &SineRecord,
    w: SineWindow,
    fits: Vec<(usize, Result<FrequencyEstimate, FrequencyError>)>,
    chosen: usize,
    rule: &str,
) -> StepAnalysis {
    let sub = sub_record(rec, w.range());
    match conclude(&sub, w.clone(), fits, chosen, rule) {
        Ok(a) => StepAnalysis {
            window: w,
            analysis: Some(a),
            error: None,
        },
        Err(e) => StepAnalysis {
            window: w,
            analysis: None,
            error: Some(e.to_string()),
        },
    }
}

/// The identified steps by increasing omega, each as the member of its model/dual pair whose phase
/// continues the previous step's (the lowest step as reported).
fn bode_points(steps: &[StepAnalysis]) -> Vec<BodePoint> {
    let mut done: Vec<&Analysis> = steps.iter().filter_map(|s| s.analysis.as_ref()).collect();
    done.sort_by(|a, b| a.estimate.omega.total_cmp(&b.estimate.omega));
    let mut out: Vec<BodePoint> = Vec::new();
    for a in done {
        let e = &a.estimate;
        let prev = out.last().map(|p| p.phase);
        let lift = |p: f64| match prev {
            Some(q) => p + ((q - p) / TAU).round() * TAU,
            None => p,
        };
        let (as_is, dual) = (lift(e.phase), lift(e.phase + PI));
        let use_dual = prev.is_some_and(|q| (dual - q).abs() < (as_is - q).abs());
        let (m, phase, member) = if use_dual {
            (e.dual(), dual, "dual")
        } else {
            (e.clone(), as_is, "reported")
        };
        out.push(BodePoint {
            omega: e.omega,
            gain: m.gain,
            phase,
            member: member.to_string(),
            fa: m.fa,
            fd: m.fd,
            explained: a.verdict.explained,
            amplitude: e.amplitude,
        });
    }
    out
}

fn spread(points: &[BodePoint]) -> Option<BorderSpread> {
    if points.len() < 2 {
        return None;
    }
    let stats = |get: &dyn Fn(&BodePoint) -> &Vec<f64>| -> (Vec<f64>, Vec<f64>) {
        let n = get(&points[0]).len();
        let k = points.len() as f64;
        let mean: Vec<f64> = (0..n)
            .map(|i| points.iter().map(|p| get(p)[i]).sum::<f64>() / k)
            .collect();
        let std: Vec<f64> = (0..n)
            .map(|i| {
                (points
                    .iter()
                    .map(|p| (get(p)[i] - mean[i]).powi(2))
                    .sum::<f64>()
                    / (k - 1.0))
                    .sqrt()
            })
            .collect();
        (mean, std)
    };
    let (fa_mean, fa_std) = stats(&|p| &p.fa);
    let (fd_mean, fd_std) = stats(&|p| &p.fd);
    Some(BorderSpread {
        fa_mean,
        fa_std,
        fd_mean,
        fd_std,
    })
}
