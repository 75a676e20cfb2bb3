//! `linear-order`: the linear block needs one more a or b coefficient than declared. No element of its
//! own: its plan refits the base model with na + 1 or nb + 1 (each fitted, the best kept).

use crate::diagnose::effects::figure::{Figure, input_correlation};
use crate::diagnose::effects::rig::{Draw, Rig};
use crate::diagnose::effects::{Effect, EffectId, Fitted, Parameters, Plan, StartContext};
use crate::diagnose::fit::starts::restructured;
use crate::diagnose::residual::test_names::{CROSS_CORRELATION, LJUNG_BOX};
use crate::plant::MAX_ORDER;
use crate::report::plot::PlotError;

pub const ID: EffectId = EffectId::declare("linear-order");

/// The catalogue entry.
pub struct LinearOrder;

impl Effect for LinearOrder {
    fn id(&self) -> EffectId {
        ID
    }

    fn describe(&self) -> &'static str {
        "one more a or b coefficient in the linear block"
    }

    fn pointing_tests(&self) -> &'static [&'static str] {
        &[CROSS_CORRELATION, LJUNG_BOX]
    }

    /// One more a or one more b coefficient, each from the padded model and from MRGIA.
    fn plan(&self, cx: &StartContext) -> Option<Plan> {
        let b = &cx.current.base;
        Plan::alternatives(
            [(b.na + 1, b.nb), (b.na, b.nb + 1)]
                .into_iter()
                .filter(|&(na, nb)| na <= MAX_ORDER && nb <= MAX_ORDER)
                .map(|(na, nb)| restructured(cx, na, nb, b.delay))
                .collect(),
        )
    }

    fn parameters(&self, f: &Fitted) -> Parameters {
        let b = &f.model.base;
        let (added, value) = if b.na > f.current.base.na {
            (format!("a{}", b.na), b.a[b.na - 1])
        } else {
            (format!("b{}", b.nb), b.b[b.nb])
        };
        Parameters::new()
            .with("na", b.na)
            .with("nb", b.nb)
            .with("added", added)
            .with("value", value)
    }

    fn evidence(&self, fig: &Figure) -> Result<String, PlotError> {
        input_correlation(fig)
    }

    /// Either b1 = +-(0.3..0.6) b0, or a3 = +-(0.1..0.25) (its sign flipped if the block would be unstable).
    fn draw(&self, rig: &mut Rig, d: &mut Draw) -> String {
        let arx = &mut rig.params.arx;
        if d.uniform(0.0, 1.0) < 0.5 {
            arx.nb = 1;
            arx.b[1] = d.sign() * d.uniform(0.3, 0.6) * arx.b[0];
            format!("b1 = {:.3}", arx.b[1])
        } else {
            arx.na = 3;
            let mut a3 = d.sign() * d.uniform(0.1, 0.25);
            if !stable(&[arx.a[0], arx.a[1], a3]) {
                a3 = -a3;
            }
            arx.a[2] = a3;
            format!("a3 = {a3:.3}")
        }
    }

    /// Two orders are tried: the log of the count.
    fn structure_penalty(&self) -> f64 {
        2f64.ln()
    }

    /// A longer b polynomial whose leading terms are zero is a longer delay: within the alias margin the
    /// delay is chosen.
    fn yields_to(&self) -> Option<EffectId> {
        Some(super::extra_delay::ID)
    }
}

/// Is the linear block with these a's stable (impulse response decays)?
pub(crate) fn stable(a: &[f64]) -> bool {
    let mut h = vec![0.0; 3000];
    h[0] = 1.0;
    for k in 1..h.len() {
        h[k] = -a
            .iter()
            .enumerate()
            .filter(|(i, _)| k > *i)
            .map(|(i, ai)| ai * h[k - 1 - i])
            .sum::<f64>();
    }
    h[2500..].iter().all(|v| v.abs() < 1e-6)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::effects::extra_delay::ExtraDelay;
    use crate::diagnose::fit::model::BaseModel;
    use crate::diagnose::fit::starts::tests::{context, paper, some_mrgia};
    use crate::plant::MAX_DELAY;

    /// `stable` by hand: 1 + 0.45 z^-1 + 0.55 z^-2 (the paper's a) has poles of modulus sqrt(0.55) < 1;
    /// a = [0.5] gives h(k) = (-0.5)^k, which decays; a = [-1] gives h(k) = 1 for ever; a = [0, 0, 1.2] has
    /// poles of modulus 1.2^(1/3) > 1.
    #[test]
    fn stable_tells_decaying_impulse_responses() {
        assert!(stable(&[0.45, 0.55]));
        assert!(stable(&[0.5]));
        assert!(!stable(&[-1.0]));
        assert!(!stable(&[0.0, 0.0, 1.2]));
    }

    /// Longer delays 2, 3, 4 from delay 1 (only up to the plant's bound), one more a or b coefficient (only
    /// up to the largest order); each from the padded model and, where MRGIA gives one, from its estimate.
    #[test]
    fn delay_and_order_alternatives() {
        let m = paper();
        let y = vec![0.0; 10];
        let p = ExtraDelay.plan(&context(&m, &y, &y, &y)).unwrap();
        let delays: Vec<usize> = p
            .alternatives
            .iter()
            .map(|a| a.template.base.delay)
            .collect();
        assert_eq!(delays, vec![2, 3, 4]);
        assert!(p.alternatives.iter().all(|a| a.starts.len() == 1));
        let cx = StartContext {
            mrgia: &some_mrgia,
            ..context(&m, &y, &y, &y)
        };
        let p = LinearOrder.plan(&cx).unwrap();
        let orders: Vec<(usize, usize)> = p
            .alternatives
            .iter()
            .map(|a| (a.template.base.na, a.template.base.nb))
            .collect();
        assert_eq!(orders, vec![(3, 0), (2, 1)]);
        assert!(p.alternatives.iter().all(|a| a.starts.len() == 2));
        assert_eq!(p.alternatives[1].starts[1].base, BaseModel::zero(2, 1, 1));
        // At the bounds: delay MAX_DELAY - 1 leaves one longer delay; na = MAX_ORDER only a b; both at their
        // largest: no alternative, no plan.
        let mut edge = paper();
        edge.base = edge.base.with_orders(MAX_ORDER, MAX_ORDER, MAX_DELAY - 1);
        let p = ExtraDelay.plan(&context(&edge, &y, &y, &y)).unwrap();
        assert_eq!(p.alternatives.len(), 1);
        assert!(LinearOrder.plan(&context(&edge, &y, &y, &y)).is_none());
        edge.base = edge.base.with_orders(MAX_ORDER, 1, MAX_DELAY);
        let p = LinearOrder.plan(&context(&edge, &y, &y, &y)).unwrap();
        assert_eq!(p.alternatives[0].template.base.nb, 2);
        assert!(ExtraDelay.plan(&context(&edge, &y, &y, &y)).is_none());
    }
}
