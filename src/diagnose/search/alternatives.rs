//! The models the verdict on play compares the final model with: the play-free alternatives (its borders with
//! the gap pinned at zero, alone and with each play-free effect of the catalogue that imitates play) and,
//! where such an effect predicts the held-out part better than the final model, a rival with play: the same
//! structure with its gap kept. The gap is then judged like with like (a play-free effect with and without
//! the gap), not a model without the effect against one with it.

use rayon::prelude::*;

use crate::diagnose::effects::{CATALOGUE, Effect};
use crate::diagnose::fit::model::{EffectModel, Objective, Simulation};
use crate::diagnose::fit::problem::Problem;
use crate::diagnose::fit::starts::StartContext;
use crate::diagnose::residual::{self, statistics::diebold_mariano};
use crate::stats::rms;
use serde::Serialize;

/// A play-free model the gap was compared with.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlayFree {
    /// `zero-gap` (the same borders without a gap) or `zero-gap + <effect>`.
    pub model: String,
    pub heldout_rmse: f64,
    /// Diebold-Mariano z of the model with the gap against it (positive: the gap predicts better).
    pub z: f64,
    /// Its held-out errors `y - y_model` (to judge it against another model with the gap).
    #[serde(skip)]
    pub errors: Vec<f64>,
}

/// A model fitted for the comparison: its name, the model and its held-out errors `y - y_model`.
pub(super) struct Fitted {
    pub name: String,
    pub model: EffectModel,
    pub heldout: Vec<f64>,
}

/// A play-free model with the effect's start it came from (the start keeps the gap) and its fitted model.
pub(super) struct Imitator {
    pub free: PlayFree,
    start: EffectModel,
    fitted: EffectModel,
    effect: &'static str,
}

/// Fit-part errors `y - y_model` of a simulation.
pub(super) fn fit_errors(p: &Problem, sim: &Simulation) -> Vec<f64> {
    p.y[..p.n_fit]
        .iter()
        .zip(&sim.y)
        .map(|(a, b)| a - b)
        .collect()
}

/// Held-out errors `y - y_model` of a simulation.
pub(super) fn heldout_errors(p: &Problem, sim: &Simulation) -> Vec<f64> {
    p.y[p.held_from..]
        .iter()
        .zip(&sim.y[p.held_from..])
        .map(|(a, b)| a - b)
        .collect()
}

/// `m` simulated over the record and its held-out errors; `None` when it cannot be simulated.
fn simulate_heldout(p: &Problem, m: &EffectModel) -> Option<Vec<f64>> {
    let sim = m.simulate(p.u, p.rest, p.u.len(), p.limit)?;
    Some(heldout_errors(p, &sim))
}

/// The zero-gap model of `start`'s structure fitted from it, judged against the held-out errors `against`
/// of the model with the gap, with the fitted model; `None` when it cannot be fitted.
pub(super) fn play_free(
    p: &Problem,
    against: &[f64],
    start: &EffectModel,
    name: &str,
) -> Option<(PlayFree, EffectModel)> {
    let (moved, pins) = start.zero_gap(p.time_scale);
    let (m, _) = p.fit_pinned(&moved, &pins, std::slice::from_ref(&moved))?;
    let errors = simulate_heldout(p, &m)?;
    let free = PlayFree {
        model: name.into(),
        heldout_rmse: rms(errors.iter().copied()),
        z: diebold_mariano(&errors, against),
        errors,
    };
    Some((free, m))
}

/// The zero-gap model of `current` with each play-free effect of the catalogue that imitates play added
/// (those `current` lacks and can take), fitted from the effect's own starts, judged against the final
/// model `last` (its simulation `sim`); named `<name> + <effect>`.
pub(super) fn imitators(
    p: &Problem,
    last: &Fitted,
    sim: &Simulation,
    current: &EffectModel,
    name: &str,
) -> Vec<Imitator> {
    let residual = fit_errors(p, sim);
    let y_fit = &p.y[..p.n_fit];
    // The clipping levels the diagnosis's rounds start saturation from: the fit part's extremes.
    let (lo, hi, _) = residual::clipping(y_fit);
    let no_mrgia = |_: usize, _: usize, _: usize| None;
    let cx = StartContext {
        current,
        u: &p.u[..p.n_fit],
        y: y_fit,
        residual: &residual,
        y_scale: p.y_scale,
        omega: 0.0,
        lattice: None,
        clip: (lo, hi),
        mrgia: &no_mrgia,
    };
    let effects: Vec<&'static dyn Effect> = CATALOGUE
        .iter()
        .copied()
        .filter(|e| e.imitates_play() && current.can_add(e.id()))
        .collect();
    effects
        .par_iter()
        .filter_map(|e| {
            let plan = e.plan(&cx)?;
            plan.alternatives
                .iter()
                .filter(|alt| alt.template.deterministic() == alt.template)
                .filter_map(|alt| {
                    let start = alt.starts.first()?;
                    let name = format!("{name} + {}", e.id());
                    let (free, fitted) = play_free(p, &last.heldout, start, &name)?;
                    Some(Imitator {
                        free,
                        start: start.clone(),
                        fitted,
                        effect: e.id().as_str(),
                    })
                })
                .min_by(|a, b| a.free.heldout_rmse.total_cmp(&b.free.heldout_rmse))
        })
        .collect()
}

/// Whether errors `e` predict the held-out part better than `last`'s by at least `min_gain` (relative fall
/// of the RMSE) with a Diebold-Mariano z of at least `min_z`.
pub(super) fn clearly_better(e: &[f64], last: &[f64], min_gain: f64, min_z: f64) -> bool {
    better_by(
        rms(e.iter().copied()),
        rms(last.iter().copied()),
        diebold_mariano(last, e),
        min_gain,
        min_z,
    )
}

/// The one rule of every held-out comparison: an RMSE `rmse` below `(1 - min_gain)` times `than`, with a
/// Diebold-Mariano z (of the other model against this one) of at least `min_z`.
pub(super) fn better_by(rmse: f64, than: f64, z: f64, min_gain: f64, min_z: f64) -> bool {
    rmse < (1.0 - min_gain) * than && z >= min_z
}

/// For each imitator that the final model `last` does not clearly beat, the same structure with its gap
/// kept, fitted from the imitator's start, from its zero-gap fit with the final model's gap opened again and
/// from that zero-gap fit as it is (the with-gap cost is not smooth: any start alone can stop short; a
/// spurious gap opened again holds a smooth curve's borders in a worse minimum), named
/// `<rival_name> + <effect>`;
/// the one that predicts the held-out part best among those clearly better than `last`, or `None`.
pub(super) fn best_rival<'a>(
    p: &Problem,
    last: &Fitted,
    threats: impl IntoIterator<Item = (&'a Imitator, &'a str)>,
    min_gain: f64,
    min_z: f64,
) -> Option<Fitted> {
    let threats: Vec<(&Imitator, &str)> = threats.into_iter().collect();
    threats
        .par_iter()
        .filter_map(|(im, rival_name)| {
            let mut opened = im.fitted.clone();
            let half = 0.5 * last.model.play().max(0.0);
            opened.base.c1 += half;
            opened.base.c2 += half;
            let starts = [im.start.clone(), opened, im.fitted.clone()];
            let (model, _) = p.fit(&im.start, &starts, Objective::Simulation)?;
            let heldout = simulate_heldout(p, &model)?;
            Some(Fitted {
                name: format!("{rival_name} + {}", im.effect),
                model,
                heldout,
            })
        })
        .filter(|f| clearly_better(&f.heldout, &last.heldout, min_gain, min_z))
        .min_by(|a, b| rms(a.heldout.iter().copied()).total_cmp(&rms(b.heldout.iter().copied())))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::fit::lm::LmOptions;
    use crate::diagnose::fit::model::tests::{paper_record, with_noise};
    use crate::diagnose::fit::problem::{fit_linear, fit_plain};
    use crate::diagnose::fit::structure::{Structure, fit_len};
    use crate::stats::quantile;

    /// The paper model's structure fitted plain on `p` (as the final model, with its held-out errors) and
    /// the play-free imitators judged against it.
    fn plain_and_imitators(p: &Problem) -> (Fitted, Vec<Imitator>) {
        let structure = Structure {
            na: 2,
            nb: 0,
            delay: 1,
        };
        let linear = fit_linear(p, structure).unwrap();
        let (plain, _) = fit_plain(p, structure, 3, 0, &linear).unwrap();
        let sim = plain.simulate(p.u, p.rest, p.u.len(), p.limit).unwrap();
        let last = Fitted {
            name: "the final model".into(),
            heldout: heldout_errors(p, &sim),
            model: plain.clone(),
        };
        let found = imitators(p, &last, &sim, &plain, "zero-gap");
        (last, found)
    }

    /// The held-out errors start where the held-out part does, not where the fit part ends: on the verdict's
    /// window of a long record the samples between them are neither fitted nor scored; the fit errors are
    /// the window's.
    #[test]
    fn held_out_errors_start_at_the_held_out_part() {
        use crate::diagnose::fit::problem::EXPLORE_SAMPLES;
        let n = EXPLORE_SAMPLES + 3000;
        let (u, sim) = paper_record(n);
        let y = with_noise(&sim.y, 0.05, 4);
        let p = Problem::new(&u, &y, n - 1000, LmOptions::default());
        let v = p.verdict_window();
        let model = EffectModel::plain(crate::diagnose::fit::model::tests::paper_base());
        let s = model.simulate(&u, v.rest, n, v.limit).unwrap();
        let held = heldout_errors(&v, &s);
        assert_eq!(held.len(), 1000);
        assert_eq!(held[0], y[n - 1000] - s.y[n - 1000]);
        assert_eq!(heldout_errors(&p, &s), held);
        let fit = fit_errors(&v, &s);
        assert_eq!(fit.len(), EXPLORE_SAMPLES);
        assert_eq!(fit[..], fit_errors(&p, &s)[..EXPLORE_SAMPLES]);
    }

    /// On records of the paper's model (play 1.5) clipped at the median of its output, judged from
    /// the plain model (which lacks the clipping): the zero-gap model with saturation is fitted, and the
    /// rival with saturation and its gap kept predicts the held-out part better than it and keeps the play.
    #[test]
    fn a_rival_keeps_the_gap_beside_the_effect_the_final_model_lacks() {
        let n = 3000;
        let (u, sim) = paper_record(n);
        let top = quantile(&sim.y, 0.5).unwrap();
        let clipped: Vec<f64> = sim.y.iter().map(|v| v.min(top)).collect();
        for seed in 0..2 {
            let y = with_noise(&clipped, 0.05, seed);
            let p = Problem::new(&u, &y, fit_len(n, 0.7), LmOptions::default());
            let (last, found) = plain_and_imitators(&p);
            let clip = found
                .iter()
                .find(|im| im.effect == "saturation")
                .expect("saturation imitates play");
            let threats = [(clip, "the final model")];
            let rival = best_rival(&p, &last, threats, 0.02, 1.645).expect("a rival");
            assert_eq!(rival.name, "the final model + saturation");
            let rmse = rms(rival.heldout.iter().copied());
            assert!(
                rmse < clip.free.heldout_rmse,
                "{seed}: {rmse} {:?}",
                clip.free
            );
            assert!(
                (rival.model.play() - 1.5).abs() < 0.1,
                "{seed}: {}",
                rival.model.play()
            );
        }
    }

    /// On records of the paper's model (play 1.5) the zero-gap model with polynomial feedback is fitted
    /// among the imitators, and the model with the gap predicts the held-out part clearly better than it: a
    /// spring that stiffens does not hold the output across the gap after each reversal.
    #[test]
    fn polynomial_feedback_does_not_replace_a_play() {
        let n = 3000;
        let (u, sim) = paper_record(n);
        for seed in 0..2 {
            let y = with_noise(&sim.y, 0.05, seed);
            let p = Problem::new(&u, &y, fit_len(n, 0.7), LmOptions::default());
            let (last, found) = plain_and_imitators(&p);
            let spring = found
                .iter()
                .find(|im| im.effect == "polynomial-feedback")
                .expect("polynomial feedback imitates play");
            assert_eq!(spring.free.model, "zero-gap + polynomial-feedback");
            assert!(
                clearly_better(&last.heldout, &spring.free.errors, 0.02, 1.645),
                "{seed}: {:?}",
                spring.free
            );
        }
    }

    /// Clearly better needs both the fall of the RMSE and its significance.
    #[test]
    fn clearly_better_needs_the_gain_and_the_z() {
        let last: Vec<f64> = (0..400)
            .map(|k| if k % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let half: Vec<f64> = last.iter().map(|v| 0.5 * v).collect();
        assert!(clearly_better(&half, &last, 0.02, 1.645));
        assert!(!clearly_better(&last, &half, 0.02, 1.645));
        let almost: Vec<f64> = last.iter().map(|v| 0.99 * v).collect();
        assert!(!clearly_better(&almost, &last, 0.02, 1.645));
    }
}
