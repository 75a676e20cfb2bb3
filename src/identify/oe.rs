//! Output-error (prediction-error) refinement of the pseudo-Wiener backlash model of paper 000, started from
//! MRGIA's estimate, with standard errors from the Fisher information and the Cramer-Rao bound (CRB) for
//! planning experiments.
//!
//! # Model and cost
//!
//! With the parameter vector (m1 = 1, see below)
//!
//! ```text
//! theta = [a_1 .. a_na, b_0 .. b_nb, m2, c1, c2]            (p = na + nb + 4 entries)
//! ```
//!
//! the model is *simulated* from the input alone (no measured output is fed back, unlike MRGIA's switching
//! functions):
//!
//! ```text
//! x^(k) = -sum_{i=1..na} a_i x^(k-i) + sum_{j=0..nb} b_j u(k-d-j)
//! w^(k) = x^(k) - c1           if x^(k) > w^(k-1) + c1          (engaged up)
//! w^(k) = m2 (x^(k) + c2)      if x^(k) < w^(k-1)/m2 - c2       (engaged down)
//! w^(k) = w^(k-1)              otherwise                        (held)
//! ```
//!
//! with all signals zero before k = 0 (as in the plant), and the estimate minimises the output-error cost
//!
//! ```text
//! V(theta) = sum_{k=0..N-1} (y(k) - w^(k|theta))^2 ,
//! ```
//!
//! the maximum-likelihood criterion for white Gaussian measurement noise y = w + e, e ~ N(0, sigma^2).
//!
//! # Why m1 = 1
//!
//! For any s > 0 the model (b, m1, m2, c1, c2) and the model (s b, m1/s, m2/s, s c1, s c2) give the same
//! output: x scales by s, the borders `m1 (x - c1)` and `m2 (x + c2)` and the switching thresholds
//! `w/m1 + c1`, `w/m2 - c2` scale with it. The output depends on m1 b and the gaps only up to that scale, so
//! m1 and b are interchangeable and one of them must be fixed; as in the paper (eq. (11)) m1 = 1.
//! [`normalise`] maps any plant to its m1 = 1 equivalent.
//!
//! # Exact sensitivities
//!
//! `J(k) = d w^(k) / d theta` is propagated with the simulation, mode by mode (the mode of each sample is
//! the one the simulation took at theta):
//!
//! ```text
//! dx^(k)/da_i = -x^(k-i) - sum_l a_l dx^(k-l)/da_i        dx^(k)/db_j = u(k-d-j) - sum_l a_l dx^(k-l)/db_j
//! dx^/dm2 = dx^/dc1 = dx^/dc2 = 0
//! up:    dw^(k) = dx^(k) - dc1                            (d[m1 (x - c1)] with m1 = 1)
//! down:  dw^(k) = m2 dx^(k) + (x^(k) + c2) dm2 + m2 dc2   (d[m2 (x + c2)])
//! held:  dw^(k) = dw^(k-1)
//! ```
//!
//! On the play side of the border crossing (see "Where it fails" below) the backlash output is a
//! continuous, piecewise smooth function of theta (at a switching threshold the engaged value equals the
//! held one), so these are the exact derivatives wherever no sample sits exactly on a threshold, i.e. almost
//! everywhere; they are checked against central differences in the tests.
//!
//! # Algorithm
//!
//! Levenberg-Marquardt on the normal equations `(J^T J + lambda diag(J^T J)) delta = J^T r`,
//! `r = y - w^`, accumulated sample by sample (J is never stored; no allocation in the simulation loop):
//!
//! - a step is accepted only if it decreases V (after a mode switch the linearisation can be wrong; a
//!   rejected step only raises the damping), and the damping follows Nielsen's schedule
//!   (`lambda *= max(1/3, 1 - (2 rho - 1)^3)` on success, with rho the ratio of actual to predicted
//!   decrease; `lambda *= nu, nu *= 2` on failure);
//! - a step that makes m2 <= [`M2_MIN`] is rejected (the lower border needs a positive slope); the gaps are
//!   not constrained (a slightly negative gap estimate is a legitimate statistical outcome on a plant with
//!   almost no play, and the standard errors remain meaningful);
//! - it stops when the Gauss-Newton step `H^-1 g` (H = J^T J, g = J^T r) is shorter than [`STEP_SE`] = 0.1
//!   standard errors in the metric of the estimate's covariance, `g^T H^-1 g <= 0.01 s^2` with
//!   `s^2 = V / (N - p)`: the cost is only piecewise smooth (every sample that changes mode adds a kink),
//!   and below that scale the iteration would wobble between kinks for tens of iterations to gain
//!   nothing statistically (on the paper example at N = 3000, 34 iterations instead of 2, for a change of
//!   0.05 standard errors). It also stops on a step below `tol (|theta_i| + tol)`, on actual and predicted
//!   relative decreases both below 1e-12 (MINPACK's ftol test), when the cost cannot be decreased any more
//!   (lambda > 1e16), or after `max_iter` iterations (reported as not converged). Noise-free data have
//!   s -> 0, so there the iteration runs to machine precision (the paper example is recovered exactly).
//!
//! Starting points: MRGIA with [`MrgiaConfig::recommended`] over the whole record (always); with
//! [`OeConfig::extra_starts`] (the default) also MRGIA with the paper's setting and the recommended estimate
//! with both gaps halved; the fit with the lowest cost wins (a later start only if it is lower by more than
//! the stopping resolution `0.01 s^2`). Before a start is used it is repaired: a
//! non-positive m2 becomes 1, an unstable linear block (simulated output not finite or 1e3 times larger
//! than the data) is replaced by its FIR part (a = 0), and a gap so large that the simulated model never
//! engages that border while the measured output moves that way is halved until it does (the gradient of a
//! border that is never engaged is zero, so the optimiser could not move it: MRGIA's known failure mode of a
//! stuck border). Other restarts were tried and dropped: a start from a linear output-error fit (backlash
//! replaced by the identity) changed nothing, and 16 random restarts around the optimum rescued 4 of the 10
//! failures below with 2% perturbations (1 with 10%) for a 10x longer fit.
//!
//! # Where it fails: crossed borders
//!
//! With m2 != 1 the two borders cross at `x* = (c1 + m2 c2) / (1 - m2)`. Beyond x* the contract's rule is
//! discontinuous: the upper test is checked first, so the output alternates between the borders (even for a
//! constant x), w is no longer continuous in theta, and the cost breaks into cells with many local minima a
//! few percent from the truth. On records that keep x on the play side of x* (any physical backlash), the
//! fit from MRGIA reached the truth's optimum on 60/60 random plants noise-free and 60/60 at SNR 100; on
//! the inputs of the MRGIA random-plant test, which drive most plants far beyond x*, on 56/60 and 54/60,
//! every failure on a plant with over a third of its samples beyond x* (test `random_plants_are_recovered`).
//!
//! # Measured (paper example, SNR 43, `backlash study`)
//!
//! RMSE / CRB std per parameter (a1, a2, b0, m2, c1, c2) over 1000 runs at N = 3000: 1.03, 1.04, 0.97,
//! 0.98, 0.99, 0.98; the 95% intervals `estimate +/- 1.96 std_err` covered the truth in 94.1-95.8% of runs;
//! the bias is within 5% of a standard error (consistent with zero: the Monte Carlo error of a mean over
//! 1000 runs is 3%). At N = 300, 1000, 3000 and 10000 (200 runs) the ratios stay within 0.91-1.10: the fit
//! is efficient from N = 300 on. MRGIA's recommended setting, for comparison, has RMSE 15-800x the bound at
//! N = 300 and 2.3-5x at N = 3000 (200 runs; over 1000 runs its few failed runs push that to 40-150x).
//! A fit takes 1.6 ms at N = 3000 (three starts; 0.5 ms with one), of which each MRGIA pass is 0.25 ms.
//!
//! # Uncertainty
//!
//! At the optimum the noise variance is estimated with N - p degrees of freedom, `s^2 = V / (N - p)`, and
//! the covariance is the inverse Fisher information `cov = s^2 (J^T J)^-1`; the standard errors are the
//! square roots of its diagonal ([`OeFit::std_err`]). The Cramer-Rao bound for a given input record, true
//! parameters and noise level is the same formula with J at the truth and the true sigma ([`crb`]); both
//! shrink as `1/sqrt(N)` for a stationary input, which [`Uncertainty::samples_for`] uses to answer how many
//! samples a target relative accuracy needs.
//!
//! # Degenerate cases
//!
//! - No excitation: the Fisher information is singular when a parameter does not change the simulated
//!   output (u = 0: nothing moves; an input that only ever drives the output up: m2 and c2 are never seen) or
//!   when parameters change it in the same way. This is detected on the scaled information matrix
//!   `D^-1/2 J^T J D^-1/2` (D its diagonal): a zero diagonal entry, or a smallest eigenvalue below
//!   [`RCOND_MIN`], makes [`fit`] and [`crb`] fail with [`OeError::NotExcited`], which names the
//!   parameters involved and says that the record does not excite them. No estimate is reported then (an
//!   estimate with infinite uncertainty is not an estimate).
//! - Noise-free data: the residual is zero up to rounding, so the standard errors are (near) zero.
//! - Records shorter than p + 1 samples, mismatched lengths and non-finite samples are refused.

mod lm;
pub mod online;
mod sim;
#[cfg(feature = "cli")]
mod study;
#[cfg(test)]
mod tests;

#[cfg(feature = "cli")]
pub use study::{
    GridConfig, GridResult, METHODS, MethodStats, PLANT_VARIANTS, PlantVariant, ROWS_HEADER, Row,
    StudyConfig, StudyError, StudyResult, grid_study, monte_carlo, plant_variant,
};

use super::mrgia::{self, Estimate, MrgiaConfig};
use crate::plant::{
    ArxParams, BacklashParams, MAX_ORDER, ParamError, PlantParams, check_order, check_positive,
    check_structure,
};
use lm::{Lm, levenberg_marquardt, repair_start};
use nalgebra::{DMatrix, SymmetricEigen};
use serde::{Deserialize, Serialize};
use sim::{SimState, Theta, cost_only, info_matrix, normal_equations, propagate, propagate_state};

/// Largest parameter count: 4 a's, 5 b's, m2, c1, c2.
pub const MAX_P: usize = MAX_ORDER + (MAX_ORDER + 1) + 3;
/// Smallest m2 a step may reach.
pub const M2_MIN: f64 = 1e-3;
/// Smallest eigenvalue of the scaled (correlation-form) Fisher information below which the record is
/// declared not to excite the parameters: the standard errors would be inflated by more than 1e5 over
/// those of uncorrelated parameters with the same information.
pub const RCOND_MIN: f64 = 1e-10;
/// The iteration stops when the Gauss-Newton step is shorter than this many standard errors (module docs).
pub const STEP_SE: f64 = 0.1;

/// Why an output-error fit or a CRB could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum OeError {
    #[error(transparent)]
    Param(#[from] ParamError),
    #[error("u has {u} samples but y has {y}")]
    Length { u: usize, y: usize },
    #[error("the record has {n} samples; at least {min} are needed for {p} parameters")]
    TooShort { n: usize, min: usize, p: usize },
    #[error("sample {index} of {signal} is not a finite number")]
    NonFinite { signal: &'static str, index: usize },
    #[error(
        "the record does not excite the parameters {}: the Fisher information is singular \
         (smallest scaled eigenvalue {rcond:.1e}); use an input that moves the output up and down \
         through both borders",
        .params.join(", ")
    )]
    NotExcited { params: Vec<String>, rcond: f64 },
    #[error("the simulated model output is not finite (unstable linear block?)")]
    Diverged,
    #[error("noise standard deviation {0} must be a finite number > 0")]
    NoiseStd(f64),
    #[error("target relative accuracy {0} must be a finite number > 0")]
    Target(f64),
}

/// Settings of the output-error fit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct OeConfig {
    /// Number of a coefficients, 0..=4.
    pub na: usize,
    /// Highest b index, 0..=4.
    pub nb: usize,
    /// Delay d in samples, 1..=64.
    pub delay: usize,
    /// Levenberg-Marquardt iterations per start (default 200; the paper example needs 2-5 from MRGIA).
    pub max_iter: usize,
    /// Relative step tolerance (default 1e-10).
    pub tol: f64,
    /// Besides MRGIA's recommended estimate, also start from MRGIA's paper-setting estimate and from the
    /// recommended estimate with both gaps halved, and keep the lowest cost (default true). Costs one more
    /// MRGIA pass and two more optimisations (1.6 ms instead of 0.5 ms at N = 3000). Measured benefit: none
    /// on the 240 random-plant fits of the tests (same successes with one start) nor on the paper example
    /// (the starts reach the same optimum); kept as cheap insurance against a bad recommended estimate.
    pub extra_starts: bool,
}

impl OeConfig {
    /// Default settings for the given structure.
    pub fn new(na: usize, nb: usize, delay: usize) -> Self {
        Self {
            na,
            nb,
            delay,
            max_iter: 200,
            tol: 1e-10,
            extra_starts: true,
        }
    }

    /// p = na + nb + 4.
    pub fn n_params(&self) -> usize {
        self.na + self.nb + 4
    }

    /// Orders and delay in range, sensible optimiser settings.
    pub fn validate(&self) -> Result<(), ParamError> {
        check_structure(self.na, self.nb, self.delay)?;
        if self.max_iter == 0 {
            return Err(ParamError::new("max_iter", 0.0, "must be at least 1"));
        }
        if !(self.tol.is_finite() && self.tol > 0.0) {
            return Err(ParamError::new("tol", self.tol, "must be positive"));
        }
        Ok(())
    }
}

/// Names of the entries of theta: a1.., b0.., m2, c1, c2.
pub fn param_names(na: usize, nb: usize) -> Vec<String> {
    (1..=na)
        .map(|i| format!("a{i}"))
        .chain((0..=nb).map(|j| format!("b{j}")))
        .chain(["m2", "c1", "c2"].map(String::from))
        .collect()
}

/// theta = [a.., b.., m2, c1, c2] of an estimate (m1 is not part of it).
pub fn theta_of(est: &Estimate) -> Vec<f64> {
    est.a
        .iter()
        .chain(&est.b)
        .copied()
        .chain([est.m2, est.c1, est.c2])
        .collect()
}

/// The m1 = 1 equivalent of a plant: b -> m1 b, c -> m1 c, m2 -> m2 / m1 (same output, see the module docs).
pub fn normalise(p: &PlantParams) -> PlantParams {
    let m1 = p.backlash.m1;
    let mut q = *p;
    for b in q.arx.b.iter_mut() {
        *b *= m1;
    }
    q.backlash = BacklashParams {
        m1: 1.0,
        m2: p.backlash.m2 / m1,
        c1: p.backlash.c1 * m1,
        c2: p.backlash.c2 * m1,
    };
    q
}

/// The estimate of an m1 = 1 plant (see [`normalise`]).
pub fn estimate_of(p: &PlantParams) -> Estimate {
    let q = normalise(p);
    Estimate {
        a: q.arx.a().to_vec(),
        b: q.arx.b().to_vec(),
        m1: 1.0,
        m2: q.backlash.m2,
        c1: q.backlash.c1,
        c2: q.backlash.c2,
    }
}

/// The plant with the parameters of an estimate (noise-free).
pub fn plant_of(est: &Estimate, delay: usize) -> Result<PlantParams, ParamError> {
    let (na, nb) = structure(est)?;
    let mut arx = ArxParams {
        na,
        nb,
        delay,
        a: [0.0; MAX_ORDER],
        b: [0.0; MAX_ORDER + 1],
    };
    arx.a[..na].copy_from_slice(&est.a);
    arx.b[..=nb].copy_from_slice(&est.b);
    let p = PlantParams {
        arx,
        backlash: BacklashParams {
            m1: est.m1,
            m2: est.m2,
            c1: est.c1,
            c2: est.c2,
        },
        noise_std: 0.0,
        noise_seed: 0,
    };
    p.arx.validate()?;
    Ok(p)
}

fn structure(est: &Estimate) -> Result<(usize, usize), ParamError> {
    check_order("na", est.a.len())?;
    if est.b.is_empty() {
        return Err(ParamError::new("nb", -1.0, "must be between 0 and 4"));
    }
    check_order("nb", est.b.len() - 1)?;
    Ok((est.a.len(), est.b.len() - 1))
}

/// Per-parameter standard deviations in the layout of an estimate (the JSON `std_err` object).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StdErr {
    pub a: Vec<f64>,
    pub b: Vec<f64>,
    pub m2: f64,
    pub c1: f64,
    pub c2: f64,
}

impl StdErr {
    /// From the standard deviations in theta order (`na + nb + 4` entries).
    pub fn from_flat(na: usize, nb: usize, v: &[f64]) -> Self {
        let p = na + nb + 4;
        Self {
            a: v[..na].to_vec(),
            b: v[na..=na + nb].to_vec(),
            m2: v[p - 3],
            c1: v[p - 2],
            c2: v[p - 1],
        }
    }

    /// In theta order.
    pub fn flat(&self) -> Vec<f64> {
        self.a
            .iter()
            .chain(&self.b)
            .copied()
            .chain([self.m2, self.c1, self.c2])
            .collect()
    }
}

/// A covariance of theta with what is needed to plan an experiment.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Uncertainty {
    /// Parameter names in theta order.
    pub names: Vec<String>,
    /// The parameter values the covariance was computed at (the truth for a CRB, the estimate for a fit).
    pub theta: Vec<f64>,
    /// Standard deviations, theta order.
    pub std: Vec<f64>,
    /// Covariance, p x p row-major.
    pub covariance: Vec<f64>,
    /// Record length N the covariance is for.
    pub samples: usize,
    /// Noise standard deviation it assumes (the truth for a CRB, the residual estimate for a fit).
    pub noise_std: f64,
}

impl Uncertainty {
    /// Samples needed so that every parameter's relative standard deviation `std_i / |theta_i|` is at most
    /// `target_rel`, by the `1/sqrt(N)` scaling of the Fisher information of a stationary input:
    /// `N_i = ceil(N (std_i / (|theta_i| target_rel))^2)`, at least p + 1. Per parameter in theta order
    /// (`None` for a parameter whose value is 0: no relative accuracy), and the largest of them.
    /// The scaling extrapolates the record's own statistics: the longer record must be like this one.
    pub fn samples_for(&self, target_rel: f64) -> Result<(Vec<Option<usize>>, usize), OeError> {
        if !(target_rel.is_finite() && target_rel > 0.0) {
            return Err(OeError::Target(target_rel));
        }
        let min = self.theta.len() + 1;
        let per: Vec<Option<usize>> = self
            .std
            .iter()
            .zip(&self.theta)
            .map(|(s, t)| {
                (*t != 0.0).then(|| {
                    let r = s / (t.abs() * target_rel);
                    ((self.samples as f64 * r * r).ceil() as usize).max(min)
                })
            })
            .collect();
        let all = per.iter().flatten().copied().max().unwrap_or(min);
        Ok((per, all))
    }

    /// Standard deviations in the layout of an estimate.
    pub fn std_err(&self) -> StdErr {
        let p = self.theta.len();
        let na = self.names.iter().filter(|n| n.starts_with('a')).count();
        StdErr::from_flat(na, p - na - 4, &self.std)
    }
}

/// The result of an output-error fit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OeFit {
    /// The estimate (m1 = 1).
    pub estimate: Estimate,
    /// Standard errors from the Fisher information at the optimum.
    pub std_err: StdErr,
    /// Covariance and planning data of the estimate.
    pub uncertainty: Uncertainty,
    /// Residual standard deviation `sqrt(V / (N - p))`, the noise estimate.
    pub sigma: f64,
    /// `sqrt(V / N)`.
    pub rmse: f64,
    /// The cost V at the optimum.
    pub cost: f64,
    /// Levenberg-Marquardt iterations of the winning start.
    pub iterations: usize,
    /// The winning start stopped on a small step or a cost it could not decrease (not on `max_iter`).
    pub converged: bool,
    /// Which start won: `mrgia-recommended`, `mrgia-paper`, `mrgia-recommended-half-gaps`, or `given`.
    pub start_method: String,
    /// The winning start, after its repair (see the module docs).
    pub start: Estimate,
    /// RMS of the output error of that start.
    pub start_rmse: f64,
    /// Samples on the upper border, the lower border and held, in the fitted model's simulation.
    pub modes: [usize; 3],
    pub samples: usize,
}

/// Simulated backlash output w^ of an estimate (m1 as given; [`plant_of`] semantics) on `u`.
pub fn simulate(est: &Estimate, delay: usize, u: &[f64]) -> Result<Vec<f64>, OeError> {
    let th = Theta::new(&normalised(est), delay)?;
    let mut w = vec![0.0; u.len()];
    propagate::<false>(&th, u, |k, wk, _| w[k] = wk);
    Ok(w)
}

/// The m1 = 1 form of an estimate.
fn normalised(est: &Estimate) -> Estimate {
    if est.m1 == 1.0 {
        return est.clone();
    }
    let m1 = est.m1;
    Estimate {
        a: est.a.clone(),
        b: est.b.iter().map(|b| b * m1).collect(),
        m1: 1.0,
        m2: est.m2 / m1,
        c1: est.c1 * m1,
        c2: est.c2 * m1,
    }
}

/// Simulated output w^ and the exact sensitivities `J[(k, i)] = d w^(k) / d theta_i` (theta of
/// [`theta_of`], m1 = 1; an estimate with m1 != 1 is normalised first) on `u`.
pub fn sensitivities(
    est: &Estimate,
    delay: usize,
    u: &[f64],
) -> Result<(Vec<f64>, DMatrix<f64>), OeError> {
    let th = Theta::new(&normalised(est), delay)?;
    let p = th.p();
    let mut w = vec![0.0; u.len()];
    let mut jac = DMatrix::zeros(u.len(), p);
    propagate::<true>(&th, u, |k, wk, dw| {
        w[k] = wk;
        for (i, d) in dw.iter().enumerate() {
            jac[(k, i)] = *d;
        }
    });
    Ok((w, jac))
}

/// Inverse of the information `J^T J`, or the parameters the record does not excite.
fn inverse_information(info: &DMatrix<f64>, names: &[String]) -> Result<DMatrix<f64>, OeError> {
    let p = info.nrows();
    let d: Vec<f64> = (0..p).map(|i| info[(i, i)]).collect();
    let dmax = d.iter().copied().fold(0.0, f64::max);
    let zero: Vec<usize> = (0..p)
        .filter(|&i| !(d[i].is_finite() && d[i] > 1e-300 && d[i] > 1e-24 * dmax))
        .collect();
    if !zero.is_empty() {
        return Err(OeError::NotExcited {
            params: zero.iter().map(|&i| names[i].clone()).collect(),
            rcond: 0.0,
        });
    }
    let s: Vec<f64> = d.iter().map(|v| 1.0 / v.sqrt()).collect();
    let scaled = DMatrix::from_fn(p, p, |i, j| info[(i, j)] * s[i] * s[j]);
    let eig = SymmetricEigen::new(scaled);
    let (imin, lmin) = eig
        .eigenvalues
        .iter()
        .copied()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .expect("p >= 4");
    // A NaN eigenvalue (non-finite information) counts as singular too.
    if lmin.is_nan() || lmin < RCOND_MIN {
        let v = eig.eigenvectors.column(imin);
        let params = (0..p)
            .filter(|&i| v[i].abs() >= 0.1)
            .map(|i| names[i].clone())
            .collect();
        return Err(OeError::NotExcited {
            params,
            rcond: lmin.max(0.0),
        });
    }
    let inv_l = DMatrix::from_diagonal(&eig.eigenvalues.map(|l| 1.0 / l));
    let inv_scaled = &eig.eigenvectors * inv_l * eig.eigenvectors.transpose();
    Ok(DMatrix::from_fn(p, p, |i, j| {
        inv_scaled[(i, j)] * s[i] * s[j]
    }))
}

fn uncertainty(
    theta: &[f64],
    names: Vec<String>,
    cov: &DMatrix<f64>,
    samples: usize,
    noise_std: f64,
) -> Uncertainty {
    let p = theta.len();
    Uncertainty {
        names,
        theta: theta.to_vec(),
        std: (0..p).map(|i| cov[(i, i)].max(0.0).sqrt()).collect(),
        covariance: cov.transpose().iter().copied().collect(),
        samples,
        noise_std,
    }
}

/// Whether the record (`u`, `y`) excites every parameter of the model `est` (m1 != 1 is normalised first):
/// the test by which [`fit`] refuses an estimate ([`OeError::NotExcited`]), at a given point. The structure
/// selection asks it of each structure it fits fully, so that it never chooses a structure the fit then
/// refuses.
pub fn check_excited(est: &Estimate, delay: usize, u: &[f64], y: &[f64]) -> Result<(), OeError> {
    let th = Theta::new(&normalised(est), delay)?;
    let ne = normal_equations(&th, u, y);
    let names = param_names(th.na, th.nb);
    inverse_information(&info_matrix(&ne, th.p()), &names).map(|_| ())
}

/// Cramer-Rao bound of the output-error model for input `u`, true plant `truth` (normalised to m1 = 1 with
/// [`normalise`]; slopes > 0, any finite gaps) and white Gaussian measurement noise of standard deviation
/// `noise_std`:
/// `cov >= noise_std^2 (J^T J)^-1` with the exact sensitivities J at the truth. Fails with
/// [`OeError::NotExcited`] when the input does not excite every parameter.
pub fn crb(truth: &PlantParams, u: &[f64], noise_std: f64) -> Result<Uncertainty, OeError> {
    // The model is defined for any real gaps (a fitted gap can be slightly negative), so only the slopes
    // must be positive here; `truth.noise_std` is not used.
    truth.arx.validate()?;
    let bl = &truth.backlash;
    check_positive("m1", bl.m1)?;
    check_positive("m2", bl.m2)?;
    crate::plant::check_finite("c1", bl.c1)?;
    crate::plant::check_finite("c2", bl.c2)?;
    if !(noise_std.is_finite() && noise_std > 0.0) {
        return Err(OeError::NoiseStd(noise_std));
    }
    check_finite("u", u)?;
    let est = estimate_of(truth);
    let th = Theta::new(&est, truth.arx.delay)?;
    let p = th.p();
    if u.len() <= p {
        return Err(OeError::TooShort {
            n: u.len(),
            min: p + 1,
            p,
        });
    }
    // y = w^ gives r = 0; only J^T J is used.
    let mut w = vec![0.0; u.len()];
    propagate::<false>(&th, u, |k, wk, _| w[k] = wk);
    let ne = normal_equations(&th, u, &w);
    let names = param_names(th.na, th.nb);
    let inv = inverse_information(&info_matrix(&ne, p), &names)?;
    let cov = inv * (noise_std * noise_std);
    Ok(uncertainty(&th.v[..p], names, &cov, u.len(), noise_std))
}

fn check_finite(signal: &'static str, v: &[f64]) -> Result<(), OeError> {
    match v.iter().position(|x| !x.is_finite()) {
        Some(index) => Err(OeError::NonFinite { signal, index }),
        None => Ok(()),
    }
}

fn check_record(cfg: &OeConfig, u: &[f64], y: &[f64]) -> Result<(), OeError> {
    cfg.validate()?;
    if u.len() != y.len() {
        return Err(OeError::Length {
            u: u.len(),
            y: y.len(),
        });
    }
    let p = cfg.n_params();
    if u.len() <= p {
        return Err(OeError::TooShort {
            n: u.len(),
            min: p + 1,
            p,
        });
    }
    check_finite("u", u)?;
    check_finite("y", y)
}

/// The starts of [`fit`] from the two MRGIA estimates.
fn default_starts(rec: Estimate, paper: Option<Estimate>) -> Vec<(&'static str, Estimate)> {
    let mut starts = vec![("mrgia-recommended", rec.clone())];
    if let Some(paper) = paper {
        starts.push(("mrgia-paper", paper));
        let mut half = rec;
        half.c1 *= 0.5;
        half.c2 *= 0.5;
        starts.push(("mrgia-recommended-half-gaps", half));
    }
    starts
}

/// Output-error fit started from MRGIA's estimate(s) over the same record (module docs).
pub fn fit(cfg: &OeConfig, u: &[f64], y: &[f64]) -> Result<OeFit, OeError> {
    check_record(cfg, u, y)?;
    let (na, nb, d) = (cfg.na, cfg.nb, cfg.delay);
    let (rec, _) = mrgia::identify(MrgiaConfig::recommended(na, nb, d), u, y)?;
    let paper = if cfg.extra_starts {
        Some(mrgia::identify(MrgiaConfig::paper(na, nb, d), u, y)?.0)
    } else {
        None
    };
    fit_from(cfg, u, y, &default_starts(rec, paper))
}

/// Output-error fit from given starting points (name, estimate), keeping the lowest cost. The estimates
/// must have `cfg.na` a's and `cfg.nb + 1` b's; m1 != 1 is normalised first.
pub fn fit_from(
    cfg: &OeConfig,
    u: &[f64],
    y: &[f64],
    starts: &[(&str, Estimate)],
) -> Result<OeFit, OeError> {
    check_record(cfg, u, y)?;
    let p = cfg.n_params();
    let mut best: Option<(Lm, &str, Theta, f64)> = None;
    for (name, est) in starts {
        let est = normalised(est);
        if est.a.len() != cfg.na || est.b.len() != cfg.nb + 1 {
            return Err(ParamError::new(
                "start",
                (est.a.len() + est.b.len()) as f64,
                "has a different structure than the configuration",
            )
            .into());
        }
        let th0 = repair_start(Theta::new(&est, cfg.delay)?, u, y);
        let (c0, _) = cost_only(&th0, u, y);
        if !c0.is_finite() {
            continue;
        }
        let lm = levenberg_marquardt(th0, u, y, cfg.max_iter, cfg.tol);
        // A later start wins only if it is better by more than the stopping resolution (STEP_SE^2 s^2), so
        // that statistically equal optima report the first (MRGIA recommended) start.
        let margin = STEP_SE * STEP_SE * lm.ne.cost / (u.len() - p) as f64;
        if best
            .as_ref()
            .is_none_or(|b| lm.ne.cost < b.0.ne.cost - margin)
        {
            best = Some((lm, name, th0, c0));
        }
    }
    let (lm, name, th0, c0) = best.ok_or(OeError::Diverged)?;
    let n = u.len();
    let names = param_names(cfg.na, cfg.nb);
    let inv = inverse_information(&info_matrix(&lm.ne, p), &names)?;
    let sigma = (lm.ne.cost / (n - p) as f64).sqrt();
    let cov = inv * (sigma * sigma);
    let unc = uncertainty(&lm.theta.v[..p], names, &cov, n, sigma);
    Ok(OeFit {
        estimate: lm.theta.estimate(),
        std_err: StdErr::from_flat(cfg.na, cfg.nb, &unc.std),
        uncertainty: unc,
        sigma,
        rmse: (lm.ne.cost / n as f64).sqrt(),
        cost: lm.ne.cost,
        iterations: lm.iterations,
        converged: lm.converged,
        start_method: name.to_string(),
        start: th0.estimate(),
        start_rmse: (c0 / n as f64).sqrt(),
        modes: lm.ne.modes,
        samples: n,
    })
}
