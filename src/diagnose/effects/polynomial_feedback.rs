//! `polynomial-feedback`: the linear block's output feeds back through a polynomial, x(k) = the block's
//! linear value + phi(x(k-1)) + r phi(x(k-2)), phi(x) = q2 x^2 + q3 x^3: the discrete image of a spring
//! whose stiffness changes with its deflection (a Duffing oscillator, a cubic spring in feedback). The
//! spring's force acts on the mass as the drive does, and a force held over a sample enters a second-order
//! block through two taps (r about 1 on a lightly damped mass); the quadratic term places the spring's centre
//! away from the operating point the record is centred on. The plant element is
//! `crate::plant::effects::PolynomialFeedback`.
//!
//! Its gain changes smoothly with the amplitude and so does its phase: a loop in the (x, y) plane that a play
//! model can bend its borders and open a small gap to follow. Without a gap it is the play-free rival the
//! verdict on play needs on such records.

use crate::diagnose::effects::curved_borders::{binned_means, rms_distance};
use crate::diagnose::effects::figure::{Figure, fmt};
use crate::diagnose::effects::rig::{Draw, Rig};
use crate::diagnose::effects::{Effect, EffectId, Fitted, Parameters, Plan, StartContext};
use crate::diagnose::fit::model::{BaseModel, EffectModel, Element, Elements, Extension, Scales};
use crate::diagnose::fit::starts::Alternative;
use crate::plant::MAX_ORDER;
use crate::plant::effects::PolynomialFeedback as Feedback;
use crate::report::plot::{Axes, PlotError, Series, line_plot};
use crate::stats::std_dev;

pub const ID: EffectId = EffectId::declare("polynomial-feedback");

/// The catalogue entry.
pub struct PolynomialFeedback;

/// The feedback `phi(x(k-1)) + lag2 phi(x(k-2))`, `phi(x) = quadratic x^2 + cubic x^3`.
pub fn extension(quadratic: f64, cubic: f64, lag2: f64) -> Extension {
    Extension::new(&PolynomialFeedback, vec![], vec![quadratic, cubic, lag2])
}

/// The plant element of `ext`.
fn feedback(ext: &Extension) -> Feedback {
    Feedback {
        quadratic: ext.theta[0],
        cubic: ext.theta[1],
        lag2: ext.theta[2],
    }
}

/// The cubic starts, as `(1 + r) q3 y_scale^2`: what the cubic adds to x(k) at one output scale from the
/// centre, as a share of x(k-1). The Duffing records of the confusion table span 0.002..0.1 (stiffening,
/// negative); the positive one is a softening spring.
const CUBIC_STARTS: [f64; 3] = [-0.01, -0.05, 0.01];

/// The second tap's weight at the starts: a force held over a sample on a lightly damped mass.
const LAG2_START: f64 = 1.0;

impl Element for PolynomialFeedback {
    fn id(&self) -> EffectId {
        ID
    }

    fn switch_on(&self, ext: &Extension, on: &mut Elements) {
        on.effects.polynomial_feedback = Some(feedback(ext));
    }

    /// Finite coefficients (a block that runs away leaves the simulation's bounds and is refused there).
    fn valid(&self, ext: &Extension, _base: &BaseModel) -> bool {
        ext.theta.iter().all(|v| v.is_finite())
    }

    /// A hundredth of x(k-1) at one scale of x from the centre; a half for the second tap's weight.
    fn typical(&self, _ext: &Extension, s: &Scales) -> Vec<f64> {
        vec![0.01 / s.x, 0.01 / (s.x * s.x), 0.5]
    }
}

impl Effect for PolynomialFeedback {
    fn id(&self) -> EffectId {
        ID
    }

    /// A spring that stiffens with its deflection changes the gain and the phase with the amplitude: the
    /// rising and falling branches part as a play's do.
    fn imitates_play(&self) -> bool {
        true
    }

    fn describe(&self) -> &'static str {
        "polynomial feedback in the linear block: x(k) gains phi(x(k-1)) + r phi(x(k-2)), phi(x) = q2 x^2 + q3 x^3, a spring whose stiffness changes with its deflection (a cubic spring, Duffing)"
    }

    /// None: a rival of play only, fitted by the verdict on play (without a gap, and with the gap kept where
    /// it predicts better than the final model) and never a candidate of the rounds. As a candidate it
    /// entered final models beside saturation and a drift of the gaps, and the gap beside them then read as
    /// `present` on the tanks' estimation record, which has no play.
    fn pointing_tests(&self) -> &'static [&'static str] {
        &[]
    }

    /// Two structures: the current block, and the block with one more pole (the spring and its mass are a
    /// mode of their own, which a block chosen for the drive's dynamics lacks), where the orders allow. Each
    /// starts from no feedback and from cubic terms of `CUBIC_STARTS` at the output's scale, all with the
    /// second tap at `LAG2_START`: from no feedback alone the fit can stay where the cubic's gradient is flat.
    fn plan(&self, cx: &StartContext) -> Option<Plan> {
        let b = &cx.current.base;
        let orders = [b.na, b.na + 1].into_iter().filter(|&na| na <= MAX_ORDER);
        Plan::alternatives(
            orders
                .map(|na| {
                    let block = cx.current.rebased(b.with_orders(na, b.nb, b.delay));
                    let starts = feedback_starts(&block, cx.y_scale);
                    Alternative {
                        template: starts[0].clone(),
                        starts,
                    }
                })
                .collect(),
        )
    }

    /// The current block and the one with one more pole: the log of the count.
    fn structure_penalty(&self) -> f64 {
        2f64.ln()
    }

    fn parameters(&self, f: &Fitted) -> Parameters {
        f.own(ID, |ext| {
            Parameters::new()
                .with("na", f.model.base.na)
                .with("q2", ext.theta[0])
                .with("q3", ext.theta[1])
                .with("r", ext.theta[2])
                .with(
                    "note",
                    "x(k) = -sum a_i x(k-i) + sum b_j u(k-delay-j) + phi(x(k-1)) + r phi(x(k-2)), phi(x) = q2 x^2 + q3 x^3, x about the operating point (q3 < 0: a stiffening spring)",
                )
        })
    }

    /// The plain model's residual (fit part) against its x_hat one sample before, and what the feedback
    /// changes at the same samples, both as means over bins of x_hat.
    fn evidence(&self, fig: &Figure) -> Result<String, PlotError> {
        if fig.model.extension(ID).is_none() {
            return super::figure::generic(fig, ID);
        }
        let x = &fig.declared.x;
        let nf = fig.n_fit.min(x.len());
        let (mut res, mut added) = (Vec::new(), Vec::new());
        for k in 1..nf {
            res.push((x[k - 1], fig.e0[k]));
            added.push((x[k - 1], fig.output[k] - fig.declared.y[k]));
        }
        let (res_mean, added_mean) = (binned_means(&res, BINS), binned_means(&added, BINS));
        line_plot(
            fig.path,
            "Evidence for polynomial-feedback: residual against the linear block's past output",
            &format!(
                "x_hat(k-1) (the linear block's output, from {})",
                fig.columns[1]
            ),
            &format!("residual of {}", fig.columns[2]),
            &[
                Series::points("residual samples", res).color(3),
                Series::line("mean residual per bin", res_mean.clone()).color(5),
                Series::dashed("what the feedback adds", added_mean.clone()).color(0),
            ],
            Axes::LINEAR,
        )?;
        Ok(format!(
            "Pointing test: {}. The {}'s residual (fit part) against its x_hat one sample before: a linear \
             block leaves no trend, a spring whose stiffness changes with its deflection leaves an odd \
             (cubic) or lopsided (quadratic) one. Solid: its mean over {BINS} bins; dashed: what the fitted \
             feedback changes at the same samples (RMS distance between the two: {}).",
            fig.test,
            fig.plain_label,
            fmt(rms_distance(&res_mean, &added_mean))
        ))
    }

    /// A stiffening cubic spring: at two standard deviations of the clean x the cubic terms of both taps take
    /// 8..16 % of x off x(k), the second tap weighing 0.5..1 of the first; no quadratic term.
    fn draw(&self, rig: &mut Rig, d: &mut Draw) -> String {
        let s = 2.0 * std_dev(&rig.x0);
        let share = d.uniform(0.08, 0.16);
        let lag2 = d.uniform(0.5, 1.0);
        rig.effects.polynomial_feedback = Some(Feedback {
            quadratic: 0.0,
            cubic: -share / ((1.0 + lag2) * s * s),
            lag2,
        });
        format!(
            "cubic feedback taking {:.0}% of x at two std of x, second tap {lag2:.2}",
            100.0 * share
        )
    }
}

/// The starts on the block `block`: no feedback, then the cubic starts at the output's scale `y_scale`.
fn feedback_starts(block: &EffectModel, y_scale: f64) -> Vec<EffectModel> {
    let s2 = y_scale * y_scale * (1.0 + LAG2_START);
    let mut starts = vec![block.with(extension(0.0, 0.0, LAG2_START))];
    if s2 > 0.0 && s2.is_finite() {
        starts.extend(
            CUBIC_STARTS
                .iter()
                .map(|c| block.with(extension(0.0, c / s2, LAG2_START))),
        );
    }
    starts
}

/// Bins of x_hat the evidence averages over.
const BINS: usize = 20;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::effects::figure::TestRecord;
    use crate::diagnose::fit::model::Rest;
    use crate::diagnose::fit::model::tests::{input, paper_base};
    use crate::diagnose::fit::starts::tests::{context, paper};
    use crate::plant::PlantParams;
    use crate::plant::effects::{Effects, simulate_with_effects};

    /// Finite coefficients only: a fit's step to a non-finite one is refused before it is simulated. One
    /// structure more than the current block: the log of two alternatives.
    #[test]
    fn validity_and_the_structure_count() {
        let base = paper_base();
        assert!(PolynomialFeedback.valid(&extension(0.1, -0.05, 1.0), &base));
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            for ext in [
                extension(bad, 0.0, 1.0),
                extension(0.0, bad, 1.0),
                extension(0.0, 0.0, bad),
            ] {
                assert!(!PolynomialFeedback.valid(&ext, &base), "{:?}", ext.theta);
            }
        }
        assert_eq!(PolynomialFeedback.structure_penalty(), 2f64.ln());
    }

    /// The bench's draw: a stiffening cubic (negative) taking 8..16% of x at two standard deviations of the
    /// clean x over both taps, no quadratic term, said in words.
    #[test]
    fn the_draw_is_a_stiffening_cubic() {
        use rand_core::SeedableRng;
        let x0 = input(500);
        let mut rig = Rig {
            params: PlantParams::PAPER,
            effects: Effects::default(),
            snr: 30.0,
            fixed_noise: None,
            w0: x0.clone(),
            x0: x0.clone(),
            u: x0.clone(),
            n: 500,
        };
        let mut d = Draw(rand_chacha::ChaCha8Rng::seed_from_u64(3));
        let words = PolynomialFeedback.draw(&mut rig, &mut d);
        let f = rig.effects.polynomial_feedback.expect("switched on");
        let s = 2.0 * std_dev(&x0);
        let share = -f.cubic * (1.0 + f.lag2) * s * s;
        assert!((0.08..0.16).contains(&share), "{share}");
        assert!(f.quadratic == 0.0 && (0.5..1.0).contains(&f.lag2), "{f:?}");
        assert!(
            words.starts_with(&format!("cubic feedback taking {:.0}%", 100.0 * share)),
            "{words}"
        );
    }

    /// The evidence: the plain model's residual and what the feedback adds, both against x_hat(k-1); where
    /// the model with the feedback is the record, the two are the same curve (RMS distance 0), and the
    /// figure is drawn.
    #[test]
    fn the_evidence_compares_the_residual_with_what_the_feedback_adds() {
        let dir = std::env::temp_dir().join(format!("pf-evidence-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("evidence.png");
        let with = EffectModel::plain(paper_base()).with(extension(0.0, -0.02, 1.0));
        let record = TestRecord::of(&with, 300);
        let e0 = &record.e0;
        let fig = record.figure(&path, "none", 210, "plain + polynomial-feedback", &with);
        let caption = PolynomialFeedback.evidence(&fig).unwrap();
        let distance: f64 = caption
            .split("RMS distance between the two: ")
            .nth(1)
            .and_then(|r| r.split(')').next())
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("{caption}"));
        assert!(distance.abs() < 1e-9, "{caption}");
        assert!(
            e0.iter().any(|e| e.abs() > 0.01),
            "the feedback moves the output"
        );
        assert!(path.metadata().unwrap().len() > 1000);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// The model with the feedback is the plant with the bench's feedback, sample for sample; no feedback
    /// is the plain model; a non-finite coefficient does not run.
    #[test]
    fn the_model_is_the_bench() {
        let u = input(400);
        let m = EffectModel::plain(paper_base()).with(extension(0.05, -0.05, 0.5));
        let s = m.simulate(&u, Rest::ZERO, u.len(), 1e9).unwrap();
        let e = Effects {
            polynomial_feedback: Some(Feedback {
                quadratic: 0.05,
                cubic: -0.05,
                lag2: 0.5,
            }),
            ..Effects::default()
        };
        let bench = simulate_with_effects(&PlantParams::PAPER, &e, &u, 0).unwrap();
        let plain = EffectModel::plain(paper_base())
            .simulate(&u, Rest::ZERO, u.len(), 1e9)
            .unwrap();
        let mut moved = 0.0f64;
        for (k, o) in bench.iter().enumerate() {
            assert!((s.y[k] - o.y).abs() < 1e-12, "{k}");
            moved = moved.max((s.y[k] - plain.y[k]).abs());
        }
        assert!(moved > 0.1, "the feedback changes the output: {moved}");
        assert_eq!(m.effects(), e);
        let none = EffectModel::plain(paper_base()).with(extension(0.0, 0.0, 0.7));
        assert_eq!(none.simulate(&u, Rest::ZERO, 400, 1e9).unwrap(), plain);
        let bad = EffectModel::plain(paper_base()).with(extension(f64::NAN, 0.0, 0.0));
        assert!(bad.simulate(&u, Rest::ZERO, 50, 1e9).is_none());
    }

    /// At rest at an input other than 0 the block rests where the feedback balances it: x(k) = 0.5 x(k-1) +
    /// u - 0.1 x(k-1)^3 - 0.05 x(k-2)^3 at u = 1 rests at x with 0.5 x + 0.15 x^3 = 1, and the simulation of
    /// a constant input stays there from its first sample.
    #[test]
    fn rests_where_the_feedback_balances_the_input() {
        let mut base = BaseModel::zero(1, 0, 1);
        base.a = vec![-0.5];
        base.b = vec![1.0];
        let m = EffectModel::plain(base).with(extension(0.0, -0.1, 0.5));
        let u = vec![1.0; 30];
        let s = m.simulate(&u, Rest(1.0), 30, 1e9).unwrap();
        let x = s.x[0];
        assert!((0.5 * x + 0.15 * x * x * x - 1.0).abs() < 1e-9, "{x}");
        assert!(s.x.iter().all(|v| (v - x).abs() < 1e-9), "{:?}", s.x);
    }

    /// A second-order block (poles 0.8 +- 0.3i) with a stiffening cubic spring in feedback, no play, white
    /// input, noise 2% of the output: fitted from the plan's starts on the linear block it comes back to the
    /// cubic within 10% (and a quadratic near zero), and predicts the record to the noise.
    #[test]
    fn a_fit_on_a_cubic_spring_record_recovers_the_cubic() {
        use crate::diagnose::fit::lm::LmOptions;
        use crate::diagnose::fit::model::Objective;
        use crate::diagnose::fit::model::tests::with_noise;
        use crate::diagnose::fit::problem::Problem;
        use crate::identify::mrgia::paper_input;
        let n = 2000;
        let u = paper_input(n, 5);
        let mut base = BaseModel::zero(2, 0, 1);
        base.a = vec![-1.6, 0.73];
        base.b = vec![0.3];
        let (q3, r) = (-0.003, 0.8);
        let truth = EffectModel::plain(base.clone()).with(extension(0.0, q3, r));
        let clean = truth.simulate(&u, Rest::ZERO, n, 1e9).unwrap().y;
        let noise = 0.02 * std_dev(&clean);
        let y = with_noise(&clean, noise, 1);
        let p = Problem::new(&u, &y, n, LmOptions::default());
        let plain = EffectModel::plain(base);
        let residual: Vec<f64> = y.iter().map(|_| 0.0).collect();
        let cx = StartContext {
            y_scale: p.y_scale,
            ..context(&plain, &u, &y, &residual)
        };
        let plan = PolynomialFeedback.plan(&cx).unwrap();
        let alt = &plan.alternatives[0];
        let (fit, cost) = p
            .fit(&alt.template, &alt.starts, Objective::Simulation)
            .unwrap();
        let t = &fit.extension(ID).unwrap().theta;
        assert!((t[1] - q3).abs() < 0.1 * q3.abs(), "{fit:?}");
        assert!((t[2] - r).abs() < 0.1, "{fit:?}");
        assert!(
            t[0].abs() * p.y_scale < 0.1 * q3.abs() * p.y_scale * p.y_scale,
            "{fit:?}"
        );
        let rmse = (cost / n as f64).sqrt();
        assert!(rmse < 1.2 * noise, "{rmse} against the noise {noise}");
    }

    /// The starts: no feedback first (the template), then the cubic starts at the output's scale, shared by
    /// the two taps; on the current block (na 2) and on one with a third pole; only the first at na 4.
    #[test]
    fn starts_by_hand() {
        let m = paper();
        let y = vec![0.0; 10];
        let p = PolynomialFeedback.plan(&context(&m, &y, &y, &y)).unwrap();
        assert_eq!(p.alternatives.len(), 2);
        for (alt, na) in p.alternatives.iter().zip([2, 3]) {
            assert_eq!(alt.template.exts, vec![extension(0.0, 0.0, 1.0)]);
            assert_eq!(alt.template.base.a[..2], m.base.a[..]);
            let cubic: Vec<f64> = alt.starts.iter().map(|s| s.exts[0].theta[1]).collect();
            // The context's output scale is 1; the two taps share each start.
            assert_eq!(cubic, [0.0, -0.005, -0.025, 0.005]);
            assert!(alt.starts.iter().all(|s| s.exts[0].theta[2] == 1.0));
            assert!(alt.starts.iter().all(|s| s.base.na == na), "{na}");
        }
        let top = EffectModel::plain(m.base.with_orders(MAX_ORDER, 0, 1));
        let p = PolynomialFeedback.plan(&context(&top, &y, &y, &y)).unwrap();
        assert_eq!(p.alternatives.len(), 1);
        // At an output scale of 2 the cubic starts are c / (2^2 (1 + 1)); a record with no output spread
        // gets only the start without feedback.
        let cubic: Vec<f64> = feedback_starts(&m, 2.0)
            .iter()
            .map(|s| s.exts[0].theta[1])
            .collect();
        assert_eq!(cubic, [0.0, -0.00125, -0.00625, 0.00125]);
        assert_eq!(feedback_starts(&m, 0.0).len(), 1);
    }
}
