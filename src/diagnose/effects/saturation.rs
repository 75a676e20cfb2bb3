//! `saturation`: the output is clipped, as by end stops: the model output clipped to [lo, hi], or only from
//! above (at hi) or only from below (at lo).
//!
//! **Which limits.** A limit is fitted only where the fit part's samples reach it: the clipping test's runs
//! of samples at the output's maximum or minimum ([`reached`]). A record that sits in runs at its maximum
//! only (a tank that overflows at the top) gets an upper limit only; a limit the data never touch is not
//! fitted (at the fit part's own minimum it would cost nothing there and clip the held-out part wherever
//! that goes lower). Without runs at either extreme (a limit before the noise, an end stop, blurs them)
//! both limits are fitted, from the clipping test's levels and the output's quantiles.

use crate::diagnose::effects::figure::{Figure, effect_against_input, extremes_caption};
use crate::diagnose::effects::rig::{Draw, Rig};
use crate::diagnose::effects::{Effect, EffectId, Fitted, Parameters, Plan, StartContext};
use crate::diagnose::fit::model::{BaseModel, EffectModel, Element, Elements, Extension, Scales};
use crate::diagnose::residual::test_names::{AGAINST_X, BILLINGS, CLIPPING, EXTREMES};
use crate::report::plot::PlotError;
use crate::stats::quantile;

pub const ID: EffectId = EffectId::declare("saturation");

/// The catalogue entry.
pub struct Saturation;

/// The extension clipping at `lo` and `hi`.
pub fn extension(lo: f64, hi: f64) -> Extension {
    Extension::new(&Saturation, vec![BOTH], vec![lo, hi])
}

/// Which limits an extension has (its `fixed` setting).
const BOTH: f64 = 0.0;
const UPPER: f64 = 1.0;
const LOWER: f64 = -1.0;

/// The extension clipping from above at `hi` only.
pub fn upper(hi: f64) -> Extension {
    Extension::new(&Saturation, vec![UPPER], vec![hi])
}

/// The extension clipping from below at `lo` only.
pub fn lower(lo: f64) -> Extension {
    Extension::new(&Saturation, vec![LOWER], vec![lo])
}

/// The limits (lo, hi) of an extension; an absent one is the largest finite number of its sign.
fn limits(ext: &Extension) -> (f64, f64) {
    match ext.fixed.first().copied() {
        Some(UPPER) => (f64::MIN, ext.theta[0]),
        Some(LOWER) => (ext.theta[0], f64::MAX),
        _ => (ext.theta[0], ext.theta[1]),
    }
}

/// Which extremes of `y` the samples sit at in runs (the clipping test's rule: at least five samples, more
/// than 0.5% of them, equal to the extreme to 1e-9 relative): (lower, upper).
pub fn reached(y: &[f64]) -> (bool, bool) {
    let hi = y.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let lo = y.iter().copied().fold(f64::INFINITY, f64::min);
    let tol = 1e-9 * hi.abs().max(lo.abs()).max(1e-300);
    let run = |level: f64| {
        let at = y.iter().filter(|v| (*v - level).abs() <= tol).count();
        at >= 5 && at as f64 > 0.005 * y.len() as f64
    };
    (run(lo), run(hi))
}

impl Element for Saturation {
    fn id(&self) -> EffectId {
        ID
    }

    /// The clip acts on the noise-free output (an end stop).
    fn switch_on(&self, ext: &Extension, on: &mut Elements) {
        let (lo, hi) = limits(ext);
        on.effects.saturation = Some(crate::plant::effects::Saturation {
            lo,
            hi,
            before_noise: true,
        });
    }

    /// Levels in order.
    fn valid(&self, ext: &Extension, _base: &BaseModel) -> bool {
        let (lo, hi) = limits(ext);
        lo <= hi
    }

    fn typical(&self, ext: &Extension, s: &Scales) -> Vec<f64> {
        vec![s.y; ext.theta.len()]
    }
}

impl Effect for Saturation {
    fn id(&self) -> EffectId {
        ID
    }

    /// Clipping holds the output at its ends, as a border holds it after a reversal.
    fn imitates_play(&self) -> bool {
        true
    }

    fn describe(&self) -> &'static str {
        "the output clipped at fitted levels lo and hi"
    }

    fn pointing_tests(&self) -> &'static [&'static str] {
        &[CLIPPING, EXTREMES, AGAINST_X, BILLINGS]
    }

    /// The levels the clipping test saw, and the 2/98% and 10/90% quantiles of the output; only the limits
    /// the samples reach in runs when one side does ([`reached`]).
    fn plan(&self, cx: &StartContext) -> Option<Plan> {
        let q = |f: f64| quantile(cx.y, f);
        let levels = [cx.clip, (q(0.02)?, q(0.98)?), (q(0.1)?, q(0.9)?)];
        let ext = |(lo, hi): (f64, f64)| match reached(cx.y) {
            (false, true) => upper(hi),
            (true, false) => lower(lo),
            _ => extension(lo, hi),
        };
        let starts: Vec<EffectModel> = levels.iter().map(|&l| cx.current.with(ext(l))).collect();
        Plan::from_starts(starts)
    }

    /// `lo` and `hi` of the limits fitted (a limit not fitted is left out), and `limits`: `both`, `upper`
    /// or `lower`.
    fn parameters(&self, f: &Fitted) -> Parameters {
        f.own(ID, |ext| {
            let (lo, hi) = limits(ext);
            let side = match ext.fixed.first().copied() {
                Some(UPPER) => "upper",
                Some(LOWER) => "lower",
                _ => "both",
            };
            Parameters::new()
                .with_some("lo", (lo > f64::MIN).then_some(lo + f.output_level))
                .with_some("hi", (hi < f64::MAX).then_some(hi + f.output_level))
                .with("limits", side)
        })
    }

    fn evidence(&self, fig: &Figure) -> Result<String, PlotError> {
        effect_against_input(fig, ID.as_str())?;
        Ok(format!(
            "Pointing test: {}. Output against input: is the measured output cut off at its extremes? {}",
            fig.test,
            extremes_caption(fig)
        ))
    }

    /// Clipped at the 85..95 % and 5..15 % quantiles of the clean backlash output; at the sensor or at an
    /// end stop (before the noise), 50/50.
    fn draw(&self, rig: &mut Rig, d: &mut Draw) -> String {
        let (qh, ql) = (d.uniform(0.85, 0.95), d.uniform(0.05, 0.15));
        let before = d.uniform(0.0, 1.0) < 0.5;
        rig.effects.saturation = Some(crate::plant::effects::Saturation {
            lo: quantile(&rig.w0, ql).unwrap_or(0.0),
            hi: quantile(&rig.w0, qh).unwrap_or(0.0),
            before_noise: before,
        });
        format!(
            "clipped at the {:.0}% / {:.0}% quantiles, {}",
            100.0 * ql,
            100.0 * qh,
            if before {
                "end stop (before the noise)"
            } else {
                "sensor range"
            }
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::fit::starts::tests::{context, paper};

    /// The limits fitted, in the output's units (the fit's output level added back), and which they are; a
    /// limit not fitted is left out, not reported at the float's end.
    #[test]
    fn parameters_report_the_fitted_limits_only() {
        let plain = paper();
        let report = |ext: Extension| {
            let m = plain.with(ext);
            let p = Saturation.parameters(&Fitted {
                output_level: 0.5,
                ..Fitted::on(&m, &plain)
            });
            serde_json::to_string(&p).unwrap()
        };
        assert_eq!(
            report(extension(-1.0, 2.0)),
            r#"{"lo":-0.5,"hi":2.5,"limits":"both"}"#
        );
        assert_eq!(report(upper(2.0)), r#"{"hi":2.5,"limits":"upper"}"#);
        assert_eq!(report(lower(-1.0)), r#"{"lo":-0.5,"limits":"lower"}"#);
    }

    /// The saturation starts: the clipping test's levels, then the 2/98% and the 10/90% quantiles of y
    /// (y = 0..=100: the values 2, 98, 10, 90).
    #[test]
    fn starts_by_hand() {
        let m = paper();
        let y: Vec<f64> = (0..=100).map(f64::from).collect();
        let p = Saturation.plan(&context(&m, &y, &y, &y)).unwrap();
        let levels: Vec<(f64, f64)> = p.alternatives[0]
            .starts
            .iter()
            .map(|s| (s.exts[0].theta[0], s.exts[0].theta[1]))
            .collect();
        assert_eq!(levels, vec![(-1.0, 1.0), (2.0, 98.0), (10.0, 90.0)]);
    }

    /// A limit is fitted only where the record reaches it: the top, the bottom, both or neither.
    #[test]
    fn one_limit_where_only_one_extreme_is_reached() {
        let m = paper();
        // Runs at the top only (an overflow): an upper limit only, at the run's level.
        let y: Vec<f64> = (0..400).map(|k| (0.05 * k as f64).sin().min(0.8)).collect();
        assert_eq!(reached(&y), (false, true));
        let p = Saturation.plan(&context(&m, &y, &y, &y)).unwrap();
        for s in &p.alternatives[0].starts {
            assert_eq!(s.exts[0].fixed, vec![UPPER]);
            assert_eq!(s.exts[0].theta.len(), 1);
        }
        let ext = upper(0.8);
        assert_eq!(limits(&ext), (f64::MIN, 0.8));
        let mut on = Elements::default();
        Saturation.switch_on(&ext, &mut on);
        let sat = on.effects.saturation.unwrap();
        assert_eq!((sat.lo, sat.hi), (f64::MIN, 0.8));
        // Runs at the bottom only: a lower limit; at both or neither: both.
        let neg: Vec<f64> = y.iter().map(|v| -v).collect();
        assert_eq!(reached(&neg), (true, false));
        assert_eq!(limits(&lower(-0.8)), (-0.8, f64::MAX));
        let both: Vec<f64> = y.iter().map(|v| v.max(-0.8)).collect();
        assert_eq!(reached(&both), (true, true));
        let none: Vec<f64> = (0..400).map(|k| (0.05 * k as f64).sin()).collect();
        assert_eq!(reached(&none), (false, false));
    }
}
