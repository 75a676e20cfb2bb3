//! A small Levenberg-Marquardt least-squares fitter for output-error fits of non-smooth models.
//!
//! The model is a black box `theta -> residuals` (the caller simulates its model and returns
//! `y - y_model`); the Jacobian is by forward differences. The backlash makes the simulated output only
//! piecewise smooth in the parameters (a sample that changes regime moves a kink), so the fitter is defensive:
//!
//! - a step is accepted only if the cost (sum of squared residuals) falls; otherwise the damping grows and the
//!   step is retried from the same Jacobian (Marquardt's scaling `J^T J + lambda diag(J^T J)`);
//! - a parameter vector whose simulation is invalid (the closure returns `false`: unstable, non-finite, out of
//!   range) counts as an infinite cost;
//! - [`fit_multistart`] runs from several starts and keeps the lowest cost.
//!
//! The finite-difference step of parameter j is `fd_rel (|theta_j| + typ_j)`, with `typ_j` a typical
//! magnitude given by the caller (so that a parameter that starts at zero still gets a sensible step; a
//! non-finite one counts as 0 there, and as 1 in the scaling of the steps, like a zero one).
//!
//! Every fit is bounded: at most `max_iter` Jacobians and `max_evals` residual evaluations, and it stops at
//! `deadline` (returning the best point so far). It stops early, as `identify oe` does, when the
//! Gauss-Newton step is statistically negligible: `g^T (J^T J)^-1 g <= stat_tol s^2` with
//! `s^2 = cost / (n - p)` (the step moves the estimate by less than `sqrt(stat_tol)` standard errors), which
//! on long records ends the fit after a few iterations instead of wobbling between the kinks of the cost.

use std::time::Instant;

use nalgebra::{DMatrix, DVector};

use crate::diagnose::residual::statistics::{ar_filter, ar_ls};

/// Settings of [`levenberg_marquardt`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmOptions {
    /// Most Jacobian evaluations (outer iterations).
    pub max_iter: usize,
    /// Stop when two consecutive accepted steps lower the cost by less than `rel_tol` of it.
    pub rel_tol: f64,
    /// Relative finite-difference step.
    pub fd_rel: f64,
    /// Initial damping.
    pub lambda0: f64,
    /// Give up when the damping exceeds this (no descent direction the fitter can find).
    pub lambda_max: f64,
    /// Stop when the Gauss-Newton step is shorter than `sqrt(stat_tol)` standard errors (0: never).
    pub stat_tol: f64,
    /// Most residual evaluations (simulations) in one fit.
    pub max_evals: usize,
    /// Stop at this instant (keeping the best point so far).
    pub deadline: Option<Instant>,
}

impl Default for LmOptions {
    fn default() -> Self {
        Self {
            max_iter: 60,
            rel_tol: 1e-7,
            fd_rel: 1e-6,
            lambda0: 1e-3,
            lambda_max: 1e8,
            stat_tol: 0.01,
            max_evals: 4000,
            deadline: None,
        }
    }
}

/// The result of a fit.
#[derive(Debug, Clone, PartialEq)]
pub struct LmFit {
    pub theta: Vec<f64>,
    /// Sum of squared residuals at `theta`.
    pub cost: f64,
    /// Number of residuals.
    pub n: usize,
    /// Jacobian evaluations.
    pub iterations: usize,
    /// Residual evaluations (simulations).
    pub evaluations: usize,
}

/// Why a fit could not start.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    #[error("the start point is not a valid model (the simulation failed)")]
    InvalidStart,
    #[error("no start points")]
    NoStarts,
}

/// Residuals in `out` (cleared and refilled by the closure); `false` marks an invalid parameter vector.
/// `Sync`: the Jacobian's columns are evaluated on all cores.
pub trait Residuals: Sync {
    fn eval(&self, theta: &[f64], out: &mut Vec<f64>) -> bool;
}

impl<F: Fn(&[f64], &mut Vec<f64>) -> bool + Sync> Residuals for F {
    fn eval(&self, theta: &[f64], out: &mut Vec<f64>) -> bool {
        self(theta, out)
    }
}

/// The sum of squared residuals.
pub(crate) fn cost_of(r: &[f64]) -> f64 {
    r.iter().map(|v| v * v).sum()
}

/// The cost at `theta` (residuals into `out`); `None` when the parameters are not a valid model or the cost
/// is not finite.
pub(crate) fn evaluate<R: Residuals + ?Sized>(
    f: &R,
    theta: &[f64],
    out: &mut Vec<f64>,
) -> Option<f64> {
    out.clear();
    if !f.eval(theta, out) {
        return None;
    }
    let c = cost_of(out);
    c.is_finite().then_some(c)
}

/// Levenberg-Marquardt from `theta0`; `typ` gives each parameter's typical magnitude (finite-difference
/// steps). Parameters listed in `fixed` are not moved.
pub fn levenberg_marquardt<R: Residuals + ?Sized>(
    f: &R,
    theta0: &[f64],
    typ: &[f64],
    fixed: &[usize],
    opts: &LmOptions,
) -> Result<LmFit, FitError> {
    let p = theta0.len();
    assert_eq!(typ.len(), p, "one typical magnitude per parameter");
    let free: Vec<usize> = (0..p).filter(|j| !fixed.contains(j)).collect();
    let mut r = Vec::new();
    let cost = evaluate(f, theta0, &mut r).ok_or(FitError::InvalidStart)?;
    let n = r.len();
    let q = free.len();
    let mut st = State {
        theta: theta0.to_vec(),
        trial: theta0.to_vec(),
        rt: Vec::with_capacity(n),
        r,
        cost,
        lambda: opts.lambda0,
        evaluations: 1,
        small: 0,
    };
    let mut iterations = 0;
    if q > 0 && n > 0 {
        let mut jac = vec![0.0; n * q];
        // Each free parameter's unit: its typical magnitude (1 where none is given).
        let unit: Vec<f64> = free
            .iter()
            .map(|&j| {
                let t = typ[j].abs();
                if t > 0.0 && t.is_finite() { t } else { 1.0 }
            })
            .collect();
        while iterations < opts.max_iter
            && st.evaluations + q < opts.max_evals
            && !out_of_time(opts)
        {
            iterations += 1;
            st.evaluations += jacobian(f, &st.theta, &st.r, typ, &free, opts.fd_rel, &mut jac);
            let (h, g) = normal_equations(&jac, &st.r, q);
            // In units of the typical magnitudes, so that the damping's floor and the factorisation do not
            // depend on the data's units (a record in millimetres and the same in metres take the same steps).
            let (h, g) = (
                DMatrix::from_fn(q, q, |a, b| h[(a, b)] * unit[a] * unit[b]),
                DVector::from_fn(q, |a, _| g[a] * unit[a]),
            );
            // Statistically negligible step: stop (the Gauss-Newton decrement in units of the noise variance).
            if opts.stat_tol > 0.0 && n > q {
                let s2 = st.cost / (n - q) as f64;
                if let Some(dec) = gn_decrement(&h, &g)
                    && dec <= opts.stat_tol * s2
                {
                    break;
                }
            }
            if !st.damped_step(f, opts, (&free, &unit), (&h, &g)) {
                break;
            }
        }
    }
    Ok(LmFit {
        theta: st.theta,
        cost: st.cost,
        n,
        iterations,
        evaluations: st.evaluations,
    })
}

fn out_of_time(opts: &LmOptions) -> bool {
    opts.deadline.is_some_and(|d| Instant::now() >= d)
}

/// A Levenberg-Marquardt fit under way: the parameters with their residuals and cost, the damping, the
/// evaluations spent, the count of small gains in a row, and scratch buffers for a trial step.
struct State {
    theta: Vec<f64>,
    r: Vec<f64>,
    cost: f64,
    lambda: f64,
    evaluations: usize,
    small: usize,
    trial: Vec<f64>,
    rt: Vec<f64>,
}

impl State {
    /// Steps from the normal equations `(h, g)` (in units `unit` of the `free` parameters) with growing
    /// damping until one lowers the cost. Returns whether the fit goes on: not after two small gains in a
    /// row, nor when the damping passes its bound or the evaluations or the time are spent.
    fn damped_step<R: Residuals + ?Sized>(
        &mut self,
        f: &R,
        opts: &LmOptions,
        (free, unit): (&[usize], &[f64]),
        (h, g): (&DMatrix<f64>, &DVector<f64>),
    ) -> bool {
        let q = free.len();
        let dmax = (0..q).map(|a| h[(a, a)]).fold(0.0f64, f64::max);
        if dmax == 0.0 {
            return false;
        }
        loop {
            let mut a = h.clone();
            for d in 0..q {
                a[(d, d)] += self.lambda * (h[(d, d)] + 1e-9 * dmax);
            }
            // Minimising |r(theta + delta)|^2 with r(theta + delta) ~ r + J delta: (J^T J) delta = -J^T r.
            if let Some(delta) = a.cholesky().map(|c| c.solve(&(-g))) {
                self.trial.copy_from_slice(&self.theta);
                for (c, &j) in free.iter().enumerate() {
                    self.trial[j] += delta[c] * unit[c];
                }
                self.evaluations += 1;
                if let Some(c_new) = evaluate(f, &self.trial, &mut self.rt)
                    && self.rt.len() == self.r.len()
                    && c_new < self.cost
                {
                    return self.accept(c_new, opts.rel_tol);
                }
            }
            self.lambda *= 4.0;
            if self.lambda > opts.lambda_max
                || self.evaluations >= opts.max_evals
                || out_of_time(opts)
            {
                return false;
            }
        }
    }

    /// Take the trial step (cost `c_new`) and ease the damping; returns false after the second gain in a row
    /// below `rel_tol` of the cost.
    fn accept(&mut self, c_new: f64, rel_tol: f64) -> bool {
        let gain = self.cost - c_new;
        self.theta.copy_from_slice(&self.trial);
        std::mem::swap(&mut self.r, &mut self.rt);
        self.cost = c_new;
        self.lambda = (self.lambda / 3.0).max(1e-12);
        if gain < rel_tol * self.cost {
            self.small += 1;
            self.small < 2
        } else {
            self.small = 0;
            true
        }
    }
}

/// Forward-difference Jacobian of the residuals at `theta` (residuals `r` there), column-major over the
/// `free` parameters, into `jac`. Returns the evaluations spent.
fn jacobian<R: Residuals + ?Sized>(
    f: &R,
    theta: &[f64],
    r: &[f64],
    typ: &[f64],
    free: &[usize],
    fd_rel: f64,
    jac: &mut [f64],
) -> usize {
    use rayon::prelude::*;
    let n = r.len();
    // One column per task, each into its own slice: the result does not depend on the thread count.
    jac[..n * free.len()]
        .par_chunks_mut(n.max(1))
        .zip(free.par_iter())
        .map(|(col, &j)| {
            let mut trial = theta.to_vec();
            let mut rt = Vec::with_capacity(n);
            let t = if typ[j].is_finite() {
                typ[j].abs()
            } else {
                0.0
            };
            let h0 = fd_rel * (theta[j].abs() + t).max(f64::MIN_POSITIVE);
            let mut evaluations = 0;
            // Forward difference; if theta + h is not a valid model (theta sits on the edge of the valid
            // region), the backward one; if neither, the parameter is locally inert.
            for sign in [1.0, -1.0] {
                trial.copy_from_slice(theta);
                trial[j] += sign * h0;
                let h = trial[j] - theta[j];
                evaluations += 1;
                if h != 0.0 && evaluate(f, &trial, &mut rt).is_some() && rt.len() == n {
                    // r = y - model: d r / d theta = (r(theta + h) - r(theta)) / h.
                    for i in 0..n {
                        col[i] = (rt[i] - r[i]) / h;
                    }
                    return evaluations;
                }
            }
            col.iter_mut().for_each(|v| *v = 0.0);
            evaluations
        })
        .sum()
}

/// Rows of the Jacobian taken together by [`normal_equations`]: a block of every column stays in the caches
/// while all its sums advance over it.
const ROW_BLOCK: usize = 512;

/// Sums [`normal_equations`] advances side by side over a block of rows (independent chains of additions).
const LANES: usize = 4;

/// `J^T J` and `J^T r` of a column-major Jacobian with `q` columns. Each entry is its products summed over
/// the rows in order from -0.0, as `Iterator::sum` adds them, so the result is bit for bit that of summing
/// one pair of columns after another. The rows are taken a block at a time, and over a block [`LANES`]
/// entries of a column advance together: each column is read from memory once per block, not once per pair
/// (a long record's Jacobian is far larger than the caches), and the additions of the entries are
/// independent chains side by side, not one chain each waiting on its last addition.
fn normal_equations(jac: &[f64], r: &[f64], q: usize) -> (DMatrix<f64>, DVector<f64>) {
    let n = r.len();
    // Row a holds the entries (a, b) of the lower triangle for b <= a, then (a, r): the other factor of
    // entry j of row a is column j, or r for j = a + 1.
    let mut sums: Vec<Vec<f64>> = (0..q).map(|a| vec![-0.0; a + 2]).collect();
    for start in (0..n).step_by(ROW_BLOCK) {
        let rows = start..(start + ROW_BLOCK).min(n);
        let other = |a: usize, j: usize| {
            if j <= a {
                &jac[j * n + rows.start..j * n + rows.end]
            } else {
                &r[rows.clone()]
            }
        };
        for (a, row) in sums.iter_mut().enumerate() {
            let ca = other(a, a);
            for j0 in (0..a + 2).step_by(LANES) {
                let m = LANES.min(a + 2 - j0);
                // Past the row's last entry a lane repeats r and is dropped.
                let cols: [&[f64]; LANES] = std::array::from_fn(|l| other(a, (j0 + l).min(a + 1)));
                let mut acc: [f64; LANES] = std::array::from_fn(|l| row[(j0 + l).min(a + 1)]);
                for (i, x) in ca.iter().enumerate() {
                    for l in 0..LANES {
                        acc[l] += x * cols[l][i];
                    }
                }
                row[j0..j0 + m].copy_from_slice(&acc[..m]);
            }
        }
    }
    let h = DMatrix::from_fn(q, q, |a, b| sums[a.max(b)][a.min(b)]);
    let g = DVector::from_fn(q, |a, _| sums[a][a + 1]);
    (h, g)
}

/// `g^T H^-1 g` (the cost decrease a full Gauss-Newton step predicts, up to a factor), `None` when H is
/// singular.
fn gn_decrement(h: &DMatrix<f64>, g: &DVector<f64>) -> Option<f64> {
    let q = g.len();
    let dmax = (0..q).map(|a| h[(a, a)]).fold(0.0f64, f64::max);
    let mut a = h.clone();
    for d in 0..q {
        a[(d, d)] += 1e-12 * dmax;
    }
    let x = a.cholesky()?.solve(g);
    Some(g.dot(&x))
}

/// The covariance `s^2 (J^T J)^-1` of a least-squares estimate at `theta`, with `s^2 = cost / (n - p)`;
/// `None` when the information matrix is singular (a parameter the data do not determine) or the point is
/// not valid.
pub fn covariance<R: Residuals + ?Sized>(
    f: &R,
    theta: &[f64],
    typ: &[f64],
    fd_rel: f64,
) -> Option<DMatrix<f64>> {
    let info = Information::at(f, theta, typ, fd_rel)?;
    // A parameter that leaves the residuals unchanged (a zero diagonal) is one the data do not determine.
    if (0..info.h.nrows()).any(|i| info.h[(i, i)] <= 0.0) {
        return None;
    }
    let s2 = info.s2();
    Some(info.h.cholesky()?.inverse() * s2)
}

/// The residuals at a point, their Jacobian (column-major, one column per parameter) and `J^T J`.
struct Information {
    r: Vec<f64>,
    cost: f64,
    jac: Vec<f64>,
    h: DMatrix<f64>,
}

impl Information {
    /// At `theta`; `None` when the point is not valid or there are no more residuals than parameters.
    fn at<R: Residuals + ?Sized>(f: &R, theta: &[f64], typ: &[f64], fd_rel: f64) -> Option<Self> {
        let p = theta.len();
        let mut r = Vec::new();
        let cost = evaluate(f, theta, &mut r)?;
        let n = r.len();
        if n <= p {
            return None;
        }
        let free: Vec<usize> = (0..p).collect();
        let mut jac = vec![0.0; n * p];
        jacobian(f, theta, &r, typ, &free, fd_rel, &mut jac);
        let (h, _) = normal_equations(&jac, &r, p);
        Some(Self { r, cost, jac, h })
    }

    /// The residual variance `cost / (n - p)`.
    fn s2(&self) -> f64 {
        self.cost / (self.r.len() - self.h.nrows()) as f64
    }
}

/// The variance of a linear combination `w . theta` of a least-squares estimate, two ways.
#[derive(Debug, Clone, PartialEq)]
pub struct CombinationVariance {
    /// `s^2 w^T (J^T J)^-1 w`: right when the residuals are white.
    pub classical: f64,
    /// The sandwich `v^T S v`, `v = (J^T J)^-1 w`, `S` the long-run variance of the scores `(v . J_t) r_t`
    /// ([`autoregressive_sum`]): right when the residuals are autocorrelated (a model that misses something
    /// leaves them so), where the classical one is too small.
    pub sandwich: f64,
    /// The order of the autoregression `S` was read from (0: the scores looked white).
    pub order: usize,
    /// The directions over the parameters (unit vectors) the record does not determine, but for the gauge
    /// the caller holds: empty where `J^T J` is positive definite or singular along the gauge alone. Where
    /// not empty the combination is still determined (else there would be no variance), through the
    /// pseudo-inverse; which parameters the directions move says whether that matters (a saturation limit
    /// the output never reaches, or the parameters of the play itself).
    pub undetermined: Vec<Vec<f64>>,
}

impl CombinationVariance {
    /// Whether the record determines the parameters at `entries` (packed positions): no undetermined
    /// direction moves them by more than rounding.
    pub fn determines(&self, entries: &[usize]) -> bool {
        self.undetermined.iter().all(|d| {
            entries
                .iter()
                .all(|&i| d.get(i).is_none_or(|v| v.abs() <= NULL_PART))
        })
    }
}

/// [`CombinationVariance`] of `w . theta` at `theta`; `None` when the data do not determine `w . theta` (see
/// `solve_determined`) or the point is not valid. Parameters the data do not determine are allowed when the
/// combination does not involve them (a gap's centre that a following friction element absorbs, with its
/// width `c1 + c2` determined), and so is a `gauge` (a direction; empty for none) the data do not determine
/// and the caller holds where `theta` has it: the variance is then that of `w . theta` with `theta` kept off
/// the gauge (a level a friction element does not see, at which the play of unequal slopes is read).
pub fn combination_variance<R: Residuals + ?Sized>(
    f: &R,
    theta: &[f64],
    typ: &[f64],
    fd_rel: f64,
    w: &[f64],
    gauge: &[f64],
) -> Option<CombinationVariance> {
    let p = theta.len();
    if w.len() != p {
        return None;
    }
    let info = Information::at(f, theta, typ, fd_rel)?;
    let s2 = info.s2();
    let Information { r, jac, h, .. } = info;
    let n = r.len();
    let gauge = (gauge.len() == p).then(|| DVector::from_column_slice(gauge));
    let (v, undetermined) = solve_determined(&h, &DVector::from_column_slice(w), gauge.as_ref())?;
    let classical = s2 * v.dot(&DVector::from_column_slice(w));
    // The influence of each sample on w . theta: (v . J_t) r_t.
    let score: Vec<f64> = (0..n)
        .map(|t| (0..p).map(|j| v[j] * jac[j * n + t]).sum::<f64>() * r[t])
        .collect();
    let (long_run, order) = autoregressive_sum(&score);
    // Negative long-run correlation cannot make an estimate more precise than white residuals would.
    let sandwich = long_run.max(classical);
    Some(CombinationVariance {
        classical,
        sandwich,
        order,
        undetermined: undetermined
            .iter()
            .map(|d| d.iter().copied().collect())
            .collect(),
    })
}

/// Relative size (to the largest eigenvalue of `J^T J`) below which a direction counts as undetermined.
const NULL_EIGEN: f64 = 1e-9;
/// Share of the combination's weights that may lie in the undetermined directions (rounding) for it to
/// count as determined.
const NULL_SHARE: f64 = 1e-6;
/// How far (unit vectors) a gauge may lie from the undetermined directions and still count as one of them.
const GAUGE_TOLERANCE: f64 = 1e-6;
/// How much of an undetermined direction (a unit vector) may lie on a parameter (rounding) for the
/// parameter to count as determined.
const NULL_PART: f64 = 1e-6;

/// `v` with `H v = w` for the information matrix `H`, and the directions `H` leaves undetermined but for
/// `gauge` (none where `H` is positive definite): by Cholesky where it is; where it is singular, by the
/// pseudo-inverse, provided `w` has no part in those directions (then `w . theta` is determined even though
/// `theta` is not, and `v` gives its variance) other than along `gauge` where the gauge is one of them (the
/// caller holds theta there); `None` otherwise.
fn solve_determined(
    h: &DMatrix<f64>,
    w: &DVector<f64>,
    gauge: Option<&DVector<f64>>,
) -> Option<(DVector<f64>, Vec<DVector<f64>>)> {
    if let Some(c) = h.clone().cholesky() {
        return Some((c.solve(w), Vec::new()));
    }
    let eig = h.clone().symmetric_eigen();
    let top = eig.eigenvalues.iter().fold(0.0f64, |a, v| a.max(*v));
    if top.is_nan() || top <= 0.0 {
        return None;
    }
    let mut v = DVector::zeros(w.len());
    let mut nulls = Vec::new();
    for (k, lambda) in eig.eigenvalues.iter().enumerate() {
        let q = eig.eigenvectors.column(k);
        if *lambda > NULL_EIGEN * top {
            v += q * (q.dot(w) / lambda);
        } else {
            nulls.push(q.clone_owned());
        }
    }
    let null_part = |x: &DVector<f64>| {
        nulls
            .iter()
            .fold(DVector::zeros(x.len()), |acc, q| acc + q * q.dot(x))
    };
    let mut null_w = null_part(w);
    // A gauge that lies in the undetermined directions takes its part of w, and of each of them, with it.
    let held = gauge
        .and_then(|g| g.try_normalize(0.0))
        .filter(|g| (null_part(g) - g).norm() <= GAUGE_TOLERANCE);
    if let Some(g) = &held {
        null_w -= g * null_w.dot(g);
        for q in &mut nulls {
            *q -= g * q.dot(g);
        }
    }
    let undetermined = nulls
        .into_iter()
        .filter_map(|q| q.try_normalize(GAUGE_TOLERANCE))
        .collect();
    (null_w.norm() <= NULL_SHARE * w.norm()).then_some((v, undetermined))
}

/// How much the residuals' autocorrelation inflates a variance read from them as if white: their long-run
/// sum ([`autoregressive_sum`], the estimate the sandwich's scores use) against their sum of squares (the
/// record's samples over the effective ones), at least 1 (negative correlation is not credited). 1 for
/// residuals that are all zero.
pub fn long_run_inflation(r: &[f64]) -> f64 {
    let c0: f64 = r.iter().map(|v| v * v).sum();
    if c0 <= 0.0 {
        return 1.0;
    }
    (autoregressive_sum(r).0 / c0).max(1.0)
}

/// The highest order [`autoregressive_sum`] tries (and at most the cube root of the series' length).
pub const MAX_AR_ORDER: usize = 12;
/// The largest sum of autoregressive coefficients [`autoregressive_sum`] credits: nearer a unit root the
/// long-run variance would be unbounded (at most `1 / (1 - 0.97)^2`, about 1,100 times the innovations').
pub const MAX_AR_SUM: f64 = 0.97;

/// The long-run sum of the series `s` (`n` times its spectral density at frequency zero: `sum s_t^2` for a
/// white series) read from an autoregression, den Haan and Levin's (1997) estimate: AR(k) by least squares,
/// the order k from 0 to [`MAX_AR_ORDER`] (and the cube root of n) by BIC, then `n sigma_k^2 / (1 - sum
/// phi)^2`, the sum of the coefficients held at [`MAX_AR_SUM`] at most. A kernel (Bartlett) window of the
/// length the residuals decorrelate in underestimates a persistent series' long-run variance by its share of
/// the decay it cuts off or downweights (a third at AR(1) 0.9 with a window of 30 lags); the autoregression
/// carries the whole decay. With the order chosen: (sum, k).
pub fn autoregressive_sum(s: &[f64]) -> (f64, usize) {
    let n = s.len();
    let white: f64 = s.iter().map(|v| v * v).sum();
    let top = MAX_AR_ORDER.min((n as f64).cbrt().floor() as usize);
    let mut best = (bic(white, n, 0), white, 0);
    for k in 1..=top {
        let Some(phi) = ar_ls(s, k) else { break };
        let innovations: f64 = ar_filter(s, &phi).iter().map(|v| v * v).sum();
        let criterion = bic(innovations, n, k);
        if criterion < best.0 {
            let sum: f64 = phi.iter().sum();
            let gain = 1.0 - sum.min(MAX_AR_SUM);
            best = (criterion, innovations / (gain * gain), k);
        }
    }
    (best.1, best.2)
}

/// [`levenberg_marquardt`] from each start; the lowest cost wins. Starts whose simulation fails are skipped.
pub fn fit_multistart<R: Residuals + ?Sized>(
    f: &R,
    starts: &[Vec<f64>],
    typ: &[f64],
    fixed: &[usize],
    opts: &LmOptions,
) -> Result<LmFit, FitError> {
    if starts.is_empty() {
        return Err(FitError::NoStarts);
    }
    let mut best: Option<LmFit> = None;
    for s in starts {
        if let Ok(fit) = levenberg_marquardt(f, s, typ, fixed, opts)
            && best.as_ref().is_none_or(|b| fit.cost < b.cost)
        {
            best = Some(fit);
        }
    }
    best.ok_or(FitError::InvalidStart)
}

/// Bayesian information criterion of a Gaussian least-squares fit: `n ln(cost / n) + k ln n`.
pub fn bic(cost: f64, n: usize, k: usize) -> f64 {
    let nf = n.max(1) as f64;
    nf * (cost.max(f64::MIN_POSITIVE) / nf).ln() + k as f64 * nf.ln()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The normal equations taken a block of rows at a time are bit for bit the sums of each pair of columns
    /// one after another over every row (`Iterator::sum`), on a Jacobian whose length is not a multiple of the
    /// block, with entries of every sign and magnitude; and empty with no columns.
    #[test]
    fn blocked_normal_equations_equal_the_pairwise_sums_bit_for_bit() {
        let (n, q) = (3 * ROW_BLOCK + 37, 5);
        let mut state = 99u64;
        let mut draw = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let v = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            v * 10f64.powi((state % 13) as i32 - 6)
        };
        let jac: Vec<f64> = (0..n * q).map(|_| draw()).collect();
        let r: Vec<f64> = (0..n).map(|_| draw()).collect();
        let (h, g) = normal_equations(&jac, &r, q);
        let col = |a: usize| &jac[a * n..(a + 1) * n];
        for a in 0..q {
            let ga: f64 = col(a).iter().zip(&r).map(|(x, y)| x * y).sum();
            assert_eq!(g[a].to_bits(), ga.to_bits());
            for b in 0..q {
                let (hi, lo) = (a.max(b), a.min(b));
                let v: f64 = col(hi).iter().zip(col(lo)).map(|(x, y)| x * y).sum();
                assert_eq!(h[(a, b)].to_bits(), v.to_bits(), "({a}, {b})");
            }
        }
        let (h0, g0) = normal_equations(&[], &r, 0);
        assert_eq!((h0.len(), g0.len()), (0, 0));
    }

    /// The residuals' inflation: 1 for residuals that alternate in sign (negative correlation is not
    /// credited) and for zeros; near 1 for a pseudo-random sequence; about 9 for AR(1) 0.8 residuals (the
    /// long-run factor (1 + 0.8) / (1 - 0.8) = 9: the autoregression carries the whole decay).
    #[test]
    fn long_run_inflation_counts_effective_samples() {
        let alternating: Vec<f64> = (0..500)
            .map(|k| if k % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        assert_eq!(long_run_inflation(&alternating), 1.0);
        assert_eq!(long_run_inflation(&[0.0; 50]), 1.0);
        let mut state = 12345u64;
        let mut draw = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let white: Vec<f64> = (0..4000).map(|_| draw()).collect();
        let w = long_run_inflation(&white);
        assert!((1.0..1.3).contains(&w), "{w}");
        let mut ar = vec![0.0; 4000];
        for k in 1..ar.len() {
            ar[k] = 0.8 * ar[k - 1] + draw();
        }
        let a = long_run_inflation(&ar);
        assert!((7.0..11.5).contains(&a), "{a}");
    }

    /// A straight line y = a + b t fitted by least squares: the classical variance of b is s^2 / sum (t -
    /// mean t)^2; residuals that alternate in sign (negatively correlated) leave the sandwich at the classical
    /// floor; residuals in long runs of one sign (positively correlated) make it larger.
    #[test]
    fn combination_variance_by_hand() {
        let n = 200;
        let t: Vec<f64> = (0..n).map(|k| k as f64 / n as f64).collect();
        let fit = |noise: &dyn Fn(usize) -> f64| {
            let y: Vec<f64> = (0..n).map(|k| 1.0 + 2.0 * t[k] + noise(k)).collect();
            let f = |th: &[f64], out: &mut Vec<f64>| {
                out.clear();
                out.extend((0..n).map(|k| y[k] - th[0] - th[1] * t[k]));
                true
            };
            let lm = levenberg_marquardt(&f, &[0.0, 0.0], &[1.0, 1.0], &[], &LmOptions::default())
                .unwrap();
            let v =
                combination_variance(&f, &lm.theta, &[1.0, 1.0], 1e-6, &[0.0, 1.0], &[]).unwrap();
            let tm = t.iter().sum::<f64>() / n as f64;
            let sxx: f64 = t.iter().map(|v| (v - tm) * (v - tm)).sum();
            (v, lm.cost / (n - 2) as f64 / sxx)
        };
        let (alternating, by_hand) = fit(&|k| if k % 2 == 0 { 0.1 } else { -0.1 });
        assert!(
            (alternating.classical / by_hand - 1.0).abs() < 1e-4,
            "{alternating:?} {by_hand}"
        );
        assert_eq!(alternating.sandwich, alternating.classical);
        let (runs, _) = fit(&|k| if (k / 20) % 2 == 0 { 0.1 } else { -0.1 });
        assert!(runs.sandwich > 4.0 * runs.classical, "{runs:?}");
        assert!(runs.order >= 1, "{runs:?}");
    }

    /// The autoregressive long-run sum: a white series' own sum of squares (order 0); an AR(1) series with
    /// coefficient 0.8 about `(1 / (1 - 0.8))^2 = 25` times its innovations' (order 1 or a little more); a
    /// random walk's held at the largest sum credited.
    #[test]
    fn the_long_run_sum_carries_the_whole_decay() {
        use rand_chacha::ChaCha8Rng;
        use rand_core::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let white: Vec<f64> = (0..4000).map(|_| StandardNormal.sample(&mut rng)).collect();
        let (sum, order) = autoregressive_sum(&white);
        let squares: f64 = white.iter().map(|v| v * v).sum();
        assert_eq!((sum, order), (squares, 0));
        let mut ar = vec![0.0; white.len()];
        for k in 1..ar.len() {
            ar[k] = 0.8 * ar[k - 1] + white[k];
        }
        let (sum, order) = autoregressive_sum(&ar);
        assert!((1..=3).contains(&order), "{order}");
        assert!((sum / squares - 25.0).abs() < 5.0, "{}", sum / squares);
        let walk: Vec<f64> = white
            .iter()
            .scan(0.0, |a, v| {
                *a += v;
                Some(*a)
            })
            .collect();
        let (sum, _) = autoregressive_sum(&walk);
        let cap = 1.0 / (1.0 - MAX_AR_SUM).powi(2);
        assert!(sum / squares <= 1.05 * cap, "{}", sum / squares);
    }

    /// y = 3 t on 100 samples of t in [0, 1), with a small deterministic error.
    fn slope_record() -> (Vec<f64>, Vec<f64>) {
        let n = 100;
        let t: Vec<f64> = (0..n).map(|k| k as f64 / n as f64).collect();
        let y: Vec<f64> = (0..n)
            .map(|k| 3.0 * t[k] + if k % 3 == 0 { 0.1 } else { -0.05 })
            .collect();
        (t, y)
    }

    /// Two parameters that enter only as their sum (y = (a + b) t): their sum's variance is that of a
    /// single slope, by the pseudo-inverse, while their difference is undetermined; a parameter the
    /// residuals ignore does not hide the others.
    #[test]
    fn a_determined_combination_of_undetermined_parameters_has_a_variance() {
        let (t, y) = slope_record();
        let n = t.len();
        let f = |th: &[f64], out: &mut Vec<f64>| {
            out.clear();
            out.extend((0..n).map(|k| y[k] - (th[0] + th[1]) * t[k]));
            true
        };
        let theta = [1.0, 2.0, 7.0];
        let typ = [1.0; 3];
        let sum = combination_variance(&f, &theta, &typ, 1e-6, &[1.0, 1.0, 0.0], &[]).unwrap();
        assert!(!sum.undetermined.is_empty());
        let single = |th: &[f64], out: &mut Vec<f64>| {
            out.clear();
            out.extend((0..n).map(|k| y[k] - th[0] * t[k]));
            true
        };
        let one = combination_variance(&single, &[3.0], &[1.0], 1e-6, &[1.0], &[]).unwrap();
        assert!(one.undetermined.is_empty());
        // s^2 = cost / (n - p) counts three parameters against one.
        let dof = (n - 1) as f64 / (n - 3) as f64;
        assert!(
            (sum.classical / one.classical / dof - 1.0).abs() < 1e-6,
            "{sum:?} {one:?}"
        );
        assert!(combination_variance(&f, &theta, &typ, 1e-6, &[1.0, -1.0, 0.0], &[]).is_none());
        assert!(combination_variance(&f, &theta, &typ, 1e-6, &[0.0, 0.0, 1.0], &[]).is_none());
        assert!(covariance(&f, &theta, &typ, 1e-6).is_none());
        // What counts as undetermined is relative to the best-determined direction: the same record in
        // other units (residuals 1e-4 and 1e4 times as large) gives the same variance.
        for scale in [1e-4, 1e4] {
            let scaled = |th: &[f64], out: &mut Vec<f64>| {
                f(th, out);
                out.iter_mut().for_each(|v| *v *= scale);
                true
            };
            let w = [1.0, 1.0, 0.0];
            let v = combination_variance(&scaled, &theta, &typ, 1e-6, &w, &[]).unwrap();
            assert!(
                (v.classical / sum.classical - 1.0).abs() < 1e-6,
                "{scale}: {v:?}"
            );
        }
    }

    /// A gauge the data do not determine, held by the caller, takes its part of the combination: th[0] alone
    /// is undetermined (only th[0] + th[1] is), but with th[0] - th[1] held it is half the sum, with a
    /// quarter of the sum's variance, and every other parameter counts as determined unless another
    /// direction is undetermined too; a gauge that is determined, or not the undetermined direction the
    /// combination has a part in, changes nothing.
    #[test]
    fn a_held_gauge_determines_the_rest() {
        let (t, y) = slope_record();
        let n = t.len();
        let f = |th: &[f64], out: &mut Vec<f64>| {
            out.clear();
            out.extend((0..n).map(|k| y[k] - (th[0] + th[1]) * t[k] - th[2]));
            true
        };
        let (theta, typ) = ([1.0, 2.0, 0.0], [1.0; 3]);
        let var = |w: &[f64], gauge: &[f64]| combination_variance(&f, &theta, &typ, 1e-6, w, gauge);
        let sum = var(&[1.0, 1.0, 0.0], &[]).unwrap();
        assert!(var(&[1.0, 0.0, 0.0], &[]).is_none());
        let first = var(&[1.0, 0.0, 0.0], &[2.0, -2.0, 0.0]).unwrap();
        assert!(
            first.undetermined.is_empty(),
            "the gauge is the one undetermined direction"
        );
        assert!(
            (first.classical / sum.classical - 0.25).abs() < 1e-6,
            "{first:?} {sum:?}"
        );
        let held = var(&[1.0, -1.0, 0.0], &[1.0, -1.0, 0.0]).unwrap();
        assert!(held.classical < 1e-12 * sum.classical, "{held:?}");
        assert!(var(&[1.0, 0.0, 0.0], &[1.0, 1.0, 0.0]).is_none());
        assert!(var(&[1.0, 0.0, 0.0], &[0.0, 0.0, 1.0]).is_none());
        assert!(var(&[1.0, 0.0, 0.0], &[1.0, -1.0]).is_none());
        // A parameter the residuals ignore beside the gauge: the combination is still read, but not every
        // parameter is determined.
        let ignored = |th: &[f64], out: &mut Vec<f64>| f(&th[..3], out);
        let four = combination_variance(
            &ignored,
            &[1.0, 2.0, 0.0, 5.0],
            &[1.0; 4],
            1e-6,
            &[1.0, 0.0, 0.0, 0.0],
            &[1.0, -1.0, 0.0, 0.0],
        )
        .unwrap();
        assert!(!four.undetermined.is_empty());
        // ... the one it ignores: the others are determined.
        assert!(four.determines(&[0, 1, 2]) && !four.determines(&[3]));
        // s^2 counts four parameters against three.
        let dof = (n - 3) as f64 / (n - 4) as f64;
        assert!((four.classical / first.classical / dof - 1.0).abs() < 1e-6);
    }

    #[test]
    fn fits_an_exponential() {
        // y = 2 exp(-0.3 t) + 0.5, exact data.
        let t: Vec<f64> = (0..50).map(|k| k as f64 * 0.2).collect();
        let y: Vec<f64> = t.iter().map(|t| 2.0 * (-0.3 * t).exp() + 0.5).collect();
        let f = |th: &[f64], out: &mut Vec<f64>| {
            out.extend(
                t.iter()
                    .zip(&y)
                    .map(|(t, y)| y - (th[0] * (-th[1] * t).exp() + th[2])),
            );
            true
        };
        let fit = levenberg_marquardt(&f, &[1.0, 1.0, 0.0], &[1.0; 3], &[], &LmOptions::default())
            .unwrap();
        assert!((fit.theta[0] - 2.0).abs() < 1e-6, "{:?}", fit.theta);
        assert!((fit.theta[1] - 0.3).abs() < 1e-6);
        assert!((fit.theta[2] - 0.5).abs() < 1e-6);
    }

    /// x^2 = 4 and x + y = 5 as residuals (solution x = 2, y = 3 from a positive start).
    fn two_equations(th: &[f64], out: &mut Vec<f64>) -> bool {
        out.extend([th[0] * th[0] - 4.0, th[0] + th[1] - 5.0]);
        true
    }

    /// As many residuals as free parameters (no noise variance to judge a step by): the statistical stop
    /// does not apply and the fit solves the equations. Here x^2 = 4, x + y = 5 from (1, 1).
    #[test]
    fn an_exactly_determined_problem_is_solved() {
        let f = two_equations;
        let opts = LmOptions::default();
        assert!(opts.stat_tol > 0.0);
        let fit = levenberg_marquardt(&f, &[1.0, 1.0], &[1.0; 2], &[], &opts).unwrap();
        assert!((fit.theta[0] - 2.0).abs() < 1e-6, "{:?}", fit.theta);
        assert!((fit.theta[1] - 3.0).abs() < 1e-6, "{:?}", fit.theta);
    }

    /// A typical magnitude of 0 or infinity says nothing: the parameter's unit is 1 and the same equations
    /// are solved.
    #[test]
    fn zero_and_infinite_typical_magnitudes_count_as_one() {
        let f = two_equations;
        let opts = LmOptions::default();
        let fit = levenberg_marquardt(&f, &[1.0, 1.0], &[0.0, f64::INFINITY], &[], &opts).unwrap();
        assert!((fit.theta[0] - 2.0).abs() < 1e-6, "{:?}", fit.theta);
        assert!((fit.theta[1] - 3.0).abs() < 1e-6, "{:?}", fit.theta);
    }

    /// The small-gain stop needs two accepted steps in a row: on r = theta^3 from 1 every Gauss-Newton
    /// step keeps about 2/3 of theta, so each gain is about ten times the new cost; with `rel_tol` 100
    /// every accepted step is small and the fit ends after the second, with `rel_tol` 0 it goes on.
    #[test]
    fn the_small_gain_stop_needs_two_small_steps_in_a_row() {
        let f = |th: &[f64], out: &mut Vec<f64>| {
            out.push(th[0].powi(3));
            true
        };
        let opts = |rel_tol| LmOptions {
            rel_tol,
            stat_tol: 0.0,
            ..LmOptions::default()
        };
        let two = levenberg_marquardt(&f, &[1.0], &[1.0], &[], &opts(100.0)).unwrap();
        assert_eq!(two.iterations, 2, "{two:?}");
        assert!((two.theta[0] - 4.0 / 9.0).abs() < 0.01, "{two:?}");
        let on = levenberg_marquardt(&f, &[1.0], &[1.0], &[], &opts(0.0)).unwrap();
        assert!(on.iterations > 10, "{on:?}");
    }

    #[test]
    fn fixed_parameters_stay_and_invalid_region_is_avoided() {
        let x: Vec<f64> = (0..30).map(|k| k as f64 / 10.0).collect();
        // Model y = a sqrt(b) x, only valid for b >= 0; truth a = 1 with b fixed at 4.
        let y: Vec<f64> = x.iter().map(|x| 2.0 * x).collect();
        let f = |th: &[f64], out: &mut Vec<f64>| {
            if th[1] < 0.0 {
                return false;
            }
            out.extend(x.iter().zip(&y).map(|(x, y)| y - th[0] * th[1].sqrt() * x));
            true
        };
        let fit =
            levenberg_marquardt(&f, &[0.1, 4.0], &[1.0, 1.0], &[1], &LmOptions::default()).unwrap();
        assert_eq!(fit.theta[1], 4.0);
        assert!((fit.theta[0] - 1.0).abs() < 1e-6);
        assert_eq!(
            levenberg_marquardt(&f, &[0.1, -1.0], &[1.0, 1.0], &[], &LmOptions::default()),
            Err(FitError::InvalidStart)
        );
    }

    #[test]
    fn multistart_keeps_the_best() {
        // A cost with two minima in theta: r = (theta^2 - 1)(theta - 3) scaled; the global one at 1 or -1.
        let f = |th: &[f64], out: &mut Vec<f64>| {
            let t = th[0];
            out.push((t * t - 1.0) * (t - 3.0) * 0.1 + 0.01 * (t - 3.0));
            out.push(0.3 * (t - 1.0));
            true
        };
        let fit = fit_multistart(
            &f,
            &[vec![4.0], vec![0.5]],
            &[1.0],
            &[],
            &LmOptions::default(),
        )
        .unwrap();
        assert!((fit.theta[0] - 1.0).abs() < 0.2, "{:?}", fit.theta);
    }

    #[test]
    fn bic_penalises_parameters() {
        assert!(bic(10.0, 100, 3) > bic(10.0, 100, 2));
        assert!(bic(9.0, 100, 3) < bic(10.0, 100, 2));
    }

    // A straight line with a deterministic wobble: y = 1 + 2 x + 0.1 sin(2.7 k), x = k / 10, k = 0..50,
    // fitted by r = y - (a + b x). Reference by NumPy (`np.linalg.lstsq`, cost / (n - p) (X^T X)^-1).
    const LINE_THETA: [f64; 2] = [1.0005955384260365, 1.9999037249863612];
    const LINE_COST: f64 = 0.24902251030682418;
    const LINE_COV: [f64; 4] = [
        0.0004028305313786861,
        -0.00012206985799354119,
        -0.00012206985799354119,
        4.9824431834098444e-05,
    ];

    fn line_residuals(th: &[f64], out: &mut Vec<f64>) -> bool {
        out.extend((0..50).map(|k| {
            let x = f64::from(k) / 10.0;
            1.0 + 2.0 * x + 0.1 * (2.7 * f64::from(k)).sin() - (th[0] + th[1] * x)
        }));
        true
    }

    #[test]
    fn covariance_of_a_straight_line_matches_numpy() {
        let cov = covariance(&line_residuals, &LINE_THETA, &[1.0, 1.0], 1e-6).unwrap();
        for (c, want) in cov.iter().zip(LINE_COV) {
            assert!((c - want).abs() < 1e-6 * want.abs(), "{cov}");
        }
        // No more residuals than parameters, a parameter the residuals do not depend on, an invalid point:
        // no covariance.
        let two = |th: &[f64], out: &mut Vec<f64>| {
            out.extend([th[0] - 1.0, th[1] - 2.0]);
            true
        };
        assert_eq!(covariance(&two, &[0.0, 0.0], &[1.0, 1.0], 1e-6), None);
        let inert = |th: &[f64], out: &mut Vec<f64>| {
            out.extend((0..10).map(|k| f64::from(k) - th[0]));
            true
        };
        assert_eq!(covariance(&inert, &[0.0, 5.0], &[1.0, 1.0], 1e-6), None);
        let invalid = |_: &[f64], _: &mut Vec<f64>| false;
        assert_eq!(covariance(&invalid, &[0.0], &[1.0], 1e-6), None);
    }

    /// From two standard errors away (sqrt(4.03e-4) = 0.0201 in a) the Gauss-Newton decrement is 4 s^2, far
    /// above stat_tol s^2 = 0.01 s^2: the fit moves to the least-squares point; there the decrement is
    /// negligible and it stops.
    #[test]
    fn the_statistical_stop_needs_a_negligible_step() {
        let se_a = LINE_COV[0].sqrt();
        let start = [LINE_THETA[0] + 2.0 * se_a, LINE_THETA[1]];
        let fit = levenberg_marquardt(
            &line_residuals,
            &start,
            &[1.0, 1.0],
            &[],
            &LmOptions::default(),
        )
        .unwrap();
        for (t, want) in fit.theta.iter().zip(LINE_THETA) {
            assert!((t - want).abs() < 0.01 * se_a, "{:?}", fit.theta);
        }
        // Within 0.01 standard errors of the minimum the cost is within 1e-4 s^2 of it (s^2 = cost / 48).
        assert!(
            (fit.cost - LINE_COST).abs() < 1e-5 * LINE_COST,
            "{}",
            fit.cost
        );
        assert_eq!(fit.n, 50);
        // Started at the least-squares point, it stops at the first check, without a step.
        let there = levenberg_marquardt(
            &line_residuals,
            &LINE_THETA,
            &[1.0, 1.0],
            &[],
            &LmOptions::default(),
        )
        .unwrap();
        assert_eq!((there.iterations, there.evaluations), (1, 3));
    }

    /// Counting: one Jacobian is one evaluation per free parameter (forward differences succeed on a valid
    /// line), so a single iteration from (0, 0) costs the start, 2 columns and one accepted trial step.
    #[test]
    fn evaluations_are_counted() {
        let opts = LmOptions {
            max_iter: 1,
            ..LmOptions::default()
        };
        let fit =
            levenberg_marquardt(&line_residuals, &[0.0, 0.0], &[1.0, 1.0], &[], &opts).unwrap();
        assert_eq!((fit.iterations, fit.evaluations), (1, 4));
        // One step from the undamped Gauss-Newton point (damping 1e-3 of the diagonal): within 1% of the way.
        assert!(
            (fit.theta[1] - LINE_THETA[1]).abs() < 0.01 * LINE_THETA[1],
            "{:?}",
            fit.theta
        );
        // With b fixed, one column.
        let fit =
            levenberg_marquardt(&line_residuals, &[0.0, 2.0], &[1.0, 1.0], &[1], &opts).unwrap();
        assert_eq!((fit.iterations, fit.evaluations), (1, 3));
        assert_eq!(fit.theta[1], 2.0);
        // Everything fixed: no iteration, the start's cost.
        let fit =
            levenberg_marquardt(&line_residuals, &LINE_THETA, &[1.0, 1.0], &[0, 1], &opts).unwrap();
        assert_eq!((fit.iterations, fit.evaluations), (0, 1));
        assert!((fit.cost - LINE_COST).abs() < 1e-9);
    }

    #[test]
    fn bic_by_hand_and_multistart_refusals() {
        // 100 ln(10 / 100) + 3 ln 100 = -216.442998741...
        assert!((bic(10.0, 100, 3) + 216.44299874144028).abs() < 1e-9);
        let f = |th: &[f64], out: &mut Vec<f64>| {
            out.push(th[0]);
            th[0] > 0.0
        };
        let opts = LmOptions::default();
        assert_eq!(
            fit_multistart(&f, &[], &[1.0], &[], &opts),
            Err(FitError::NoStarts)
        );
        assert_eq!(
            fit_multistart(&f, &[vec![-1.0], vec![-2.0]], &[1.0], &[], &opts),
            Err(FitError::InvalidStart)
        );
        // Of two starts that cannot move (the parameter fixed), the lower cost wins.
        let fit =
            fit_multistart(&f, &[vec![3.0], vec![2.0], vec![4.0]], &[1.0], &[0], &opts).unwrap();
        assert_eq!(fit.theta, vec![2.0]);
        assert_eq!(fit.cost, 4.0);
    }

    /// At the edge of the valid region the Jacobian takes the backward difference: a residual function that
    /// fills its output and then reports the point invalid is not used. The line y = t x at t = 1 with
    /// residuals +-0.5 on x = 1..20: s^2 = 20 * 0.25 / 19, sum x^2 = 20 * 21 * 41 / 6 = 2870, so the variance
    /// of t is s^2 / 2870 (the backward difference of a linear residual is exact up to rounding).
    #[test]
    fn jacobian_takes_the_backward_difference_at_the_edge_of_the_valid_region() {
        let x: Vec<f64> = (1..=20).map(f64::from).collect();
        let y: Vec<f64> = x
            .iter()
            .enumerate()
            .map(|(i, v)| v + if i % 2 == 0 { 0.5 } else { -0.5 })
            .collect();
        let f = |th: &[f64], out: &mut Vec<f64>| {
            if th[0] > 1.0 {
                out.extend(std::iter::repeat_n(1e6, x.len()));
                return false;
            }
            out.extend(y.iter().zip(&x).map(|(a, b)| a - th[0] * b));
            true
        };
        let cov = covariance(&f, &[1.0], &[1.0], 1e-6).unwrap();
        let want = (20.0 * 0.25 / 19.0) / 2870.0;
        assert!((cov[(0, 0)] - want).abs() < 1e-6 * want, "{cov} vs {want}");
    }
}
