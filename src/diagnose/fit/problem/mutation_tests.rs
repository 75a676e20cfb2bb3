//! Tests that pin behaviour a mutation sample found unchecked.

use super::*;
use crate::diagnose::fit::model::tests::{paper_base, paper_record};

/// The divergence bound is 1e4 (1 + max|u| + max|y|), the maxima taken over absolute values:
/// with max|u| = 2 (a negative sample) and max|y| = 3 (a negative sample), 1e4 * (1 + 2 + 3) = 60 000.
#[test]
fn sim_limit_scales_with_the_largest_magnitudes() {
    assert_eq!(sim_limit(&[-2.0, 1.0, 0.5], &[0.5, -3.0, 2.0]), 60_000.0);
    // An all-zero record still gets the bound 1e4.
    assert_eq!(sim_limit(&[0.0; 3], &[0.0; 3]), 1e4);
}

/// Up to `SCREEN_KEEP` (6) starts are not screened: each gets a short fit, so six starts of which five are
/// invalid (m2 < 0, refused by the simulation) still yield the valid one's short fit, with its window cost.
/// (Screening would drop the five and hand back the lone survivor unevaluated, cost `None`.)
#[test]
fn six_starts_are_all_fitted_without_screening() {
    let n = 150;
    let (u, sim) = paper_record(n);
    let y = sim.y;
    let p = Problem::new(&u, &y, n, LmOptions::default());
    assert!(!p.windowed());
    let mut near = paper_base();
    near.b[0] = 0.7;
    let mut invalid = paper_base();
    invalid.m2 = -1.0;
    let mut starts = vec![EffectModel::plain(invalid); SCREEN_KEEP - 1];
    starts.push(EffectModel::plain(near.clone()));
    let start_cost = p
        .cost(&EffectModel::plain(near), Objective::Simulation)
        .expect("the valid start runs");
    let (_, cost) = p
        .explore(
            &EffectModel::plain(paper_base()),
            &starts,
            Objective::Simulation,
        )
        .expect("one start is valid");
    let cost = cost.expect("a short fit ran and reported its window cost");
    assert!(cost < start_cost, "{cost} >= {start_cost}");
}

/// With no iterations allowed and no restarts, the plain fit returns its best start as it is. On a record
/// made by the linear model's own structure with its play widened by 0.01 of the output's spread on both
/// borders, the best start is the linear model with a small play opened around it: c1 and c2 each moved by
/// 0.01 y_scale, everything else the linear model's. (The record's spread is taken before the play is
/// widened, so that start misses the truth by 0.01 of the spread's tiny change; every other start is off by
/// a whole play, a whole gain or the whole dynamics.)
#[test]
fn plain_fit_opens_a_small_play_on_both_borders_of_the_linear_model() {
    let n = 120;
    let u: Vec<f64> = (0..n)
        .map(|k| 10.0 * (k as f64 * 0.37).sin() + 5.0 * (k as f64 * 0.05).cos())
        .collect();
    // Parallel borders (m2 = m1 = 1): no input, however large, inverts the memory zone.
    let lin = BaseModel {
        m2: 1.0,
        ..paper_base()
    };
    let run = |b: &BaseModel| {
        EffectModel::plain(b.clone())
            .simulate(&u, Rest::ZERO, n, 1e6)
            .expect("the paper model runs")
            .y
    };
    let spread = crate::stats::std_dev(&run(&lin));
    let truth = BaseModel {
        c1: lin.c1 + 0.01 * spread,
        c2: lin.c2 + 0.01 * spread,
        ..lin.clone()
    };
    let y = run(&truth);
    let frozen = LmOptions {
        max_iter: 0,
        ..LmOptions::default()
    };
    let p = Problem::new(&u, &y, n, frozen);
    // Far from 1, so that a play of 0.01 y_scale differs from one of 0.01 / y_scale.
    assert!(p.y_scale > 2.0, "{}", p.y_scale);
    let s = Structure {
        na: 2,
        nb: 0,
        delay: 1,
    };
    let want = BaseModel {
        c1: lin.c1 + 0.01 * p.y_scale,
        c2: lin.c2 + 0.01 * p.y_scale,
        ..lin.clone()
    };
    // The opened start is among the starts exactly; frozen, the fit returns the best start, which is that
    // one unless `identify oe`'s fit (a start that has iterated on its own) reached lower.
    assert!(plain_starts(&p, s, &lin).contains(&want));
    let (m, cost) = fit_plain(&p, s, 0, 0, &(lin.clone(), f64::INFINITY)).expect("the starts run");
    let want_cost = p
        .cost(&EffectModel::plain(want.clone()), Objective::Simulation)
        .expect("the opened start runs");
    assert!(
        m.base == want || cost < want_cost,
        "{:?}: {cost} against {want_cost}",
        m.base
    );
}

/// A start whose memory zone is inverted (c1 + c2 < 0) or narrower than the minimum gets the minimum
/// half-width and keeps its offset (c2 - c1) / 2; a start with enough play is left alone.
#[test]
fn open_play_keeps_the_offset() {
    let mut m = BaseModel {
        c1: 1.0,
        c2: -3.0,
        ..paper_base()
    };
    open_play(&mut m, 0.5);
    assert_eq!((m.c1, m.c2), (2.5, -1.5));
    let mut wide = BaseModel {
        c1: 0.4,
        c2: 0.7,
        ..paper_base()
    };
    open_play(&mut wide, 0.5);
    assert_eq!((wide.c1, wide.c2), (0.4, 0.7));
}

/// A restart that only ties the best cost does not replace the best model (ties keep the earlier start, so
/// restarts never move a model they do not improve). With a zero input every model simulates 0, so every
/// start and restart ties on a constant output: the fit with restarts is the fit without.
#[test]
fn restarts_that_tie_keep_the_first_model() {
    let n = 150;
    let u = vec![0.0; n];
    let y = vec![1.0; n];
    let p = Problem::new(&u, &y, n, LmOptions::default());
    let s = Structure {
        na: 2,
        nb: 0,
        delay: 1,
    };
    let lin = (paper_base(), f64::INFINITY);
    let (without, c0) = fit_plain(&p, s, 0, 7, &lin).expect("the starts run");
    let (with, c3) = fit_plain(&p, s, 3, 7, &lin).expect("the starts run");
    assert_eq!(c0, c3);
    assert_eq!(without, with);
}

/// MRGIA's slope is used as a start above 1e-3 only; at or below it (or NaN) the start's slope is 1.
#[test]
fn mrgia_slopes_at_most_a_thousandth_start_at_one() {
    assert_eq!(usable_slope(0.5), 0.5);
    assert_eq!(usable_slope(0.0011), 0.0011);
    assert_eq!(usable_slope(1e-3), 1.0);
    assert_eq!(usable_slope(-2.0), 1.0);
    assert_eq!(usable_slope(f64::NAN), 1.0);
}

/// Restarts never make the plain fit worse: a restart replaces the model only when its cost is lower. With
/// no iterations allowed the restarts are the perturbed best start as they are, mostly worse than it. On a
/// short record and on one long enough for exploration on a window.
#[test]
fn restarts_never_raise_the_cost() {
    for n in [150, EXPLORE_SAMPLES + 5_000] {
        restarts_never_raise_the_cost_on(n);
    }
}

fn restarts_never_raise_the_cost_on(n: usize) {
    let (u, sim) = paper_record(n);
    let y = sim.y;
    let frozen = LmOptions {
        max_iter: 0,
        ..LmOptions::default()
    };
    let p = Problem::new(&u, &y, n, frozen);
    assert_eq!(p.windowed(), n > EXPLORE_SAMPLES);
    let s = Structure {
        na: 2,
        nb: 0,
        delay: 1,
    };
    let lin = (paper_base(), f64::INFINITY);
    for seed in 0..3 {
        let (_, c0) = fit_plain(&p, s, 0, seed, &lin).expect("the starts run");
        let (_, c4) = fit_plain(&p, s, 4, seed, &lin).expect("the starts run");
        assert!(c4 <= c0, "{n} samples, seed {seed}: {c4} > {c0}");
    }
}

/// Stabilising scales every root by 0.9 per pass (a_i by 0.9^i) until the block is stable: a pole at 1.1
/// takes one pass (a1 -1.1 -> -0.99), poles at +-1.1 too (a2 -1.21 -> -0.9801); a stable block is unchanged.
#[test]
fn stabilize_scales_the_roots_by_a_tenth() {
    let mut first = [-1.1];
    stabilize(&mut first);
    assert!((first[0] + 0.99).abs() < 1e-15, "{first:?}");
    let mut second = [0.0, -1.21];
    stabilize(&mut second);
    assert_eq!(second[0], 0.0);
    assert!((second[1] + 0.9801).abs() < 1e-15, "{second:?}");
    let mut stable = [0.45, 0.55];
    stabilize(&mut stable);
    assert_eq!(stable, [0.45, 0.55]);
}
