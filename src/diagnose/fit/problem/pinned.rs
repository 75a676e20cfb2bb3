//! Fits with some parameters held ([`Pins`]): the play pinned at a width (zero: the same borders without a
//! gap, the nearest play-free model; a positive width: a point of the play's profile), and the variance of
//! the play that holds when the residuals are not white.

use crate::diagnose::fit::lm::{CombinationVariance, combination_variance};
use crate::diagnose::fit::model::{EffectModel, Objective};

use super::{Problem, SCRATCH};
use crate::diagnose::fit::pins::Pins;

impl Problem<'_> {
    /// Fit `template`'s structure with the entries `pins` holds, from `starts` (their held entries are
    /// replaced by the rule's values). Returns the model and its fit-part cost.
    pub fn fit_pinned(
        &self,
        template: &EffectModel,
        pins: &Pins,
        starts: &[EffectModel],
    ) -> Option<(EffectModel, f64)> {
        let ts = self.time_scale;
        let unpack = |th: &[f64]| template.unpack(&pins.expand(th), ts);
        let reduced: Vec<Vec<f64>> = starts.iter().map(|s| pins.reduce(&s.pack(ts))).collect();
        let typ = pins.reduce(&self.typical(template));
        let (th, cost) = self.fit_packed(&unpack, &reduced, &typ, Objective::Simulation)?;
        Some((unpack(&th), cost))
    }

    /// The variance of `w . theta` (theta packed as [`EffectModel::pack`]) at `m`, the classical one and
    /// the sandwich that holds with autocorrelated residuals (simulation errors on the fit part).
    pub fn combination_variance(&self, m: &EffectModel, w: &[f64]) -> Option<CombinationVariance> {
        let ts = self.time_scale;
        let f = |th: &[f64], out: &mut Vec<f64>| {
            let mm = m.unpack(th, ts);
            SCRATCH
                .with_borrow_mut(|s| self.residuals(&mm, Objective::Simulation, self.n_fit, s, out))
        };
        combination_variance(&f, &m.pack(ts), &self.typical(m), self.lm.fd_rel, w)
    }
}
