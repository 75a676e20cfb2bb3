//! `direction-dependent`: the linear block has a second set of coefficients (same orders) and a constant for
//! while its output falls: x(k) = x_rise(k) unless that falls below x(k-1), then x_fall(k), as a motor driven
//! up and coasting down. The constant places where the falling set rests against the rising one: without it
//! the two sets' steady states would cross at the input's zero, which about an operating point (or in a
//! sensor's units) is arbitrary.

use crate::diagnose::effects::figure::{Figure, held_out_stretch, over_time};
use crate::diagnose::effects::rig::{Draw, Rig};
use crate::diagnose::effects::{Effect, EffectId, Fitted, Parameters, Plan, StartContext};
use crate::diagnose::fit::model::{
    BaseModel, Element, Elements, Extension, Scales, coefficient_scales, is_stable,
};
use crate::diagnose::residual::test_names::{BILLINGS, BY_MODE, LJUNG_BOX, SINCE_REVERSAL};
use crate::plant::MAX_ORDER;
use crate::report::plot::PlotError;

pub const ID: EffectId = EffectId::declare("direction-dependent");

/// The catalogue entry.
pub struct DirectionDependent;

/// The falling set `a`, `b` (the base model's `na` and `nb + 1` entries) with no constant.
pub fn extension(a: &[f64], b: &[f64]) -> Extension {
    with_offset(a, b, 0.0)
}

/// The falling set `a`, `b` and its constant `offset` (added to x_fall).
pub fn with_offset(a: &[f64], b: &[f64], offset: f64) -> Extension {
    Extension::new(
        &DirectionDependent,
        vec![a.len() as f64],
        a.iter().chain(b).chain([&offset]).copied().collect(),
    )
}

/// The falling set's `a`, `b` and constant in `ext`.
pub fn falling_set(ext: &Extension) -> (&[f64], &[f64], f64) {
    let (a, rest) = ext.theta.split_at(ext.fixed[0] as usize);
    let (b, offset) = rest.split_at(rest.len().saturating_sub(1));
    (a, b, offset.first().copied().unwrap_or(0.0))
}

/// The falling set's extra starts scale the block's poles by these factors (faster, then slower).
const FALL_POLE_SCALES: [f64; 2] = [0.55, 1.0 / 0.55];

/// The block `a`, `b` with every pole scaled by `s` (a_i s^i) and b rescaled to keep the static gain;
/// `None` when the block has no pole or the scaled one is unstable or has no static gain.
fn scaled_poles(a: &[f64], b: &[f64], s: f64) -> Option<(Vec<f64>, Vec<f64>)> {
    let mut scale = 1.0;
    let fall: Vec<f64> = a
        .iter()
        .map(|v| {
            scale *= s;
            v * scale
        })
        .collect();
    let (den, den_fall) = (1.0 + a.iter().sum::<f64>(), 1.0 + fall.iter().sum::<f64>());
    let usable = !a.is_empty() && is_stable(&fall) && den != 0.0 && den_fall != 0.0;
    usable.then(|| (fall, b.iter().map(|v| v * den_fall / den).collect()))
}

/// Coefficients `a`, `b` (at most the plant's orders) padded with zeros to the plant's arrays.
fn padded(a: &[f64], b: &[f64]) -> ([f64; MAX_ORDER], [f64; MAX_ORDER + 1]) {
    let mut pa = [0.0; MAX_ORDER];
    let mut pb = [0.0; MAX_ORDER + 1];
    pa.iter_mut().zip(a).for_each(|(d, s)| *d = *s);
    pb.iter_mut().zip(b).for_each(|(d, s)| *d = *s);
    (pa, pb)
}

impl Element for DirectionDependent {
    fn id(&self) -> EffectId {
        ID
    }

    fn switch_on(&self, ext: &Extension, on: &mut Elements) {
        let (a, b, offset) = falling_set(ext);
        let (a, b) = padded(a, b);
        on.effects.direction_dependent =
            Some(crate::plant::effects::DirectionDependent { a, b, offset });
    }

    /// A stable, finite falling set.
    fn valid(&self, ext: &Extension, _base: &BaseModel) -> bool {
        let (a, _, _) = falling_set(ext);
        is_stable(a) && ext.theta.iter().all(|v| v.is_finite())
    }

    /// The base model's magnitudes for its coefficients ([`BaseModel::typical`]); the linear block's output
    /// scale for the constant.
    fn typical(&self, ext: &Extension, s: &Scales) -> Vec<f64> {
        let (a, b, _) = falling_set(ext);
        let mut t = coefficient_scales(a.len(), b, 0.0);
        t.push(s.x);
        t
    }

    /// The falling set takes the base's orders, a new coefficient starting at the base's own (no direction
    /// dependence in it); the constant stays.
    fn rebased(&self, ext: &Extension, base: &BaseModel) -> Extension {
        let (a, b, offset) = falling_set(ext);
        let resize = |fall: &[f64], own: &[f64]| -> Vec<f64> {
            (0..own.len())
                .map(|i| fall.get(i).copied().unwrap_or(own[i]))
                .collect()
        };
        with_offset(&resize(a, &base.a), &resize(b, &base.b), offset)
    }
}

impl Effect for DirectionDependent {
    fn id(&self) -> EffectId {
        ID
    }

    /// Different dynamics up and down make two branches, as two borders do.
    fn imitates_play(&self) -> bool {
        true
    }

    fn describe(&self) -> &'static str {
        "direction-dependent dynamics: the linear block has a second set of coefficients (same orders) for while its output falls, as a motor driven up and coasting down"
    }

    fn pointing_tests(&self) -> &'static [&'static str] {
        &[BY_MODE, SINCE_REVERSAL, BILLINGS, LJUNG_BOX]
    }

    /// The falling set starts as the block's own coefficients and no constant (the current model), and with
    /// its poles faster and slower (`FALL_POLE_SCALES`, same static gain): from the current model alone a
    /// fit can stay where both sets are one.
    fn plan(&self, cx: &StartContext) -> Option<Plan> {
        let b = &cx.current.base;
        let mut starts = vec![cx.current.with(extension(&b.a, &b.b))];
        starts.extend(
            FALL_POLE_SCALES
                .iter()
                .filter_map(|&s| scaled_poles(&b.a, &b.b, s))
                .map(|(a, bb)| cx.current.with(extension(&a, &bb))),
        );
        Plan::from_starts(starts)
    }

    fn parameters(&self, f: &Fitted) -> Parameters {
        f.own(ID, |ext| {
            let (a, b, offset) = falling_set(ext);
            let base = &f.model.base;
            Parameters::new()
                .with("a_rise", &base.a)
                .with("b_rise", &base.b)
                .with("a_fall", a)
                .with("b_fall", b)
                .with("offset_fall", offset)
                .with(
                    "note",
                    "x(k) = -sum a_rise_i x(k-i) + sum b_rise_j u(k-delay-j) unless that is below x(k-1); then the same with a_fall, b_fall, plus offset_fall (u about the operating point)",
                )
        })
    }

    /// The held-out output over time, at most 400 samples so that single rises and falls show.
    fn evidence(&self, fig: &Figure) -> Result<String, PlotError> {
        over_time(
            fig,
            "Evidence for direction-dependent: rises and falls (held-out part)",
            held_out_stretch(fig, 400),
            false,
        )?;
        Ok(format!(
            "Pointing test: {}. The measured output rises and falls at different speeds; the declared \
             linear block has one set of coefficients for both (red), the block with a falling set follows \
             both (blue).",
            fig.test
        ))
    }

    /// While x falls the linear block's poles are 0.4..0.7 times the rising ones (a_i scaled by s^i), b0
    /// scaled to keep the static gain.
    fn draw(&self, rig: &mut Rig, d: &mut Draw) -> String {
        let s = d.uniform(0.4, 0.7);
        let arx = &rig.params.arx;
        let mut fall = crate::plant::effects::DirectionDependent {
            a: arx.a,
            b: arx.b,
            offset: 0.0,
        };
        let mut scale = 1.0;
        for a in fall.a.iter_mut().take(arx.na) {
            scale *= s;
            *a *= scale;
        }
        let gain = (1.0 + fall.a.iter().sum::<f64>()) / (1.0 + arx.a.iter().sum::<f64>());
        fall.b.iter_mut().for_each(|b| *b *= gain);
        rig.effects.direction_dependent = Some(fall);
        format!("falling poles {s:.2} times the rising ones, same static gain")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::fit::model::{EffectModel, Rest};
    use crate::diagnose::fit::starts::tests::{context, paper};

    /// Padding fills the plant's arrays with zeros after the given coefficients.
    #[test]
    fn padding_by_hand() {
        let (a, b) = padded(&[0.1, 0.2], &[0.3]);
        assert_eq!(a[..2], [0.1, 0.2]);
        assert!(a[2..].iter().chain(&b[1..]).all(|v| *v == 0.0));
        assert_eq!(b[0], 0.3);
    }

    /// Poles scaled by s: a_i s^i, b rescaled to the same static gain. x(k) = 0.5 x(k-1) + u: a = [-0.5], gain
    /// 2; at s = 0.5, a = [-0.25] and b = 1.5 keep the gain (1.5 / 0.75). Second order at s = 2: a_1 2,
    /// a_2 4. No pole, an unstable scaled block, or no static gain: none.
    #[test]
    fn scaled_poles_by_hand() {
        assert_eq!(
            scaled_poles(&[-0.5], &[1.0], 0.5),
            Some((vec![-0.25], vec![1.5]))
        );
        let (a, b) = scaled_poles(&[-0.25, 0.125], &[0.5, 0.25], 2.0).unwrap();
        assert_eq!(a, [-0.5, 0.5]);
        // Gain (0.5 + 0.25) / (1 - 0.25 + 0.125) kept: b times (1 - 0.5 + 0.5) / 0.875.
        assert_eq!(b, [0.5 / 0.875, 0.25 / 0.875]);
        assert_eq!(scaled_poles(&[], &[1.0], 0.5), None);
        assert_eq!(scaled_poles(&[-0.8], &[1.0], 1.0 / 0.55), None);
        assert_eq!(scaled_poles(&[-1.0], &[1.0], 0.5), None);
    }

    /// The falling set starts as the block's own coefficients, so the start simulates as the current model.
    #[test]
    fn starts_at_the_current_model() {
        let m = paper();
        let y = vec![0.0; 10];
        let p = DirectionDependent.plan(&context(&m, &y, &y, &y)).unwrap();
        assert_eq!(p.alternatives.len(), 1);
        let start = &p.alternatives[0].starts[0];
        assert_eq!(start.exts, vec![extension(&m.base.a, &m.base.b)]);
        let u: Vec<f64> = (0..80).map(|k| (0.3 * k as f64).sin()).collect();
        let (plain, with): (EffectModel, &EffectModel) = (m.clone(), start);
        assert_eq!(
            plain.simulate(&u, Rest::ZERO, 80, 1e9).unwrap().y,
            with.simulate(&u, Rest::ZERO, 80, 1e9).unwrap().y
        );
    }
}
