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
        let rss: f64 = ar_filter(e, &phi).iter().map(|v| v * v).sum();
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
    let det = ss * cc - sc * sc;
    let (a_sin, a_cos) = if det.abs() > 1e-12 {
        ((se * cc - ce * sc) / det, (ce * ss - se * sc) / det)
    } else {
        (0.0, 0.0)
    };
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
    let gain = bb.b.iter().sum::<f64>() / (1.0 + bb.a.iter().sum::<f64>());
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
    let gain = bb.b.iter().sum::<f64>() / (1.0 + bb.a.iter().sum::<f64>());
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
}
