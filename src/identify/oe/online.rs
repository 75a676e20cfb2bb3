//! On-line output-error estimation at the Cramer-Rao bound: MRGIA's `refine` setting.
//!
//! [`Refined`] is a recursive prediction-error estimator (recursive Gauss-Newton) of the output-error model of
//! [`super`], on the *simulated* output, with the exact sensitivities of that module, started from an
//! output-error fit of a warm-up record. It processes one sample at a time with bounded work and no
//! allocation once started, and reports standard errors from the same Fisher information as [`super::fit`].
//!
//! # Phases
//!
//! 1. **Warm-up** (the first [`WARMUP`] samples): the plain MRGIA estimator of the given settings runs, and
//!    its estimate is the output. The last [`WARMUP`] samples are kept in a fixed ring.
//! 2. **Start**, once, after sample [`WARMUP`]: [`super::fit_from`] on the warm-up record, from the running
//!    MRGIA estimate and the starts of [`super::fit`] (MRGIA recommended and paper settings on the record,
//!    and the recommended estimate with halved gaps); the estimate is projected into the valid region (below).
//!    The recursion then starts from that estimate with `P = (J^T J)^-1` (the inverse Fisher information of
//!    the warm-up record without the noise variance), the cost `V` of the fit and the simulated model's state
//!    (output, linear block, sensitivities) at the end of the record. If the record does not excite the
//!    parameters (the output does not move both ways, or the fit fails), the start is tried again on the next
//!    [`WARMUP`] samples (the record then starts from a non-zero state, a transient the fit absorbs); the
//!    estimator stays plain MRGIA meanwhile.
//! 3. **Recursion**, per sample k with the estimate theta(k-1):
//!
//! ```text
//! w^(k), psi(k) = dw^(k)/dtheta      simulated model and sensitivities stepped with theta(k-1)
//! e(k)   = y(k) - w^(k)               output (prediction) error, reported as e, w^ as y_hat
//! e_c(k) = clamp(e(k), +-CLIP s)      s = the current noise estimate (below), CLIP = 5
//! K      = P psi / (lambda + psi^T P psi)
//! theta  = theta(k-1) + K e_c         then projected (below)
//! P      = (P - K psi^T P) / lambda   symmetric; trace P <= its trace at the start / min(1, W (1 - lambda))
//! ```
//!
//! With lambda = 1 this is the recursive form of the Gauss-Newton fit of the cost `sum e^2` over the whole
//! record (the warm-up enters through the fit's P and V), so that the estimate follows the offline
//! output-error optimum and has its accuracy. The clamp only acts on residuals beyond 5 noise standard
//! deviations (probability 6e-7 for Gaussian noise): a sample where the model switched borders at a
//! different time than the plant, whose error is not noise, cannot throw the estimate far.
//!
//! # Forgetting (wear)
//!
//! `lambda = 1 - rho_min` with MRGIA's floor `rho_min` (0: no forgetting, lambda = 1). The noise variance and
//! the cost are discounted alike: `V = lambda V + e^2`, `W1 = lambda W1 + 1`, `W2 = lambda^2 W2 + 1` (both
//! start at the warm-up length), `s^2 = V / (W1 - p)` (`V / W1` while `W1 <= 2p`). After a change of the plant
//! the output errors grow, so s^2 and with it the standard errors widen until the estimate has followed.
//!
//! # Standard errors
//!
//! `std_i = sqrt(s^2 P_ii W2 / W1)`. With lambda = 1, `P = (J^T J)^-1` over all samples and W2 = W1, so this is
//! `identify oe`'s `s^2 (J^T J)^-1` (with J accumulated along the recursion instead of at the final estimate).
//! With forgetting, P is the inverse of the discounted information `sum lambda^(k-i) psi psi^T` and the
//! estimate is a weighted least-squares one, whose covariance is `s^2 R^-1 (sum lambda^(2(k-i)) psi psi^T)
//! R^-1`; for a stationary psi that is `s^2 P W2 / W1`. They are 0 (unknown) during the warm-up.
//!
//! # Valid region (projection)
//!
//! After every update: the gaps are clamped at 0 from below, m2 at [`M2_MIN`]; if the linear block is not
//! stable ([`is_stable`]), the step in the a's is halved up to 8 times, and if it is still unstable the a's
//! keep their previous (stable) values. A step with a non-finite value is refused (theta and P unchanged).
//! The estimate therefore never leaves the valid region: gaps >= 0, slopes > 0, stable linear block.
//!
//! # Divergence rule
//!
//! Beside the recursion, the last good estimate (theta, P and the model state) is simulated with its
//! parameters frozen. Every [`CHECK_WINDOW`] samples the output-error costs of the window are compared: if
//! the recursion's (its prediction errors) exceeds [`ROLLBACK_RATIO`] times the frozen estimate's (plus a
//! rounding floor of `1e-12 max|y|^2` per sample), the recursion has diverged: theta, the model state and P
//! are rolled back to the last good ones, with P multiplied by [`ROLLBACK_INFLATE`] (within the trace cap)
//! so that the estimate re-adapts; otherwise the current estimate becomes the last good one. A divergence is
//! therefore left at most [`CHECK_WINDOW`] samples before it is undone.
//!
//! # Degenerate cases
//!
//! - Non-finite input: the sample is ignored (as by MRGIA), the result has `updating = false`.
//! - Noise-free data: s = 0, so the clamp is off and the standard errors are 0 (up to rounding).
//! - psi = 0 (held output, no information): K = 0, theta unchanged, P only divided by lambda (capped).
//! - `lambda + psi^T P psi` not finite and positive: the update is refused.

use super::{
    M2_MIN, MAX_P, OeConfig, SimState, StdErr, Theta, default_starts, fit_from, info_matrix,
    inverse_information, normal_equations, param_names, propagate_state,
};
use crate::identify::mrgia::{self, Estimate, Mrgia, MrgiaConfig, StepResult};
use crate::plant::ParamError;
use crate::plant::linear::is_stable;
use serde::{Deserialize, Serialize};

/// Samples of the warm-up (plain MRGIA) before the recursion starts; also the length of the record the
/// start's output-error fit uses.
pub const WARMUP: usize = 500;
/// Ring of past samples: a power of two holding the warm-up record and the longest input lag (64 + 4).
const RING: usize = 512;
const _: () = assert!(RING >= WARMUP && RING.is_power_of_two() && RING > 68);
/// Samples between two divergence checks.
pub const CHECK_WINDOW: usize = 250;
/// The recursion has diverged when its window cost exceeds this multiple of the last good estimate's.
pub const ROLLBACK_RATIO: f64 = 1.5;
/// P is multiplied by this on a roll-back.
pub const ROLLBACK_INFLATE: f64 = 4.0;
/// Residuals are clamped at this many noise standard deviations in the update.
pub const CLIP: f64 = 5.0;
/// Halvings of an a-step that leaves the stable region before the a's are kept.
const MAX_HALVINGS: usize = 8;
/// Rounding floor of the divergence test, relative to max|y|^2 per sample.
const COST_REL_FLOOR: f64 = 1e-12;

type Mat = [[f64; MAX_P]; MAX_P];

/// The recursion's state (phase 3 of the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct Recursion {
    theta: Theta,
    p: Mat,
    sim: SimState,
    lambda: f64,
    /// Discounted cost V and weight sums W1, W2 (module docs).
    cost: f64,
    w1: f64,
    w2: f64,
    /// Cap on trace P.
    p_cap: f64,
    good_theta: Theta,
    good_p: Mat,
    good_sim: SimState,
    win_cost: f64,
    good_cost: f64,
    win_len: usize,
    rollbacks: u64,
}

/// MRGIA with the `refine` setting (module docs). Clone and serde-(de)serialisable (the FMU state); a
/// deserialised state must pass [`Refined::check`] before use.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Refined {
    mrgia: Mrgia,
    /// Inputs and outputs of the last [`RING`] samples, sample k in slot `k % RING`.
    u_ring: Vec<f64>,
    y_ring: Vec<f64>,
    samples: u64,
    /// Sample count at which the next start is tried.
    next_start: u64,
    y_max: f64,
    rec: Option<Recursion>,
    last: StepResult,
}

impl Refined {
    /// Plain MRGIA with `cfg` for the warm-up; the recursion's forgetting comes from `cfg.rho_min`.
    pub fn new(cfg: MrgiaConfig) -> Result<Self, ParamError> {
        Ok(Self {
            mrgia: Mrgia::new(cfg)?,
            u_ring: vec![0.0; RING],
            y_ring: vec![0.0; RING],
            samples: 0,
            next_start: WARMUP as u64,
            y_max: 0.0,
            rec: None,
            last: StepResult::default(),
        })
    }

    pub fn config(&self) -> &MrgiaConfig {
        self.mrgia.config()
    }

    /// Process sample k = (u(k), y(k)). Never panics; never produces NaN from finite input.
    pub fn update(&mut self, u: f64, y: f64) -> StepResult {
        if !(u.is_finite() && y.is_finite()) {
            return StepResult {
                updating: false,
                ..self.last
            };
        }
        let k = self.samples;
        self.y_max = self.y_max.max(y.abs());
        let r = match &mut self.rec {
            None => self.mrgia.update(u, y),
            Some(rec) => rec.step(k, &self.u_ring, y, self.y_max),
        };
        let slot = (k as usize) & (RING - 1);
        self.u_ring[slot] = u;
        self.y_ring[slot] = y;
        self.samples += 1;
        if self.rec.is_none() && self.samples >= self.next_start {
            self.rec = self.start();
            if self.rec.is_none() {
                self.next_start = self.samples + WARMUP as u64;
            }
        }
        self.last = r;
        r
    }

    /// Phase 2 of the module docs: the recursion's initial state from the last [`WARMUP`] samples, or None
    /// when they do not excite the parameters.
    fn start(&self) -> Option<Recursion> {
        let cfg = *self.mrgia.config();
        let (na, nb, d) = (cfg.na, cfg.nb, cfg.delay);
        let first = self.samples - WARMUP as u64;
        let at = |ring: &[f64], i: usize| ring[(first as usize + i) & (RING - 1)];
        let u: Vec<f64> = (0..WARMUP).map(|i| at(&self.u_ring, i)).collect();
        let y: Vec<f64> = (0..WARMUP).map(|i| at(&self.y_ring, i)).collect();
        let rises = y.windows(2).any(|w| w[1] > w[0]);
        let falls = y.windows(2).any(|w| w[1] < w[0]);
        if !(rises && falls) {
            return None;
        }
        let (rec, _) = mrgia::identify(MrgiaConfig::recommended(na, nb, d), &u, &y).ok()?;
        let (paper, _) = mrgia::identify(MrgiaConfig::paper(na, nb, d), &u, &y).ok()?;
        let mut starts = vec![("mrgia-running", self.mrgia.estimate())];
        starts.extend(default_starts(rec, Some(paper)));
        let fit = fit_from(&OeConfig::new(na, nb, d), &u, &y, &starts).ok()?;
        let mut theta = Theta::new(&fit.estimate, d).ok()?;
        let p = theta.p();
        for c in &mut theta.v[p - 2..p] {
            *c = c.max(0.0);
        }
        theta.v[p - 3] = theta.v[p - 3].max(M2_MIN);
        if !is_stable(&theta.v[..na]) {
            return None;
        }
        let ne = normal_equations(&theta, &u, &y);
        let inv = inverse_information(&info_matrix(&ne, p), &param_names(na, nb)).ok()?;
        let mut pm = [[0.0; MAX_P]; MAX_P];
        for (i, row) in pm.iter_mut().enumerate().take(p) {
            for (j, v) in row.iter_mut().enumerate().take(p) {
                *v = inv[(i, j)];
            }
        }
        let (_, sim) = propagate_state::<true>(&theta, &u, |_, _, _| {});
        let lambda = 1.0 - cfg.rho_min;
        let trace: f64 = (0..p).map(|i| pm[i][i]).sum();
        let memory = WARMUP as f64 * (1.0 - lambda);
        let p_cap = if memory > 1.0 { trace * memory } else { trace };
        let all_finite = pm.iter().flatten().all(|v| v.is_finite()) && ne.cost.is_finite();
        all_finite.then_some(Recursion {
            theta,
            p: pm,
            sim,
            lambda,
            cost: ne.cost,
            w1: WARMUP as f64,
            w2: WARMUP as f64,
            p_cap,
            good_theta: theta,
            good_p: pm,
            good_sim: sim,
            win_cost: 0.0,
            good_cost: 0.0,
            win_len: 0,
            rollbacks: 0,
        })
    }

    /// Whether the recursion runs (phase 3); false during the warm-up.
    pub fn refining(&self) -> bool {
        self.rec.is_some()
    }

    /// Roll-backs of the divergence rule so far.
    pub fn rollbacks(&self) -> u64 {
        self.rec.as_ref().map_or(0, |r| r.rollbacks)
    }

    /// Number of samples processed (non-finite samples are not counted).
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// The result of the latest sample (all zeros before the first).
    pub fn last(&self) -> StepResult {
        self.last
    }

    /// The current estimate as `[a1..a_na, b0..b_nb, m2, c1, c2]` (the first `na + nb + 4` entries; the
    /// rest 0). No allocation.
    pub fn values(&self) -> [f64; MAX_P] {
        match &self.rec {
            Some(r) => r.theta.v,
            None => {
                let t = self.mrgia.theta();
                let mut v = [0.0; MAX_P];
                v[..t.len()].copy_from_slice(t);
                v[t.len() - 3] += 1.0;
                v
            }
        }
    }

    /// Standard errors of [`Refined::values`], same layout; all 0 during the warm-up. No allocation.
    pub fn std_err_values(&self) -> [f64; MAX_P] {
        let mut s = [0.0; MAX_P];
        for (i, si) in s.iter_mut().enumerate() {
            *si = self.std_err_at(i);
        }
        s
    }

    /// Entry `i` of [`Refined::std_err_values`] (0 beyond the parameter count).
    pub fn std_err_at(&self, i: usize) -> f64 {
        match &self.rec {
            Some(r) if i < r.theta.p() => (r.noise_variance() * r.p[i][i] * r.w2 / r.w1)
                .max(0.0)
                .sqrt(),
            _ => 0.0,
        }
    }

    /// The current estimate.
    pub fn estimate(&self) -> Estimate {
        let c = self.config();
        let v = self.values();
        let n = c.n_params();
        Estimate {
            a: v[..c.na].to_vec(),
            b: v[c.na..=c.na + c.nb].to_vec(),
            m1: 1.0,
            m2: v[n - 3],
            c1: v[n - 2],
            c2: v[n - 1],
        }
    }

    /// The standard errors of the current estimate, None during the warm-up.
    pub fn std_err(&self) -> Option<StdErr> {
        let c = self.config();
        self.rec
            .as_ref()
            .map(|_| StdErr::from_flat(c.na, c.nb, &self.std_err_values()[..c.n_params()]))
    }

    /// Consistency of a deserialised state (the inner MRGIA checks itself when deserialised).
    pub fn check(&self) -> Result<(), String> {
        if self.u_ring.len() != RING || self.y_ring.len() != RING {
            return Err("refine state: malformed sample ring".into());
        }
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        if !(finite(&self.u_ring) && finite(&self.y_ring) && self.y_max.is_finite()) {
            return Err("refine state: non-finite values".into());
        }
        let Some(r) = &self.rec else { return Ok(()) };
        let c = self.config();
        let same = |t: &Theta| (t.na, t.nb, t.delay) == (c.na, c.nb, c.delay);
        if !(same(&r.theta) && same(&r.good_theta)) {
            return Err("refine state: the recursion's orders differ from the settings".into());
        }
        let ok = finite(&r.theta.v)
            && finite(&r.good_theta.v)
            && r.p.iter().chain(&r.good_p).all(|row| finite(row))
            && [
                r.lambda,
                r.cost,
                r.w1,
                r.w2,
                r.p_cap,
                r.win_cost,
                r.good_cost,
            ]
            .iter()
            .all(|v| v.is_finite())
            && r.lambda > 0.0
            && r.lambda <= 1.0
            && r.w1 >= 1.0
            && r.w2 >= 1.0
            && r.win_len < CHECK_WINDOW
            && r.sim.pos < 4
            && r.good_sim.pos < 4;
        if !ok {
            return Err("refine state: inconsistent recursion".into());
        }
        Ok(())
    }
}

/// The on-line estimator of the FMU and of `identify mrgia`: plain MRGIA, or with `refine`, [`Refined`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum OnlineEstimator {
    Plain(Box<Mrgia>),
    Refined(Box<Refined>),
}

impl OnlineEstimator {
    pub fn new(cfg: MrgiaConfig, refine: bool) -> Result<Self, ParamError> {
        Ok(if refine {
            Self::Refined(Box::new(Refined::new(cfg)?))
        } else {
            Self::Plain(Box::new(Mrgia::new(cfg)?))
        })
    }

    /// Samples processed (non-finite samples are not counted).
    pub fn samples(&self) -> u64 {
        match self {
            Self::Plain(m) => m.samples(),
            Self::Refined(r) => r.samples(),
        }
    }

    /// Whether this is the `refine` kind.
    pub fn refining_kind(&self) -> bool {
        matches!(self, Self::Refined(_))
    }

    pub fn config(&self) -> &MrgiaConfig {
        match self {
            Self::Plain(m) => m.config(),
            Self::Refined(r) => r.config(),
        }
    }

    /// Entry `i` of the estimate `[a.., b.., m2, c1, c2]` (MRGIA's theta holds m2 - 1). No allocation.
    pub fn value(&self, i: usize) -> f64 {
        match self {
            Self::Plain(m) => {
                let t = m.theta();
                t[i] + if i + 3 == t.len() { 1.0 } else { 0.0 }
            }
            Self::Refined(r) => r.values()[i],
        }
    }

    /// Standard error of entry `i` (0 when unknown: plain MRGIA, the warm-up). No allocation.
    pub fn std_err_at(&self, i: usize) -> f64 {
        match self {
            Self::Plain(_) => 0.0,
            Self::Refined(r) => r.std_err_at(i),
        }
    }

    pub fn estimate(&self) -> Estimate {
        match self {
            Self::Plain(m) => m.estimate(),
            Self::Refined(r) => r.estimate(),
        }
    }

    /// Standard errors, None when unknown.
    pub fn std_err(&self) -> Option<StdErr> {
        match self {
            Self::Plain(_) => None,
            Self::Refined(r) => r.std_err(),
        }
    }

    pub fn last(&self) -> StepResult {
        match self {
            Self::Plain(m) => m.last(),
            Self::Refined(r) => r.last(),
        }
    }

    pub fn update(&mut self, u: f64, y: f64) -> StepResult {
        match self {
            Self::Plain(m) => m.update(u, y),
            Self::Refined(r) => r.update(u, y),
        }
    }

    /// Consistency of a deserialised state (see [`Refined::check`]).
    pub fn check(&self) -> Result<(), String> {
        match self {
            Self::Plain(_) => Ok(()),
            Self::Refined(r) => r.check(),
        }
    }
}

impl Recursion {
    /// s^2 of the module docs.
    fn noise_variance(&self) -> f64 {
        let p = self.theta.p() as f64;
        let dof = if self.w1 > 2.0 * p {
            self.w1 - p
        } else {
            self.w1
        };
        (self.cost / dof).max(0.0)
    }

    /// Sample k (phase 3): `u_ring` holds u(0..k-1) (lags 1..RING-1 are valid).
    fn step(&mut self, k: u64, u_ring: &[f64], y: f64, y_max: f64) -> StepResult {
        let d = self.theta.delay;
        let lag = |j: usize| {
            let l = (d + j) as u64;
            if k >= l {
                u_ring[((k - l) as usize) & (RING - 1)]
            } else {
                0.0
            }
        };
        let (w, _) = self.sim.step::<true>(&self.theta, lag);
        let (wg, _) = self.good_sim.step::<true>(&self.good_theta, lag);
        let e = y - w;
        let s = self.noise_variance().sqrt();
        let ec = if s > 0.0 {
            e.clamp(-CLIP * s, CLIP * s)
        } else {
            e
        };
        let updating = self.update(ec);
        let l = self.lambda;
        self.cost = l * self.cost + e * e;
        self.w1 = l * self.w1 + 1.0;
        self.w2 = l * l * self.w2 + 1.0;
        self.win_cost += e * e;
        self.good_cost += (y - wg) * (y - wg);
        self.win_len += 1;
        if self.win_len == CHECK_WINDOW {
            self.check_divergence(y_max);
        }
        StepResult {
            y_hat: w,
            e,
            updating,
        }
    }

    /// The recursive Gauss-Newton update with the (clamped) error `e` and the sensitivities in `self.sim`;
    /// whether theta changed.
    fn update(&mut self, e: f64) -> bool {
        let p = self.theta.p();
        let psi = self.sim.dw;
        let mut ppsi = [0.0; MAX_P];
        for (i, v) in ppsi.iter_mut().enumerate().take(p) {
            *v = (0..p).map(|j| self.p[i][j] * psi[j]).sum();
        }
        let denom = self.lambda + (0..p).map(|i| psi[i] * ppsi[i]).sum::<f64>();
        if !(denom.is_finite() && denom > 0.0) {
            return false;
        }
        let mut next = self.theta;
        for (t, k) in next.v[..p].iter_mut().zip(&ppsi[..p]) {
            *t += k / denom * e;
        }
        let mut pn = self.p;
        for i in 0..p {
            for j in i..p {
                let v = (self.p[i][j] - ppsi[i] * ppsi[j] / denom) / self.lambda;
                pn[i][j] = v;
                pn[j][i] = v;
            }
        }
        let trace: f64 = (0..p).map(|i| pn[i][i]).sum();
        if trace > self.p_cap {
            let f = self.p_cap / trace;
            pn.iter_mut().flatten().for_each(|v| *v *= f);
        }
        if !(next.v.iter().all(|v| v.is_finite()) && pn.iter().flatten().all(|v| v.is_finite())) {
            return false;
        }
        project(&mut next, &self.theta);
        let changed = next.v != self.theta.v;
        self.theta = next;
        self.p = pn;
        changed
    }

    /// The divergence rule of the module docs, at the end of a window.
    fn check_divergence(&mut self, y_max: f64) {
        let floor = COST_REL_FLOOR * y_max * y_max * CHECK_WINDOW as f64;
        if self.win_cost > ROLLBACK_RATIO * self.good_cost + floor {
            self.theta = self.good_theta;
            self.sim = self.good_sim;
            let p = self.theta.p();
            let trace: f64 = (0..p).map(|i| self.good_p[i][i]).sum();
            let f = ROLLBACK_INFLATE.min(self.p_cap / trace.max(f64::MIN_POSITIVE));
            self.p = self.good_p;
            self.p.iter_mut().flatten().for_each(|v| *v *= f.max(1.0));
            self.rollbacks += 1;
        } else {
            self.good_theta = self.theta;
            self.good_p = self.p;
            self.good_sim = self.sim;
        }
        self.win_cost = 0.0;
        self.good_cost = 0.0;
        self.win_len = 0;
    }
}

/// Into the valid region (module docs), given the previous, valid, estimate `old`.
fn project(th: &mut Theta, old: &Theta) {
    let (na, p) = (th.na, th.p());
    th.v[p - 3] = th.v[p - 3].max(M2_MIN);
    th.v[p - 2] = th.v[p - 2].max(0.0);
    th.v[p - 1] = th.v[p - 1].max(0.0);
    for _ in 0..MAX_HALVINGS {
        if is_stable(&th.v[..na]) {
            return;
        }
        for i in 0..na {
            th.v[i] = 0.5 * (th.v[i] + old.v[i]);
        }
    }
    if !is_stable(&th.v[..na]) {
        th.v[..na].copy_from_slice(&old.v[..na]);
    }
}

pub mod monitor;
#[cfg(test)]
mod tests;
