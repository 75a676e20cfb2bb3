//! `extra-delay`: the true delay is longer than declared. No element of its own: its plan refits the base
//! model with the delay + 1, + 2 or + 3 (each fitted, the best kept).

use crate::diagnose::effects::figure::{Figure, input_correlation};
use crate::diagnose::effects::rig::{Draw, Rig};
use crate::diagnose::effects::{Effect, EffectId, Fitted, Parameters, Plan, StartContext};
use crate::diagnose::fit::starts::restructured;
use crate::diagnose::residual::test_names::CROSS_CORRELATION;
use crate::plant::MAX_DELAY;
use crate::report::plot::PlotError;

pub const ID: EffectId = EffectId::declare("extra-delay");

/// The catalogue entry.
pub struct ExtraDelay;

impl Effect for ExtraDelay {
    fn id(&self) -> EffectId {
        ID
    }

    fn describe(&self) -> &'static str {
        "a longer delay: delay + 1, + 2 or + 3 samples"
    }

    fn pointing_tests(&self) -> &'static [&'static str] {
        &[CROSS_CORRELATION]
    }

    /// Delays + 1, + 2, + 3 (up to the plant's bound), each from the shifted model and from MRGIA.
    fn plan(&self, cx: &StartContext) -> Option<Plan> {
        let b = &cx.current.base;
        Plan::alternatives(
            (1..=3)
                .map(|extra| b.delay + extra)
                .filter(|&d| d <= MAX_DELAY)
                .map(|d| restructured(cx, b.na, b.nb, d))
                .collect(),
        )
    }

    fn parameters(&self, f: &Fitted) -> Parameters {
        let (delay, declared) = (f.model.base.delay, f.current.base.delay);
        Parameters::new()
            .with("delay", delay)
            .with("declared_delay", declared)
            .with("extra", delay.saturating_sub(declared))
    }

    fn evidence(&self, fig: &Figure) -> Result<String, PlotError> {
        input_correlation(fig)
    }

    /// The true delay 2..4 (declared 1).
    fn draw(&self, rig: &mut Rig, d: &mut Draw) -> String {
        let extra = 1 + (d.uniform(0.0, 3.0) as usize).min(2);
        rig.params.arx.delay += extra;
        format!("true delay {}", rig.params.arx.delay)
    }

    /// Three delays are tried: the log of the count (the extra delay adds no continuous parameter, so
    /// without this term it would tie exactly with a longer b polynomial whose leading terms are zero).
    fn structure_penalty(&self) -> f64 {
        3f64.ln()
    }
}
