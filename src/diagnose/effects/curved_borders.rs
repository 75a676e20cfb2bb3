//! `curved-borders`: quadratic and cubic terms on both borders, upper = s + p2 s^2 + p3 s^3 (s = x - c1),
//! lower = m2 s + q2 s^2 + q3 s^3 (s = x + c2).

use crate::diagnose::effects::figure::{Figure, fmt};
use crate::diagnose::effects::rig::{Draw, Rig};
use crate::diagnose::effects::{Effect, EffectId, Fitted, Parameters, Plan, StartContext};
use crate::diagnose::fit::model::{BaseModel, Element, Elements, Extension, Scales};
use crate::diagnose::residual::test_names::{AGAINST_X, BILLINGS, EXTREMES};
use crate::plant::Mode;
use crate::report::plot::{Axes, PlotError, Series, line_plot};
use crate::stats::std_dev;

pub const ID: EffectId = EffectId::declare("curved-borders");

/// The catalogue entry.
pub struct CurvedBorders;

/// The extension with `[s^2, s^3]` coefficients `upper` and `lower`.
pub fn extension(upper: [f64; 2], lower: [f64; 2]) -> Extension {
    Extension::new(
        &CurvedBorders,
        vec![],
        vec![upper[0], upper[1], lower[0], lower[1]],
    )
}

impl Element for CurvedBorders {
    fn id(&self) -> EffectId {
        ID
    }

    fn switch_on(&self, ext: &Extension, on: &mut Elements) {
        let t = &ext.theta;
        on.effects.curved_borders = Some(crate::plant::effects::CurvedBorders {
            upper: [t[0], t[1]],
            lower: [t[2], t[3]],
        });
    }

    /// Any coefficients: the switching rule is defined (it may jump) where the borders do not increase.
    fn valid(&self, _ext: &Extension, _base: &BaseModel) -> bool {
        true
    }

    /// Without a gap both borders are one curve: the lower border's terms are the upper's.
    fn zero_gap_ties(&self, _ext: &Extension) -> Option<crate::diagnose::fit::model::Ties> {
        Some(vec![(2, 0, 1.0), (3, 1, 1.0)])
    }

    /// A tenth of the output's scale at one scale of x from the border's zero.
    fn typical(&self, _ext: &Extension, s: &Scales) -> Vec<f64> {
        let (ys, xs) = (s.y, s.x);
        vec![
            0.1 * ys / (xs * xs),
            0.1 * ys / (xs * xs * xs),
            0.1 * ys / (xs * xs),
            0.1 * ys / (xs * xs * xs),
        ]
    }
}

impl Effect for CurvedBorders {
    fn id(&self) -> EffectId {
        ID
    }

    /// A memoryless curve after the linear block (the zero-gap borders) bends as curved borders do.
    fn imitates_play(&self) -> bool {
        true
    }

    fn describe(&self) -> &'static str {
        "quadratic and cubic terms on both borders: upper = s + p2 s^2 + p3 s^3 (s = x - c1), lower likewise"
    }

    fn pointing_tests(&self) -> &'static [&'static str] {
        &[AGAINST_X, BILLINGS, EXTREMES]
    }

    /// Straight borders: the current model.
    fn plan(&self, cx: &StartContext) -> Option<Plan> {
        Some(Plan::at(cx.current.with(extension([0.0; 2], [0.0; 2]))))
    }

    fn parameters(&self, f: &Fitted) -> Parameters {
        f.own(ID, |ext| {
            let t = &ext.theta;
            Parameters::new()
                .with("upper_s2", t[0])
                .with("upper_s3", t[1])
                .with("lower_s2", t[2])
                .with("lower_s3", t[3])
        })
    }

    /// The plain model's residual on engaged samples (fit part) against its x_hat, and what the extension
    /// changes at those same samples (the extended model's output minus the plain model's), both as their
    /// means over bins of x_hat: the curves cover only where there are samples, in the samples' units.
    fn evidence(&self, fig: &Figure) -> Result<String, PlotError> {
        if fig.model.extension(ID).is_none() {
            return super::figure::generic(fig, ID);
        }
        let sim = fig.declared;
        let (mut up, mut dn, mut up_fit, mut dn_fit) = (vec![], vec![], vec![], vec![]);
        for k in 0..fig.n_fit {
            let (x, added) = (sim.x[k], fig.output[k] - sim.y[k]);
            match sim.mode[k] {
                Mode::Up => (up.push((x, fig.e0[k])), up_fit.push((x, added))),
                Mode::Down => (dn.push((x, fig.e0[k])), dn_fit.push((x, added))),
                Mode::Held => ((), ()),
            };
        }
        let (up_fit, dn_fit) = (binned_means(&up_fit, BINS), binned_means(&dn_fit, BINS));
        let (up_mean, dn_mean) = (binned_means(&up, BINS), binned_means(&dn, BINS));
        line_plot(
            fig.path,
            "Evidence for curved-borders: residual against the linear block's output",
            &format!("x_hat (the linear block's output, from {})", fig.columns[1]),
            &format!("residual of {} on the border", fig.columns[2]),
            &[
                Series::points("upper border: residual samples", up).color(1),
                Series::points("lower border: residual samples", dn).color(2),
                Series::line("upper: mean residual per bin", up_mean.clone()).color(5),
                Series::line("lower: mean residual per bin", dn_mean.clone()).color(4),
                Series::dashed("upper: what the curvature adds", up_fit.clone()).color(5),
                Series::dashed("lower: what the curvature adds", dn_fit.clone()).color(4),
            ],
            Axes::LINEAR,
        )?;
        Ok(format!(
            "Pointing test: {}. The {}'s residual on engaged samples (fit part) against its x_hat: straight \
             borders leave no trend. Solid: its mean over {BINS} bins of x_hat; dashed: what the extension \
             changes at the same samples, also per bin (RMS distance between the two: upper {}, lower {}).",
            fig.test,
            fig.plain_label,
            fmt(rms_distance(&up_mean, &up_fit)),
            fmt(rms_distance(&dn_mean, &dn_fit))
        ))
    }

    /// At s = 2 std(x0) the s^2 term is 5..15 % and the s^3 term 2..8 % of the linear one, random signs,
    /// redrawn (at most 100 times) until both borders increase over +-3 std(x0).
    fn draw(&self, rig: &mut Rig, d: &mut Draw) -> String {
        let bl = rig.params.backlash;
        let std_x = std_dev(&rig.x0);
        let s_ref = 2.0 * std_x;
        let mut c = crate::plant::effects::CurvedBorders::default();
        for _ in 0..100 {
            let (m1, m2) = (bl.m1, bl.m2);
            c = crate::plant::effects::CurvedBorders {
                upper: [
                    d.sign() * d.uniform(0.05, 0.15) * m1 / s_ref,
                    d.sign() * d.uniform(0.02, 0.08) * m1 / (s_ref * s_ref),
                ],
                lower: [
                    d.sign() * d.uniform(0.05, 0.15) * m2 / s_ref,
                    d.sign() * d.uniform(0.02, 0.08) * m2 / (s_ref * s_ref),
                ],
            };
            let increasing = (-30..=30).all(|i| {
                let s = i as f64 / 10.0 * std_x;
                m1 + 2.0 * c.upper[0] * s + 3.0 * c.upper[1] * s * s > 0.2 * m1
                    && m2 + 2.0 * c.lower[0] * s + 3.0 * c.lower[1] * s * s > 0.2 * m2
            });
            if increasing {
                break;
            }
        }
        rig.effects.curved_borders = Some(c);
        format!(
            "upper [{:.3}, {:.4}], lower [{:.3}, {:.4}]",
            c.upper[0], c.upper[1], c.lower[0], c.lower[1]
        )
    }
}

/// Bins of x_hat the evidence averages over.
const BINS: usize = 20;

/// The means of `points` (x, v) over `bins` equal bins of the x they cover, at each non-empty bin's mean x
/// (nothing for no points: a curve is never drawn where the data do not reach).
pub(crate) fn binned_means(points: &[(f64, f64)], bins: usize) -> Vec<(f64, f64)> {
    let (lo, hi) = points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), (x, _)| {
            (a.min(*x), b.max(*x))
        });
    let mut sums = vec![(0.0, 0.0, 0usize); bins.max(1)];
    for (x, v) in points {
        let i = if hi > lo {
            (((x - lo) / (hi - lo) * bins as f64) as usize).min(bins - 1)
        } else {
            0
        };
        sums[i] = (sums[i].0 + x, sums[i].1 + v, sums[i].2 + 1);
    }
    sums.into_iter()
        .filter(|s| s.2 > 0)
        .map(|(x, v, c)| (x / c as f64, v / c as f64))
        .collect()
}

/// RMS of the differences of two curves' values, point by point.
pub(crate) fn rms_distance(a: &[(f64, f64)], b: &[(f64, f64)]) -> f64 {
    crate::stats::rms(a.iter().zip(b).map(|(p, q)| p.1 - q.1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::fit::starts::tests::{context, paper};

    /// The binned means cover exactly the x the points cover: each bin's mean x and mean value, empty bins
    /// left out; no points, no curve.
    #[test]
    fn binned_means_stay_within_the_samples() {
        let points = [(0.0, 1.0), (0.1, 3.0), (1.5, -1.0), (2.0, -3.0), (1.0, 5.0)];
        let got = binned_means(&points, 4);
        assert_eq!(got, vec![(0.05, 2.0), (1.0, 5.0), (1.75, -2.0)]);
        assert!(binned_means(&[], 4).is_empty());
        assert_eq!(binned_means(&[(1.0, 2.0), (1.0, 4.0)], 4), vec![(1.0, 3.0)]);
        assert_eq!(
            rms_distance(&[(0.0, 1.0), (1.0, 2.0)], &[(0.0, 2.0), (1.0, 1.0)]),
            1.0
        );
    }

    #[test]
    fn starts_at_the_current_model() {
        let m = paper();
        let y = vec![0.0; 10];
        let p = CurvedBorders.plan(&context(&m, &y, &y, &y)).unwrap();
        assert_eq!(
            p.alternatives[0].template.exts,
            vec![extension([0.0; 2], [0.0; 2])]
        );
    }
}
