//! `quantization`: the sensor has a coarse resolution. It rounds to offset + q Z; the model gives the
//! expected reading for Gaussian noise of std sigma (at most 2 q) before the rounding. q and the offset
//! come from the value lattice, sigma is fitted.

use crate::diagnose::effects::figure::{Figure, fmt, held_out_stretch, over_time};
use crate::diagnose::effects::rig::{Draw, Rig};
use crate::diagnose::effects::{Effect, EffectId, Fitted, Parameters, Plan, StartContext};
use crate::diagnose::fit::model::{BaseModel, EffectModel, Element, Elements, Extension, Scales};
use crate::diagnose::residual::test_names::LATTICE;
use crate::report::plot::PlotError;
use crate::stats::{rms, std_dev};

pub const ID: EffectId = EffectId::declare("quantization");

/// The catalogue entry.
pub struct Quantization;

/// The sensor rounding to `offset + step Z` with Gaussian noise of std `sigma` before the rounding
/// (`crate::plant::effects::expected_reading`; sigma = 0: plain rounding).
pub fn extension(step: f64, offset: f64, sigma: f64) -> Extension {
    Extension::new(&Quantization, vec![step, offset], vec![sigma])
}

impl Element for Quantization {
    fn id(&self) -> EffectId {
        ID
    }

    fn switch_on(&self, ext: &Extension, on: &mut Elements) {
        on.effects.quantization = Some(crate::plant::effects::Quantization {
            step: ext.fixed[0],
            offset: ext.fixed[1],
        });
        on.rounding_noise = ext.theta[0];
    }

    /// A positive, finite rounding step.
    fn valid(&self, ext: &Extension, _base: &BaseModel) -> bool {
        let step = ext.fixed[0];
        step > 0.0 && step.is_finite()
    }

    fn typical(&self, ext: &Extension, _s: &Scales) -> Vec<f64> {
        vec![0.1 * ext.fixed[0]]
    }

    /// Noise of more than two steps hides the rounding (the expected reading is then the value itself), so
    /// sigma is bounded there: the fit cannot wander off to an unbounded parameter.
    fn unpack(&self, ext: &Extension, th: &[f64], _time_scale: f64) -> Vec<f64> {
        vec![th[0].abs().min(2.0 * ext.fixed[0])]
    }

    /// The step and the offset are estimated from the measured values (not by the least-squares fit) and
    /// count too.
    fn n_estimated(&self, _ext: &Extension) -> usize {
        3
    }
}

impl Effect for Quantization {
    fn id(&self) -> EffectId {
        ID
    }

    fn describe(&self) -> &'static str {
        "the sensor rounds to a step q (from the value lattice) with an offset; the model gives the expected reading for a fitted noise level before the rounding"
    }

    fn pointing_tests(&self) -> &'static [&'static str] {
        &[LATTICE]
    }

    /// The lattice's step, its offset as the circular mean of the values' phase on it, and three noise
    /// levels; no plan without a lattice.
    fn plan(&self, cx: &StartContext) -> Option<Plan> {
        let q = cx.lattice?;
        let (s, c) = cx.y.iter().fold((0.0, 0.0), |(s, c), v| {
            let ph = 2.0 * std::f64::consts::PI * v / q;
            (s + ph.sin(), c + ph.cos())
        });
        let offset = q * s.atan2(c) / (2.0 * std::f64::consts::PI);
        let sigma = rms(cx.residual.iter().copied()).min(q);
        let starts: Vec<EffectModel> = [sigma, 0.3 * sigma, 0.05 * q]
            .into_iter()
            .map(|sigma| cx.current.with(extension(q, offset, sigma)))
            .collect();
        Plan::from_starts(starts)
    }

    fn parameters(&self, f: &Fitted) -> Parameters {
        f.own(ID, |ext| {
            Parameters::new()
                .with("step", ext.fixed[0])
                .with("offset", {
                    // Where the record's own values sit on the lattice, within half a step of 0.
                    let (q, o) = (ext.fixed[0], ext.fixed[1] + f.output_level);
                    o - q * (o / q).round()
                })
                .with("noise_before_rounding", ext.theta[0])
        })
    }

    /// A stretch of the held-out part: the measured values on their grid and the models.
    fn evidence(&self, fig: &Figure) -> Result<String, PlotError> {
        let Some(ext) = fig.model.extension(ID) else {
            return super::figure::generic(fig, ID);
        };
        over_time(
            fig,
            "Evidence for quantization: a stretch of the held-out part",
            held_out_stretch(fig, 150),
            true,
        )?;
        Ok(format!(
            "Pointing test: {}. The measured values sit on a grid of step {} (the lattice test); the extended \
             model predicts the sensor's expected reading on that grid.",
            fig.test,
            fmt(ext.fixed[0])
        ))
    }

    /// A step of 0.1..0.3 std(w0) at any offset, the noise std step / (6..20) (a coarse sensor: its noise
    /// is well below one step).
    fn draw(&self, rig: &mut Rig, d: &mut Draw) -> String {
        let std_w = std_dev(&rig.w0);
        let step = d.uniform(0.1, 0.3) * std_w;
        let ratio = d.uniform(6.0, 20.0);
        let offset = d.uniform(0.0, step);
        rig.fixed_noise = Some(step / ratio);
        rig.effects.quantization = Some(crate::plant::effects::Quantization { step, offset });
        format!("step {:.3} std(w), noise step/{ratio:.1}", step / std_w)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::fit::starts::tests::{context, paper};

    /// The evidence draws a stretch of the held-out part to its file and says the lattice's step: on a
    /// record of the paper's model read through a quantizer of step 0.25, the figure is written (a PNG of
    /// some size) and the caption names the test and the step; a model without a quantizer gets the
    /// generic figure, whose caption does not speak of a grid.
    #[test]
    fn evidence_draws_the_held_out_stretch_and_names_the_step() {
        use crate::diagnose::effects::figure::TestRecord;
        let dir = std::env::temp_dir().join(format!("quant-evidence-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("a temporary folder");
        let plain = paper();
        let with = plain.with(extension(0.25, 0.0, 0.0));
        let record = TestRecord::of(&with, 400);
        let caption = |model: &EffectModel, name: &str| {
            let path = dir.join(name);
            let fig = record.figure(&path, "lattice", 280, "plain + quantization", model);
            let said = Quantization.evidence(&fig).expect("it draws");
            (said, path.metadata().map_or(0, |m| m.len()))
        };
        let (said, size) = caption(&with, "quantization.png");
        assert!(size > 1000, "{size}");
        assert!(said.contains("Pointing test: lattice"), "{said}");
        assert!(said.contains("grid of step 0.25"), "{said}");
        let (generic, _) = caption(&plain, "generic.png");
        assert!(!generic.contains("grid of step"), "{generic}");
        std::fs::remove_dir_all(&dir).expect("removed");
    }

    /// The reported offset is where the record's values sit on the lattice, within half a step of 0: the
    /// fitted offset 1.25 plus the output level 0.125 the fit worked about is 1.375, 2.75 steps of 0.5, so
    /// -0.125. The step and the noise level as fitted; a model without a quantizer reports nothing.
    #[test]
    fn parameters_place_the_offset_within_half_a_step() {
        let plain = paper();
        let m = plain.with(extension(0.5, 1.25, 0.0625));
        let fitted = |model| Fitted {
            output_level: 0.125,
            ..Fitted::on(model, &plain)
        };
        let p = Quantization.parameters(&fitted(&m));
        assert_eq!(
            serde_json::to_string(&p).unwrap(),
            r#"{"step":0.5,"offset":-0.125,"noise_before_rounding":0.0625}"#
        );
        assert_eq!(Quantization.parameters(&fitted(&plain)), Parameters::new());
    }

    /// Values 0.03 + 0.1 n all sit at phase 0.3 of the step 0.1: the offset is 0.03. The residual's rms
    /// (0.02) is the first noise level, then 0.3 of it and 0.05 of the step; with a residual larger than
    /// the step, the step.
    #[test]
    fn starts_on_the_lattice() {
        let m = paper();
        let y: Vec<f64> = (0..40).map(|k| 0.03 + 0.1 * f64::from(k % 7)).collect();
        let r: Vec<f64> = (0..40)
            .map(|k| if k % 2 == 0 { 0.02 } else { -0.02 })
            .collect();
        assert!(Quantization.plan(&context(&m, &y, &y, &r)).is_none());
        let cx = StartContext {
            lattice: Some(0.1),
            ..context(&m, &y, &y, &r)
        };
        let p = Quantization.plan(&cx).unwrap();
        let got: Vec<(f64, f64, f64)> = p.alternatives[0]
            .starts
            .iter()
            .map(|s| (s.exts[0].fixed[0], s.exts[0].fixed[1], s.exts[0].theta[0]))
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
        let p = Quantization.plan(&cx).unwrap();
        assert_eq!(p.alternatives[0].starts[0].exts[0].theta[0], 0.1);
    }

    /// sigma unpacks as its magnitude, bounded by two steps; the step and the offset count as estimated.
    #[test]
    fn sigma_is_bounded_by_two_steps() {
        let e = extension(0.5, 0.1, 0.2);
        assert_eq!(e.unpack(&[-0.3], 1.0).theta, vec![0.3]);
        assert_eq!(e.unpack(&[7.0], 1.0).theta, vec![1.0]);
        assert_eq!(e.n_estimated(), 3);
        assert_eq!(e.n_fitted(), 1);
    }
}
