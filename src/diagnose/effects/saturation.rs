//! `saturation`: the output is clipped, as by end stops: the model output clipped to [lo, hi].

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
    Extension::new(&Saturation, vec![], vec![lo, hi])
}

impl Element for Saturation {
    fn id(&self) -> EffectId {
        ID
    }

    /// The clip acts on the noise-free output (an end stop).
    fn switch_on(&self, ext: &Extension, on: &mut Elements) {
        on.effects.saturation = Some(crate::plant::effects::Saturation {
            lo: ext.theta[0],
            hi: ext.theta[1],
            before_noise: true,
        });
    }

    /// Levels in order.
    fn valid(&self, ext: &Extension, _base: &BaseModel) -> bool {
        ext.theta[0] <= ext.theta[1]
    }

    fn typical(&self, _ext: &Extension, s: &Scales) -> Vec<f64> {
        vec![s.y; 2]
    }
}

impl Effect for Saturation {
    fn id(&self) -> EffectId {
        ID
    }

    fn describe(&self) -> &'static str {
        "the output clipped at fitted levels lo and hi"
    }

    fn pointing_tests(&self) -> &'static [&'static str] {
        &[CLIPPING, EXTREMES, AGAINST_X, BILLINGS]
    }

    /// The levels the clipping test saw, and the 2/98% and 10/90% quantiles of the output.
    fn plan(&self, cx: &StartContext) -> Option<Plan> {
        let q = |f: f64| quantile(cx.y, f);
        let levels = [cx.clip, (q(0.02)?, q(0.98)?), (q(0.1)?, q(0.9)?)];
        let starts: Vec<EffectModel> = levels
            .iter()
            .map(|&(lo, hi)| cx.current.with(extension(lo, hi)))
            .collect();
        Plan::from_starts(starts)
    }

    fn parameters(&self, f: &Fitted) -> Parameters {
        f.own(ID, |ext| {
            Parameters::new()
                .with("lo", ext.theta[0])
                .with("hi", ext.theta[1])
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

    /// Named in at least 9 of 10 held-out test-bench records, the held-out error falling in each, with its
    /// evidence figure in the report.
    #[test]
    fn named_in_held_out_records() {
        crate::diagnose::bench::tests::check_effect(
            ID,
            "is the measured output cut off at its extremes?",
        );
    }
}
