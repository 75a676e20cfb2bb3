//! `dead-zone`: an actuator or valve dead zone on the input. An input with |u| up to a width moves
//! nothing; a larger one acts on the linear block shifted towards zero by the width,
//! `u - width sign(u)` (the plant element `crate::plant::effects::DeadZone`).

use crate::diagnose::effects::figure::{Figure, fmt, pts};
use crate::diagnose::effects::rig::{Draw, Rig};
use crate::diagnose::effects::{Effect, EffectId, Fitted, Parameters, Plan, StartContext};
use crate::diagnose::fit::model::{BaseModel, EffectModel, Element, Elements, Extension, Scales};
use crate::diagnose::residual::test_names::{
    AGAINST_X, BILLINGS, CROSS_CORRELATION, EXTREMES, LJUNG_BOX,
};
use crate::plant::effects::DeadZone as Zone;
use crate::report::plot::{Axes, PlotError, Series, line_plot};
use crate::stats::{mean, quantile};

pub const ID: EffectId = EffectId::declare("dead-zone");

/// The catalogue entry.
pub struct DeadZone;

/// The dead zone of half-width `width` (input units).
pub fn extension(width: f64) -> Extension {
    Extension::new(&DeadZone, vec![], vec![width])
}

impl Element for DeadZone {
    fn id(&self) -> EffectId {
        ID
    }

    fn switch_on(&self, ext: &Extension, on: &mut Elements) {
        on.effects.dead_zone = Some(Zone {
            width: ext.theta[0],
        });
    }

    /// A width of zero or more (zero: the plain input).
    fn valid(&self, ext: &Extension, _base: &BaseModel) -> bool {
        ext.theta[0] >= 0.0 && ext.theta[0].is_finite()
    }

    fn typical(&self, _ext: &Extension, s: &Scales) -> Vec<f64> {
        vec![0.1 * s.u]
    }
}

impl Effect for DeadZone {
    fn id(&self) -> EffectId {
        ID
    }

    /// An input dead zone holds the output near the centre, as a gap holds it after a reversal.
    fn imitates_play(&self) -> bool {
        true
    }

    fn describe(&self) -> &'static str {
        "an actuator or valve dead zone on the input: |u| up to a fitted width moves nothing, beyond it the input acts shifted by the width, u - width sign(u)"
    }

    fn pointing_tests(&self) -> &'static [&'static str] {
        &[BILLINGS, AGAINST_X, EXTREMES, CROSS_CORRELATION, LJUNG_BOX]
    }

    /// Widths of 5 to 50 % of the input's 90th magnitude percentile, each with the linear block's gain
    /// raised so that the mean input magnitude it passes stays the current model's.
    fn plan(&self, cx: &StartContext) -> Option<Plan> {
        let mags: Vec<f64> = cx.u.iter().map(|v| v.abs()).collect();
        let (q90, mean_mag) = (quantile(&mags, 0.9)?, mean(&mags));
        if q90 <= 0.0 {
            return None;
        }
        let starts: Vec<EffectModel> = [0.05, 0.1, 0.2, 0.3, 0.5]
            .into_iter()
            .map(|f| {
                let width = f * q90;
                let passed = mean(
                    &mags
                        .iter()
                        .map(|m| (m - width).max(0.0))
                        .collect::<Vec<_>>(),
                );
                let mut base = cx.current.base.clone();
                if passed > 0.0 {
                    base.b.iter_mut().for_each(|b| *b *= mean_mag / passed);
                }
                cx.current.rebased(base).with(extension(width))
            })
            .collect();
        Some(Plan::one(cx.current.with(extension(0.0)), starts))
    }

    fn parameters(&self, f: &Fitted) -> Parameters {
        let Some(ext) = f.extension(ID) else {
            return Parameters::new();
        };
        Parameters::new()
            .with("width", ext.theta[0])
            .with("unit", "input")
    }

    /// The residual of both models on the fit part against the input that drives the linear block now
    /// (u(k - delay)).
    fn evidence(&self, fig: &Figure) -> Result<String, PlotError> {
        let Some(ext) = fig.model.extension(ID) else {
            return super::figure::generic(fig, ID);
        };
        let d = fig.model.base.delay;
        let nf = fig.n_fit;
        let u = &fig.u[..nf - d.min(nf)];
        let (e0, e1) = (&fig.e0[d.min(nf)..nf], &fig.e1[d.min(nf)..nf]);
        let width = ext.theta[0];
        let (lo, hi) = e0
            .iter()
            .fold((0.0f64, 0.0f64), |(l, h), v| (l.min(*v), h.max(*v)));
        line_plot(
            fig.path,
            "Evidence for dead-zone: residual against the input that drives it (fit part)",
            &format!("{} (delayed by {d} samples)", fig.columns[1]),
            &format!("residual of {}", fig.columns[2]),
            &[
                Series::points(fig.plain_label, pts(u, e0)).color(3),
                Series::points(fig.after_label, pts(u, e1)).color(0),
                Series::dashed("fitted dead zone", vec![(-width, lo), (-width, hi)]).color(1),
                Series::dashed("", vec![(width, lo), (width, hi)]).color(1),
            ],
            Axes::LINEAR,
        )?;
        Ok(format!(
            "Pointing test: {}. The {}'s residual against the input that drives the linear block: small \
             inputs move the output less than the model says; dashed: the dead zone the fit found (+-{}), with \
             which the residual no longer depends on the input.",
            fig.test,
            fig.plain_label,
            fmt(width)
        ))
    }

    /// A width of 10..30 % of the largest input magnitude.
    fn draw(&self, rig: &mut Rig, d: &mut Draw) -> String {
        let umax = rig.u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let frac = d.uniform(0.1, 0.3);
        rig.effects.dead_zone = Some(Zone { width: frac * umax });
        format!("dead zone +-{:.0}% of the largest input", 100.0 * frac)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::fit::model::Rest;
    use crate::diagnose::fit::model::tests::{input, paper_base};
    use crate::diagnose::fit::starts::tests::{context, paper};
    use crate::plant::PlantParams;
    use crate::plant::effects::{Effects, simulate_with_effects};

    /// The model with a dead zone is the plant with the bench's dead zone, sample for sample.
    #[test]
    fn the_model_is_the_bench() {
        let u = input(400);
        let m = EffectModel::plain(paper_base()).with(extension(0.7));
        let s = m.simulate(&u, Rest::ZERO, u.len(), 1e9).unwrap();
        let e = Effects {
            dead_zone: Some(Zone { width: 0.7 }),
            ..Effects::default()
        };
        let bench = simulate_with_effects(&PlantParams::PAPER, &e, &u, 0).unwrap();
        for (k, o) in bench.iter().enumerate() {
            assert!((s.y[k] - o.y).abs() < 1e-12, "{k}");
        }
        assert_eq!(m.effects(), e);
        // A negative width is no dead zone.
        let bad = EffectModel::plain(paper_base()).with(extension(-0.1));
        assert!(bad.simulate(&u, Rest::ZERO, 50, 1e9).is_none());
    }

    /// The starts: five widths from the input's 90th magnitude percentile, the gain raised with each; the
    /// template is the current model; no start on an input that never moves.
    #[test]
    fn starts_by_hand() {
        let m = paper();
        // |u| = 0, 1, ..., 10: the 90th percentile 9, mean 5.
        let u: Vec<f64> = (0..=10)
            .map(|k| if k % 2 == 0 { k } else { -k } as f64)
            .collect();
        let p = DeadZone.plan(&context(&m, &u, &u, &u)).unwrap();
        let starts = &p.alternatives[0].starts;
        assert_eq!(starts.len(), 5);
        assert_eq!(starts[0].exts[0].theta, vec![0.05 * 9.0]);
        // Width 0.45: mean of max(|u| - 0.45, 0) = (55 - 10 * 0.45) / 11; b scaled by 5 over that.
        let passed = (55.0 - 10.0 * 0.45) / 11.0;
        assert!((starts[0].base.b[0] - 0.8 * 5.0 / passed).abs() < 1e-12);
        assert_eq!(p.alternatives[0].template.exts[0].theta, vec![0.0]);
        let flat = vec![0.0; 11];
        assert!(DeadZone.plan(&context(&m, &flat, &flat, &flat)).is_none());
    }
}
