//! The Levenberg-Marquardt fitter of the output-error model (the parent module's docs, "Algorithm") and the repair
//! of its starting points.

use super::sim::{Normal, Theta, cost_only, info_matrix, normal_equations, propagate};
use super::{M2_MIN, STEP_SE};
use nalgebra::{DMatrix, DVector};

/// lambda above which the optimiser gives up decreasing the cost.
const LAMBDA_MAX: f64 = 1e16;
/// Relative cost tolerance: a step whose actual and predicted decreases are both below `FTOL V` ends the
/// iteration (as MINPACK's ftol). At V = N s^2 a parameter change of e standard errors changes V by about
/// e^2 s^2, so 1e-12 stops at ~1e-4 standard errors for N up to 1e5.
const FTOL: f64 = 1e-12;

/// Outcome of one Levenberg-Marquardt run.
#[derive(Debug, Clone, Copy)]
pub(super) struct Lm {
    pub(super) theta: Theta,
    pub(super) ne: Normal,
    pub(super) iterations: usize,
    pub(super) converged: bool,
}

/// Solve `(H + lambda D) delta = g` with `D = diag(H)` floored at 1e-12 max diag (so that a parameter with
/// no information this iteration still gets a finite, tiny step).
fn lm_step(ne: &Normal, p: usize, lambda: f64) -> Option<DVector<f64>> {
    let dmax = (0..p).map(|i| ne.h[i][i]).fold(0.0, f64::max).max(1e-300);
    let a = DMatrix::from_fn(p, p, |i, j| {
        let v = if i <= j { ne.h[i][j] } else { ne.h[j][i] };
        if i == j {
            v + lambda * v.max(1e-12 * dmax)
        } else {
            v
        }
    });
    let g = DVector::from_iterator(p, ne.g[..p].iter().copied());
    let delta = a.cholesky()?.solve(&g);
    delta.iter().all(|v| v.is_finite()).then_some(delta)
}

/// `g^T H^-1 g` (the decrease of V the undamped Gauss-Newton step predicts), if H is positive definite.
fn gn_decrement(ne: &Normal, p: usize) -> Option<f64> {
    let h = info_matrix(ne, p);
    let g = DVector::from_iterator(p, ne.g[..p].iter().copied());
    let step = h.cholesky()?.solve(&g);
    let d = step.dot(&g);
    d.is_finite().then_some(d)
}

/// The Gauss-Newton step H^-1 g is shorter than STEP_SE standard errors in the metric of the estimate's
/// covariance s^2 H^-1 (g^T H^-1 g <= STEP_SE^2 s^2), `n` samples: a statistical convergence test.
fn step_is_insignificant(ne: &Normal, p: usize, n: usize) -> bool {
    gn_decrement(ne, p).is_some_and(|dec| {
        let s2 = ne.cost / (n - p) as f64;
        dec <= STEP_SE * STEP_SE * s2
    })
}

/// Predicted decrease of the linearised cost for the step `delta` at damping `lambda`:
/// delta^T g + lambda delta^T D delta (> 0).
fn predicted_decrease(ne: &Normal, delta: &DVector<f64>, p: usize, lambda: f64) -> f64 {
    let dmax = (0..p).map(|i| ne.h[i][i]).fold(0.0, f64::max);
    (0..p)
        .map(|i| {
            let dii = ne.h[i][i].max(1e-12 * dmax);
            delta[i] * ne.g[i] + lambda * dii * delta[i] * delta[i]
        })
        .sum()
}

/// The Levenberg-Marquardt damping (Nielsen's update).
struct Damping {
    lambda: f64,
    nu: f64,
}

impl Damping {
    /// After a rejected step: more damping; `false` once it exceeds LAMBDA_MAX (no step can decrease the
    /// cost any more).
    fn reject(&mut self) -> bool {
        self.lambda *= self.nu;
        self.nu *= 2.0;
        self.lambda <= LAMBDA_MAX
    }

    /// After an accepted step with gain ratio `rho` (actual over predicted decrease).
    fn accept(&mut self, rho: f64) {
        self.lambda =
            (self.lambda * (1.0 / 3.0f64).max(1.0 - (2.0 * rho - 1.0).powi(3))).max(1e-15);
        self.nu = 2.0;
    }
}

pub(super) fn levenberg_marquardt(
    th0: Theta,
    u: &[f64],
    y: &[f64],
    max_iter: usize,
    tol: f64,
) -> Lm {
    let p = th0.p();
    let im2 = th0.im2();
    let mut th = th0;
    let mut ne = normal_equations(&th, u, y);
    let mut damping = Damping {
        lambda: 1e-3,
        nu: 2.0,
    };
    let mut converged = false;
    let mut iterations = 0;
    while iterations < max_iter {
        if ne.cost == 0.0 || step_is_insignificant(&ne, p, u.len()) {
            converged = true;
            break;
        }
        iterations += 1;
        let Some(delta) = lm_step(&ne, p, damping.lambda) else {
            if !damping.reject() {
                converged = true;
                break;
            }
            continue;
        };
        let mut trial = th;
        for (t, d) in trial.v[..p].iter_mut().zip(delta.iter()) {
            *t += d;
        }
        let small = (0..p).all(|i| delta[i].abs() <= tol * (th.v[i].abs() + tol));
        let pred = predicted_decrease(&ne, &delta, p, damping.lambda);
        let tn = (trial.v[im2] > M2_MIN).then(|| normal_equations(&trial, u, y));
        let actual = tn.map_or(f64::NEG_INFINITY, |t| ne.cost - t.cost);
        // MINPACK's test: neither the actual nor the predicted relative decrease exceeds FTOL.
        let flat = pred <= FTOL * ne.cost && actual.abs() <= FTOL * ne.cost;
        match tn {
            Some(tn) if tn.cost.is_finite() && tn.cost < ne.cost => {
                damping.accept(if pred > 0.0 { actual / pred } else { 0.0 });
                th = trial;
                ne = tn;
                if small || flat {
                    converged = true;
                    break;
                }
            }
            // Even a negligible step does not decrease the cost: a minimum at the resolution of the
            // (piecewise smooth) cost.
            _ if small || flat => {
                converged = true;
                break;
            }
            _ => {
                if !damping.reject() {
                    converged = true;
                    break;
                }
            }
        }
    }
    Lm {
        theta: th,
        ne,
        iterations,
        converged,
    }
}

/// Repair a starting point (module docs): positive m2, a stable-looking linear block, both borders engaged
/// when the data move that way.
pub(super) fn repair_start(mut th: Theta, u: &[f64], y: &[f64]) -> Theta {
    let p = th.p();
    let im2 = th.im2();
    for i in 0..p {
        if !th.v[i].is_finite() {
            th.v[i] = if i == im2 { 1.0 } else { 0.0 };
        }
    }
    if th.v[im2] <= M2_MIN {
        th.v[im2] = 1.0;
    }
    let y_max = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let bound = 1e3 * (1.0 + y_max);
    let mut w_max = 0.0f64;
    let mut finite = true;
    propagate::<false>(&th, u, |_, w, _| {
        finite &= w.is_finite();
        w_max = w_max.max(w.abs());
    });
    if !finite || w_max > bound {
        th.v[..th.na].iter_mut().for_each(|a| *a = 0.0);
    }
    let rises = y.windows(2).any(|w| w[1] > w[0]);
    let falls = y.windows(2).any(|w| w[1] < w[0]);
    for _ in 0..40 {
        let (_, modes) = cost_only(&th, u, y);
        let need_up = rises && modes[0] == 0 && th.v[p - 2] > 0.0;
        let need_down = falls && modes[1] == 0 && th.v[p - 1] > 0.0;
        if !(need_up || need_down) {
            break;
        }
        if need_up {
            th.v[p - 2] *= 0.5;
        }
        if need_down {
            th.v[p - 1] *= 0.5;
        }
    }
    th
}
