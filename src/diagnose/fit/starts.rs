//! Where a candidate's fit starts: the [`Plan`] an effect returns (`crate::diagnose::effects::Effect::plan`)
//! from what its [`StartContext`] knows.
//!
//! A plan lists the structures to fit (extra-delay tries three delays, linear-order two orders, friction
//! two arrangements of the play; the others one) with their start points and the objective; the engine fits
//! every structure from its starts and keeps the lowest cost.

use crate::diagnose::fit::model::{BaseModel, EffectModel, Objective};

/// What the start points are computed from: the current model, its residual, and the residual tests'
/// findings, all on the fit part.
pub struct StartContext<'a> {
    pub current: &'a EffectModel,
    pub u: &'a [f64],
    pub y: &'a [f64],
    /// y - current model's output.
    pub residual: &'a [f64],
    pub y_scale: f64,
    /// The residual spectrum's peak [rad/sample].
    pub omega: f64,
    /// The value lattice's step, if the output sits on one.
    pub lattice: Option<f64>,
    /// The clipping levels the clipping test saw.
    pub clip: (f64, f64),
    /// MRGIA's estimate for another structure (na, nb, delay), as a start.
    pub mrgia: &'a (dyn Fn(usize, usize, usize) -> Option<BaseModel> + Sync),
}

/// One structure to fit and its start points.
pub struct Alternative {
    pub template: EffectModel,
    pub starts: Vec<EffectModel>,
}

/// The fits a candidate needs.
pub struct Plan {
    pub objective: Objective,
    pub alternatives: Vec<Alternative>,
}

impl Plan {
    /// One structure, `template`, fitted by simulation from `starts`.
    pub fn one(template: EffectModel, starts: Vec<EffectModel>) -> Self {
        Self {
            objective: Objective::Simulation,
            alternatives: vec![Alternative { template, starts }],
        }
    }

    /// One structure fitted from `starts`, the first of them its template; none without a start.
    pub fn from_starts(starts: Vec<EffectModel>) -> Option<Self> {
        let template = starts.first()?.clone();
        Some(Self::one(template, starts))
    }

    /// One structure fitted from the template itself.
    pub fn at(start: EffectModel) -> Self {
        Self::one(start.clone(), vec![start])
    }

    /// Several structures fitted by simulation; `None` when there is none (no room for a longer delay or
    /// order).
    pub fn alternatives(alternatives: Vec<Alternative>) -> Option<Self> {
        (!alternatives.is_empty()).then_some(Self {
            objective: Objective::Simulation,
            alternatives,
        })
    }
}

/// The current model with other orders and delay (its extensions rebased), started from itself padded
/// and, where MRGIA gives one, from MRGIA's estimate of that structure.
pub fn restructured(cx: &StartContext, na: usize, nb: usize, delay: usize) -> Alternative {
    let template = cx
        .current
        .rebased(cx.current.base.with_orders(na, nb, delay));
    let mut starts = vec![template.clone()];
    starts.extend((cx.mrgia)(na, nb, delay).map(|base| cx.current.rebased(base)));
    Alternative { template, starts }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::diagnose::fit::model::tests::paper_base;

    /// The paper's linear block (static gain 0.8 / 2 = 0.4) and backlash.
    pub(crate) fn paper() -> EffectModel {
        EffectModel::plain(paper_base())
    }

    pub(crate) fn no_mrgia(_: usize, _: usize, _: usize) -> Option<BaseModel> {
        None
    }

    pub(crate) fn some_mrgia(na: usize, nb: usize, delay: usize) -> Option<BaseModel> {
        Some(BaseModel::zero(na, nb, delay))
    }

    /// A context on `u`, `y`, `residual` with the model `current` and no test findings.
    pub(crate) fn context<'a>(
        current: &'a EffectModel,
        u: &'a [f64],
        y: &'a [f64],
        residual: &'a [f64],
    ) -> StartContext<'a> {
        StartContext {
            current,
            u,
            y,
            residual,
            y_scale: 1.0,
            omega: 0.4,
            lattice: None,
            clip: (-1.0, 1.0),
            mrgia: &no_mrgia,
        }
    }

    /// A plan with no structure is no plan; one structure is fitted by simulation from its template.
    #[test]
    fn plans_by_hand() {
        assert!(Plan::alternatives(Vec::new()).is_none());
        let p = Plan::at(paper());
        assert_eq!(p.objective, Objective::Simulation);
        assert_eq!(p.alternatives.len(), 1);
        assert_eq!(p.alternatives[0].starts, vec![paper()]);
    }
}
