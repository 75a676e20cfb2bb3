//! Frequency identification of a Wiener system with a polynomial-border backlash (paper 003: Giri,
//! Rochdi, Ikhouane, Brouri, Chaoui, "Frequency identification of Wiener systems with backlash operators
//! using separable least squares estimators").
//!
//! One experiment: the system is excited by `u(t) = U cos(omega t)`; from the record of `u` and `y` the
//! estimator returns the phase lag `phi(omega) = -arg G(j omega)`, the gain `|G(j omega)|` and the
//! coefficients of the borders `f_a`, `f_d` (eq. (3)), up to the model's scaling and its dual.
//!
//! # Steps
//!
//! 1. Phase reference: `u` is fitted by `U' cos(omega t - phi_u)`; phases are measured from the input's
//!    (`rho = omega t - phi_u`), so an input that is a sine or starts at another phase is handled. `U'` must
//!    agree with the declared amplitude within 5 % (it enters the gain, eq. (35)).
//! 2. Transient and periodic averaging, eq. (21) (private module `fold`): the transient is detected and
//!    dropped, the steady full periods are averaged bin by bin (phase bins generalise (21) to sampling
//!    incommensurate with the period).
//! 3. Admissibility (Proposition 1.3): an averaged output that does not vary beyond its noise is refused,
//!    [`FrequencyError::NonAdmissible`], with the advice to raise `U`.
//! 4. Table 1 and eq. (26): the separable LS (24)-(25) on the whole period is tried first (case 1 of
//!    Table 1: no constant stages). If its residual is within the noise (chi-square test, 5 standard
//!    deviations), the output has no constant stages that the data can show, and the SLS estimate is
//!    returned. Otherwise the averaged output has constant stages (case 2): flat runs of bins are
//!    detected, each long run alone (Table 1, 2b "otherwise") and each pair of runs half a period apart
//!    (2b) is a candidate for the stages; the candidate is removed from the optimisation set `I_N` and
//!    the LS estimator (23) is applied with `psi = omega t_bar` (23a), where `t_bar` is the start of the
//!    stage. On samples `t_bar` is only known to a bin or two (a stage starts where `x` peaks, and `w`
//!    meets the stage tangentially), so `psi` is refined by minimising the same cost (22) over a bracket
//!    around `omega t_bar`: from three bins before the run's start to its end (for a pair, the
//!    intersection of both brackets modulo `pi`); the stage bins are not in `I_N`, so inside that bracket
//!    the cost is smooth and its minimum is (23a)'s phase. The candidate with the smallest residual per
//!    degree of freedom wins; if none beats the SLS, the SLS is kept with a warning.
//! 5. The SLS phase search, eq. (25a): the cost is `pi`-periodic in `psi`; a grid over `[0, pi)` with a
//!    spacing of a quarter of a bin (the scale on which the cost's pieces change, so no basin of the cost
//!    can fall between grid points) and refinement of the three best local minima where the cost's derivative
//!    vanishes (variable projection, private module `fit`).
//! 6. Recovery, eqs. (28), (35)-(37): `|G| = (sum_i |alpha_i|^(n/i))^(1/n) / U`,
//!    `a_i = alpha_i / S^(i/n)`, `d_i = delta_i / S^(i/n)` with `S = sum_i |alpha_i|^(n/i)` for **both**
//!    borders. Eq. (37) of the paper divides the `delta_i` by the sum over the `|delta_i|`; eqs. (33a)-(34a)
//!    show that the scale is `U |G(j omega)|`, i.e. the same sum over the `alpha_i` (a known typo of the
//!    paper), which is what is used.
//!
//! # Convention: model or dual, and normalisation
//!
//! The data determine the system only up to `(G(s)/K, F[K x])`, `K > 0`, and up to the dual
//! `(-G(s), F[-x])` (eqs. (6)-(7)). The estimate is normalised as in eqs. (29)-(30a): `K` is such that the
//! *reported* ascending border satisfies `sum_{i=1..n} |a_i|^(n/i) = 1`, and `gain` is `|G(j omega)| / K`.
//! Of the model and its dual, the one reported is **the one whose phase lag lies in `[0, pi)`** (the search
//! domain of eq. (25a)): the true model `(G, F)` when `-arg G(j omega)` modulo `2 pi` is in `[0, pi)` (e.g.
//! at every frequency for a second-order low-pass with positive static gain), otherwise its dual, itself
//! re-normalised by (29)-(30a) (the paper's claim (30a) that a model and its dual are normalised together
//! only holds when `sum |a_i|^(n/i) = sum |d_i|^(n/i)`; in general the dual has its own `K`, so its `gain`
//! differs from the model's by the factor `(sum |d_i|^(n/i))^(1/n)` of the normalised model).
//! [`FrequencyEstimate::dual`] converts an estimate to the other member of the pair.

pub mod analysis;
pub mod experiment;
mod fit;
mod fold;
pub mod window;

#[cfg(test)]
mod tests;

use std::f64::consts::{PI, TAU};

use serde::{Deserialize, Serialize};

use fit::{Problem, Run, flat_runs};

/// Highest border degree the estimator accepts.
pub const MAX_DEGREE: usize = 6;

/// Tolerance on the agreement between the `u` column's amplitude and the declared `U`.
pub const AMPLITUDE_TOLERANCE: f64 = 0.05;

/// The experiment's settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrequencyOptions {
    /// Excitation frequency, rad/s, against the record's time scale.
    pub omega: f64,
    /// Excitation amplitude `U`.
    pub amplitude: f64,
    /// Border degree `n` (known, paper 003 section 2).
    pub degree: usize,
    /// Seconds to discard at the start of the record; `None` detects the transient.
    pub transient: Option<f64>,
}

/// A record of one sine experiment: time stamps (s, strictly increasing), optionally the input (used as
/// the phase reference; without it the input is taken to be `U cos(omega t)`), and the measured output.
#[derive(Debug, Clone, Copy)]
pub struct SineRecord<'a> {
    pub time: &'a [f64],
    pub u: Option<&'a [f64]>,
    pub y: &'a [f64],
}

/// Which estimator of eq. (26) produced the result.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum EstimatorPath {
    /// Constant stages found: LS estimator (23).
    Ls,
    /// No constant stages: separable LS (24)-(25).
    Sls,
}

/// The result of one experiment (see the module documentation for the convention).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrequencyEstimate {
    pub omega: f64,
    pub amplitude: f64,
    pub degree: usize,
    /// Phase lag `phi` in `[0, pi)` (rad): `x = U gain cos(omega t - phi)` relative to the input.
    pub phase: f64,
    /// `|G(j omega)| / K`, eq. (35).
    pub gain: f64,
    /// Ascending border `a_0..a_n`, eqs. (28), (36); normalised, `sum |a_i|^(n/i) = 1`.
    pub fa: Vec<f64>,
    /// Descending border `d_0..d_n`, eqs. (28), (37) corrected.
    pub fd: Vec<f64>,
    pub path: EstimatorPath,
    /// Lumped parameters `alpha_i = a_i (U |G|)^i`, eq. (12c) (ascending branch).
    pub alpha: Vec<f64>,
    /// Lumped parameters `delta_i = d_i (U |G|)^i` (descending branch).
    pub delta: Vec<f64>,
    /// Length (s) of the constant stage that starts the ascending branch (at the minimum of x); 0 if none.
    /// Known to a bin.
    pub tau_a: f64,
    /// Length (s) of the constant stage that starts the descending branch (at the maximum of x); 0 if none.
    pub tau_d: f64,
    /// Steady full periods averaged (`N` of eq. (21)).
    pub periods_used: usize,
    /// Full periods dropped as transient.
    pub transient_periods: usize,
    /// Phase bins per period.
    pub samples_per_period: usize,
    /// RMS of the averaged output minus the model on the optimisation set `I_N` (per sample).
    pub residual_rms: f64,
    /// Estimated noise standard deviation of one sample of `y`.
    pub noise_std: f64,
    /// `sum_j count_j (w_j - model_j)^2 / sigma^2` over `I_N`: the cost (22) in units of the noise variance
    /// (with a floor of 1e-12 of the output's size under `sigma` for noise-free records).
    pub chi2: f64,
    /// Degrees of freedom of `chi2`: bins in `I_N` minus the fitted parameters.
    pub dof: f64,
    /// Samples averaged into the bins of `I_N`.
    pub samples_averaged: f64,
    /// Parameters fitted: `alpha`, `delta`, the phase and one stage length per constant stage.
    pub parameters: usize,
    /// Amplitude and phase `U'`, `phi_u` of the input fitted as `U' cos(omega t - phi_u)`, if given.
    pub input_amplitude: Option<f64>,
    pub input_phase: Option<f64>,
    pub warnings: Vec<String>,
}

/// Why an experiment could not be identified.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FrequencyError {
    #[error("invalid setting {name} = {value}: {reason}")]
    InvalidOption {
        name: &'static str,
        value: f64,
        reason: &'static str,
    },
    #[error("the record's columns differ in length: {what}")]
    Lengths { what: String },
    #[error("sample {index} of {column} is not a finite number ({value})")]
    NotFinite {
        column: &'static str,
        index: usize,
        value: f64,
    },
    #[error("time does not increase at sample {index}")]
    TimeNotIncreasing { index: usize },
    #[error(
        "the record holds {periods:.2} periods of 2 pi/omega and {transient} are dropped as transient: \
         no full steady period is left; record more periods"
    )]
    NoFullPeriod { periods: f64, transient: usize },
    #[error(
        "only {per_period} samples per period of 2 pi/omega; at least {needed} are needed for degree \
         {degree}: sample faster or lower omega"
    )]
    TooFewSamples {
        per_period: usize,
        needed: usize,
        degree: usize,
    },
    #[error(
        "the input is not a sine at omega = {omega} rad/s: a fit U cos(omega t - phi) leaves an RMS \
         residual of {residual:.3e} for an amplitude {fitted:.3e} (check omega and the time column)"
    )]
    InputNotSine {
        omega: f64,
        fitted: f64,
        residual: f64,
    },
    #[error(
        "the input's amplitude is {fitted:.6} but the declared amplitude U is {declared}: they must agree \
         within 5 % (the gain is computed from U)"
    )]
    AmplitudeMismatch { fitted: f64, declared: f64 },
    #[error(
        "non-admissible experiment (paper 003, Proposition 1.3): the averaged output is constant \
         (variation {variation:.3e} within the noise, std {noise:.3e} per averaged sample): the sine of \
         amplitude U = {amplitude} does not move the backlash off a horizontal segment; raise the \
         amplitude U"
    )]
    NonAdmissible {
        amplitude: f64,
        variation: f64,
        noise: f64,
    },
    #[error(
        "the {branch} branch of the cycle has only {found} varying samples per period (at least {needed} \
         are needed for degree {degree}): raise the amplitude U (or sample faster)"
    )]
    TooFewBranchSamples {
        branch: &'static str,
        found: usize,
        needed: usize,
        degree: usize,
    },
    #[error(
        "the ascending branch shows no variation (alpha_1..alpha_n are all zero), so the scale of \
         eqs. (35)-(37) is undefined: raise the amplitude U"
    )]
    FlatAscending,
    #[error(
        "the record holds {} steps of a steady sine, at omega = {} rad/s: choose one (its omega, or the \
         start and end of its window), or identify every step as a stepped-sine record",
        .omegas.len(), list(.omegas)
    )]
    SeveralSteps { omegas: Vec<f64> },
    #[error(
        "no steady part of the input is a sine at omega = {omega} rad/s (within {tolerance} %); the steady \
         steps found are at omega = {} rad/s",
        if .found.is_empty() { "(none)".to_string() } else { list(.found) }
    )]
    NoStepAt {
        omega: f64,
        tolerance: f64,
        found: Vec<f64>,
    },
    #[error(
        "the input has fewer than two cycles between t = {start} and t = {end} s, so its frequency cannot \
         be found: give omega"
    )]
    NoFrequency { start: f64, end: f64 },
    #[error("{name} must be given: {why}")]
    Missing {
        name: &'static str,
        why: &'static str,
    },
    #[error(
        "the window from t = {start} to t = {end} s holds {samples} samples; at least 3 are needed"
    )]
    EmptyWindow {
        start: f64,
        end: f64,
        samples: usize,
    },
    #[error(
        "no steady sine step was found in the input (a step is at least 2 cycles of constant frequency and amplitude)"
    )]
    NoSteps,
}

/// `a, b, c` with four significant digits.
fn list(v: &[f64]) -> String {
    v.iter()
        .map(|x| format!("{x:.4}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Normalise a model `(gain, f_a, f_d)` as in eqs. (29)-(30a): the rescaled model `(G/K, F[K x])` with
/// `K = (sum_{i=1..n} |a_i|^(n/i))^(-1/n)`. Coefficients lowest power first, padded to `degree + 1`.
/// `None` when `a_1..a_n` are all zero.
pub fn normalize(
    gain: f64,
    fa: &[f64],
    fd: &[f64],
    degree: usize,
) -> Option<(f64, Vec<f64>, Vec<f64>)> {
    let n = degree;
    if n == 0 {
        return None;
    }
    let pad =
        |c: &[f64]| -> Vec<f64> { (0..=n).map(|i| c.get(i).copied().unwrap_or(0.0)).collect() };
    let (a, d) = (pad(fa), pad(fd));
    let s: f64 = (1..=n).map(|i| a[i].abs().powf(n as f64 / i as f64)).sum();
    if !(s.is_finite() && s > 0.0) {
        return None;
    }
    let k = s.powf(-1.0 / n as f64);
    let scale = |c: Vec<f64>| -> Vec<f64> {
        c.iter()
            .enumerate()
            .map(|(i, v)| v * k.powi(i as i32))
            .collect()
    };
    Some((gain / k, scale(a), scale(d)))
}

/// The dual model's borders, eqs. (7a)-(7b): `f_a^-(x) = f_d(-x)`, `f_d^-(x) = f_a(-x)`.
pub fn dual_borders(fa: &[f64], fd: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let flip = |c: &[f64]| -> Vec<f64> {
        c.iter()
            .enumerate()
            .map(|(i, v)| if i % 2 == 1 { -v } else { *v })
            .collect()
    };
    (flip(fd), flip(fa))
}

/// Recovery of the gain and the normalised borders from the lumped parameters, eqs. (28), (35)-(37)
/// (with (37)'s normaliser corrected to the sum over the `alpha_i`).
pub fn recover(
    alpha: &[f64],
    delta: &[f64],
    amplitude: f64,
) -> Result<(f64, Vec<f64>, Vec<f64>), FrequencyError> {
    let n = alpha.len() - 1;
    let s: f64 = (1..=n)
        .map(|i| alpha[i].abs().powf(n as f64 / i as f64))
        .sum();
    let scale = s.powf(1.0 / n as f64);
    let size = alpha
        .iter()
        .chain(delta)
        .fold(0.0f64, |m, v| m.max(v.abs()))
        .max(f64::MIN_POSITIVE);
    if !(scale.is_finite() && scale > 1e-9 * size) {
        return Err(FrequencyError::FlatAscending);
    }
    let gain = scale / amplitude;
    let norm = |c: &[f64]| -> Vec<f64> {
        c.iter()
            .enumerate()
            .map(|(i, v)| v / scale.powi(i as i32))
            .collect()
    };
    Ok((gain, norm(alpha), norm(delta)))
}

impl FrequencyEstimate {
    /// `f_a(x)` of the estimate.
    pub fn ascending(&self, x: f64) -> f64 {
        crate::plant::poly::poly_eval(&self.fa, x)
    }

    /// `f_d(x)` of the estimate.
    pub fn descending(&self, x: f64) -> f64 {
        crate::plant::poly::poly_eval(&self.fd, x)
    }

    /// The other member of the model/dual pair (eqs. (6)-(8), (16)), normalised by (29)-(30a); its phase
    /// is `phase + pi` modulo `2 pi` (so it lies in `[pi, 2 pi)` for an estimate straight from
    /// [`estimate`]). Returns a clone if the dual's ascending border is constant (no normalisation).
    pub fn dual(&self) -> FrequencyEstimate {
        let (fa, fd) = dual_borders(&self.fa, &self.fd);
        let Some((gain, fa, fd)) = normalize(self.gain, &fa, &fd, self.degree) else {
            return self.clone();
        };
        let (alpha, delta) = dual_borders(&self.alpha, &self.delta);
        FrequencyEstimate {
            phase: (self.phase + PI).rem_euclid(TAU),
            gain,
            fa,
            fd,
            alpha,
            delta,
            tau_a: self.tau_d,
            tau_d: self.tau_a,
            ..self.clone()
        }
    }
}

fn check_inputs(rec: &SineRecord, opts: &FrequencyOptions) -> Result<(), FrequencyError> {
    let bad = |name, value, reason| {
        Err(FrequencyError::InvalidOption {
            name,
            value,
            reason,
        })
    };
    if !(opts.omega.is_finite() && opts.omega > 0.0) {
        return bad(
            "omega",
            opts.omega,
            "must be a finite frequency > 0 (rad/s)",
        );
    }
    if !(opts.amplitude.is_finite() && opts.amplitude > 0.0) {
        return bad(
            "amplitude",
            opts.amplitude,
            "must be a finite amplitude > 0",
        );
    }
    if opts.degree < 1 || opts.degree > MAX_DEGREE {
        return bad("degree", opts.degree as f64, "must be between 1 and 6");
    }
    if let Some(t) = opts.transient
        && !(t.is_finite() && t >= 0.0)
    {
        return bad("transient", t, "must be a finite duration >= 0 (s)");
    }
    let n = rec.time.len();
    if rec.y.len() != n || rec.u.is_some_and(|u| u.len() != n) {
        return Err(FrequencyError::Lengths {
            what: format!(
                "time {n}, y {}{}",
                rec.y.len(),
                rec.u
                    .map(|u| format!(", u {}", u.len()))
                    .unwrap_or_default()
            ),
        });
    }
    let cols: [(&'static str, Option<&[f64]>); 3] =
        [("time", Some(rec.time)), ("u", rec.u), ("y", Some(rec.y))];
    for (name, col) in cols {
        if let Some(c) = col
            && let Some(i) = c.iter().position(|v| !v.is_finite())
        {
            return Err(FrequencyError::NotFinite {
                column: name,
                index: i,
                value: c[i],
            });
        }
    }
    if let Some(i) = rec.time.windows(2).position(|w| w[1] <= w[0]) {
        return Err(FrequencyError::TimeNotIncreasing { index: i + 1 });
    }
    Ok(())
}

/// A candidate optimisation set: bins excluded as constant stages, and the phase bracket of (23a).
struct Candidate {
    runs: Vec<Run>,
    lo: f64,
    hi: f64,
}

/// Identify one sine experiment (see the module documentation).
pub fn estimate(
    rec: &SineRecord,
    opts: &FrequencyOptions,
) -> Result<FrequencyEstimate, FrequencyError> {
    check_inputs(rec, opts)?;
    let omega = opts.omega;
    let p = opts.degree + 1;
    // 1. Phase reference.
    let (input_amplitude, input_phase) = phase_reference(rec, opts)?;
    let phi_u = input_phase.unwrap_or(0.0);
    let rho: Vec<f64> = rec.time.iter().map(|&t| omega * t - phi_u).collect();
    // 2. Bins, transient, averaging (21).
    let bins = bins_per_period(rec.time, omega, opts.degree)?;
    let folded = fold::fold(&rho, rec.y, bins, opts.transient.map(|s| s * omega))?;
    let mut warnings = folded.warnings.clone();
    // 3. Admissibility.
    check_admissible(&folded, opts.amplitude)?;
    // 4-5. SLS on the whole period, then constant-stage candidates if it does not fit.
    let fitting = Fitting::new(&folded, p);
    let (psi, runs, path) = fitting.choose(opts.degree, &mut warnings);
    // 6. Final fit at psi in [0, pi), checks, recovery.
    let psi = psi.rem_euclid(PI);
    let mut est = fitting.finish(psi, &runs, opts)?;
    let (tau_a, tau_d) = stage_lengths(&runs, &folded, psi, omega);
    est.path = path;
    est.tau_a = tau_a;
    est.tau_d = tau_d;
    est.input_amplitude = input_amplitude;
    est.input_phase = input_phase;
    est.warnings = warnings;
    Ok(est)
}

/// Step 1: the input's amplitude and phase `U'`, `phi_u` (fitted as `U' cos(omega t - phi_u)`), or
/// `None` without an input column; refused if the input is not that sine or `U'` is not the declared `U`.
fn phase_reference(
    rec: &SineRecord,
    opts: &FrequencyOptions,
) -> Result<(Option<f64>, Option<f64>), FrequencyError> {
    let Some(u) = rec.u else {
        return Ok((None, None));
    };
    let fit = window::fit_sine(rec.time, u, opts.omega, false);
    let (amp, ph, res) = (fit.amplitude, fit.phase, fit.residual);
    if !(amp.is_finite() && amp > 0.0) || res > 0.1 * amp {
        return Err(FrequencyError::InputNotSine {
            omega: opts.omega,
            fitted: amp,
            residual: res,
        });
    }
    if (amp - opts.amplitude).abs() > AMPLITUDE_TOLERANCE * opts.amplitude {
        return Err(FrequencyError::AmplitudeMismatch {
            fitted: amp,
            declared: opts.amplitude,
        });
    }
    Ok((Some(amp), Some(ph)))
}

/// Step 2: phase bins per period, `2 pi / (omega Ts)` with `Ts` the median time step; refused below what
/// degree `n` needs.
fn bins_per_period(time: &[f64], omega: f64, n: usize) -> Result<usize, FrequencyError> {
    let dts: Vec<f64> = time.windows(2).map(|w| w[1] - w[0]).collect();
    let bins = crate::stats::median(&dts).map_or(0, |dt| (TAU / (omega * dt)).round() as usize);
    let needed = (4 * (n + 1)).max(12);
    if bins < needed {
        return Err(FrequencyError::TooFewSamples {
            per_period: bins,
            needed,
            degree: n,
        });
    }
    Ok(bins)
}

/// Step 3, Proposition 1.3: refused when the averaged output does not vary beyond its noise.
fn check_admissible(folded: &fold::Folded, amplitude: f64) -> Result<(), FrequencyError> {
    let nb = folded.w.len();
    let total: f64 = folded.count.iter().sum();
    let mean = folded
        .w
        .iter()
        .zip(&folded.count)
        .map(|(w, c)| w * c)
        .sum::<f64>()
        / total;
    let chi_const: f64 = (0..nb)
        .map(|j| ((folded.w[j] - mean) / folded.sigma_bin(j)).powi(2))
        .sum();
    let dof_const = (nb - 1) as f64;
    if chi_const > dof_const + 5.0 * (2.0 * dof_const).sqrt() {
        return Ok(());
    }
    let (lo, hi) = folded
        .w
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
            (l.min(v), h.max(v))
        });
    Err(FrequencyError::NonAdmissible {
        amplitude,
        variation: hi - lo,
        noise: folded.sigma.max(folded.sigma_floor) / (total / nb as f64).sqrt(),
    })
}

/// Stage lengths `(tau_a, tau_d)`: a run that holds the start of the ascending (descending) half.
fn stage_lengths(runs: &[Run], folded: &fold::Folded, psi: f64, omega: f64) -> (f64, f64) {
    let delta = folded.delta;
    let (mut tau_a, mut tau_d) = (0.0, 0.0);
    for r in runs {
        let (first, last) = r.phases(&folded.phase);
        for (start, tau) in [(psi, &mut tau_d), (psi + PI, &mut tau_a)] {
            // Move the branch start next to the run.
            let s = start + ((first - start) / TAU).round() * TAU;
            if s >= first - 3.0 * delta && s <= last + delta {
                *tau = ((last + 0.5 * delta - s) / omega).max(0.0);
            }
        }
    }
    (tau_a, tau_d)
}

/// Steps 4-6 on one averaged period: the cost (22) on optimisation sets, their scores, the choice of
/// Table 1 and the final fit.
struct Fitting<'a> {
    folded: &'a fold::Folded,
    /// Row weights: square roots of the bins' sample counts.
    sw: Vec<f64>,
    /// Parameters per branch, `n + 1`.
    p: usize,
    /// Noise std of one sample, with its floor.
    sigma: f64,
}

impl<'a> Fitting<'a> {
    fn new(folded: &'a fold::Folded, p: usize) -> Fitting<'a> {
        Fitting {
            folded,
            sw: folded.count.iter().map(|c| c.sqrt()).collect(),
            p,
            sigma: folded.sigma.max(folded.sigma_floor),
        }
    }

    /// The cost over the bins outside `runs`.
    fn problem(&self, runs: &[Run]) -> Problem<'a> {
        let nb = self.folded.w.len();
        Problem::new(
            &self.folded.phase,
            &self.folded.w,
            self.sw.clone(),
            (0..nb)
                .map(|j| !runs.iter().any(|r| r.contains(j, nb)))
                .collect(),
            self.p,
        )
    }

    /// `(chi2, dof)` of a cost over `included` bins.
    fn score(&self, cost: f64, included: usize) -> (f64, f64) {
        let dof = (included as f64 - 2.0 * self.p as f64 - 1.0).max(1.0);
        (cost / (self.sigma * self.sigma), dof)
    }

    /// Table 1 and eq. (26): `(psi, stage runs, path)`; the SLS (with a warning) when it does not fit and
    /// no constant-stage candidate beats it.
    fn choose(&self, n: usize, warnings: &mut Vec<String>) -> (f64, Vec<Run>, EstimatorPath) {
        let delta = self.folded.delta;
        let (psi_sls, j_sls) = self.problem(&[]).minimise(0.0, PI, delta / 4.0, true);
        let (chi_sls, dof_sls) = self.score(j_sls, self.folded.w.len());
        if chi_sls <= dof_sls + 5.0 * (2.0 * dof_sls).sqrt() {
            return (psi_sls, Vec::new(), EstimatorPath::Sls);
        }
        match self.best_candidate() {
            Some((per_dof, psi, runs)) if per_dof < chi_sls / dof_sls => {
                (psi, runs, EstimatorPath::Ls)
            }
            _ => {
                warnings.push(format!(
                    "the averaged output is not explained by degree-{n} borders within the noise \
                     (chi-square per degree of freedom {:.3e}) and no constant stage improves the fit: \
                     check the degree, the steady state and the frequency",
                    chi_sls / dof_sls
                ));
                (psi_sls, Vec::new(), EstimatorPath::Sls)
            }
        }
    }

    /// The constant-stage candidates (module documentation, step 4): the four longest flat runs alone and
    /// the pairs of them whose brackets meet modulo `pi`.
    fn candidates(&self) -> Vec<Candidate> {
        let (folded, delta) = (self.folded, self.folded.delta);
        let nb = folded.w.len();
        let tol: Vec<f64> = (0..nb).map(|j| 4.0 * folded.sigma_bin(j)).collect();
        let top: Vec<Run> = flat_runs(&folded.w, &tol).into_iter().take(4).collect();
        let bracket = |r: &Run| {
            let (first, last) = r.phases(&folded.phase);
            (first - 3.0 * delta, last + delta)
        };
        let mut cands: Vec<Candidate> = top
            .iter()
            .map(|r| {
                let (lo, hi) = bracket(r);
                Candidate {
                    runs: vec![*r],
                    lo,
                    hi,
                }
            })
            .collect();
        for (i, r1) in top.iter().enumerate() {
            for r2 in &top[i + 1..] {
                if (0..nb).any(|j| r1.contains(j, nb) && r2.contains(j, nb)) {
                    continue;
                }
                let (lo1, hi1) = bracket(r1);
                let (lo2, hi2) = bracket(r2);
                // Align the second bracket, shifted by a multiple of pi, on the first.
                let shift = (((lo1 + hi1) - (lo2 + hi2)) / 2.0 / PI).round() * PI;
                let (lo, hi) = (lo1.max(lo2 + shift), hi1.min(hi2 + shift));
                if lo < hi {
                    cands.push(Candidate {
                        runs: vec![*r1, *r2],
                        lo,
                        hi,
                    });
                }
            }
        }
        cands
    }

    /// The candidate of smallest chi-square per degree of freedom: `(chi2 / dof, psi, runs)`.
    fn best_candidate(&self) -> Option<(f64, f64, Vec<Run>)> {
        let mut best: Option<(f64, f64, Vec<Run>)> = None;
        for c in self.candidates() {
            let pb = self.problem(&c.runs);
            // Inside the bracket the stage bins are out of I_N and the cost is smooth: half-bin grid.
            let (psi, j) = pb.minimise(c.lo, c.hi, self.folded.delta / 2.0, false);
            let (chi, dof) = self.score(j, pb.included());
            let per_dof = chi / dof;
            if best.as_ref().is_none_or(|b| per_dof < b.0) {
                best = Some((per_dof, psi, c.runs));
            }
        }
        best
    }

    /// Step 6: the fit at `psi` without the bins of `runs`, its checks and the recovery (28), (35)-(37).
    /// The path, stage lengths, input fit and warnings are left for the caller.
    fn finish(
        &self,
        psi: f64,
        runs: &[Run],
        opts: &FrequencyOptions,
    ) -> Result<FrequencyEstimate, FrequencyError> {
        let (p, n, folded) = (self.p, opts.degree, self.folded);
        let pb = self.problem(runs);
        let fit = pb.fit(psi);
        for (branch, b) in [
            ("ascending", &fit.ascending),
            ("descending", &fit.descending),
        ] {
            if b.rank < p {
                return Err(FrequencyError::TooFewBranchSamples {
                    branch,
                    found: b.rows,
                    needed: p,
                    degree: n,
                });
            }
        }
        let alpha = fit.ascending.theta.clone();
        let delta = fit.descending.theta.clone();
        let (gain, fa, fd) = recover(&alpha, &delta, opts.amplitude)?;
        let included_samples: f64 = (0..folded.w.len())
            .filter(|&j| pb.include[j])
            .map(|j| folded.count[j])
            .sum();
        let (chi2, dof) = self.score(fit.cost(), pb.included());
        Ok(FrequencyEstimate {
            omega: opts.omega,
            amplitude: opts.amplitude,
            degree: n,
            phase: psi,
            gain,
            fa,
            fd,
            path: EstimatorPath::Sls,
            alpha,
            delta,
            tau_a: 0.0,
            tau_d: 0.0,
            periods_used: folded.periods_used,
            transient_periods: folded.transient_periods,
            samples_per_period: folded.bins,
            residual_rms: (fit.cost() / included_samples).sqrt(),
            noise_std: folded.sigma,
            chi2,
            dof,
            samples_averaged: included_samples,
            parameters: 2 * p + 1 + runs.len(),
            input_amplitude: None,
            input_phase: None,
            warnings: Vec::new(),
        })
    }
}
