//! Where each candidate extension's fit starts: one small function per effect, keyed by its id.
//!
//! A [`Plan`] lists the structures to fit (extra-delay tries three delays, linear-order two orders, friction
//! two arrangements of the play; the others one) with their start points and the objective; the engine fits
//! every structure from its starts and keeps the lowest cost.

use super::catalogue::EffectId;
use super::model::{BaseModel, EffectModel, Extension, Objective};
use super::statistics::{ar_filter, ar_ls};
use crate::plant::effects::FrictionForm;
use crate::plant::{MAX_DELAY, MAX_ORDER};
use crate::stats::{quantile, rms};

/// What the start points are computed from: the current model, its residual, and the residual tests'
/// findings, all on the fit part.
pub struct StartContext<'a> {
    pub current: &'a EffectModel,
    pub u: &'a [f64],
    pub y: &'a [f64],
    /// y - current model's output.
    pub residual: &'a [f64],
    pub y_scale: f64,
    /// The residual spectrum's peak [rad/sample].
    pub omega: f64,
    /// The value lattice's step, if the output sits on one.
    pub lattice: Option<f64>,
    /// The clipping levels the clipping test saw.
    pub clip: (f64, f64),
    /// MRGIA's estimate for another structure (na, nb, delay), as a start.
    pub mrgia: &'a (dyn Fn(usize, usize, usize) -> Option<BaseModel> + Sync),
}

/// One structure to fit and its start points.
pub struct Alternative {
    pub template: EffectModel,
    pub starts: Vec<EffectModel>,
}

/// The fits a candidate needs.
pub struct Plan {
    pub objective: Objective,
    pub alternatives: Vec<Alternative>,
}

impl Plan {
    fn one(template: EffectModel, starts: Vec<EffectModel>) -> Self {
        Self {
            objective: Objective::Simulation,
            alternatives: vec![Alternative { template, starts }],
        }
    }
}

/// The plan of candidate `id`, or `None` when the data give it no start (no lattice for quantization, no
/// room for a longer delay or order).
pub fn plan(id: EffectId, cx: &StartContext) -> Option<Plan> {
    let plan = match id {
        EffectId::GapDrift => gap_drift(cx),
        EffectId::CurvedBorders => curved_borders(cx),
        EffectId::ExtraDelay => extra_delay(cx),
        EffectId::LinearOrder => linear_order(cx),
        EffectId::ColouredNoise => coloured_noise(cx),
        EffectId::Saturation => saturation(cx),
        EffectId::PeriodicDisturbance => periodic(cx),
        EffectId::Quantization => quantization(cx),
        EffectId::Friction => friction(cx),
        EffectId::DirectionDependent => direction_dependent(cx),
    }?;
    (!plan.alternatives.is_empty()).then_some(plan)
}

fn with_ext(cx: &StartContext, ext: Extension) -> EffectModel {
    cx.current.with(ext)
}

/// The extension's own parameters start at zero (no drift, straight borders): the current model.
fn gap_drift(cx: &StartContext) -> Option<Plan> {
    let m = with_ext(
        cx,
        Extension::GapDrift {
            c1_rate: 0.0,
            c2_rate: 0.0,
        },
    );
    Some(Plan::one(m.clone(), vec![m]))
}

fn curved_borders(cx: &StartContext) -> Option<Plan> {
    let m = with_ext(
        cx,
        Extension::CurvedBorders {
            upper: [0.0; 2],
            lower: [0.0; 2],
        },
    );
    Some(Plan::one(m.clone(), vec![m]))
}

/// The falling set starts as the block's own coefficients: the current model.
fn direction_dependent(cx: &StartContext) -> Option<Plan> {
    let b = &cx.current.base;
    let m = with_ext(
        cx,
        Extension::DirectionDependent {
            a: b.a.clone(),
            b: b.b.clone(),
        },
    );
    Some(Plan::one(m.clone(), vec![m]))
}

/// Delays + 1, + 2, + 3 (up to the plant's bound), each from the shifted model and from MRGIA.
fn extra_delay(cx: &StartContext) -> Option<Plan> {
    let b = &cx.current.base;
    let alternatives = (1..=3)
        .map(|extra| b.delay + extra)
        .filter(|&d| d <= MAX_DELAY)
        .map(|d| restructured(cx, b.na, b.nb, d))
        .collect();
    Some(Plan {
        objective: Objective::Simulation,
        alternatives,
    })
}

/// One more a or one more b coefficient, each from the padded model and from MRGIA.
fn linear_order(cx: &StartContext) -> Option<Plan> {
    let b = &cx.current.base;
    let alternatives = [(b.na + 1, b.nb), (b.na, b.nb + 1)]
        .into_iter()
        .filter(|&(na, nb)| na <= MAX_ORDER && nb <= MAX_ORDER)
        .map(|(na, nb)| restructured(cx, na, nb, b.delay))
        .collect();
    Some(Plan {
        objective: Objective::Simulation,
        alternatives,
    })
}

fn restructured(cx: &StartContext, na: usize, nb: usize, delay: usize) -> Alternative {
    let template = cx
        .current
        .rebased(cx.current.base.with_orders(na, nb, delay));
    let mut starts = vec![template.clone()];
    starts.extend((cx.mrgia)(na, nb, delay).map(|base| cx.current.rebased(base)));
    Alternative { template, starts }
}

/// AR order 1..3 by BIC of the least-squares fit on the residual (the fit itself: the engine keeps the
/// deterministic part, see `engine`).
fn coloured_noise(cx: &StartContext) -> Option<Plan> {
    let e = cx.residual;
    let mut best: Option<(Vec<f64>, f64)> = None;
    for order in 1..=3 {
        let Some(phi) = ar_ls(e, order) else { continue };
        let rss = super::fit::cost_of(&ar_filter(e, &phi));
        let b = super::fit::bic(rss, e.len(), order);
        if best.as_ref().is_none_or(|x| b < x.1) {
            best = Some((phi, b));
        }
    }
    let (phi, _) = best?;
    let m = with_ext(cx, Extension::ColouredNoise { phi });
    Some(Plan {
        objective: Objective::Prediction,
        alternatives: vec![Alternative {
            template: m.clone(),
            starts: vec![m],
        }],
    })
}

/// The levels the clipping test saw, and the 2/98% and 10/90% quantiles of the output.
fn saturation(cx: &StartContext) -> Option<Plan> {
    let q = |f: f64| quantile(cx.y, f);
    let levels = [cx.clip, (q(0.02)?, q(0.98)?), (q(0.1)?, q(0.9)?)];
    let starts: Vec<EffectModel> = levels
        .iter()
        .map(|&(lo, hi)| with_ext(cx, Extension::Saturation { lo, hi }))
        .collect();
    Some(Plan::one(starts[0].clone(), starts))
}

/// The solution of the 2x2 normal equations `[[g0, g1], [g1, g2]] x = r` by Cramer's rule; (0, 0) when the
/// determinant's magnitude is at most 1e-12 (a sinusoid at frequency 0 or pi, or too few samples: no start).
fn solve_symmetric_2x2(g: [f64; 3], r: [f64; 2]) -> (f64, f64) {
    let det = g[0] * g[2] - g[1] * g[1];
    if det.abs() > 1e-12 {
        (
            (r[0] * g[2] - r[1] * g[1]) / det,
            (r[1] * g[0] - r[0] * g[1]) / det,
        )
    } else {
        (0.0, 0.0)
    }
}

/// The residual's least-squares sinusoid at the spectrum's peak.
fn periodic(cx: &StartContext) -> Option<Plan> {
    let w = cx.omega;
    let (mut ss, mut cc, mut sc, mut se, mut ce) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (k, v) in cx.residual.iter().enumerate() {
        let (s, c) = (w * k as f64).sin_cos();
        ss += s * s;
        cc += c * c;
        sc += s * c;
        se += s * v;
        ce += c * v;
    }
    let (a_sin, a_cos) = solve_symmetric_2x2([ss, sc, cc], [se, ce]);
    let m = with_ext(
        cx,
        Extension::Periodic {
            omega: w,
            a_sin,
            a_cos,
        },
    );
    Some(Plan::one(m.clone(), vec![m]))
}

/// The lattice's step, its offset as the circular mean of the values' phase on it, and three noise levels.
fn quantization(cx: &StartContext) -> Option<Plan> {
    let q = cx.lattice?;
    let (s, c) = cx.y.iter().fold((0.0, 0.0), |(s, c), v| {
        let ph = 2.0 * std::f64::consts::PI * v / q;
        (s + ph.sin(), c + ph.cos())
    });
    let offset = q * s.atan2(c) / (2.0 * std::f64::consts::PI);
    let sigma = rms(cx.residual.iter().copied()).min(q);
    let starts: Vec<EffectModel> = [sigma, 0.3 * sigma, 0.05 * q]
        .into_iter()
        .map(|sigma| {
            with_ext(
                cx,
                Extension::Quantization {
                    step: q,
                    offset,
                    sigma,
                },
            )
        })
        .collect();
    Some(Plan::one(starts[0].clone(), starts))
}

/// Gains of the friction grid: from the current one up past twice the steepest slope, by factors of sqrt 2
/// (at most 40).
pub fn gain_scales(r: f64) -> Vec<f64> {
    let mut scales = vec![1.0];
    while scales.len() < 40 && *scales.last().unwrap() < 2.0 * r.max(4.0) {
        let next = scales.last().unwrap() * std::f64::consts::SQRT_2;
        scales.push(next);
    }
    scales
}

/// The steepest part of the output against the input (the 90th percentile of |dy / du| over moves of u
/// above its median) over the current model's static gain; 1 when either is unknown.
fn steepness_ratio(cx: &StartContext) -> f64 {
    let bb = &cx.current.base;
    let gain = bb.static_gain();
    let (u, y) = (cx.u, cx.y);
    let du: Vec<f64> = u.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
    let du_med = quantile(&du, 0.5).unwrap_or(0.0);
    let slopes: Vec<f64> = (1..u.len())
        .filter(|&k| du_med > 0.0 && (u[k] - u[k - 1]).abs() > du_med)
        .map(|k| ((y[k] - y[k - 1]) / (u[k] - u[k - 1])).abs())
        .collect();
    let steep = quantile(&slopes, 0.9).unwrap_or(0.0);
    if gain.abs() > 0.0 && steep.is_finite() && steep > 0.0 {
        steep / gain.abs()
    } else {
        1.0
    }
}

/// A grid for both arrangements of the play: gains ([`gain_scales`]), slip levels at fractions of the
/// output's 1% / 99% quantiles, gap offsets and widths.
fn friction(cx: &StartContext) -> Option<Plan> {
    let bb = &cx.current.base;
    let gain = bb.static_gain();
    let (q01, q99) = (quantile(cx.y, 0.01)?, quantile(cx.y, 0.99)?);
    let u_range = quantile(cx.u, 0.99)? - quantile(cx.u, 0.01)?;
    let small_gap = 0.01 * cx.y_scale;
    // Series form: the offset of the gaps sets the element's first output (w(0) jumps onto a border when a
    // gap is negative): the current one scaled, none, and +-1/8 of the output's range.
    let spread = (q99 - q01) / 8.0;
    let model = |b: &BaseModel, c1: f64, c2: f64, frac: f64, form: FrictionForm| {
        cx.current
            .rebased(BaseModel {
                c1,
                c2,
                ..b.clone()
            })
            .with(Extension::Friction {
                f_plus: frac * q99,
                f_minus: -frac * q01,
                form,
            })
    };
    let (mut series, mut contact) = (Vec::new(), Vec::new());
    for scale in gain_scales(steepness_ratio(cx)) {
        let mut b = bb.clone();
        b.b.iter_mut().for_each(|v| *v *= scale);
        // Equal slopes: with a small gap, unequal ones invert the memory zone within the range (the element
        // carries the asymmetry in its two slip levels).
        b.m2 = 1.0;
        let gap = ((bb.c1 + bb.c2) / 2.0 * scale).max(small_gap);
        for offset in [(bb.c2 - bb.c1) / 2.0 * scale, 0.0, spread, -spread] {
            for frac in [1.0, 0.9, 0.8, 0.7] {
                for g in [gap, small_gap] {
                    series.push(model(
                        &b,
                        g - offset,
                        g + offset,
                        frac,
                        FrictionForm::Series,
                    ));
                }
            }
        }
        // Contact form: the play, a few percent of the stroke of x, placed around the start.
        let x_range = scale * gain.abs() * u_range;
        for play in [0.02, 0.05, 0.1] {
            let g = play * x_range;
            for offset in [0.0, 0.5 * g, -0.5 * g] {
                for frac in [1.0, 0.9, 0.8] {
                    contact.push(model(
                        &b,
                        g - offset,
                        g + offset,
                        frac,
                        FrictionForm::Contact,
                    ));
                }
            }
        }
    }
    let (lo, hi) = (
        cx.y.iter().copied().fold(f64::INFINITY, f64::min),
        cx.y.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    );
    let template = |form| {
        with_ext(
            cx,
            Extension::Friction {
                f_plus: hi,
                f_minus: -lo,
                form,
            },
        )
    };
    let alternatives = [
        (FrictionForm::Series, series),
        (FrictionForm::Contact, contact),
    ]
    .into_iter()
    .map(|(form, starts)| Alternative {
        template: template(form),
        starts,
    })
    .filter(|alt| {
        cx.current
            .admits(alt.template.exts.last().expect("friction added"))
    })
    .collect();
    Some(Plan {
        objective: Objective::Simulation,
        alternatives,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::model::Rest;

    /// Cramer's rule on a symmetric 2x2 system, and no solution at or below the singularity bound.
    #[test]
    fn symmetric_2x2_by_hand() {
        // [[2, 1], [1, 3]] x = [3, 5]: x = (4/5, 7/5).
        let (x0, x1) = solve_symmetric_2x2([2.0, 1.0, 3.0], [3.0, 5.0]);
        assert!(
            (x0 - 0.8).abs() < 1e-15 && (x1 - 1.4).abs() < 1e-15,
            "{x0} {x1}"
        );
        // Determinant exactly 1e-12: singular; just above it: solved.
        assert_eq!(
            solve_symmetric_2x2([1.0, 0.0, 1e-12], [1.0, 1.0]),
            (0.0, 0.0)
        );
        let (y0, y1) = solve_symmetric_2x2([1.0, 0.0, 2e-12], [1.0, 1.0]);
        assert_eq!(y0, 1.0);
        assert!((y1 - 5e11).abs() < 1.0);
        assert_eq!(solve_symmetric_2x2([0.0, 0.0, 5.0], [1.0, 1.0]), (0.0, 0.0));
    }

    #[test]
    fn friction_gains_grow_by_sqrt_2_up_to_twice_the_ratio() {
        let s = gain_scales(10.0);
        assert_eq!(s[0], 1.0);
        for w in s.windows(2) {
            assert!((w[1] / w[0] - std::f64::consts::SQRT_2).abs() < 1e-12);
        }
        // The first scale at or above 2 r = 20: sqrt(2)^9 = 22.6.
        assert_eq!(s.len(), 10);
        assert!(*s.last().unwrap() >= 20.0 && s[s.len() - 2] < 20.0);
        // Small ratios still reach 8; huge ones stop at 40 scales.
        assert_eq!(gain_scales(0.1).len(), 7);
        assert_eq!(gain_scales(1e30).len(), 40);
    }

    /// The paper's linear block (static gain 0.8 / 2 = 0.4) and backlash.
    fn paper() -> EffectModel {
        EffectModel::plain(crate::diagnose::model::tests::paper_base())
    }

    fn no_mrgia(_: usize, _: usize, _: usize) -> Option<BaseModel> {
        None
    }

    fn some_mrgia(na: usize, nb: usize, delay: usize) -> Option<BaseModel> {
        Some(BaseModel::zero(na, nb, delay))
    }

    /// A context on `u`, `y`, `residual` with the paper's model and no test findings.
    fn context<'a>(
        current: &'a EffectModel,
        u: &'a [f64],
        y: &'a [f64],
        residual: &'a [f64],
    ) -> StartContext<'a> {
        StartContext {
            current,
            u,
            y,
            residual,
            y_scale: 1.0,
            omega: 0.4,
            lattice: None,
            clip: (-1.0, 1.0),
            mrgia: &no_mrgia,
        }
    }

    /// The residual 0.7 sin(0.4 k) - 0.3 cos(0.4 k) + 0.05 sin(2.3 k), k < 60: its least-squares sinusoid at
    /// 0.4 rad/sample by NumPy (`lstsq` on [sin, cos]).
    #[test]
    fn periodic_starts_at_the_least_squares_sinusoid() {
        let m = paper();
        let r: Vec<f64> = (0..60)
            .map(f64::from)
            .map(|k| 0.7 * (0.4 * k).sin() - 0.3 * (0.4 * k).cos() + 0.05 * (2.3 * k).sin())
            .collect();
        let p = plan(EffectId::PeriodicDisturbance, &context(&m, &r, &r, &r)).unwrap();
        assert_eq!(p.objective, Objective::Simulation);
        match p.alternatives[0].starts[0].exts[..] {
            [
                Extension::Periodic {
                    omega,
                    a_sin,
                    a_cos,
                },
            ] => {
                assert_eq!(omega, 0.4);
                assert!((a_sin - 0.7001429053851362).abs() < 1e-12, "{a_sin}");
                assert!((a_cos + 0.2997369530916549).abs() < 1e-12, "{a_cos}");
            }
            ref e => panic!("{e:?}"),
        }
        // At omega = 0 the sine column vanishes: no fit, zero amplitudes.
        let cx = StartContext {
            omega: 0.0,
            ..context(&m, &r, &r, &r)
        };
        match plan(EffectId::PeriodicDisturbance, &cx)
            .unwrap()
            .alternatives[0]
            .starts[0]
            .exts[..]
        {
            [Extension::Periodic { a_sin, a_cos, .. }] => assert_eq!((a_sin, a_cos), (0.0, 0.0)),
            ref e => panic!("{e:?}"),
        }
    }

    /// Values 0.03 + 0.1 n all sit at phase 0.3 of the step 0.1: the offset is 0.03. The residual's rms
    /// (0.02) is the first noise level, then 0.3 of it and 0.05 of the step; with a residual larger than the
    /// step, the step.
    #[test]
    fn quantization_starts_on_the_lattice() {
        let m = paper();
        let y: Vec<f64> = (0..40).map(|k| 0.03 + 0.1 * f64::from(k % 7)).collect();
        let r: Vec<f64> = (0..40)
            .map(|k| if k % 2 == 0 { 0.02 } else { -0.02 })
            .collect();
        assert!(plan(EffectId::Quantization, &context(&m, &y, &y, &r)).is_none());
        let cx = StartContext {
            lattice: Some(0.1),
            ..context(&m, &y, &y, &r)
        };
        let p = plan(EffectId::Quantization, &cx).unwrap();
        let got: Vec<(f64, f64, f64)> = p.alternatives[0]
            .starts
            .iter()
            .map(|s| match s.exts[..] {
                [
                    Extension::Quantization {
                        step,
                        offset,
                        sigma,
                    },
                ] => (step, offset, sigma),
                ref e => panic!("{e:?}"),
            })
            .collect();
        let want = [(0.1, 0.03, 0.02), (0.1, 0.03, 0.006), (0.1, 0.03, 0.005)];
        assert_eq!(got.len(), 3);
        for ((step, offset, sigma), (s0, o0, g0)) in got.into_iter().zip(want) {
            assert_eq!(step, s0);
            assert!(
                (offset - o0).abs() < 1e-12 && (sigma - g0).abs() < 1e-12,
                "{offset} {sigma}"
            );
        }
        let big: Vec<f64> = r.iter().map(|v| 10.0 * v).collect();
        let cx = StartContext {
            lattice: Some(0.1),
            ..context(&m, &y, &y, &big)
        };
        match plan(EffectId::Quantization, &cx).unwrap().alternatives[0].starts[0].exts[..] {
            [Extension::Quantization { sigma, .. }] => assert_eq!(sigma, 0.1),
            ref e => panic!("{e:?}"),
        }
    }

    /// y = 2 u exactly: every slope is 2, over the model's static gain 0.4 a ratio of 5; without moves (a
    /// constant input) or without a gain, 1.
    #[test]
    fn steepness_ratio_by_hand() {
        let m = paper();
        let u: Vec<f64> = (0..20).map(|k| f64::from(k * k) / 10.0).collect();
        let y: Vec<f64> = u.iter().map(|v| 2.0 * v).collect();
        assert!((steepness_ratio(&context(&m, &u, &y, &y)) - 5.0).abs() < 1e-12);
        let flat = vec![1.0; 20];
        assert_eq!(steepness_ratio(&context(&m, &flat, &y, &y)), 1.0);
        let no_gain = EffectModel::plain(BaseModel::zero(2, 0, 1));
        assert_eq!(steepness_ratio(&context(&no_gain, &u, &y, &y)), 1.0);
        // Only moves of u above the median move count: steps of 1, 0.5 and 0.125 in turn (median 0.5, all
        // exact in binary), y rising 2 per unit of u on the steps of 1 and 10 on the others: the slope 2
        // over the gain 0.4 is 5 (counting every move would give 10 / 0.4 = 25).
        let (mut u, mut y) = (vec![0.0], vec![0.0]);
        for k in 0..21 {
            let du = [1.0, 0.5, 0.125][k % 3];
            let slope = if du == 1.0 { 2.0 } else { 10.0 };
            u.push(u[k] + du);
            y.push(y[k] + slope * du);
        }
        assert_eq!(steepness_ratio(&context(&m, &u, &y, &y)), 5.0);
    }

    /// Friction's grid for y = 2 u (ratio 5: gains 1 .. sqrt(2)^7 = 11.3, 8 of them): per gain 4 offsets x 4
    /// slip fractions x 2 gaps in series and 3 plays x 3 offsets x 3 fractions in contact. The first series
    /// start keeps the model's gaps (their mean 0.75 plus-minus their half difference 0.25) with m2 = 1 and
    /// slip levels at the 99% / 1% quantiles of y; the templates slip at the extremes of y.
    /// The series grid's third and fourth gap offsets are +spread and -spread, spread = (q99 - q01) / 8 =
    /// (9.8 + 9.8) / 8 = 2.45 for y = 2 u: per offset 4 fractions x 2 gaps = 8 starts, so the first start of
    /// each is number 16 (c1 - c2 = -2 spread = -4.9) and number 24 (+4.9).
    #[test]
    fn friction_offsets_go_both_ways() {
        let u: Vec<f64> = (0..101).map(|k| f64::from(k) / 10.0 - 5.0).collect();
        let y: Vec<f64> = u.iter().map(|v| 2.0 * v).collect();
        let p = plan(EffectId::Friction, &context(&paper(), &u, &y, &y)).unwrap();
        let series = &p.alternatives[0].starts;
        let diff = |i: usize| series[i].base.c1 - series[i].base.c2;
        assert!((diff(16) + 4.9).abs() < 1e-12, "{}", diff(16));
        assert!((diff(24) - 4.9).abs() < 1e-12, "{}", diff(24));
        // Contact: per play three offsets (0, +g/2, -g/2) of three fractions each; the first play g is 2% of
        // the stroke of x, 0.02 * 0.4 * 9.8: starts 3 and 6 have c1 - c2 = -g and +g.
        let contact = &p.alternatives[1].starts;
        let g = 0.02 * 0.4 * 9.8;
        let cdiff = |i: usize| contact[i].base.c1 - contact[i].base.c2;
        assert!((cdiff(3) + g).abs() < 1e-12, "{}", cdiff(3));
        assert!((cdiff(6) - g).abs() < 1e-12, "{}", cdiff(6));
    }

    #[test]
    fn friction_grid_by_hand() {
        let m = paper();
        let u: Vec<f64> = (0..101).map(|k| f64::from(k) / 10.0 - 5.0).collect();
        let y: Vec<f64> = u.iter().map(|v| 2.0 * v).collect();
        let p = plan(EffectId::Friction, &context(&m, &u, &y, &y)).unwrap();
        let [series, contact] = &p.alternatives[..] else {
            panic!("two arrangements")
        };
        assert_eq!(series.starts.len(), 8 * 32);
        assert_eq!(contact.starts.len(), 8 * 27);
        let first = &series.starts[0];
        assert_eq!(
            (first.base.c1, first.base.c2, first.base.m2),
            (0.5, 1.0, 1.0)
        );
        assert_eq!(first.base.b, vec![0.8]);
        // The next gain (start 32, after 4 offsets x 4 fractions x 2 gaps) scales the gaps with it.
        let second = &series.starts[32];
        let r2 = std::f64::consts::SQRT_2;
        assert!((second.base.b[0] - 0.8 * r2).abs() < 1e-12);
        assert!(
            (second.base.c1 - 0.5 * r2).abs() < 1e-12 && (second.base.c2 - r2).abs() < 1e-12,
            "{:?}",
            (second.base.c1, second.base.c2)
        );
        // quantile(y, 0.99): the element at round(100 * 0.99) = 99 of the sorted 101, 2 (99 / 10 - 5) = 9.8.
        match first.exts[..] {
            [
                Extension::Friction {
                    f_plus,
                    f_minus,
                    form,
                },
            ] => {
                assert!((f_plus - 9.8).abs() < 1e-12 && (f_minus - 9.8).abs() < 1e-12);
                assert_eq!(form, FrictionForm::Series);
            }
            ref e => panic!("{e:?}"),
        }
        match series.template.exts[..] {
            [
                Extension::Friction {
                    f_plus, f_minus, ..
                },
            ] => assert_eq!((f_plus, f_minus), (10.0, 10.0)),
            ref e => panic!("{e:?}"),
        }
        // The last gain is sqrt(2)^7 times the model's b.
        let last = &series.starts[series.starts.len() - 1];
        assert!((last.base.b[0] - 0.8 * 2f64.sqrt().powi(7)).abs() < 1e-12);
        // Contact: the first play is 2% of the stroke of x, gain 0.4 times the 1%..99% range of u (9.8).
        let c = &contact.starts[0];
        assert!((c.base.c1 - 0.02 * 0.4 * 9.8).abs() < 1e-12 && c.base.c1 == c.base.c2);
        // On curved borders the contact form is not offered.
        let curved = m.with(Extension::CurvedBorders {
            upper: [0.0; 2],
            lower: [0.0; 2],
        });
        let p = plan(EffectId::Friction, &context(&curved, &u, &y, &y)).unwrap();
        assert_eq!(p.alternatives.len(), 1);
        assert_eq!(
            p.alternatives[0].template.exts.last(),
            Some(&Extension::Friction {
                f_plus: 10.0,
                f_minus: 10.0,
                form: FrictionForm::Series,
            })
        );
    }

    /// The saturation starts: the clipping test's levels, then the 2/98% and the 10/90% quantiles of y
    /// (y = 0..=100: the values 2, 98, 10, 90).
    #[test]
    fn saturation_starts_by_hand() {
        let m = paper();
        let y: Vec<f64> = (0..=100).map(f64::from).collect();
        let p = plan(EffectId::Saturation, &context(&m, &y, &y, &y)).unwrap();
        let levels: Vec<(f64, f64)> = p.alternatives[0]
            .starts
            .iter()
            .map(|s| match s.exts[..] {
                [Extension::Saturation { lo, hi }] => (lo, hi),
                ref e => panic!("{e:?}"),
            })
            .collect();
        assert_eq!(levels, vec![(-1.0, 1.0), (2.0, 98.0), (10.0, 90.0)]);
    }

    /// Longer delays 2, 3, 4 from delay 1 (only up to the plant's bound), one more a or b coefficient (only
    /// up to the largest order); each from the padded model and, where MRGIA gives one, from its estimate.
    #[test]
    fn delay_and_order_alternatives() {
        let m = paper();
        let y = vec![0.0; 10];
        let p = plan(EffectId::ExtraDelay, &context(&m, &y, &y, &y)).unwrap();
        let delays: Vec<usize> = p
            .alternatives
            .iter()
            .map(|a| a.template.base.delay)
            .collect();
        assert_eq!(delays, vec![2, 3, 4]);
        assert!(p.alternatives.iter().all(|a| a.starts.len() == 1));
        let cx = StartContext {
            mrgia: &some_mrgia,
            ..context(&m, &y, &y, &y)
        };
        let p = plan(EffectId::LinearOrder, &cx).unwrap();
        let orders: Vec<(usize, usize)> = p
            .alternatives
            .iter()
            .map(|a| (a.template.base.na, a.template.base.nb))
            .collect();
        assert_eq!(orders, vec![(3, 0), (2, 1)]);
        assert!(p.alternatives.iter().all(|a| a.starts.len() == 2));
        assert_eq!(p.alternatives[1].starts[1].base, BaseModel::zero(2, 1, 1));
        // At the bounds: delay MAX_DELAY - 1 leaves one longer delay; na = MAX_ORDER only a b; both at their
        // largest: no alternative, no plan.
        let mut edge = paper();
        edge.base = edge.base.with_orders(MAX_ORDER, MAX_ORDER, MAX_DELAY - 1);
        let p = plan(EffectId::ExtraDelay, &context(&edge, &y, &y, &y)).unwrap();
        assert_eq!(p.alternatives.len(), 1);
        assert!(plan(EffectId::LinearOrder, &context(&edge, &y, &y, &y)).is_none());
        edge.base = edge.base.with_orders(MAX_ORDER, 1, MAX_DELAY);
        let p = plan(EffectId::LinearOrder, &context(&edge, &y, &y, &y)).unwrap();
        assert_eq!(p.alternatives[0].template.base.nb, 2);
        assert!(plan(EffectId::ExtraDelay, &context(&edge, &y, &y, &y)).is_none());
    }

    /// An AR(1) residual e(k) = 0.6 e(k-1) + v(k), v(k) = sin(1.7 k^1.3) + 0.5 cos(0.9 k), k < 60: by
    /// NumPy least squares (conditional, as `ar_ls`) and BIC n ln(rss / n) + p ln n over orders 1..3, the
    /// order 2 wins (-40.33 against -30.90 and -37.83) with phi = [1.00544, -0.43992].
    #[test]
    fn coloured_noise_starts_at_the_bic_best_ar_fit() {
        let m = paper();
        let mut e = vec![0.0; 60];
        for k in 0..60 {
            let kf = f64::from(k as u32);
            let v = (1.7 * kf.powf(1.3)).sin() + 0.5 * (0.9 * kf).cos();
            e[k] = if k > 0 { 0.6 * e[k - 1] } else { 0.0 } + v;
        }
        let p = plan(EffectId::ColouredNoise, &context(&m, &e, &e, &e)).unwrap();
        assert_eq!(p.objective, Objective::Prediction);
        match &p.alternatives[0].starts[0].exts[..] {
            [Extension::ColouredNoise { phi }] => {
                assert_eq!(phi.len(), 2);
                assert!((phi[0] - 1.0054404372362657).abs() < 1e-9, "{phi:?}");
                assert!((phi[1] + 0.4399247944902299).abs() < 1e-9, "{phi:?}");
            }
            e => panic!("{e:?}"),
        }
        // A zero residual has no AR fit: no plan.
        let zero = vec![0.0; 60];
        assert!(plan(EffectId::ColouredNoise, &context(&m, &zero, &zero, &zero)).is_none());
    }

    #[test]
    fn gap_drift_and_curved_borders_start_at_the_current_model() {
        let m = paper();
        let y = vec![0.0; 10];
        let cx = context(&m, &y, &y, &y);
        let p = plan(EffectId::GapDrift, &cx).unwrap();
        assert_eq!(
            p.alternatives[0].starts[0].exts,
            vec![Extension::GapDrift {
                c1_rate: 0.0,
                c2_rate: 0.0
            }]
        );
        let p = plan(EffectId::CurvedBorders, &cx).unwrap();
        assert_eq!(
            p.alternatives[0].template.exts,
            vec![Extension::CurvedBorders {
                upper: [0.0; 2],
                lower: [0.0; 2]
            }]
        );
    }

    /// The falling set starts as the block's own coefficients, so the start simulates as the current model.
    #[test]
    fn direction_dependent_starts_at_the_current_model() {
        let m = paper();
        let y = vec![0.0; 10];
        let p = plan(EffectId::DirectionDependent, &context(&m, &y, &y, &y)).unwrap();
        assert_eq!(p.alternatives.len(), 1);
        let start = &p.alternatives[0].starts[0];
        assert_eq!(
            start.exts,
            vec![Extension::DirectionDependent {
                a: m.base.a.clone(),
                b: m.base.b.clone()
            }]
        );
        let u: Vec<f64> = (0..80).map(|k| (0.3 * k as f64).sin()).collect();
        let (plain, with) = (
            m.simulate(&u, Rest::ZERO, 80, 1e9).unwrap(),
            start.simulate(&u, Rest::ZERO, 80, 1e9).unwrap(),
        );
        assert_eq!(plain.y, with.y);
    }
}
