//! The adaptive compensation loop: reference in, plant input out, the on-line estimator updating both
//! inverses.
//!
//! At sample k the controller takes the reference `d` samples ahead, `r(k + d)` (d the linear block's
//! delay: the input u(k) first acts on x(k + d)), and answers u(k):
//!
//! 1. the backlash inverse ([`BacklashInverse`]) turns r(k + d) into the wanted linear-block output
//!    `v = x(k + d)`;
//! 2. the feed-forward inverse of the linear block solves `x(k+d) = -sum a_i x(k+d-i) + sum b_j u(k-j)` for
//!    u(k), with the past x taken as the values it aimed at before (the model's x):
//!    `u(k) = (v + sum_{i>=1} a_i x(k+d-i) - sum_{j>=1} b_j u(k-j)) / b0`.
//!
//! After the plant answers, [`Controller::observe`] feeds the pair (u(k), y(k)) to the estimator (MRGIA with
//! the recommended setting and `refine`, forgetting with a memory of N samples: `rho_min = 1/N`), whose
//! estimate both inverses use from the next sample on, once the estimator's warm-up ([`WARMUP`] samples,
//! plain MRGIA) is over. During the warm-up the loop runs on the estimator's theta(0), x(k) = u(k - d), and
//! v = r (the backlash inverse runs on the estimates, so that its memory follows, but its v is not used): MRGIA's first estimates are far off (measured on the paper plant: RMS of y - r
//! 27.8 over the first 50 samples with them, u up to 154), and the warm-up's input is the reference itself.
//!
//! **What the feed-forward needs.** The inverse of the linear block has the zeros of B as poles: it needs
//! `b0 != 0` and a minimum-phase B (every root of `b0 + b1 z^-1 + ...` inside the unit circle), else u grows
//! without bound; and, being open loop, a stable A (an unstable plant drifts away from any feed-forward). An
//! estimate that fails these (early in a run, or a plant that has them) is not used: the controller keeps
//! the last linear estimate that passed (at first the estimator's theta(0): x(k) = u(k - d)) and counts the
//! samples in [`LoopRun::refused_linear`]. A plant whose true B is not minimum phase is not compensated by
//! this loop (its estimates are refused throughout); that needs a feedback design.
//!
//! **Estimate lag.** With [`LoopSettings::estimate_lag`] 0 the inverses at sample k use the estimate after
//! samples 0..k-1 (the latest). With 1 they use the estimate of the sample before (after 0..k-2): what a
//! master that passes values between units only at communication points (a Jacobi master: libcosim's
//! fixed step, FMPy's SSP and container) delivers, since the estimate of sample k appears at t_k, the
//! instant the plant takes u(k), and the compensator needs a step to answer for it.

use super::inverse::BacklashInverse;
use crate::identify::mrgia::MrgiaConfig;
use crate::identify::oe::online::{OnlineEstimator, WARMUP};
use crate::plant::linear::{ArxParams, History, MAX_ORDER, is_stable};
use crate::plant::{BacklashParams, ParamError, Plant, PlantParams};
use crate::stats::rms_diff;
use rand_chacha::ChaCha8Rng;
use rand_core::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

/// What the loop compensates with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Mode {
    /// The linear feed-forward from the true initial plant, no backlash inverse.
    None,
    /// Both inverses from the true initial plant, never updated (wear goes uncompensated).
    Fixed,
    /// Both inverses from the on-line estimates.
    Adaptive,
    /// The linear feed-forward from the true plant on a plant without play (the bound to aim at).
    NoPlay,
}

impl Mode {
    pub const ALL: [Mode; 4] = [Mode::None, Mode::Fixed, Mode::Adaptive, Mode::NoPlay];

    /// The name in JSON and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Mode::None => "none",
            Mode::Fixed => "fixed",
            Mode::Adaptive => "adaptive",
            Mode::NoPlay => "no-play",
        }
    }
}

/// A setting of the loop out of range, in words.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LoopError {
    #[error(
        "memory {0} is invalid: must be a number of samples above 1 (rho_min = 1/memory below 1)"
    )]
    Memory(f64),
    #[error(transparent)]
    Smoothing(#[from] super::inverse::SmoothingError),
    #[error(transparent)]
    Param(#[from] ParamError),
    #[error("the reference is empty")]
    Empty,
    #[error(
        "estimate lag {0} is invalid: 0 (the latest estimate) or 1 (the estimate of the sample before)"
    )]
    EstimateLag(usize),
}

/// The estimator's structure and the loop's own settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LoopSettings {
    pub na: usize,
    pub nb: usize,
    pub delay: usize,
    /// The estimator's memory in samples (forgetting `rho_min = 1/memory`); None: no forgetting.
    pub memory: Option<f64>,
    /// The backlash inverse's smoothing half-width (0 = exact).
    pub smoothing: f64,
    /// Samples by which the estimate the inverses use lags the latest: 0 or 1 (module docs).
    #[serde(default)]
    pub estimate_lag: usize,
}

impl LoopSettings {
    /// The estimator's structure that of the linear block `arx` (its orders and delay).
    pub fn for_structure(arx: &ArxParams, memory: Option<f64>, smoothing: f64) -> Self {
        Self {
            na: arx.na,
            nb: arx.nb,
            delay: arx.delay,
            memory,
            smoothing,
            estimate_lag: 0,
        }
    }

    /// The estimator's setting: MRGIA recommended, with the forgetting of the memory.
    pub fn estimator_config(&self) -> Result<MrgiaConfig, LoopError> {
        let rho_min = match self.memory {
            None => 0.0,
            Some(n) if n.is_finite() && n > 1.0 / 0.999 => 1.0 / n,
            Some(n) => return Err(LoopError::Memory(n)),
        };
        let cfg = MrgiaConfig {
            rho_min,
            ..MrgiaConfig::recommended(self.na, self.nb, self.delay)
        };
        cfg.validate()?;
        Ok(cfg)
    }
}

/// Whether the feed-forward can invert `m`: finite, b0 away from 0, B minimum phase, A stable.
pub fn invertible(m: &ArxParams) -> bool {
    let (a, b) = (m.a(), m.b());
    let scale = b.iter().fold(0.0f64, |s, x| s.max(x.abs()));
    if !(a.iter().chain(b).all(|x| x.is_finite()) && b[0].abs() > 1e-6 * scale) {
        return false;
    }
    let mut monic = [0.0; MAX_ORDER];
    for (z, bj) in monic.iter_mut().zip(&b[1..]) {
        *z = bj / b[0];
    }
    is_stable(a) && is_stable(&monic[..b.len() - 1])
}

/// The feed-forward inverse of the linear block: the model's past x and past u.
#[derive(Debug, Clone)]
struct FeedForward {
    x: History,
    u: History,
}

impl FeedForward {
    fn new() -> Self {
        Self {
            x: History::zeros(MAX_ORDER),
            u: History::zeros(MAX_ORDER),
        }
    }

    /// u(k) that makes the model's x(k + d) equal `x_target` (module docs).
    fn input(&mut self, m: &ArxParams, x_target: f64) -> f64 {
        let mut acc = x_target;
        for (i, ai) in m.a().iter().enumerate() {
            acc += ai * self.x.get(i);
        }
        let b = m.b();
        for (j, bj) in b.iter().enumerate().skip(1) {
            acc -= bj * self.u.get(j - 1);
        }
        let u = acc / b[0];
        self.x.push(x_target);
        self.u.push(u);
        u
    }
}

/// The controller of the module docs.
#[derive(Debug, Clone)]
pub struct Controller {
    inverse: BacklashInverse,
    ff: FeedForward,
    linear: ArxParams,
    /// The backlash to invert; None: no backlash inverse (v = r).
    backlash: Option<BacklashParams>,
    est: Option<OnlineEstimator>,
    /// With an estimate lag of 1: the estimate before the estimator's last update.
    lagged: Option<(ArxParams, BacklashParams)>,
    lag: usize,
    /// Samples the estimator has seen.
    seen: usize,
    degenerate: usize,
    refused_linear: usize,
}

impl Controller {
    /// Fixed inverses: `linear` and, if given, `backlash`.
    pub fn fixed(
        linear: ArxParams,
        backlash: Option<BacklashParams>,
        smoothing: f64,
    ) -> Result<Self, LoopError> {
        linear.validate()?;
        Ok(Self {
            inverse: BacklashInverse::new(smoothing)?,
            ff: FeedForward::new(),
            linear,
            backlash,
            est: None,
            lagged: None,
            lag: 0,
            seen: 0,
            degenerate: 0,
            refused_linear: 0,
        })
    }

    /// Inverses from the on-line estimates (module docs).
    pub fn adaptive(s: &LoopSettings) -> Result<Self, LoopError> {
        if s.estimate_lag > 1 {
            return Err(LoopError::EstimateLag(s.estimate_lag));
        }
        let est = OnlineEstimator::new(s.estimator_config()?, true)?;
        let mut b = [0.0; MAX_ORDER + 1];
        b[0] = 1.0;
        let start = ArxParams {
            na: s.na,
            nb: s.nb,
            delay: s.delay,
            a: [0.0; MAX_ORDER],
            b,
        };
        let mut c = Self::fixed(start, None, s.smoothing)?;
        c.est = Some(est);
        c.lag = s.estimate_lag;
        Ok(c)
    }

    /// The current estimate as a linear block and a backlash.
    fn estimate(&self, e: &OnlineEstimator) -> (ArxParams, BacklashParams) {
        let mut m = self.linear;
        let (na, nb) = (m.na, m.nb);
        for i in 0..na {
            m.a[i] = e.value(i);
        }
        for j in 0..=nb {
            m.b[j] = e.value(na + j);
        }
        let t = na + nb + 1;
        let p = BacklashParams {
            m1: 1.0,
            m2: e.value(t),
            c1: e.value(t + 1),
            c2: e.value(t + 2),
        };
        (m, p)
    }

    /// u(k) for the reference `r_ahead` = r(k + d).
    pub fn input(&mut self, r_ahead: f64) -> f64 {
        // During the estimator's warm-up the inverse runs (its memory follows) but its v is not used.
        let warm = self.est.is_some() && self.seen < WARMUP;
        if let Some(e) = &self.est {
            let (m, p) = self.lagged.unwrap_or_else(|| self.estimate(e));
            if !warm && invertible(&m) {
                self.linear = m;
            } else if !warm {
                self.refused_linear += 1;
            }
            self.backlash = Some(p);
        }
        let v = match &self.backlash {
            Some(p) => {
                let a = self.inverse.commit(r_ahead, p);
                self.degenerate += usize::from(a.degenerate.is_some() && !warm);
                if warm { r_ahead } else { a.v }
            }
            None => r_ahead,
        };
        self.ff.input(&self.linear, v)
    }

    /// The plant's answer to u(k): the estimator (if any) learns from the pair.
    pub fn observe(&mut self, u: f64, y: f64) {
        if let Some(e) = &self.est
            && self.lag == 1
        {
            self.lagged = Some(self.estimate(e));
        }
        if let Some(e) = &mut self.est {
            e.update(u, y);
            self.seen += 1;
        }
    }

    /// The backlash estimate the inverse works with now (None without a backlash inverse).
    pub fn backlash(&self) -> Option<BacklashParams> {
        self.backlash
    }
}

/// How the play changes over a simulated record of N samples.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", tag = "kind")]
pub enum Wear {
    None,
    /// Both gaps grow linearly to `1 + ratio` times their start over the record.
    Ramp {
        ratio: f64,
    },
    /// Both gaps jump to `1 + ratio` times their start at the middle of the record.
    Step {
        ratio: f64,
    },
}

impl Wear {
    /// The gaps' factor at sample k of n.
    pub fn factor(self, k: usize, n: usize) -> f64 {
        match self {
            Wear::None => 1.0,
            Wear::Ramp { ratio } => 1.0 + ratio * k as f64 / n.max(1) as f64,
            Wear::Step { ratio } if 2 * k >= n => 1.0 + ratio,
            Wear::Step { .. } => 1.0,
        }
    }
}

/// One simulated run of the loop.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LoopRun {
    pub mode: Mode,
    /// Plant input u(k) and measured output y(k), k = 0..N.
    pub u: Vec<f64>,
    pub y: Vec<f64>,
    /// RMS of y - r over the record, and over its last quarter (after the wear).
    pub rmse: f64,
    pub rmse_last_quarter: f64,
    /// RMS of f - r over the last quarter, f the plant's noise-free output: the tracking error without the
    /// measurement noise that y carries (the floor of `rmse_last_quarter` is the noise's std).
    pub rmse_clean_last_quarter: f64,
    /// Samples whose backlash estimate was degenerate, and whose linear estimate the feed-forward refused.
    pub degenerate: usize,
    pub refused_linear: usize,
    /// The backlash the inverse used at the end.
    pub backlash: Option<BacklashParams>,
}

/// The controller of `mode` for `plant` (its true initial parameters for `None`, `Fixed`, `NoPlay`).
fn controller(mode: Mode, plant: &PlantParams, s: &LoopSettings) -> Result<Controller, LoopError> {
    match mode {
        Mode::None | Mode::NoPlay => Controller::fixed(plant.arx, None, s.smoothing),
        Mode::Fixed => Controller::fixed(plant.arx, Some(plant.backlash), s.smoothing),
        Mode::Adaptive => Controller::adaptive(s),
    }
}

/// Runs the loop of `mode` on `plant` (noise as in its parameters) with `wear` for the reference `r`.
pub fn simulate(
    r: &[f64],
    plant: &PlantParams,
    wear: Wear,
    mode: Mode,
    s: &LoopSettings,
) -> Result<LoopRun, LoopError> {
    if r.is_empty() {
        return Err(LoopError::Empty);
    }
    let mut params = *plant;
    if mode == Mode::NoPlay {
        params.backlash = BacklashParams {
            m1: 1.0,
            m2: 1.0,
            c1: 0.0,
            c2: 0.0,
        };
    }
    let mut p = Plant::new(params)?;
    let mut c = controller(mode, plant, s)?;
    let n = r.len();
    // The reference d samples ahead: the delay of the plant's (and the estimator's) structure.
    let d = plant.arx.delay;
    let (mut u, mut y) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let mut clean = Vec::with_capacity(n);
    for k in 0..n {
        let f = wear.factor(k, n);
        let b = params.backlash;
        p.set_backlash(BacklashParams {
            c1: b.c1 * f,
            c2: b.c2 * f,
            ..b
        })?;
        let uk = c.input(r[(k + d).min(n - 1)]);
        let out = p.output();
        c.observe(uk, out.y);
        p.advance(uk);
        u.push(uk);
        y.push(out.y);
        clean.push(out.f);
    }
    let q = n - n / 4;
    Ok(LoopRun {
        mode,
        rmse: rms_diff(&y, r),
        rmse_last_quarter: rms_diff(&y[q..], &r[q..]),
        rmse_clean_last_quarter: rms_diff(&clean[q..], &r[q..]),
        u,
        y,
        degenerate: c.degenerate,
        refused_linear: c.refused_linear,
        backlash: c.backlash(),
    })
}

/// The RMS of `y - r` over consecutive windows of `window` samples: (the window's last sample, its RMS).
pub fn windowed_rmse(y: &[f64], r: &[f64], window: usize) -> Vec<(usize, f64)> {
    let w = window.max(1);
    let n = y.len().min(r.len());
    (0..n / w)
        .map(|i| {
            let span = i * w..(i + 1) * w;
            ((i + 1) * w - 1, rms_diff(&y[span.clone()], &r[span]))
        })
        .collect()
}

/// A reference of the measurements: low-pass noise, white Gaussian noise through `r(k) = 0.9 r(k-1) + e(k)`
/// scaled to standard deviation `std` (stationary from the start), from the seed `seed`.
pub fn low_pass_reference(n: usize, std: f64, seed: u64) -> Vec<f64> {
    const POLE: f64 = 0.9;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut draw = move || -> f64 { StandardNormal.sample(&mut rng) };
    let gain = std * (1.0 - POLE * POLE).sqrt();
    let mut r = std * draw();
    (0..n)
        .map(|_| {
            let now = r;
            r = POLE * r + gain * draw();
            now
        })
        .collect()
}

#[cfg(test)]
#[path = "adaptive_tests.rs"]
mod tests;
