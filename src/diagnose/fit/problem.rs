//! Fitting models on a record: the fit part, its exploration window, the linear model and the plain
//! backlash model with their starts. The strategy of every fit (`Problem::fit`): screen many starts by
//! their cost on the exploration window, run short fits from the best few there, refine the best on the
//! whole fit part (which, with the statistical stopping rule of [`crate::diagnose::fit::lm`], takes a few iterations).

use std::cell::RefCell;

thread_local! {
    /// Each thread's simulation buffers (fits evaluate Jacobian columns on all cores).
    static SCRATCH: RefCell<Simulation> = RefCell::new(Simulation::default());
}
use std::time::Instant;

use rand_chacha::ChaCha8Rng;
use rand_core::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

use crate::diagnose::fit::lm::{LmOptions, cost_of, evaluate, levenberg_marquardt};
use crate::diagnose::fit::model::{
    BaseModel, EffectModel, Objective, Rest, Scales, Simulation, coefficient_scales, is_stable,
};
use crate::diagnose::fit::orders::Structure;
use crate::diagnose::record::excitation_of;
use crate::identify::mrgia::{Mrgia, MrgiaConfig};
use crate::identify::oe::{self, OeConfig};
use crate::stats::std_dev;

/// Exploration (screening grids of starts, short runs) uses at most this many samples of the fit part.
pub const EXPLORE_SAMPLES: usize = 20_000;

/// Iterations of each short run from a start during exploration.
pub const EXPLORE_ITER: usize = 8;

/// Iterations of the refinement on the whole fit part after exploring on a shorter window.
pub const POLISH_ITER: usize = 6;

/// The refinement gives up on a step once the damping passes this (near the optimum a step that needs more
/// damping moves nothing that matters; each rejected step costs a simulation of the whole fit part).
pub const POLISH_LAMBDA_MAX: f64 = 1e2;

/// With more starts than this, a fit ranks them by cost and refines only this many.
const SCREEN_KEEP: usize = 6;

/// A bound on |x| beyond which a simulation counts as diverged.
pub fn sim_limit(u: &[f64], y: &[f64]) -> f64 {
    let umax = u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let ymax = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    1e4 * (1.0 + umax + ymax)
}

/// A record split into a fit part (and its exploration window) and a held-out part, with the scales the fits
/// need.
#[derive(Clone)]
pub(crate) struct Problem<'a> {
    pub u: &'a [f64],
    pub y: &'a [f64],
    /// The input level at which every simulation starts at rest.
    pub rest: Rest,
    pub n_fit: usize,
    /// The held-out part is samples `held_from..`: `n_fit`, or later where the fit part is a window of the
    /// record's ([`Problem::verdict_window`]).
    pub held_from: usize,
    /// Exploration uses samples `0..n_explore` (at most the fit part).
    pub n_explore: usize,
    pub limit: f64,
    pub time_scale: f64,
    pub y_scale: f64,
    pub x_scale: f64,
    /// The input's scale on the fit part (its standard deviation, at least 1e-12).
    pub u_scale: f64,
    pub lm: LmOptions,
    /// Told what the diagnosis is doing, stage by stage (a progress display; may be called from any thread).
    pub progress: &'a (dyn Fn(&str) + Sync),
}

impl<'a> Problem<'a> {
    pub fn new(u: &'a [f64], y: &'a [f64], n_fit: usize, lm: LmOptions) -> Self {
        let y_fit = &y[..n_fit];
        let y_scale =
            std_dev(y_fit).max(1e-12 * (1.0 + y_fit.iter().fold(0.0f64, |m, v| m.max(v.abs()))));
        Self {
            u,
            y,
            rest: Rest::ZERO,
            n_fit,
            held_from: n_fit,
            n_explore: n_fit.min(EXPLORE_SAMPLES),
            limit: sim_limit(u, y),
            time_scale: n_fit as f64,
            y_scale,
            x_scale: y_scale,
            u_scale: std_dev(&u[..n_fit]).max(1e-12),
            lm,
            progress: &|_| {},
        }
    }

    /// The same record with a shorter fit part (samples `0..n_fit`), for choosing on the rest of it.
    pub fn shortened(&self, n_fit: usize) -> Self {
        Self {
            time_scale: n_fit as f64,
            ..self.resplit(n_fit)
        }
    }

    /// The same record split elsewhere (held out from `held_from` on, fit part `0..held_from`), its scales
    /// kept: a model fitted on `self` means the same on it (a drift's rate is per the same time scale), so it
    /// can be refitted from there. Where `self` fits on a window ([`Problem::verdict_window`]), the window
    /// stays the fit part as far as it lies before the new held-out part.
    pub fn resplit(&self, held_from: usize) -> Self {
        let n_fit = if self.n_fit < self.held_from {
            self.n_fit.min(held_from)
        } else {
            held_from
        };
        Self {
            n_fit,
            held_from,
            n_explore: n_fit.min(EXPLORE_SAMPLES),
            ..self.clone()
        }
    }

    /// The input's excitation on the held-out part over the fit part's ([`excitation_of`]: the ratios of
    /// standard deviation and of range).
    pub fn held_out_excitation(&self) -> (f64, f64) {
        excitation_of(&self.u[..self.n_fit], &self.u[self.held_from..])
    }

    /// The record as the verdict on play judges it: on a long record (exploration on a window of the fit
    /// part) that window is the fit part, and the held-out part stays where it is, so that every model the
    /// verdict compares is fitted on the same first [`EXPLORE_SAMPLES`] samples and scored on the same
    /// held-out part (like with like, at a window's cost); `self` elsewhere.
    pub fn verdict_window(&self) -> Self {
        Self {
            n_fit: self.n_explore,
            ..self.clone()
        }
    }

    /// The settings of the refinement on the whole fit part: when exploration ran on a shorter window, the
    /// start is already near the optimum and at most [`POLISH_ITER`] iterations refine it (each costs a few
    /// simulations of the whole fit part).
    fn polish(&self) -> LmOptions {
        if self.windowed() {
            LmOptions {
                max_iter: self.lm.max_iter.min(POLISH_ITER),
                lambda_max: self.lm.lambda_max.min(POLISH_LAMBDA_MAX),
                ..self.lm
            }
        } else {
            self.lm
        }
    }

    /// The settings of a short run from each kept start during exploration: at most [`EXPLORE_ITER`]
    /// iterations.
    fn exploration(&self) -> LmOptions {
        LmOptions {
            max_iter: self.lm.max_iter.min(EXPLORE_ITER),
            ..self.lm
        }
    }

    /// Is exploration on a window shorter than the fit part?
    pub fn windowed(&self) -> bool {
        self.n_explore < self.n_fit
    }

    pub fn out_of_time(&self) -> bool {
        self.lm.deadline.is_some_and(|d| Instant::now() >= d)
    }

    /// Residuals of `m` on samples `0..n` into `out`.
    fn residuals(
        &self,
        m: &EffectModel,
        obj: Objective,
        n: usize,
        scratch: &mut Simulation,
        out: &mut Vec<f64>,
    ) -> bool {
        if !m.simulate_into(self.u, self.rest, n, self.limit, scratch) {
            return false;
        }
        let y = &self.y[..n];
        match (obj, m.noise()) {
            (Objective::Prediction, Some(phi)) => {
                if phi.iter().any(|p| !p.is_finite()) {
                    return false;
                }
                out.extend(
                    m.predict_from(&scratch.y, y)
                        .iter()
                        .zip(y)
                        .map(|(p, v)| v - p),
                );
            }
            _ => out.extend(y.iter().zip(&scratch.y).map(|(a, b)| a - b)),
        }
        true
    }

    /// The fit-part cost of `m` (sum of squared residuals of the objective), `None` if it is not valid.
    pub fn cost(&self, m: &EffectModel, obj: Objective) -> Option<f64> {
        let mut out = Vec::with_capacity(self.n_fit);
        let ok = self.residuals(m, obj, self.n_fit, &mut Simulation::default(), &mut out);
        let c = cost_of(&out);
        (ok && c.is_finite()).then_some(c)
    }

    /// Typical magnitudes of the packed parameters of `m`: the base model's, then each extension's as its
    /// element gives them from the data's scales.
    fn typical(&self, m: &EffectModel) -> Vec<f64> {
        let scales = Scales {
            y: self.y_scale,
            x: self.x_scale.max(1e-12),
            u: self.u_scale,
            n_fit: self.n_fit,
        };
        let mut t = m.base.typical(self.y_scale);
        for e in &m.exts {
            t.extend(e.element.typical(e, &scales));
        }
        t
    }

    /// Fit `template`'s structure from `starts`. Returns the model and its fit-part cost.
    pub fn fit(
        &self,
        template: &EffectModel,
        starts: &[EffectModel],
        obj: Objective,
    ) -> Option<(EffectModel, f64)> {
        let (th, _) = self.explore(template, starts, obj)?;
        self.polish_from(template, &th, obj)
    }

    /// Fit several structures (each a template with its starts) and keep the lowest cost. On a long record
    /// (exploration on a window) the structures are ranked by their explored cost on the window and only the
    /// best is refined on the whole fit part: each refinement costs several simulations of the whole record,
    /// and the ranking of structures that differ in a delay or an order is settled on the window already.
    pub fn fit_alternatives(
        &self,
        alternatives: &[(&EffectModel, &[EffectModel])],
        obj: Objective,
    ) -> Option<(EffectModel, f64)> {
        let explored = alternatives.iter().filter_map(|(template, starts)| {
            Some((*template, self.explore(template, starts, obj)?))
        });
        if self.windowed() {
            // Every structure was explored on the window here, so each has its window cost.
            let window_cost = |c: Option<f64>| c.unwrap_or(f64::INFINITY);
            let (template, (th, _)) =
                explored.min_by(|a, b| window_cost(a.1.1).total_cmp(&window_cost(b.1.1)))?;
            return self.polish_from(template, &th, obj);
        }
        explored
            .filter_map(|(template, (th, _))| self.polish_from(template, &th, obj))
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// Explore `template`'s structure from `starts` on the exploration window: the packed parameters of the
    /// best point and its cost there (see [`Problem::explore_packed`]).
    pub fn explore(
        &self,
        template: &EffectModel,
        starts: &[EffectModel],
        obj: Objective,
    ) -> Option<(Vec<f64>, Option<f64>)> {
        let ts = self.time_scale;
        let packed: Vec<Vec<f64>> = starts.iter().map(|s| s.pack(ts)).collect();
        let unpack = |th: &[f64]| template.unpack(th, ts);
        self.explore_packed(&unpack, &packed, &self.typical(template), obj)
    }

    /// Refine packed parameters of `template`'s structure on the whole fit part.
    pub fn polish_from(
        &self,
        template: &EffectModel,
        theta: &[f64],
        obj: Objective,
    ) -> Option<(EffectModel, f64)> {
        let ts = self.time_scale;
        let unpack = |th: &[f64]| template.unpack(th, ts);
        let (th, cost) = self.polish_packed(&unpack, theta, &self.typical(template), obj)?;
        Some((unpack(&th), cost))
    }

    /// Residuals of the parametrisation `unpack` on samples `0..n`, for the fitter.
    fn on<'s>(
        &'s self,
        unpack: &'s (dyn Fn(&[f64]) -> EffectModel + Sync),
        obj: Objective,
        n: usize,
    ) -> impl Fn(&[f64], &mut Vec<f64>) -> bool + Sync + 's {
        move |th: &[f64], out: &mut Vec<f64>| {
            SCRATCH.with_borrow_mut(|scratch| self.residuals(&unpack(th), obj, n, scratch, out))
        }
    }

    /// The fitting strategy for any parametrisation: explore, then refine on the whole fit part.
    fn fit_packed(
        &self,
        unpack: &(dyn Fn(&[f64]) -> EffectModel + Sync),
        starts: &[Vec<f64>],
        typ: &[f64],
        obj: Objective,
    ) -> Option<(Vec<f64>, f64)> {
        let (th, _) = self.explore_packed(unpack, starts, typ, obj)?;
        self.polish_packed(unpack, &th, typ, obj)
    }

    /// Screen many starts by their cost on the exploration window and keep [`SCREEN_KEEP`]; run a short fit
    /// (8 iterations) from each on the window. Returns the best point and its window cost; a single start on
    /// a record short enough to need no window is returned as it is, unevaluated (cost `None`: the
    /// refinement evaluates it first thing).
    fn explore_packed(
        &self,
        unpack: &(dyn Fn(&[f64]) -> EffectModel + Sync),
        starts: &[Vec<f64>],
        typ: &[f64],
        obj: Objective,
    ) -> Option<(Vec<f64>, Option<f64>)> {
        let window = self.on(unpack, obj, self.n_explore);
        let mut kept: Vec<&Vec<f64>> = starts.iter().collect();
        if kept.len() > SCREEN_KEEP {
            let mut r = Vec::new();
            let mut window_cost = |th: &[f64]| evaluate(&window, th, &mut r);
            let mut scored: Vec<(f64, &Vec<f64>)> = starts
                .iter()
                .filter_map(|s| Some((window_cost(s)?, s)))
                .collect();
            scored.sort_by(|a, b| a.0.total_cmp(&b.0));
            kept = scored
                .into_iter()
                .take(SCREEN_KEEP)
                .map(|(_, s)| s)
                .collect();
        }
        if kept.len() == 1 && !self.windowed() {
            return Some((kept[0].clone(), None));
        }
        let short = self.exploration();
        kept.into_iter()
            .filter_map(|s| levenberg_marquardt(&window, s, typ, &[], &short).ok())
            .map(|fit| (fit.theta, fit.cost))
            .reduce(|best, f| if f.1 < best.1 { f } else { best })
            .map(|(th, cost)| (th, Some(cost)))
    }

    /// Refine on the whole fit part (see [`Problem::polish`] for the settings).
    fn polish_packed(
        &self,
        unpack: &(dyn Fn(&[f64]) -> EffectModel + Sync),
        theta: &[f64],
        typ: &[f64],
        obj: Objective,
    ) -> Option<(Vec<f64>, f64)> {
        let fit = levenberg_marquardt(
            &self.on(unpack, obj, self.n_fit),
            theta,
            typ,
            &[],
            &self.polish(),
        )
        .ok()?;
        Some((fit.theta, fit.cost))
    }

    /// MRGIA (recommended setting) on the fit part, as a start.
    pub fn mrgia_start(&self, s: Structure) -> Option<BaseModel> {
        let mut est = Mrgia::new(MrgiaConfig::recommended(s.na, s.nb, s.delay)).ok()?;
        for k in 0..self.n_fit {
            est.update(self.u[k], self.y[k]);
        }
        let e = est.estimate();
        let ok =
            e.a.iter()
                .chain(&e.b)
                .chain([&e.m2, &e.c1, &e.c2])
                .all(|v| v.is_finite());
        ok.then(|| BaseModel {
            na: s.na,
            nb: s.nb,
            delay: s.delay,
            a: e.a.clone(),
            b: e.b.clone(),
            m1: 1.0,
            m2: usable_slope(e.m2),
            c1: e.c1,
            c2: e.c2,
        })
    }

    /// The output-error fit of `identify oe` (from MRGIA's estimates, from rest at 0) on the fit part, as a
    /// start; `None` when it refuses the record.
    pub fn oe_start(&self, s: Structure) -> Option<BaseModel> {
        let cfg = OeConfig::new(s.na, s.nb, s.delay);
        let f = oe::fit(&cfg, &self.u[..self.n_fit], &self.y[..self.n_fit]).ok()?;
        let e = f.estimate;
        Some(BaseModel {
            na: s.na,
            nb: s.nb,
            delay: s.delay,
            a: e.a,
            b: e.b,
            m1: 1.0,
            m2: e.m2,
            c1: e.c1,
            c2: e.c2,
        })
    }

    /// The first sample at which every regressor of `s` is measured.
    pub fn arx_start(s: Structure) -> usize {
        s.na.max(s.delay + s.nb)
    }

    /// The regressors of y(k) for the structure `s` into `row` (na + nb + 2 entries): -y(k-1..k-na),
    /// u(k-delay..k-delay-nb), 1. `k` is at least [`Problem::arx_start`].
    pub fn arx_row(&self, s: Structure, k: usize, row: &mut [f64]) {
        let (na, nb, delay) = (s.na, s.nb, s.delay);
        for (i, r) in row.iter_mut().take(na).enumerate() {
            *r = -self.y[k - 1 - i];
        }
        for j in 0..=nb {
            row[na + j] = self.u[k - delay - j];
        }
        row[na + nb + 1] = 1.0;
    }

    /// Equation-error least squares of y on its past, the delayed inputs and a constant, on the fit part:
    /// (a, b, the constant as an output offset: `y = x + offset` with x the linear block's output). `None` when the record is too short for the structure or the equations are singular.
    pub fn arx(&self, s: Structure) -> Option<(Vec<f64>, Vec<f64>, f64)> {
        use nalgebra::{DMatrix, DVector};
        let (na, nb) = (s.na, s.nb);
        let k0 = Self::arx_start(s);
        if self.n_fit <= k0 + na + nb + 3 {
            return None;
        }
        let cols = na + nb + 2;
        let mut h = DMatrix::<f64>::zeros(cols, cols);
        let mut g = DVector::<f64>::zeros(cols);
        let mut row = vec![0.0; cols];
        for k in k0..self.n_fit {
            self.arx_row(s, k, &mut row);
            for a in 0..cols {
                g[a] += row[a] * self.y[k];
                for b in 0..=a {
                    h[(a, b)] += row[a] * row[b];
                }
            }
        }
        for a in 0..cols {
            for b in a + 1..cols {
                h[(a, b)] = h[(b, a)];
            }
        }
        // A ridge relative to each column's own size (not the largest one's), so that the fit does not
        // depend on the record's units; a column of zeros gets coefficient 0.
        for i in 0..cols {
            let d = h[(i, i)];
            h[(i, i)] = if d > 0.0 { d * (1.0 + 1e-9) } else { 1.0 };
        }
        let th = h.cholesky()?.solve(&g);
        let a: Vec<f64> = th.iter().take(na).copied().collect();
        // The equation's constant c enters the dynamics; at the output it is c / (1 + sum a).
        let den = 1.0 + a.iter().sum::<f64>();
        let offset = if den.abs() > 1e-6 {
            th[cols - 1] / den
        } else {
            th[cols - 1]
        };
        (th.iter().all(|v| v.is_finite()) && offset.is_finite()).then(|| {
            (
                a,
                th.iter().skip(na).take(nb + 1).copied().collect(),
                offset,
            )
        })
    }
}

/// The linear model as a backlash with no play: `y = x + offset` on both borders.
pub fn linear_base(s: Structure, a: &[f64], b: &[f64], offset: f64) -> BaseModel {
    BaseModel {
        na: s.na,
        nb: s.nb,
        delay: s.delay,
        a: a.to_vec(),
        b: b.to_vec(),
        m1: 1.0,
        m2: 1.0,
        c1: -offset,
        c2: offset,
    }
}

/// The best linear output-error model of the structure: from the equation-error fit (stabilised) and from
/// its FIR part, parameters a, b and the offset. Returns the model and its fit-part cost.
pub(crate) fn fit_linear(p: &Problem, s: Structure) -> Option<(BaseModel, f64)> {
    let mean_y = crate::stats::mean(&p.y[..p.n_fit]);
    let (mut a, b, offset) = p
        .arx(s)
        .unwrap_or((vec![0.0; s.na], vec![0.0; s.nb + 1], mean_y));
    stabilize(&mut a);
    let pack = |a: &[f64], b: &[f64], o: f64| {
        let mut v = a.to_vec();
        v.extend(b);
        v.push(o);
        v
    };
    let na = s.na;
    let nb = s.nb;
    let unpack = move |th: &[f64]| {
        EffectModel::plain(linear_base(
            s,
            &th[..na],
            &th[na..na + nb + 1],
            th[na + nb + 1],
        ))
    };
    let gain = linear_base(s, &a, &b, offset).static_gain();
    let mut fir = vec![0.0; nb + 1];
    fir[0] = gain;
    let starts = vec![
        pack(&a, &b, offset),
        pack(&vec![0.0; na], &fir, offset),
        pack(&vec![0.0; na], &vec![0.0; nb + 1], mean_y),
    ];
    let mut typ = coefficient_scales(na, &b, gain);
    typ.push(p.y_scale);
    // When the fit fails on the whole fit part (a point explored on the window that is not valid over the
    // whole of it), the best valid start is the linear model: a record is never refused for want of one.
    let (th, cost) = p
        .fit_packed(&unpack, &starts, &typ, Objective::Simulation)
        .or_else(|| {
            starts
                .iter()
                .filter_map(|th| Some((th.clone(), p.cost(&unpack(th), Objective::Simulation)?)))
                .min_by(|a, b| a.1.total_cmp(&b.1))
        })?;
    Some((unpack(&th).base, cost))
}

/// The estimator's lower-border slope as a start: itself when above 1e-3, else 1 (a flat or reversed
/// border is no backlash to start from).
fn usable_slope(m2: f64) -> f64 {
    if m2 > 1e-3 { m2 } else { 1.0 }
}

/// Give a start whose memory zone is inverted or narrower than `min_gap` (half-width `(c1 + c2) / 2`) the
/// half-width `min_gap`, keeping its offset `(c2 - c1) / 2`: such a start is not a backlash.
fn open_play(m: &mut BaseModel, min_gap: f64) {
    let (offset, gap) = ((m.c2 - m.c1) / 2.0, (m.c1 + m.c2) / 2.0);
    if gap < min_gap {
        m.c1 = min_gap - offset;
        m.c2 = min_gap + offset;
    }
}

/// Pull an unstable start's poles inside the unit circle: a_i -> a_i r^i (every root scaled by r = 0.9)
/// until stable.
pub(crate) fn stabilize(a: &mut [f64]) {
    for _ in 0..200 {
        if is_stable(a) {
            return;
        }
        let mut r = 1.0;
        for v in a.iter_mut() {
            r *= 0.9;
            *v *= r;
        }
    }
    a.iter_mut().for_each(|v| *v = 0.0);
}

/// The plain model's starts: MRGIA's estimate, the least-squares model with unit slopes and its constant
/// turned into gaps around a small play, a start without dynamics, every one stable and with its play open;
/// then the fit of `identify oe` on the fit part, the linear model (`linear`, no play) and the linear model with a
/// small play opened around it.
fn plain_starts(p: &Problem, s: Structure, linear: &BaseModel) -> Vec<BaseModel> {
    let mut starts: Vec<BaseModel> = Vec::new();
    starts.extend(p.mrgia_start(s));
    if let Some((a, b, o)) = p.arx(s) {
        // Unit slopes, the constant turned into gaps around a small play.
        let gap = 0.05 * p.y_scale;
        starts.push(BaseModel {
            c1: -o + gap,
            c2: o + gap,
            ..linear_base(s, &a, &b, 0.0)
        });
    }
    // Always one start without dynamics (stable whatever the data), with the last start's gain if any.
    let b0 = starts.last().map_or(vec![1.0; s.nb + 1], |m| m.b.clone());
    starts.push(BaseModel {
        b: b0,
        ..BaseModel::zero(s.na, s.nb, s.delay)
    });
    for m in &mut starts {
        stabilize(&mut m.a);
        open_play(m, 0.01 * p.y_scale);
    }
    // The output-error fit of `identify oe` on the fit part (its own starts and fitter), so that a declared
    // structure starts where `identify oe` ends.
    starts.extend(p.oe_start(s));
    // The linear model itself (no play) and with a small play opened around it.
    starts.push(linear.clone());
    starts.push(BaseModel {
        c1: linear.c1 + 0.01 * p.y_scale,
        c2: linear.c2 + 0.01 * p.y_scale,
        ..linear.clone()
    });
    starts
}

/// A restart explored on the window is refined on the whole fit part only if the optimum it reached there
/// (`window_cost`) is below the best model's own optimum there; when the best has none on the window, any
/// restart is worth refining.
fn worth_refining(window_cost: f64, best_window: Option<f64>) -> bool {
    best_window.is_none_or(|b| window_cost < b)
}

/// Fit the plain backlash model: MRGIA, least-squares, linear and dynamics-free starts, then perturbed
/// restarts; never above the linear model's cost (`linear`).
pub(crate) fn fit_plain(
    p: &Problem,
    s: Structure,
    restarts: usize,
    seed: u64,
    linear: &(BaseModel, f64),
) -> Option<(EffectModel, f64)> {
    let models: Vec<EffectModel> = plain_starts(p, s, &linear.0)
        .into_iter()
        .map(EffectModel::plain)
        .collect();
    let template = models[0].clone();
    let (lin, lin_cost) = linear;
    // A fit that fails on the whole fit part (see `fit_linear`) leaves the linear model.
    let Some((mut best, mut cost)) = p.fit(&template, &models, Objective::Simulation) else {
        return lin_cost
            .is_finite()
            .then(|| (EffectModel::plain(lin.clone()), *lin_cost));
    };
    // Perturbed restarts in CHAINS independent chains from the same best, each seeded by its own index;
    // the user's seed only orders the chains, and the lowest cost over all of them wins (ties to the lower
    // chain), so that no seed picks the answer.
    // On a long record restarts are explored on the window, judged against the best's optimum there: both
    // computed once, shared by the chains.
    let window = p.windowed().then(|| p.shortened(p.n_explore));
    let best_window = window.as_ref().and_then(|w| {
        w.fit(&best, std::slice::from_ref(&best), Objective::Simulation)
            .map(|(_, c)| c)
    });
    let ends: Vec<(u64, EffectModel, f64)> = (0..CHAINS)
        .map(|i| (i + seed) % CHAINS)
        .map(|c| {
            let start = (best.clone(), cost, best_window);
            let (m, k) = restart_chain(p, s, window.as_ref(), start, (restarts, c));
            (c, m, k)
        })
        .collect();
    if let Some((_, m, k)) = ends
        .into_iter()
        .min_by(|a, b| a.2.total_cmp(&b.2).then(a.0.cmp(&b.0)))
    {
        (best, cost) = (m, k);
    }
    if cost > *lin_cost {
        return Some((EffectModel::plain(lin.clone()), *lin_cost));
    }
    Some((best, cost))
}

/// Independent chains of perturbed restarts of the plain fit.
pub const CHAINS: u64 = 3;

/// One chain of `restarts` perturbed restarts around the best so far (model, fit-part cost and its optimum on
/// the exploration `window`, when the record is long enough to have one), seeded by `chain`. On a long record
/// a restart is explored on the window and refined on the whole fit part only if the optimum it reaches there
/// is lower than the best's own optimum there (the best, refined on the whole fit part, sits off the window's
/// optimum: its raw window cost would let almost every restart through, each costing a refinement).
fn restart_chain(
    p: &Problem,
    s: Structure,
    window: Option<&Problem>,
    (mut best, mut cost, mut best_window): (EffectModel, f64, Option<f64>),
    (restarts, chain): (usize, u64),
) -> (EffectModel, f64) {
    let mut rng = ChaCha8Rng::seed_from_u64(chain ^ 0xD1A6_0000);
    let typ = best.base.typical(p.y_scale);
    for _ in 0..restarts {
        if p.out_of_time() {
            break;
        }
        let th: Vec<f64> = best
            .pack(p.time_scale)
            .iter()
            .zip(&typ)
            .enumerate()
            .map(|(j, (v, t))| {
                let z: f64 = StandardNormal.sample(&mut rng);
                if j < s.na {
                    v * (1.0 + 0.1 * z)
                } else {
                    v + 0.3 * t * z
                }
            })
            .collect();
        let start = best.unpack(&th, p.time_scale);
        if let Some(w) = window {
            let Some((m, c)) = w.fit(&best, std::slice::from_ref(&start), Objective::Simulation)
            else {
                continue;
            };
            if !worth_refining(c, best_window) {
                continue;
            }
            if let Some((m, c_full)) =
                p.polish_from(&best, &m.pack(p.time_scale), Objective::Simulation)
                && c_full < cost
            {
                best = m;
                cost = c_full;
                best_window = Some(c);
            }
        } else if let Some((m, c)) = p.fit(&best, &[start], Objective::Simulation)
            && c < cost
        {
            best = m;
            cost = c;
        }
    }
    (best, cost)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Refined only when strictly below the best's window optimum, or when the best has none.
    #[test]
    fn a_restart_is_refined_only_below_the_best_window_optimum() {
        assert!(worth_refining(5.0, None));
        assert!(worth_refining(1.0, Some(2.0)));
        assert!(!worth_refining(2.0, Some(2.0)));
        assert!(!worth_refining(3.0, Some(2.0)));
    }

    /// A constant input is collinear with the equation's constant: the ridge relative to each column keeps the
    /// equations solvable, and what the record determines comes out. y(k) = 0.6 y(k-1) + 2 u(k-1) from rest at
    /// 0 with u = 1: the transient identifies a1 = -0.6 (the crate's sign: x(k) = -a1 x(k-1) + ...), and the
    /// steady state b0 / (1 + a1) + offset = 2 / 0.4 = 5, however b0 and the constant share the 2.
    #[test]
    fn arx_with_a_constant_input_is_solved() {
        let n = 400;
        let u = vec![1.0; n];
        let mut y = vec![0.0; n];
        for k in 1..n {
            y[k] = 0.6 * y[k - 1] + 2.0 * u[k - 1];
        }
        let p = Problem::new(&u, &y, 300, LmOptions::default());
        let (a, b, offset) = p
            .arx(Structure {
                na: 1,
                nb: 0,
                delay: 1,
            })
            .expect("a constant input is solved, not refused");
        assert!((a[0] + 0.6).abs() < 1e-6, "{a:?}");
        let steady = b[0] / (1.0 + a[0]) + offset;
        assert!((steady - 5.0).abs() < 1e-6, "{b:?} {offset}");
    }

    /// Noise-free data of a second-order block with a delay of 2 and two input lags,
    /// x(k) = -a1 x(k-1) - a2 x(k-2) + b0 u(k-2) + b1 u(k-3) with a1 = -0.5, a2 = 0.2, b0 = 1.5, b1 = -0.4,
    /// plus an output offset of 3: the least squares return exactly these (each lag in its place) and the
    /// offset.
    #[test]
    fn arx_recovers_every_lag_in_its_place() {
        let n = 600;
        let u: Vec<f64> = (0..n)
            .map(|k| (0.3 * k as f64).sin() + (1.1 * k as f64).sin())
            .collect();
        let mut x = vec![0.0; n];
        for k in 3..n {
            x[k] = 0.5 * x[k - 1] - 0.2 * x[k - 2] + 1.5 * u[k - 2] - 0.4 * u[k - 3];
        }
        let y: Vec<f64> = x.iter().map(|v| v + 3.0).collect();
        let p = Problem::new(&u, &y, 500, LmOptions::default());
        let (a, b, offset) = p
            .arx(Structure {
                na: 2,
                nb: 1,
                delay: 2,
            })
            .unwrap();
        for (got, want) in a
            .iter()
            .chain(&b)
            .chain([&offset])
            .zip([-0.5, 0.2, 1.5, -0.4, 3.0])
        {
            assert!((got - want).abs() < 1e-6, "{a:?} {b:?} {offset}");
        }
    }

    /// Refining after exploring on a window caps the iterations and the damping; without a window the fit's
    /// own settings hold.
    #[test]
    fn polish_is_capped_only_after_a_window() {
        let n = EXPLORE_SAMPLES + 100;
        let (u, y) = (vec![0.0; n], vec![0.0; n]);
        let lm = LmOptions::default();
        let whole = Problem::new(&u, &y, n, lm);
        assert!(whole.windowed());
        let capped = whole.polish();
        assert_eq!(
            (capped.max_iter, capped.lambda_max),
            (POLISH_ITER, POLISH_LAMBDA_MAX)
        );
        assert_eq!(capped.max_evals, lm.max_evals);
        let short = Problem::new(&u, &y, EXPLORE_SAMPLES, lm);
        assert!(!short.windowed());
        assert_eq!(short.polish(), lm);
    }

    /// A shortened problem fits on its own first samples: fit part, exploration window and time scale follow
    /// the new length; exploration runs are capped at [`EXPLORE_ITER`] iterations.
    #[test]
    fn a_shortened_problem_and_the_exploration_settings() {
        let n = 3 * EXPLORE_SAMPLES;
        let (u, y) = (vec![0.0; n], vec![0.0; n]);
        let p = Problem::new(&u, &y, 2 * EXPLORE_SAMPLES, LmOptions::default());
        let short = p.shortened(500);
        assert_eq!(
            (short.n_fit, short.n_explore, short.time_scale),
            (500, 500, 500.0)
        );
        let long = p.shortened(EXPLORE_SAMPLES + 1);
        assert_eq!(long.n_explore, EXPLORE_SAMPLES);
        assert_eq!(p.exploration().max_iter, EXPLORE_ITER);
        assert_eq!(p.exploration().max_evals, p.lm.max_evals);
    }

    /// The verdict's window: on a long record the fit part is the exploration window and the held-out part
    /// stays where the split put it; moved to another split, the window stays the fit part as far as it
    /// lies before the new held-out part; a short record is judged as it is.
    #[test]
    fn the_verdict_fits_on_the_window_and_holds_out_the_split_s_rest() {
        let n = 3 * EXPLORE_SAMPLES;
        let (u, y) = (vec![0.0; n], vec![0.0; n]);
        let p = Problem::new(&u, &y, 2 * EXPLORE_SAMPLES, LmOptions::default());
        assert_eq!(p.held_from, p.n_fit);
        let v = p.verdict_window();
        assert_eq!(
            (v.n_fit, v.n_explore, v.held_from, v.time_scale),
            (
                EXPLORE_SAMPLES,
                EXPLORE_SAMPLES,
                2 * EXPLORE_SAMPLES,
                p.time_scale
            )
        );
        assert!(!v.windowed());
        let later = v.resplit(2 * EXPLORE_SAMPLES + 7);
        assert_eq!(
            (later.n_fit, later.held_from),
            (EXPLORE_SAMPLES, 2 * EXPLORE_SAMPLES + 7)
        );
        let early = v.resplit(EXPLORE_SAMPLES - 9);
        assert_eq!(
            (early.n_fit, early.held_from),
            (EXPLORE_SAMPLES - 9, EXPLORE_SAMPLES - 9)
        );
        let whole = p.resplit(EXPLORE_SAMPLES + 3);
        assert_eq!(
            (whole.n_fit, whole.held_from),
            (EXPLORE_SAMPLES + 3, EXPLORE_SAMPLES + 3)
        );
        let short = Problem::new(&u[..900], &y[..900], 600, LmOptions::default());
        let same = short.verdict_window();
        assert_eq!((same.n_fit, same.held_from), (600, 600));
    }

    /// The plain model's starts on y = 2 u(k-1) + 3 (no dynamics, nb = 0): MRGIA's, the least-squares start
    /// with unit slopes and the constant 3 as gaps -3 + 0.05 s and 3 + 0.05 s (s the output's std), the
    /// start without dynamics with that gain (its play opened to 0.01 s), the linear
    /// model as given and with 0.01 s added to both gaps.
    #[test]
    fn plain_starts_by_hand() {
        let n = 400;
        let u = crate::diagnose::fit::model::tests::input(n);
        let y: Vec<f64> = (0..n)
            .map(|k| if k == 0 { 3.0 } else { 2.0 * u[k - 1] + 3.0 })
            .collect();
        let p = Problem::new(&u, &y, 300, LmOptions::default());
        let st = Structure {
            na: 0,
            nb: 0,
            delay: 1,
        };
        let linear = BaseModel {
            c1: -0.7,
            c2: 0.9,
            ..BaseModel::zero(0, 0, 1)
        };
        let starts = plain_starts(&p, st, &linear);
        let s = p.y_scale;
        let close = |a: f64, b: f64| (a - b).abs() < 1e-6;
        let n_mrgia = usize::from(p.mrgia_start(st).is_some());
        let n_oe = usize::from(p.oe_start(st).is_some());
        assert_eq!(starts.len(), n_mrgia + 4 + n_oe);
        let ls = &starts[n_mrgia];
        assert!(close(ls.b[0], 2.0), "{ls:?}");
        assert!(
            close(ls.c1, -3.0 + 0.05 * s) && close(ls.c2, 3.0 + 0.05 * s),
            "{ls:?}"
        );
        let flat = &starts[n_mrgia + 1];
        assert!(close(flat.b[0], 2.0), "{flat:?}");
        assert!(flat.c1 == 0.01 * s && flat.c2 == 0.01 * s, "{flat:?}");
        assert_eq!(starts[n_mrgia + 2 + n_oe], linear);
        let opened = &starts[n_mrgia + 3 + n_oe];
        assert!(opened.c1 == -0.7 + 0.01 * s && opened.c2 == 0.9 + 0.01 * s);
        assert_eq!(opened.b, linear.b);
    }

    /// A record whose own x goes beyond the paper backlash's border crossing (x = -4) and flips there as the
    /// plant does (noise 0.02): the plain fit, from its usual starts, recovers the true parameters and ends
    /// at the noise level. (With every move against x refused, the true model was invalid on such a record
    /// and the fit ended in another minimum.)
    #[test]
    fn the_plain_fit_recovers_a_plant_that_visits_its_inverted_zone() {
        use crate::diagnose::fit::model::tests::{crossing_input, slow_base, with_noise};
        let u = crossing_input();
        let n = u.len();
        let truth = EffectModel::plain(slow_base());
        let clean = truth.simulate(&u, Rest::ZERO, n, 1e6).unwrap().y;
        let y = with_noise(&clean, 0.02, 3);
        let p = Problem::new(&u, &y, n, LmOptions::default());
        let s = Structure {
            na: 1,
            nb: 0,
            delay: 1,
        };
        let linear = (
            BaseModel {
                m2: 1.0,
                c1: 0.0,
                c2: 0.0,
                ..slow_base()
            },
            f64::INFINITY,
        );
        let (fit, cost) = fit_plain(&p, s, 3, 7, &linear).expect("the starts run");
        let b = &fit.base;
        let rmse = (cost / n as f64).sqrt();
        assert!(rmse < 0.021, "fit RMSE {rmse}: {b:?}");
        let off = [
            b.a[0] + 0.97,
            b.b[0] - 0.06,
            b.m2 - 1.5,
            b.c1 - 0.5,
            b.c2 - 1.0,
        ];
        assert!(off[..2].iter().all(|d| d.abs() < 1e-3), "{b:?}");
        assert!(off[2..].iter().all(|d| d.abs() < 0.02), "{b:?}");
    }
}

#[cfg(test)]
mod mutation_tests;
mod pinned;
pub use crate::diagnose::fit::pins::{Pin, Pins};
