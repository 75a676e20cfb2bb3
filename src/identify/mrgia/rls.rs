//! The covariance part of the MRGIA, eqs. (19)-(21) and (18), over a fixed parameter dimension `N`.
//!
//! [`Rls<N>`] holds the estimate theta and the matrix P; [`Core`] is the closed set of dimensions the
//! estimator supports, `N = na + nb + 4` in `4..=12`, so that every per-sample operation works on
//! stack-allocated, fully sized nalgebra matrices (no heap allocation per sample).

use nalgebra::{SMatrix, SVector};
use serde::{Deserialize, Serialize};

/// Largest parameter dimension: na = nb = 4 gives 4 + 5 + 3.
pub(crate) const MAX_N: usize = 12;

/// theta and P for a parameter vector of dimension `N`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct Rls<const N: usize> {
    pub(crate) theta: SVector<f64, N>,
    pub(crate) p: SMatrix<f64, N, N>,
}

impl<const N: usize> Rls<N> {
    pub(crate) fn new(theta0: &[f64], p0: f64) -> Self {
        Self {
            theta: SVector::from_fn(|i, _| theta0[i]),
            p: SMatrix::identity() * p0,
        }
    }

    #[cfg(test)]
    fn load(h: &[f64; MAX_N]) -> SVector<f64, N> {
        SVector::from_fn(|i, _| h[i])
    }

    /// `h^T theta`.
    #[inline]
    pub(crate) fn predict(&self, h: &SVector<f64, N>) -> f64 {
        h.dot(&self.theta)
    }

    /// [`Rls::update_with`] with the regressor in the first `N` entries of `h` (tests).
    #[cfg(test)]
    pub(crate) fn update(
        &mut self,
        h: &[f64; MAX_N],
        e: f64,
        mu: f64,
        sigma: f64,
        p_cap: f64,
    ) -> bool {
        self.update_with(&Self::load(h), e, mu, sigma, p_cap)
    }

    /// One gated update (the `Phi(k) = 1` branch of eqs. (18)-(21)) with prediction error `e`, forgetting
    /// factor `mu` = mu(k) of eq. (30) and noise estimate `sigma` = Sigma(k) of eq. (22):
    ///
    /// ```text
    /// S(k) = h^T P(k-1) h + mu Sigma                                        (19)
    /// K(k) = P(k-1) h / S(k)                                                (20)
    /// P(k) = (1/mu) (I - K h^T) P(k-1) (I - K h^T)^T + Sigma K K^T           (21)
    /// theta(k) = theta(k-1) + K(k) e(k)                                     (18), sign/index typo fixed
    /// ```
    ///
    /// Eq. (21) is read with the braces closing after the first product: then it is exactly the Joseph form
    /// of the Kalman/RLS update with measurement variance `mu Sigma`, divided by `mu`, i.e.
    /// `P(k) = (P(k-1) - P h h^T P / S) / mu`, which is what the appendix's (47)-(48) use. The Joseph form is
    /// evaluated in O(N^2) as two rank-one corrections, `A = P - K (P h)^T`, `B = A - (A h) K^T`, which is
    /// the product `(I - K h^T) P (I - K h^T)^T` without forming it, then symmetrised. (In exact arithmetic
    /// `A h = r K`, so `w = A h - r K` below is the rounding residual that the Joseph form feeds back; the
    /// cheaper `P - v v^T / S` drops it and can lose positive definiteness when `r << h^T P h`, as on
    /// noise-free data with `P(0) = 1e6 I`, so it is not used.)
    ///
    /// Cost for dimension N: three N x N passes (`P h`, `A` fused with `A h`, `B` fused with the
    /// symmetrisation) of one multiply and one add per entry, about `6 N^2` flops, on plain arrays of
    /// columns so that each pass vectorises; no allocation.
    ///
    /// `p_cap` bounds `trace P`: when the update would exceed it, P is scaled down to that trace (a
    /// covariance wind-up guard for directions the data never excite while `mu < 1` inflates P).
    ///
    /// Returns false, leaving theta and P untouched, when `S` is not positive and finite or the result is not
    /// finite (possible only for absurd, overflowing data); the caller then reports no update.
    #[inline]
    pub(crate) fn update_with(
        &mut self,
        h: &SVector<f64, N>,
        e: f64,
        mu: f64,
        sigma: f64,
        p_cap: f64,
    ) -> bool {
        let v = self.p * h; // P h (P symmetric, so also (h^T P)^T)
        let r = mu * sigma;
        let s = h.dot(&v) + r; // (19)
        if !(s > 0.0 && s.is_finite()) {
            return false;
        }
        let k = v / s; // (20)
        let theta = self.theta + k * e; // (18)
        // (21): A = (I - K h^T) P = P - K v^T; B = A (I - K h^T)^T = A - (A h) K^T; P(k) = (B + r K K^T)/mu.
        // The last two steps are one rank-one update with w = A h - r K. Storage is column-major:
        // `a[j][i]` is entry (i, j).
        let (kv, vv, hv) = (&k.data.0[0], &v.data.0[0], &h.data.0[0]);
        let mut a: [[f64; N]; N] = self.p.data.0;
        // A, column by column, with A h accumulated in the same pass (sum over j in order, as a matrix-vector
        // product does).
        let mut ah = [0.0; N];
        for (j, col) in a.iter_mut().enumerate() {
            for (x, ki) in col.iter_mut().zip(kv) {
                *x -= ki * vv[j];
            }
            if j == 0 {
                for (acc, x) in ah.iter_mut().zip(col.iter()) {
                    *acc = x * hv[0];
                }
            } else {
                for (acc, x) in ah.iter_mut().zip(col.iter()) {
                    *acc += x * hv[j];
                }
            }
        }
        let mut w = [0.0; N];
        for ((wi, ahi), ki) in w.iter_mut().zip(&ah).zip(kv) {
            *wi = ahi - ki * r;
        }
        // B = A - w K^T (entry (i, j): a_ij - w_i k_j).
        for (col, kj) in a.iter_mut().zip(kv) {
            for (x, wi) in col.iter_mut().zip(&w) {
                *x -= wi * kj;
            }
        }
        // P(k) = (B + B^T) / (2 mu): symmetric by construction (the sum commutes); the diagonal is B_jj / mu
        // exactly (2 x / 2 is exact).
        let half_inv_mu = 0.5 / mu;
        let mut p = [[0.0; N]; N];
        for (j, col) in p.iter_mut().enumerate() {
            for (i, x) in col.iter_mut().enumerate() {
                *x = (a[j][i] + a[i][j]) * half_inv_mu;
            }
        }
        let mut tr = 0.0;
        for (j, col) in p.iter().enumerate() {
            tr += col[j];
        }
        let mut p = SMatrix::<f64, N, N>::from_data(nalgebra::ArrayStorage(p));
        if tr > p_cap {
            p *= p_cap / tr;
        }
        if !(all_finite(theta.as_slice()) & all_finite(p.as_slice())) {
            return false;
        }
        self.theta = theta;
        self.p = p;
        true
    }
}

/// What to run on the estimator's [`Rls`] at its actual dimension: [`Core::with`] dispatches once per sample
/// and the whole per-sample computation is then compiled for that fixed `N` (no runtime-sized loops, no
/// bounds checks on the regressor, no copy of it between dispatches).
pub(crate) trait WithRls {
    type Out;
    fn run<const N: usize>(self, rls: &mut Rls<N>) -> Self::Out;
}

/// Every entry finite. A fold without short-circuit over the contiguous storage, so that it compiles to a
/// few vector compares (the iterator form with `all` was a quarter of the update's time).
#[inline]
fn all_finite(x: &[f64]) -> bool {
    x.iter().fold(true, |ok, v| ok & v.is_finite())
}

/// [`Rls`] for the supported dimensions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) enum Core {
    N4(Rls<4>),
    N5(Rls<5>),
    N6(Rls<6>),
    N7(Rls<7>),
    N8(Rls<8>),
    N9(Rls<9>),
    N10(Rls<10>),
    N11(Rls<11>),
    N12(Rls<12>),
}

macro_rules! dispatch {
    ($self:expr, $c:ident => $body:expr) => {
        match $self {
            Core::N4($c) => $body,
            Core::N5($c) => $body,
            Core::N6($c) => $body,
            Core::N7($c) => $body,
            Core::N8($c) => $body,
            Core::N9($c) => $body,
            Core::N10($c) => $body,
            Core::N11($c) => $body,
            Core::N12($c) => $body,
        }
    };
}

impl Core {
    /// theta(0) = `theta0` (its length is the dimension, 4..=12), P(0) = p0 I (eq. (31)).
    pub(crate) fn new(theta0: &[f64], p0: f64) -> Self {
        match theta0.len() {
            4 => Core::N4(Rls::new(theta0, p0)),
            5 => Core::N5(Rls::new(theta0, p0)),
            6 => Core::N6(Rls::new(theta0, p0)),
            7 => Core::N7(Rls::new(theta0, p0)),
            8 => Core::N8(Rls::new(theta0, p0)),
            9 => Core::N9(Rls::new(theta0, p0)),
            10 => Core::N10(Rls::new(theta0, p0)),
            11 => Core::N11(Rls::new(theta0, p0)),
            12 => Core::N12(Rls::new(theta0, p0)),
            n => unreachable!("parameter dimension {n} outside 4..=12 (validated before)"),
        }
    }

    pub(crate) fn theta(&self) -> &[f64] {
        dispatch!(self, c => c.theta.as_slice())
    }

    /// P as a row-major vector of length n*n (for tests and diagnostics).
    pub(crate) fn p_rows(&self) -> Vec<f64> {
        dispatch!(self, c => c.p.transpose().as_slice().to_vec())
    }

    /// Run `w` on the [`Rls`] of the actual dimension.
    #[inline]
    pub(crate) fn with<W: WithRls>(&mut self, w: W) -> W::Out {
        dispatch!(self, c => w.run(c))
    }

    /// Overwrite theta (tests: put the estimator in a chosen state).
    #[cfg(test)]
    pub(crate) fn set_theta(&mut self, theta: &[f64]) {
        dispatch!(self, c => c.theta.copy_from_slice(theta))
    }
}
