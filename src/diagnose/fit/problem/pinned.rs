//! Fits with some parameters held: the play pinned at a width (zero: the same borders without a gap, the
//! nearest play-free model; a positive width: a point of the play's profile), and the variance of the play
//! that holds when the residuals are not white.

use crate::diagnose::fit::lm::{CombinationVariance, combination_variance};
use crate::diagnose::fit::model::{EffectModel, Objective};

use super::{Problem, SCRATCH};

/// How one entry of a packed parameter vector is filled from the free ones.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pin {
    /// Fitted.
    Free,
    /// Held at a value.
    Fixed(f64),
    /// `scale * entry[to] + offset`, `to` a free entry.
    Tied { to: usize, scale: f64, offset: f64 },
}

/// A rule for every entry of a packed vector.
#[derive(Debug, Clone, PartialEq)]
pub struct Pins(pub Vec<Pin>);

impl Pins {
    /// Every entry of a vector of `n` fitted.
    pub fn free(n: usize) -> Self {
        Self(vec![Pin::Free; n])
    }

    /// The free entries of `full`, in order.
    pub fn reduce(&self, full: &[f64]) -> Vec<f64> {
        self.0
            .iter()
            .zip(full)
            .filter(|(p, _)| **p == Pin::Free)
            .map(|(_, v)| *v)
            .collect()
    }

    /// The whole vector from its free entries `reduced`.
    pub fn expand(&self, reduced: &[f64]) -> Vec<f64> {
        let mut free = reduced.iter();
        let mut full: Vec<f64> = self
            .0
            .iter()
            .map(|p| match p {
                Pin::Free => free.next().copied().unwrap_or(f64::NAN),
                Pin::Fixed(v) => *v,
                Pin::Tied { .. } => f64::NAN,
            })
            .collect();
        for (i, p) in self.0.iter().enumerate() {
            if let Pin::Tied { to, scale, offset } = *p {
                full[i] = scale * full[to] + offset;
            }
        }
        full
    }
}

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

#[cfg(test)]
mod tests {
    use super::*;

    /// Free entries come back in order; a tie follows its free entry; a fixed one keeps its value.
    #[test]
    fn pins_expand_what_they_reduce() {
        let pins = Pins(vec![
            Pin::Free,
            Pin::Fixed(1.0),
            Pin::Free,
            Pin::Tied {
                to: 2,
                scale: -1.0,
                offset: 0.5,
            },
        ]);
        let full = [3.0, 9.0, 2.0, 7.0];
        let r = pins.reduce(&full);
        assert_eq!(r, vec![3.0, 2.0]);
        assert_eq!(pins.expand(&r), vec![3.0, 1.0, 2.0, -1.5]);
        assert_eq!(Pins::free(2).expand(&[4.0, 5.0]), vec![4.0, 5.0]);
    }
}
