//! The output-error model simulated over a record with its exact sensitivities (the parent module's docs give the
//! equations): the parameter vector with its structure, the simulation's state between samples, and the
//! normal equations `J^T J`, `J^T r` that the fitter and the recursive estimator are built on. No allocation
//! in the simulation loop.

use super::{MAX_P, structure, theta_of};
use crate::identify::mrgia::Estimate;
use crate::plant::{MAX_ORDER, ParamError, check_delay};
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

/// Internal parameter vector with its structure.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub(super) struct Theta {
    pub(super) v: [f64; MAX_P],
    pub(super) na: usize,
    pub(super) nb: usize,
    pub(super) delay: usize,
}

impl Theta {
    pub(super) fn new(est: &Estimate, delay: usize) -> Result<Self, ParamError> {
        let (na, nb) = structure(est)?;
        check_delay(delay)?;
        let mut v = [0.0; MAX_P];
        let flat = theta_of(est);
        v[..flat.len()].copy_from_slice(&flat);
        Ok(Self { v, na, nb, delay })
    }
    pub(super) fn p(&self) -> usize {
        self.na + self.nb + 4
    }
    pub(super) fn im2(&self) -> usize {
        self.na + self.nb + 1
    }
    pub(super) fn estimate(&self) -> Estimate {
        let (na, nb, p) = (self.na, self.nb, self.p());
        Estimate {
            a: self.v[..na].to_vec(),
            b: self.v[na..=na + nb].to_vec(),
            m1: 1.0,
            m2: self.v[p - 3],
            c1: self.v[p - 2],
            c2: self.v[p - 1],
        }
    }
}

/// Samples per mode: up, down, held.
pub(super) type Modes = [usize; 3];

/// The state of the simulated model between samples: x^(k-1..k-4) with their sensitivities, w^(k-1) and
/// dw^(k-1)/dtheta. [`propagate`] runs it over a record; the recursive estimator of [`super::online`] steps it one
/// sample at a time with a theta that changes between samples.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub(super) struct SimState {
    /// Ring of x^(k-1..k-4): slot `(pos + i) & 3` holds lag i + 1.
    pub(super) xh: [f64; MAX_ORDER],
    /// The sensitivities of `xh`, same slots.
    pub(super) dxh: [[f64; MAX_P]; MAX_ORDER],
    pub(super) pos: usize,
    pub(super) w_prev: f64,
    /// dw^(k-1)/dtheta (kept through held samples).
    pub(super) dw: [f64; MAX_P],
}

/// Index of the mode a sample took: up, down, held (the order of [`Modes`]).
pub(super) const UP: usize = 0;
pub(super) const DOWN: usize = 1;
pub(super) const HELD: usize = 2;

impl SimState {
    /// All signals zero (before the first sample, as in the plant).
    pub(super) const ZERO: Self = Self {
        xh: [0.0; MAX_ORDER],
        dxh: [[0.0; MAX_P]; MAX_ORDER],
        pos: 0,
        w_prev: 0.0,
        dw: [0.0; MAX_P],
    };

    /// x^(k) of the last sample stepped (the linear block's output, before the backlash).
    pub(super) fn last_x(&self) -> f64 {
        self.xh[self.pos]
    }

    /// Sample k at `th`, with `u_lag(j)` = u(k - d - j) (0 before the record): returns w^(k) and its mode
    /// ([`UP`], [`DOWN`], [`HELD`]); with `SENS` the sensitivities dw^(k)/dtheta are left in `self.dw`
    /// (otherwise they stay zero). No allocation.
    #[inline(always)]
    pub(super) fn step<const SENS: bool>(
        &mut self,
        th: &Theta,
        u_lag: impl Fn(usize) -> f64,
    ) -> (f64, usize) {
        let (na, nb) = (th.na, th.nb);
        let nl = na + nb + 1;
        let (im2, ic1, ic2) = (nl, nl + 1, nl + 2);
        let v = &th.v;
        let (m2, c1, c2) = (v[im2], v[ic1], v[ic2]);
        let mut x = 0.0;
        let mut dx = [0.0f64; MAX_P];
        for i in 0..na {
            let s = (self.pos + i) & (MAX_ORDER - 1);
            let (ai, xp) = (v[i], self.xh[s]);
            x -= ai * xp;
            if SENS {
                dx[i] -= xp;
                for (q, dh) in dx[..nl].iter_mut().zip(&self.dxh[s][..nl]) {
                    *q -= ai * dh;
                }
            }
        }
        for j in 0..=nb {
            let uu = u_lag(j);
            x += v[na + j] * uu;
            if SENS {
                dx[na + j] += uu;
            }
        }
        let (w, mode) = backlash_step(x, self.w_prev, m2, c1, c2);
        let dw = &mut self.dw;
        if SENS && mode == UP {
            dw[..nl].copy_from_slice(&dx[..nl]);
            dw[im2] = 0.0;
            dw[ic1] = -1.0;
            dw[ic2] = 0.0;
        } else if SENS && mode == DOWN {
            for (o, s) in dw[..nl].iter_mut().zip(&dx[..nl]) {
                *o = m2 * s;
            }
            dw[im2] = x + c2;
            dw[ic1] = 0.0;
            dw[ic2] = m2;
        }
        self.pos = (self.pos + MAX_ORDER - 1) & (MAX_ORDER - 1);
        self.xh[self.pos] = x;
        if SENS {
            self.dxh[self.pos] = dx;
        }
        self.w_prev = w;
        (w, mode)
    }
}

/// The backlash of the model on the linear block's output `x` after the output `w_prev`, with slope `m2` of
/// the lower border and gaps `c1`, `c2`: the output and its mode ([`UP`], [`DOWN`], [`HELD`]).
#[inline(always)]
pub(super) fn backlash_step(x: f64, w_prev: f64, m2: f64, c1: f64, c2: f64) -> (f64, usize) {
    if x > w_prev + c1 {
        (x - c1, UP)
    } else if x < w_prev / m2 - c2 {
        (m2 * (x + c2), DOWN)
    } else {
        (w_prev, HELD)
    }
}

/// Simulate the model over `u`, calling `visit(k, w^(k), dw^(k)/dtheta)` for every sample (the sensitivity
/// slice has p entries; with `SENS = false` it is all zeros and not computed). No allocation. Returns the
/// samples per mode and the state after the last sample.
pub(super) fn propagate_state<const SENS: bool>(
    th: &Theta,
    u: &[f64],
    mut visit: impl FnMut(usize, f64, &[f64]),
) -> (Modes, SimState) {
    let (d, p) = (th.delay, th.p());
    let mut s = SimState::ZERO;
    let mut modes = [0usize; 3];
    for k in 0..u.len() {
        let (w, mode) = s.step::<SENS>(th, |j| if k >= d + j { u[k - d - j] } else { 0.0 });
        modes[mode] += 1;
        visit(k, w, &s.dw[..p]);
    }
    (modes, s)
}

/// [`propagate_state`] without the final state.
pub(super) fn propagate<const SENS: bool>(
    th: &Theta,
    u: &[f64],
    visit: impl FnMut(usize, f64, &[f64]),
) -> Modes {
    propagate_state::<SENS>(th, u, visit).0
}

const _: () = assert!(MAX_ORDER.is_power_of_two());

/// Cost, `J^T J` (upper triangle), `J^T r` and the modes at theta.
#[derive(Debug, Clone, Copy)]
pub(super) struct Normal {
    pub(super) cost: f64,
    pub(super) h: [[f64; MAX_P]; MAX_P],
    pub(super) g: [f64; MAX_P],
    pub(super) modes: Modes,
}

pub(super) fn normal_equations(th: &Theta, u: &[f64], y: &[f64]) -> Normal {
    let p = th.p();
    let mut h = [[0.0f64; MAX_P]; MAX_P];
    let mut g = [0.0f64; MAX_P];
    let mut cost = 0.0;
    let modes = propagate::<true>(th, u, |k, w, dw| {
        let r = y[k] - w;
        cost += r * r;
        for q in 0..p {
            let dq = dw[q];
            g[q] += dq * r;
            for (hr, dr) in h[q][q..p].iter_mut().zip(&dw[q..p]) {
                *hr += dq * dr;
            }
        }
    });
    Normal { cost, h, g, modes }
}

pub(super) fn cost_only(th: &Theta, u: &[f64], y: &[f64]) -> (f64, Modes) {
    let mut cost = 0.0;
    let modes = propagate::<false>(th, u, |k, w, _| {
        let r = y[k] - w;
        cost += r * r;
    });
    (cost, modes)
}

/// The full symmetric `J^T J` as a matrix.
pub(super) fn info_matrix(n: &Normal, p: usize) -> DMatrix<f64> {
    DMatrix::from_fn(p, p, |i, j| if i <= j { n.h[i][j] } else { n.h[j][i] })
}
