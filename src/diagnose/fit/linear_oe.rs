//! The linear output-error model of one structure, fitted cheaply: what the structure selection ranks every
//! structure by (its free-run simulation error), instead of the equation error of a least-squares fit.
//!
//! The model is `y^(k) = x(k) + c` with `x(k) = -sum_i a_i x(k-i) + sum_j b_j v(k-d-j)`, `v = u - u_rest`
//! (the input measured from the level the record rests at, so that rest at `u_rest` is rest at 0 here and the
//! constant `c` absorbs the steady state). Its sensitivities are filtered signals, exactly:
//!
//! ```text
//! d y^(k) / d b_j =  f(k-d-j),   f = v / A(q)
//! d y^(k) / d a_i = -g(k-i),     g = x / A(q)
//! d y^(k) / d c   =  1
//! ```
//!
//! so a Gauss-Newton iteration costs three passes over the samples and the normal equations; the
//! Levenberg-Marquardt damping keeps every accepted step stable and cost-decreasing. Started from the
//! equation-error least-squares fit (stabilised) and from its FIR part, a few iterations are enough to rank
//! structures: the ranking then rewards the structure that simulates well, which on a record sampled far
//! faster than its dynamics is not the one that predicts one step ahead well.

use nalgebra::{DMatrix, DVector};

use crate::plant::linear::is_stable;

/// Levenberg-Marquardt iterations of a ranking fit.
pub const RANK_ITER: usize = 12;

/// A linear output-error model: `a` (na), `b` (nb + 1), the constant `c`, for inputs measured from `u_rest`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct LinearOe {
    pub a: Vec<f64>,
    pub b: Vec<f64>,
    pub c: f64,
}

/// The data of a fit: input measured from its rest level, output, delay, samples `0..n` fitted.
pub(crate) struct Data<'a> {
    pub v: &'a [f64],
    pub y: &'a [f64],
    pub delay: usize,
    pub n: usize,
}

/// `x` of the model on `v` over samples `0..n` (0 before the first sample).
pub(crate) fn simulate(m: &LinearOe, v: &[f64], delay: usize, n: usize) -> Vec<f64> {
    let mut x = vec![0.0; n];
    for k in 0..n {
        let mut s = 0.0;
        for (i, a) in m.a.iter().enumerate() {
            if k > i {
                s -= a * x[k - 1 - i];
            }
        }
        for (j, b) in m.b.iter().enumerate() {
            if k >= delay + j {
                s += b * v[k - delay - j];
            }
        }
        x[k] = s;
    }
    x
}

/// `s / A(q)`: `f(k) = s(k) - sum_i a_i f(k-i)`.
fn filtered(a: &[f64], s: &[f64]) -> Vec<f64> {
    let mut f = vec![0.0; s.len()];
    for k in 0..s.len() {
        let mut v = s[k];
        for (i, ai) in a.iter().enumerate() {
            if k > i {
                v -= ai * f[k - 1 - i];
            }
        }
        f[k] = v;
    }
    f
}

/// The fit-part cost (sum of squared output errors) of `m`.
fn cost(m: &LinearOe, d: &Data) -> f64 {
    let x = simulate(m, d.v, d.delay, d.n);
    x.iter()
        .zip(&d.y[..d.n])
        .map(|(x, y)| (y - x - m.c).powi(2))
        .sum()
}

/// The normal equations `J^T J`, `J^T r` at `m`.
fn normal_equations(m: &LinearOe, d: &Data) -> (DMatrix<f64>, DVector<f64>) {
    let (na, nb1) = (m.a.len(), m.b.len());
    let p = na + nb1 + 1;
    let x = simulate(m, d.v, d.delay, d.n);
    let f = filtered(&m.a, &d.v[..d.n]);
    let g = filtered(&m.a, &x);
    let mut h = DMatrix::<f64>::zeros(p, p);
    let mut rhs = DVector::<f64>::zeros(p);
    let mut row = vec![0.0; p];
    for k in 0..d.n {
        for (i, r) in row.iter_mut().take(na).enumerate() {
            *r = if k > i { -g[k - 1 - i] } else { 0.0 };
        }
        for j in 0..nb1 {
            row[na + j] = if k >= d.delay + j {
                f[k - d.delay - j]
            } else {
                0.0
            };
        }
        row[p - 1] = 1.0;
        let r = d.y[k] - x[k] - m.c;
        for a in 0..p {
            rhs[a] += row[a] * r;
            for b in 0..=a {
                h[(a, b)] += row[a] * row[b];
            }
        }
    }
    for a in 0..p {
        for b in a + 1..p {
            h[(a, b)] = h[(b, a)];
        }
    }
    (h, rhs)
}

/// `m` moved by `delta` (the layout a, b, c).
fn moved(m: &LinearOe, delta: &DVector<f64>) -> LinearOe {
    let na = m.a.len();
    let nb1 = m.b.len();
    LinearOe {
        a: (0..na).map(|i| m.a[i] + delta[i]).collect(),
        b: (0..nb1).map(|j| m.b[j] + delta[na + j]).collect(),
        c: m.c + delta[na + nb1],
    }
}

/// Levenberg-Marquardt from `start` for at most `max_iter` iterations; every accepted step is stable and
/// lowers the cost. Returns the model and its cost (`None` when the start is unstable or not finite).
pub(crate) fn fit(start: LinearOe, d: &Data, max_iter: usize) -> Option<(LinearOe, f64)> {
    if !is_stable(&start.a) {
        return None;
    }
    let mut m = start;
    let mut c = cost(&m, d);
    if !c.is_finite() {
        return None;
    }
    let mut lambda = 1e-3;
    let (mut h, mut g) = normal_equations(&m, d);
    let mut iter = 0;
    while iter < max_iter && lambda < 1e10 && c > 0.0 {
        iter += 1;
        let mut damped = h.clone();
        for i in 0..damped.nrows() {
            damped[(i, i)] += lambda * h[(i, i)].max(1e-12);
        }
        let Some(delta) = damped.cholesky().map(|ch| ch.solve(&g)) else {
            lambda *= 10.0;
            continue;
        };
        let trial = moved(&m, &delta);
        let tc = if is_stable(&trial.a) {
            cost(&trial, d)
        } else {
            f64::INFINITY
        };
        if tc.is_finite() && tc < c {
            let gain = (c - tc) / c;
            m = trial;
            c = tc;
            lambda = (lambda / 3.0).max(1e-9);
            if gain < 1e-7 {
                break;
            }
            (h, g) = normal_equations(&m, d);
        } else {
            lambda *= 4.0;
        }
    }
    Some((m, c))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A slow first-order block (pole 0.98) with output noise: the fit from a poor start reaches the true
    /// coefficients, and the sensitivities are those of central differences.
    #[test]
    fn a_slow_block_is_recovered_from_a_poor_start() {
        let n = 3000;
        let v: Vec<f64> = (0..n)
            .map(|k| if (k / 40) % 3 == 0 { 1.0 } else { -0.5 })
            .collect();
        let truth = LinearOe {
            a: vec![-0.98],
            b: vec![0.04],
            c: 0.3,
        };
        let x = simulate(&truth, &v, 2, n);
        let y: Vec<f64> = x
            .iter()
            .enumerate()
            .map(|(k, x)| x + 0.3 + 0.01 * ((k * 7919) % 13) as f64 / 13.0 - 0.005)
            .collect();
        let d = Data {
            v: &v,
            y: &y,
            delay: 2,
            n,
        };
        let start = LinearOe {
            a: vec![-0.5],
            b: vec![0.2],
            c: 0.0,
        };
        let (m, _) = fit(start, &d, 60).unwrap();
        assert!((m.a[0] + 0.98).abs() < 1e-3, "{m:?}");
        assert!((m.b[0] - 0.04).abs() < 2e-3, "{m:?}");
        // Sensitivities against central differences at a point off the optimum.
        let at = LinearOe {
            a: vec![-0.9],
            b: vec![0.1],
            c: 0.1,
        };
        let (h, g) = normal_equations(&at, &d);
        let eps = 1e-6;
        for i in 0..3 {
            let mut delta = DVector::zeros(3);
            delta[i] = eps;
            let up = cost(&moved(&at, &delta), &d);
            let down = cost(&moved(&at, &(-delta)), &d);
            // d cost / d theta_i = -2 (J^T r)_i.
            let numeric = (up - down) / (2.0 * eps);
            assert!(
                (numeric + 2.0 * g[i]).abs() < 1e-4 * (1.0 + numeric.abs()),
                "{i}: {numeric} {}",
                -2.0 * g[i]
            );
            assert!(h[(i, i)] > 0.0);
        }
    }

    /// An unstable start is refused; nothing unstable is ever accepted.
    #[test]
    fn unstable_starts_are_refused() {
        let v = vec![1.0; 50];
        let y = vec![1.0; 50];
        let d = Data {
            v: &v,
            y: &y,
            delay: 1,
            n: 50,
        };
        let bad = LinearOe {
            a: vec![-1.2],
            b: vec![1.0],
            c: 0.0,
        };
        assert!(fit(bad, &d, 5).is_none());
    }
}
