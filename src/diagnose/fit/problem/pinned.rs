//! Fits with some parameters held ([`Pins`]): the play pinned at a width (zero: the same borders without a
//! gap, the nearest play-free model; a positive width: a point of the play's profile), and the variance of
//! the play that holds when the residuals are not white and counts the noise of the level it is measured at.

use std::ops::Range;

use crate::diagnose::fit::lm::{CombinationVariance, combination_variance, levenberg_marquardt};
use crate::diagnose::fit::model::{EffectModel, Objective};

use super::{Problem, SCRATCH};
use crate::diagnose::fit::pins::{Pin, Pins};

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
    /// the sandwich that holds with autocorrelated residuals (simulation errors on the fit part); where the
    /// fit part does not determine the output's level (a friction element sees only its changes), at `m`'s
    /// level, or where a friction element's slider absorbs the gap's centre, at `m`'s centre
    /// ([`EffectModel::gauge_weights`]).
    pub fn combination_variance(&self, m: &EffectModel, w: &[f64]) -> Option<CombinationVariance> {
        let ts = self.time_scale;
        let f = |th: &[f64], out: &mut Vec<f64>| {
            let mm = m.unpack(th, ts);
            SCRATCH
                .with_borrow_mut(|s| self.residuals(&mm, Objective::Simulation, self.n_fit, s, out))
        };
        let gauge = m.gauge_weights(ts);
        combination_variance(&f, &m.pack(ts), &self.typical(m), self.lm.fd_rel, w, &gauge)
    }

    /// The play of `m` refitted to the fit part's samples `range` alone, with its sandwich standard error
    /// (infinite where the range does not determine it). The model is simulated from the record's start, so
    /// that a range that starts mid-record starts in the state the record left, not at rest, to the range's
    /// end, or over the whole fit part where `m` is refused there (the share of samples its memory zone may
    /// be inverted on is a share of the samples simulated: over the first half alone, a model the fit
    /// accepted can be refused at its start); its linear block is held at `m`'s and everything else refitted
    /// to the range's simulation errors. `None` when the refit fails.
    pub fn range_play(&self, m: &EffectModel, range: Range<usize>) -> Option<(f64, f64)> {
        let ts = self.time_scale;
        let full = m.pack(ts);
        let held = m.base.na + m.base.nb + 1;
        let pins = Pins(
            full.iter()
                .enumerate()
                .map(|(i, v)| if i < held { Pin::Fixed(*v) } else { Pin::Free })
                .collect(),
        );
        let unpack = |th: &[f64]| m.unpack(&pins.expand(th), ts);
        let end = range.end.min(self.n_fit);
        let accepted =
            SCRATCH.with_borrow_mut(|s| m.simulate_into(self.u, self.rest, end, self.limit, s));
        let horizon = if accepted { end } else { self.n_fit };
        let f = |th: &[f64], out: &mut Vec<f64>| {
            SCRATCH.with_borrow_mut(|s| {
                let ok = unpack(th).simulate_into(self.u, self.rest, horizon, self.limit, s);
                if ok {
                    let (y, sim) = (&self.y[range.start..end], &s.y[range.start..end]);
                    out.extend(y.iter().zip(sim).map(|(a, b)| a - b));
                }
                ok
            })
        };
        let typ = pins.reduce(&self.typical(m));
        let fit = levenberg_marquardt(&f, &pins.reduce(&full), &typ, &[], &self.lm).ok()?;
        let fitted = unpack(&fit.theta);
        let w = pins.reduce(&fitted.play_weights(ts));
        let gauge = pins.reduce(&fitted.gauge_weights(ts));
        let var = combination_variance(&f, &fit.theta, &typ, self.lm.fd_rel, &w, &gauge);
        Some((
            fitted.play(),
            var.map_or(f64::INFINITY, |v| v.sandwich.sqrt()),
        ))
    }

    /// The variance of the play c1 + c2 at `m`: [`Problem::combination_variance`] of its weights plus the
    /// part no fit sees. The play is the borders' width at the output level every fit works about, the
    /// record's first sample (the operating point), and that sample carries its noise: a level off by `d`
    /// is absorbed by the gaps (c1 by `d / m1`, c2 by `-d / m2`, as with a constant offset), which moves
    /// the play by `d (1/m1 - 1/m2)`. Where the slopes differ the play therefore varies with the first
    /// sample's noise, whose variance is the fit part's mean square simulation error; the term is added to
    /// both variances (it holds for white residuals too). Without it, on random plants with play at a
    /// noise of 1/30 of the output's spread, the play's spread over noise draws was three times its
    /// standard error (`examples/play_coverage.rs --plant 48`). The level's direction is
    /// [`EffectModel::level_weights`], the one the variance is held at where the fit part leaves it free
    /// (with the play inside a friction element's spring, the gap's centre is held instead).
    pub fn play_variance(&self, m: &EffectModel) -> Option<CombinationVariance> {
        let play = m.play_weights(self.time_scale);
        let mut v = self.combination_variance(m, &play)?;
        let level = self.cost(m, Objective::Simulation)? / self.n_fit as f64;
        let along = m.level_weights(self.time_scale);
        let tilt: f64 = play.iter().zip(&along).map(|(a, b)| a * b).sum();
        v.classical += tilt * tilt * level;
        v.sandwich += tilt * tilt * level;
        Some(v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::fit::lm::LmOptions;
    use crate::diagnose::fit::model::tests::{paper_base, paper_record, with_noise};

    /// The paper's plant (m1 = 1, m2 = 1.5: 1/m1 - 1/m2 = 1/3) at noise 0.05. The same record with its output
    /// 0.3 higher, which the fits see as a level 0.3 off, gives a play 0.1 lower (the gaps absorb the level,
    /// c1 by 0.3 and c2 by -0.2): the play depends on the level it is measured at. So its variance adds
    /// (1/3)^2 times the mean square error to both of `combination_variance`'s, and nothing where the slopes
    /// are equal.
    #[test]
    fn the_play_moves_with_the_output_level_and_its_variance_counts_that() {
        let n = 1500;
        let (u, sim) = paper_record(n);
        let y = with_noise(&sim.y, 0.05, 5);
        let raised: Vec<f64> = y.iter().map(|v| v + 0.3).collect();
        let truth = EffectModel::plain(paper_base());
        let play = |y: &[f64]| {
            let p = Problem::new(&u, y, n, LmOptions::default());
            let (m, _) = p
                .fit(&truth, std::slice::from_ref(&truth), Objective::Simulation)
                .expect("the fit runs");
            m.play()
        };
        let moved = play(&raised) - play(&y);
        assert!((moved + 0.1).abs() < 0.01, "the play moved by {moved}");

        let p = Problem::new(&u, &y, n, LmOptions::default());
        let ts = p.time_scale;
        let added = |m: &EffectModel| {
            let v = p.play_variance(m).unwrap();
            let c = p.combination_variance(m, &m.play_weights(ts)).unwrap();
            [v.classical - c.classical, v.sandwich - c.sandwich]
        };
        let level = p.cost(&truth, Objective::Simulation).unwrap() / n as f64;
        for d in added(&truth) {
            assert!(
                (d - level / 9.0).abs() < 1e-9 * level,
                "{d} against {level} / 9"
            );
        }
        let mut parallel = truth.clone();
        parallel.base.m2 = 1.0;
        assert_eq!(added(&parallel), [0.0, 0.0]);
    }

    /// The paper's plant (play 1.5) at noise 0.05: each half of the record, refitted from the whole record's
    /// fit on its own samples (the second half in the state the first left), finds the play within 3 of its
    /// standard errors of 1.5. The halves' plays differ from the whole fit's: they are refitted, not copied.
    /// A model whose linear block runs away gives none.
    #[test]
    fn each_half_refits_the_play_on_its_own_samples() {
        let n = 2000;
        let (u, sim) = paper_record(n);
        let y = with_noise(&sim.y, 0.05, 7);
        let p = Problem::new(&u, &y, n, LmOptions::default());
        let truth = EffectModel::plain(paper_base());
        let (whole, _) = p
            .fit(&truth, std::slice::from_ref(&truth), Objective::Simulation)
            .unwrap();
        for range in [0..n / 2, n / 2..n] {
            let (play, se) = p.range_play(&whole, range.clone()).unwrap();
            assert!(se.is_finite() && se > 0.0, "{range:?}: {se}");
            assert!((play - 1.5).abs() < 3.0 * se, "{range:?}: {play} +/- {se}");
            assert!(play != whole.play(), "{range:?}");
        }
        let mut unstable = whole.clone();
        unstable.base.a = vec![-2.5, 0.0];
        assert!(p.range_play(&unstable, n / 2..n).is_none());
    }
}
