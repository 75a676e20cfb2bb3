//! `curved-borders`: quadratic and cubic terms on both borders, upper = s + p2 s^2 + p3 s^3 (s = x - c1),
//! lower = m2 s + q2 s^2 + q3 s^3 (s = x + c2).

use crate::diagnose::effects::figure::Figure;
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

    /// The declared model's residual on engaged samples against its x_hat, with the fitted curvatures.
    fn evidence(&self, fig: &Figure) -> Result<String, PlotError> {
        let Some(ext) = fig.model.extension(ID) else {
            return super::figure::generic(fig, ID);
        };
        let (upper, lower) = ([ext.theta[0], ext.theta[1]], [ext.theta[2], ext.theta[3]]);
        let (mut up, mut dn) = (Vec::new(), Vec::new());
        let sim = fig.declared;
        for ((m, x), e) in sim.mode.iter().zip(&sim.x).zip(fig.e0).take(fig.n_fit) {
            match m {
                Mode::Up => up.push((*x, *e)),
                Mode::Down => dn.push((*x, *e)),
                Mode::Held => {}
            }
        }
        let base = &fig.model.base;
        line_plot(
            fig.path,
            "Evidence for curved-borders: residual against the linear block's output",
            &format!("x_hat (the linear block's output, from {})", fig.columns[1]),
            "residual on the border",
            &[
                Series::points("upper border samples", up.clone()).color(1),
                Series::points("lower border samples", dn.clone()).color(2),
                Series::line(
                    "fitted upper curvature",
                    border_curve(&upper, -base.c1, &up),
                )
                .color(1),
                Series::line("fitted lower curvature", border_curve(&lower, base.c2, &dn)).color(2),
            ],
            Axes::LINEAR,
        )?;
        Ok(format!(
            "Pointing test: {}. The declared model's residual on engaged samples against its x_hat: straight \
             borders leave no trend; lines: the quadratic and cubic terms the extension fitted.",
            fig.test
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

/// A fitted border curvature `s^2 (coef[0] + coef[1] s)`, `s = x + shift`, at 101 evenly spaced x over the
/// range the border's `samples` (x, residual) cover (nothing when there are none: a curve is never drawn
/// where the data do not reach).
fn border_curve(coef: &[f64; 2], shift: f64, samples: &[(f64, f64)]) -> Vec<(f64, f64)> {
    if samples.is_empty() {
        return Vec::new();
    }
    let (xmin, xmax) = samples
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), (x, _)| {
            (a.min(*x), b.max(*x))
        });
    (0..=100)
        .map(|i| {
            let x = xmin + (xmax - xmin) * i as f64 / 100.0;
            let s = x + shift;
            (x, s * s * (coef[0] + s * coef[1]))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::fit::starts::tests::{context, paper};

    /// A border's fitted curve spans exactly the x its samples cover, in 100 equal steps, with the
    /// curvature's value at each x; no samples, no curve.
    #[test]
    fn border_curve_spans_the_samples() {
        let samples = [(3.0, 0.1), (-1.0, 0.2), (1.0, -0.3)];
        let got = border_curve(&[2.0, 0.5], 1.0, &samples);
        assert_eq!(got.len(), 101);
        assert_eq!(got[0].0, -1.0);
        assert_eq!(got[50].0, 1.0);
        assert_eq!(got[100].0, 3.0);
        assert!(
            got.windows(2)
                .all(|w| (w[1].0 - w[0].0 - 0.04).abs() < 1e-12)
        );
        // At x = 1: s = 2, s^2 (2 + 0.5 s) = 4 * 3 = 12.
        assert!((got[50].1 - 12.0).abs() < 1e-12);
        assert!(border_curve(&[2.0, 0.5], 1.0, &[]).is_empty());
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

    /// Named in at least 9 of 10 held-out test-bench records, the held-out error falling in each, with its
    /// evidence figure in the report.
    #[test]
    fn named_in_held_out_records() {
        crate::diagnose::bench::tests::check_effect(ID, "straight borders leave no trend");
    }
}
