//! Wear monitoring: a CUSUM test on the output-error residual against a reference model that raises an alarm
//! when the play (c1 + c2) has grown, at a mean false-alarm period the user sets.
//!
//! # Reference
//!
//! The monitor drives a [`Refined`] estimator. [`MonitorConfig::learn`] samples after its recursion has
//! started (after the refine warm-up), the refined estimate is frozen as the reference model theta0, with
//! the noise variance `s^2` and the standard error of the play from the same recursion. A reference play
//! given in [`MonitorConfig::reference_play`] rescales the learned gaps c1, c2 (ratio kept) to it.
//!
//! # The test
//!
//! From then on the reference model is simulated from the input alone (as the output-error model), with its
//! sensitivities, and per sample k:
//!
//! ```text
//! e(k)  = y(k) - w0(k)                                  residual against the (tracked) reference model
//! g(k)  = c1 dw0/dc1 + c2 dw0/dc2                       output change per unit of relative play growth
//! h(k)  = sum_j b_j dw0/db_j                            output change per unit of relative linear gain
//! gt(k) = g(k) - beta0 - beta1 h(k)                     g without its projection on (1, h) over the samples
//!                                                        since the reference (least squares on 1, h)
//! z(k)  = r gt(k) (2 e(k) - r gt(k)) / (2 sigma^2)      log-likelihood ratio of "the output moved by r gt"
//! S(k)  = max(0, S(k-1) + z(k))                         CUSUM
//! ```
//!
//! with r one of the growths of the bank (below), w0 the output of the reference model with the tracked offset and
//! gain (below) and the sums of the projection running over all samples since the reference. A play growth
//! by r moves the output by about `r g(k)`. An output offset moves it by a constant, a change of the linear
//! block's gain by a multiple of h (to first order: h is the output's derivative with respect to the log of
//! that gain); neither is wear, and `gt` is orthogonal to 1 and h over the record, so their first-order
//! effect adds no drift to S.
//!
//! **Tracked offset and gain.** First order is not enough for a gain change: a 10% gain change moves the
//! output by several noise standard deviations, and what the line through h leaves (the switching instants
//! move: about 0.4 noise standard deviations rms at SNR 20, in spikes at the reversals) is not noise and
//! lines up with g often enough to raise alarms (measured before the tracker: one every ~7,800 samples at a
//! period of 1e4, 13 times the unchanged rate, each called a play growth). So the reference model is not
//! frozen in its offset and gain: after each sample (once the test has used it) a recursive least-squares
//! fit of the residual on (1, h), with forgetting `1 - 1/`[`NUISANCE_MEMORY`], moves an output offset and
//! the log of the linear block's gain (the b's of the simulated model are the reference's times
//! `exp(log_gain)`), residuals clamped at 5 sigma. The model then follows a gain or offset change exactly
//! (nonlinearly: it is simulated with the new gain), and the residual is noise again within a few hundred
//! samples. A play growth is left alone: its output change `r g` is nearly orthogonal to (1, h) (on the
//! paper plant a 10% play step projects on h as a 0.6% gain change). The model at sample k depends on
//! samples before k only, so z(k) stays a log-likelihood ratio given the past; the tracker's own estimation
//! error adds about `2 / NUISANCE_MEMORY` of the noise variance to the residual.
//!
//! **A bank of CUSUMs.** A CUSUM is fastest on the change it is tuned to; a step much larger than r is
//! detected with the per-sample drift `(2 q r - r^2) gt^2 / (2 sigma^2)`, a fraction of its distance. So
//! three CUSUMs run side by side, tuned to r = `wear_ratio` x [`BANK`] (10%, 25% and 50% by default), each
//! with its own excursion window and its own threshold at a share of the false-alarm rate
//! ([`BANK_SHARE`]: half to the tuned one, a quarter to each other; the rates add up to at most
//! `1 / alarm_period`, so the bank's false alarms are no more frequent than one CUSUM's at that period). The
//! first that alarms (in the bank's order) gives the alarm and its onset, and all restart.
//!
//! **Confirmation.** The first-order nuisance also adds variance to S over short stretches, so the alarm
//! needs a second test: the generalised likelihood ratio of a play growth with an unknown offset and gain
//! change, on a window from an onset to now,
//!
//! ```text
//! d(k) = (w_r(k) - w0(k)) / r                     the play change's signature: w_r the model with both gaps
//!                                                  scaled by 1 + r, simulated from w0 at the onset on
//! G    = (e' . d')^2 / (2 sigma^2 d' . d')        if e' . d' > 0, else 0
//! ```
//!
//! with e' and d' the residuals of e and d after least squares on (1, h) within the window (from running
//! sums: no storage of the window). The signature is the play change itself, simulated (the backlash on the
//! linear block's output x, which the gaps do not change, so one more backlash step per sample): after a
//! step the wider gap holds the output until x has crossed it, then the output moves by `-r c1` on the
//! upper border and `+r m2 c2` on the lower one, and those shapes (the hold, the sign that changes with the
//! side) are what an offset or a gain change cannot make. Two kinds of window are tried:
//!
//! - the CUSUM's current excursion (since S was last 0): its onset is where S began to climb, which after a
//!   step often lags the change by several samples (the hold adds little to S). It is tried twice: with d,
//!   and with the first-order direction g for d (a play that had always been larger), which fits a gradual
//!   growth over a long excursion (a drift) better than a step simulated from the excursion's onset;
//! - each of the last [`RECENT`] samples as the onset, the samples kept in a ring and the windows replayed
//!   only while S >= H. Scanning onsets would let an offset or gain step that came after the onset pass as
//!   the hold and its end, so a scanned window must also beat every single split: its G is the smallest
//!   over the split points of the GLR with (1, h) fitted separately before and after the split (and
//!   without a split), and the window with the largest such G is the one tried.
//!
//! **The alarm comes when S >= H and G >= H for one of these windows** (S, H of one CUSUM of the bank, d
//! with its r). `gt` depends on the input and the model only, never on the present measured output, so
//! z(k) is a log-likelihood ratio of two Gaussian hypotheses about y(k) given the past, which bounds the
//! false alarms of S; the second test only removes alarms.
//!
//! # The threshold H
//!
//! For Gaussian increments with per-sample Kullback-Leibler distance `K = r^2 mean(gt^2) / (2 sigma^2)`
//! Siegmund's approximation of the CUSUM's mean run length without change is
//!
//! ```text
//! ARL0(H) = (exp(H + 1.166 d) - H - 1.166 d - 1) / K ,      d = sqrt(2 K)
//! ```
//!
//! and H solves `ARL0(H) = alarm_period / share` for the CUSUM's share of the rate ([`BANK_SHARE`]). Two uncertainties of the reference are then covered: sigma^2 is
//! the recursion's noise variance raised to its upper 97.5% bound `s^2 (1 + 2 sqrt(2 / n))` (n samples
//! behind it), and an error eps of the reference play tilts the log-likelihood ratio so that the run length
//! becomes `ARL0(H (1 - 2 eps / r))`; with eps at two standard errors of the play, each CUSUM's H is
//! divided by `1 - 4 se / (r play)` with its own r (at least 0.5). H is recomputed from the moments every [`REFRESH`] samples.
//! The test starts [`MIN_SAMPLES`] samples after the reference (the projection needs a few samples).
//!
//! # Alarm
//!
//! At an alarm the onset is the first sample of the confirming window, and the relative growth over it is
//! the window's least-squares estimate `rho = e' . d' / d' . d'` (d scaled to a unit growth, so rho is a
//! growth; the signature is that of r, not of rho, so a growth far from r is estimated less well), with
//! standard error `sigma / sqrt(d' . d')`; the play after the change is `play0 (1 + rho)`. With
//! [`MonitorConfig::follow`] the reference's gaps are then scaled by `1 + rho` (when rho > 0) and the test
//! restarts, so that a further growth (or the rest of a large step) raises a further alarm; without it the
//! test restarts on the same reference (what a false-alarm study needs). The latched alarm and the first
//! onset stay.
//!
//! # Degenerate cases
//!
//! - The refine recursion never starts (the record does not excite the model): no reference, no test,
//!   statistic 0, no alarm.
//! - A reference play of 0 (no backlash): g = 0, K = 0, the statistic stays 0 and no alarm can come (nothing
//!   to scale); [`Monitor::status`] says so.
//! - Non-finite samples are skipped (as by the estimator).
//! - Noise-free data: sigma^2 = 0 would make z infinite; sigma^2 is floored at `1e-12 max|y|^2`.
//!
//! No allocation per sample: the state is a few fixed-size arrays (the FMU's contract).

use super::{Refined, Theta};
use crate::identify::oe::sim::{SimState, backlash_step};
use serde::{Deserialize, Serialize};

/// The bank of CUSUMs: the growth each is tuned to, as a multiple of [`MonitorConfig::wear_ratio`] (module
/// docs).
pub const BANK: [f64; 3] = [1.0, 2.5, 5.0];
/// The share of the false-alarm rate `1 / alarm_period` each CUSUM of the bank may spend (summing to 1, so
/// that the bank's false alarms come no more often than once per period): half to the CUSUM tuned to
/// `wear_ratio` (its threshold 0.69 higher than alone), a quarter to each of the others (module docs).
pub const BANK_SHARE: [f64; 3] = [0.5, 0.25, 0.25];
/// Samples remembered for the confirmation's scan over recent onsets (module docs).
pub const RECENT: usize = 32;
/// Fewest samples in a confirmation window (two go to the offset and the gain).
const MIN_WINDOW: u64 = 3;
/// Samples after the reference before the test runs.
pub const MIN_SAMPLES: u64 = 200;
/// Samples between two recomputations of the threshold.
pub const REFRESH: u64 = 256;
/// Siegmund's overshoot correction of the Gaussian CUSUM (0.583 per side).
const OVERSHOOT: f64 = 1.166;
/// Smallest tilt factor of the threshold for the reference's own error.
const MIN_TILT: f64 = 0.5;
/// Memory (samples) of the tracker of the output offset and the linear block's gain (module docs).
pub const NUISANCE_MEMORY: f64 = 500.0;
/// Samples of the tracker's information before it moves the model.
const NUISANCE_START: f64 = 20.0;
/// Residuals enter the tracker clamped at this many noise standard deviations.
const NUISANCE_CLIP: f64 = 5.0;

/// What the bank's CUSUMs see of one sample: the residual `e`, the gain direction `h`, the projected play
/// direction `gt`, the linear block's output `x`, and the simulated model's output before the sample and at
/// it (`w_prev`, `w`; without the tracked offset).
struct Sample {
    e: f64,
    h: f64,
    g: f64,
    gt: f64,
    x: f64,
    w_prev: f64,
    w: f64,
}

/// One remembered sample (module docs): [x, w_prev, w, e, h, t, k] as in [`Sample`], with the time and the
/// sample index.
type Recent = [f64; 7];

/// The CUSUM test against a frozen reference (module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct Detector {
    /// The reference model and the model simulated: the reference with the tracked gain.
    reference: Theta,
    theta: Theta,
    nuisance: Nuisance,
    sim: SimState,
    sigma2: f64,
    /// The play of the reference and its standard error.
    play: f64,
    play_se: f64,
    /// Divisor of each CUSUM's threshold for the reference's error (module docs).
    tilt: [f64; BANK.len()],
    /// Samples since the reference (or the last re-reference).
    n: u64,
    /// Sums over those samples: h, h^2, g, h g, g^2.
    sh: f64,
    shh: f64,
    sg: f64,
    shg: f64,
    sgg: f64,
    /// Per CUSUM of the bank: its threshold, its statistic and the sums over its current excursion.
    threshold: [f64; BANK.len()],
    stat: [f64; BANK.len()],
    window: [Window; BANK.len()],
    /// Per CUSUM of the bank: the sums over its current excursion with the first-order direction g for d.
    first_order: [Window; BANK.len()],
    /// Per CUSUM of the bank: the output of the play-change model (the gaps scaled by its growth) simulated
    /// from the start of its current excursion (module docs).
    alt: [f64; BANK.len()],
    /// The last [`RECENT`] samples (the one counted `q` since the restart in slot `q % RECENT`) and the count.
    recent: [Recent; RECENT],
    recent_n: u64,
}

impl Detector {
    fn reset_moments(&mut self) {
        (self.n, self.sh, self.shh, self.sg, self.shg, self.sgg) = (0, 0.0, 0.0, 0.0, 0.0, 0.0);
        self.threshold = [f64::INFINITY; BANK.len()];
        self.restart();
    }

    fn restart(&mut self) {
        self.stat = [0.0; BANK.len()];
        self.window = [Window::default(); BANK.len()];
        self.first_order = [Window::default(); BANK.len()];
        self.alt = [0.0; BANK.len()];
        self.recent_n = 0;
    }

    /// (beta0, beta1) of the least-squares projection of g on (1, h) and the mean squared residual.
    fn projection(&self) -> (f64, f64, f64) {
        let n = self.n as f64;
        let det = n * self.shh - self.sh * self.sh;
        if !well_posed(det, n * self.shh) {
            // h is constant (or zero): project on the constant only.
            let b0 = self.sg / n;
            return (b0, 0.0, (self.sgg / n - b0 * b0).max(0.0));
        }
        let b0 = (self.shh * self.sg - self.sh * self.shg) / det;
        let b1 = (n * self.shg - self.sh * self.sg) / det;
        let rss = self.sgg - b0 * self.sg - b1 * self.shg;
        (b0, b1, (rss / n).max(0.0))
    }

    /// Thresholds H of the module docs from the current moments: each CUSUM of the bank at the period
    /// divided by its [`BANK_SHARE`].
    fn refresh_threshold(&mut self, r: f64, period: f64) {
        let (_, _, var) = self.projection();
        for (i, h) in self.threshold.iter_mut().enumerate() {
            let kl = (BANK[i] * r).powi(2) * var / (2.0 * self.sigma2);
            *h = threshold(kl, period / BANK_SHARE[i]) / self.tilt[i];
        }
    }

    /// Sample k at time t; `lag(j)` = u(k - delay - j). Returns the alarm, if this sample raised one.
    fn step(
        &mut self,
        cfg: &MonitorConfig,
        (k, t): (u64, f64),
        lag: impl Fn(usize) -> f64,
        y: f64,
    ) -> Option<Alarm> {
        let w_prev = self.sim.w_prev;
        let (w, _) = self.sim.step::<true>(&self.theta, lag);
        let x = self.sim.last_x();
        let e = y - (w + self.nuisance.offset);
        let th = &self.theta;
        let (na, nb, p) = (th.na, th.nb, th.p());
        let dw = &self.sim.dw;
        let g = th.v[p - 2] * dw[p - 2] + th.v[p - 1] * dw[p - 1];
        let h: f64 = (0..=nb).map(|j| th.v[na + j] * dw[na + j]).sum();
        self.n += 1;
        self.sh += h;
        self.shh += h * h;
        self.sg += g;
        self.shg += h * g;
        self.sgg += g * g;
        self.recent[(self.recent_n % RECENT as u64) as usize] = [x, w_prev, w, e, h, t, k as f64];
        self.recent_n += 1;
        if self.n < MIN_SAMPLES {
            self.track(e, h);
            return None;
        }
        if self.n == MIN_SAMPLES || self.n.is_multiple_of(REFRESH) {
            self.refresh_threshold(cfg.wear_ratio, cfg.alarm_period);
        }
        let (b0, b1, _) = self.projection();
        let gt = g - b0 - b1 * h;
        let sample = Sample {
            e,
            h,
            g,
            gt,
            x,
            w_prev,
            w,
        };
        let fired =
            (0..BANK.len()).find_map(|i| self.cusum(i, cfg.wear_ratio * BANK[i], &sample, (k, t)));
        self.track(e, h);
        fired.map(|win| self.alarm(cfg, (k, t), &win))
    }

    /// The backlash of the play-change model for growth `r`: the slope of the lower border and the gaps
    /// scaled by `1 + r`.
    fn grown(&self, r: f64) -> (f64, f64, f64) {
        let (v, p) = (&self.theta.v, self.theta.p());
        (v[p - 3], v[p - 2] * (1.0 + r), v[p - 1] * (1.0 + r))
    }

    /// The confirmation window, among those from each remembered sample (at least [`MIN_WINDOW`] back) to
    /// now, with the largest GLR of a play change by `r` beginning at its first sample against an offset and
    /// gain change at its start and at any one sample within it ([`Detector::split_glr`]), and that GLR
    /// (module docs). None without such a window.
    fn scan(&self, r: f64) -> Option<(Window, f64)> {
        let (m2, c1, c2) = self.grown(r);
        let entry = |q: u64| &self.recent[(q % RECENT as u64) as usize];
        let first = self.recent_n.saturating_sub(RECENT as u64);
        let last = self.recent_n.saturating_sub(MIN_WINDOW - 1);
        let mut best: Option<(Window, f64)> = None;
        let mut prefix = [[0.0; 9]; RECENT];
        for q0 in first..last {
            let [_, mut wa, .., t0, k0] = *entry(q0);
            let mut win = Window {
                start: k0 as u64,
                start_time: t0,
                sums: [0.0; 9],
            };
            for (q, sums) in (q0..self.recent_n).zip(prefix.iter_mut()) {
                let [x, _, w, e, h, ..] = *entry(q);
                wa = backlash_step(x, wa, m2, c1, c2).0;
                win.add(e, h, (wa - w) / r);
                *sums = win.sums;
            }
            let n = (self.recent_n - q0) as usize;
            let glr = self.split_glr(&win, &prefix[..n - 1]);
            if best.is_none_or(|(_, b)| glr > b) {
                best = Some((win, glr));
            }
        }
        best
    }

    /// The GLR of the play change on `win` against the worst single split of its offset and gain: the
    /// smallest over the split points of the GLR with (1, h) fitted separately before and after the split
    /// (`prefix[m]`: the window's sums over its first m + 1 samples), and without a split (module docs).
    fn split_glr(&self, win: &Window, prefix: &[[f64; 9]]) -> f64 {
        let mut glr = win.glr(self.sigma2);
        for head in prefix {
            let mut tail = win.sums;
            for (t, p) in tail.iter_mut().zip(head) {
                *t -= p;
            }
            let part = |sums: [f64; 9]| Window { sums, ..*win }.projected();
            let ((ed1, dd1), (ed2, dd2)) = (part(*head), part(tail));
            glr = glr.min(growth_glr(ed1 + ed2, dd1 + dd2, self.sigma2));
        }
        glr
    }

    /// CUSUM `i` of the bank, tuned to the growth `r`, on `sample`; when it alarms (S >= H and a
    /// confirmation window's GLR >= H): that window (module docs).
    fn cusum(&mut self, i: usize, r: f64, s: &Sample, (k, t): (u64, f64)) -> Option<Window> {
        let z = r * s.gt * (2.0 * s.e - r * s.gt) / (2.0 * self.sigma2);
        if !z.is_finite() {
            return None;
        }
        if self.stat[i] + z <= 0.0 {
            (self.stat[i], self.window[i]) = (0.0, Window::default());
            self.first_order[i] = Window::default();
            return None;
        }
        if self.stat[i] == 0.0 {
            (self.window[i].start, self.window[i].start_time) = (k, t);
            (self.first_order[i].start, self.first_order[i].start_time) = (k, t);
            self.alt[i] = s.w_prev;
        }
        self.stat[i] += z;
        let (m2, c1, c2) = self.grown(r);
        self.alt[i] = backlash_step(s.x, self.alt[i], m2, c1, c2).0;
        self.window[i].add(s.e, s.h, (self.alt[i] - s.w) / r);
        self.first_order[i].add(s.e, s.h, s.g);
        let h = self.threshold[i];
        if self.stat[i] < h {
            return None;
        }
        if self.window[i].glr(self.sigma2) >= h {
            return Some(self.window[i]);
        }
        if self.first_order[i].glr(self.sigma2) >= h {
            return Some(self.first_order[i]);
        }
        self.scan(r).filter(|(_, glr)| *glr >= h).map(|(w, _)| w)
    }

    /// The tracker's update with the residual `e` and sensitivity `h` of this sample (after the test used
    /// them: the test's model depends on the past only), and the linear block's b at the new gain.
    fn track(&mut self, e: f64, h: f64) {
        self.nuisance.update(e, h, self.sigma2.sqrt());
        let th = &mut self.theta;
        let f = self.nuisance.log_gain.exp();
        for j in th.na..=th.na + th.nb {
            th.v[j] = self.reference.v[j] * f;
        }
    }

    /// The alarm at sample k confirmed on the window `win` (its onset, the growth `rho` fitted on it and its
    /// standard error), then the restart of the bank (and re-reference with `follow`).
    fn alarm(&mut self, cfg: &MonitorConfig, (k, t): (u64, f64), win: &Window) -> Alarm {
        let (ed, dd) = win.projected();
        let rho = ed / dd;
        let se = (self.sigma2 / dd).sqrt();
        let alarm = Alarm {
            sample: k,
            time: t,
            onset_sample: win.start,
            onset: win.start_time,
            play_before: self.play,
            play_before_se: self.play_se,
            play_after: self.play * (1.0 + rho),
            play_after_se: self.play * se,
        };
        if cfg.follow && rho > 0.0 && rho.is_finite() {
            let p = self.theta.p();
            for th in [&mut self.theta, &mut self.reference] {
                th.v[p - 2] *= 1.0 + rho;
                th.v[p - 1] *= 1.0 + rho;
            }
            (self.play, self.play_se) = (alarm.play_after, alarm.play_after_se);
            self.reset_moments();
        } else {
            self.restart();
        }
        alarm
    }
}

/// Whether the 2 x 2 normal equations on (1, h) with determinant `det` and scale `n sum h^2` are solvable
/// (false for NaN).
fn well_posed(det: f64, scale: f64) -> bool {
    det > 1e-12 * scale.max(f64::MIN_POSITIVE)
}

/// H with `ARL0(H) = period` for per-sample distance `kl` (module docs); +inf when kl is 0 (no test).
fn threshold(kl: f64, period: f64) -> f64 {
    if !(kl > 0.0 && kl.is_finite()) {
        return f64::INFINITY;
    }
    let target = period * kl;
    // e^x - x - 1 = target: x = ln(1 + target + x), a contraction for x > 0.
    let mut x = (1.0 + target).ln().max((2.0 * target).sqrt());
    for _ in 0..50 {
        x = (1.0 + target + x).ln();
    }
    let h = x - OVERSHOOT * (2.0 * kl).sqrt();
    h.max(0.5 * x)
}

/// The wear monitor over a [`Refined`] estimator (module docs). Clone and serde-(de)serialisable (the FMU
/// state); a deserialised one must pass [`Monitor::check`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Monitor {
    cfg: MonitorConfig,
    /// Sample count at which the reference is frozen (set when the recursion starts).
    freeze_at: Option<u64>,
    det: Option<Detector>,
    first: Option<Alarm>,
    alarms: u64,
    y_max: f64,
}

impl Monitor {
    pub fn new(cfg: MonitorConfig) -> Result<Self, MonitorError> {
        cfg.validate()?;
        Ok(Self {
            cfg,
            freeze_at: None,
            det: None,
            first: None,
            alarms: 0,
            y_max: 0.0,
        })
    }

    pub fn config(&self) -> &MonitorConfig {
        &self.cfg
    }

    /// Sample (u, y) at time t through the estimator and the test: the estimator's step result and the alarm
    /// this sample raised, if any. No allocation.
    pub fn update(
        &mut self,
        est: &mut Refined,
        t: f64,
        u: f64,
        y: f64,
    ) -> (crate::identify::mrgia::StepResult, Option<Alarm>) {
        if !(u.is_finite() && y.is_finite() && t.is_finite()) {
            return (est.update(u, y), None);
        }
        let k = est.samples;
        let alarm = match self.input_delay() {
            Some(delay) => {
                let ring = &est.u_ring;
                let lag = |j: usize| {
                    let l = (delay + j) as u64;
                    if k >= l {
                        ring[((k - l) as usize) & (super::RING - 1)]
                    } else {
                        0.0
                    }
                };
                self.test_sample((k, t), lag, y)
            }
            None => None,
        };
        self.y_max = self.y_max.max(y.abs());
        let r = est.update(u, y);
        if self.det.is_none() && est.refining() {
            let at = *self.freeze_at.get_or_insert(est.samples + self.cfg.learn);
            if est.samples >= at {
                self.det = self.freeze(est);
            }
        }
        (r, alarm)
    }

    /// The test alone on sample k at time t, with `lag(j)` = u(k - d - j) for the model's delay d
    /// ([`Monitor::input_delay`]); the estimator is not stepped. [`Monitor::update`] runs it before the
    /// estimator's step; a study of the test on a frozen reference runs it alone (half the work per sample).
    /// The alarm, if this sample raised one; None while learning.
    pub fn test_sample(
        &mut self,
        (k, t): (u64, f64),
        lag: impl Fn(usize) -> f64,
        y: f64,
    ) -> Option<Alarm> {
        let alarm = self.det.as_mut()?.step(&self.cfg, (k, t), lag, y);
        if let Some(a) = alarm {
            self.alarms += 1;
            self.first.get_or_insert(a);
        }
        alarm
    }

    /// The information per sample about the relative play growth that the test uses: `mean(gt^2)` over the
    /// samples since the reference (module docs), so that a growth by q has the per-sample distance
    /// `q^2 mean(gt^2) / (2 sigma^2)` once the offset and gain are unknown (the efficient information). None
    /// while learning.
    pub fn play_information(&self) -> Option<f64> {
        self.det
            .as_ref()
            .filter(|d| d.n > 0)
            .map(|d| d.projection().2)
    }

    /// The input delay of the reference model (None while learning).
    pub fn input_delay(&self) -> Option<usize> {
        self.det.as_ref().map(|d| d.theta.delay)
    }

    /// Clear the latched alarm ([`Monitor::first_alarm`]: None again) and restart the test on the current
    /// reference: an operator's acknowledgement (the FMU's `wear_reset`). The count of alarms stays; a
    /// growth that goes on raises a new alarm.
    pub fn reset_alarm(&mut self) {
        self.first = None;
        self.restart();
    }

    /// The reference from the running recursion (module docs); None without a recursion.
    fn freeze(&self, est: &Refined) -> Option<Detector> {
        let rec = est.rec.as_ref()?;
        let mut theta = rec.theta;
        let p = theta.p();
        let (mut play, mut play_se) = play_of(est);
        if let Some(given) = self.cfg.reference_play
            && play > 0.0
        {
            let f = given / play;
            theta.v[p - 2] *= f;
            theta.v[p - 1] *= f;
            (play, play_se) = (given, 0.0);
        }
        let n = rec.w1.max(1.0);
        let floor = 1e-12 * self.y_max * self.y_max;
        let inflate = 1.0 + 2.0 * (2.0 / n).sqrt();
        let sigma2 = (rec.noise_variance() * inflate).max(floor);
        let rel = if play > 0.0 { play_se / play } else { 0.0 };
        let tilt = BANK.map(|m| (1.0 - 4.0 * rel / (m * self.cfg.wear_ratio)).max(MIN_TILT));
        let mut d = Detector {
            reference: theta,
            theta,
            nuisance: Nuisance::default(),
            sim: rec.sim,
            sigma2: if sigma2 > 0.0 {
                sigma2
            } else {
                f64::MIN_POSITIVE
            },
            play,
            play_se,
            tilt,
            n: 0,
            sh: 0.0,
            shh: 0.0,
            sg: 0.0,
            shg: 0.0,
            sgg: 0.0,
            threshold: [f64::INFINITY; BANK.len()],
            stat: [0.0; BANK.len()],
            window: [Window::default(); BANK.len()],
            first_order: [Window::default(); BANK.len()],
            alt: [0.0; BANK.len()],
            recent: [[0.0; 7]; RECENT],
            recent_n: 0,
        };
        d.reset_moments();
        Some(d)
    }

    /// Restart the test on the same reference, as after an alarm without `follow` (the alarm stays latched).
    pub fn restart(&mut self) {
        if let Some(d) = &mut self.det {
            d.restart();
        }
    }

    pub fn status(&self) -> Status {
        match &self.det {
            None => Status::Learning,
            Some(d) if d.play <= 0.0 => Status::NoPlay,
            Some(_) => Status::Testing,
        }
    }

    /// The largest of the bank's CUSUM statistics, each divided by its threshold: an alarm can come when it
    /// reaches 1 (0 while learning).
    pub fn statistic(&self) -> f64 {
        let Some(d) = &self.det else { return 0.0 };
        d.stat
            .iter()
            .zip(&d.threshold)
            .filter(|(_, h)| h.is_finite() && **h > 0.0)
            .map(|(s, h)| s / h)
            .fold(0.0, f64::max)
    }

    /// The threshold H in log-likelihood units of the CUSUM tuned to `wear_ratio` (None while learning or
    /// before the test runs).
    pub fn threshold(&self) -> Option<f64> {
        self.det
            .as_ref()
            .map(|d| d.threshold[0])
            .filter(|h| h.is_finite())
    }

    /// The reference play (after any re-reference) and its standard error; None while learning.
    pub fn reference(&self) -> Option<(f64, f64)> {
        self.det.as_ref().map(|d| (d.play, d.play_se))
    }

    /// The noise standard deviation the test uses (None while learning).
    pub fn sigma(&self) -> Option<f64> {
        self.det.as_ref().map(|d| d.sigma2.sqrt())
    }

    /// The first alarm (latched).
    pub fn first_alarm(&self) -> Option<&Alarm> {
        self.first.as_ref()
    }

    /// Alarms so far.
    pub fn alarms(&self) -> u64 {
        self.alarms
    }

    /// Consistency of a deserialised state.
    pub fn check(&self) -> Result<(), String> {
        self.cfg.validate().map_err(|e| e.to_string())?;
        let Some(d) = &self.det else { return Ok(()) };
        let vals = [
            d.sigma2,
            d.play,
            d.play_se,
            d.sh,
            d.shh,
            d.sg,
            d.shg,
            d.sgg,
            d.nuisance.offset,
            d.nuisance.log_gain,
        ];
        let ok = vals
            .iter()
            .chain(d.window.iter().chain(&d.first_order).flat_map(|w| &w.sums))
            .chain(&d.stat)
            .chain(&d.tilt)
            .chain(&d.nuisance.info)
            .all(|v| v.is_finite())
            && d.sigma2 > 0.0
            && d.stat.iter().all(|s| *s >= 0.0)
            && d.tilt.iter().all(|t| *t > 0.0)
            && d.sim.pos < 4
            && d.alt
                .iter()
                .chain(d.recent.iter().flatten())
                .all(|v| v.is_finite())
            && d.theta
                .v
                .iter()
                .chain(&d.reference.v)
                .all(|v| v.is_finite());
        if ok {
            Ok(())
        } else {
            Err("wear monitor state: inconsistent test".into())
        }
    }
}

/// The play c1 + c2 of the estimator's current estimate and its standard error (0 while unknown). No
/// allocation.
pub fn play_of(est: &Refined) -> (f64, f64) {
    let v = est.values();
    let p = est.config().n_params();
    let play = v[p - 2] + v[p - 1];
    let se = match &est.rec {
        Some(r) => {
            let (i, j) = (p - 2, p - 1);
            let var = r.p[i][i] + r.p[j][j] + 2.0 * r.p[i][j];
            (r.noise_variance() * var * r.w2 / r.w1).max(0.0).sqrt()
        }
        None => 0.0,
    };
    (play, se)
}

mod config;
mod session;
pub mod study;
mod window;

pub use config::{Alarm, MonitorConfig, MonitorError, Status};
pub use session::{Session, Summary};
use window::{Nuisance, Window, growth_glr};
#[cfg(test)]
mod tests;
