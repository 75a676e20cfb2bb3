//! Tests that pin behaviour a mutation sample found unchecked.

use super::*;
use crate::diagnose::effects::EffectId;
use crate::diagnose::effects::{coloured_noise, extra_delay, gap_drift, periodic, saturation};
use crate::diagnose::fit::model::Rest;
use crate::diagnose::fit::model::tests::{input, paper_base, paper_record};
use crate::diagnose::fit::starts::StartContext;
use crate::diagnose::residual::statistics::{INPUT_LINE_RATIO, input_line_ratio};
use crate::diagnose::residual::test_names;
use crate::diagnose::search::round::{Context, Current, find, judged_as_is};
use std::time::Duration;

/// A judged candidate's numbers on a record whose output is the paper model's plus 0.3 (n = 80, fit part 60):
/// the held-out error is 0.3 on every sample, the fit RMSE sqrt(cost / 60), and the BIC
/// 60 ln(0.4 / 60) + 6 ln 60 (k = 6: a1, a2, b0, m2, c1, c2) = -276.07205027, plus the current model's
/// penalty 0.5, plus the extra delay's ln 3: -274.47343798 (numpy: 60*np.log(0.4/60)+6*np.log(60)+0.5+np.log(3)).
/// The fit counts as stuck (and says so) exactly when its cost equals the current model's.
#[test]
fn judge_adds_every_penalty_to_the_bic() {
    let model = EffectModel::plain(paper_base());
    let (u, sim) = paper_record(80);
    let y: Vec<f64> = sim.y.iter().map(|v| v + 0.3).collect();
    let p = Problem::new(&u, &y, 60, LmOptions::default());
    let cfg = DiagnoseConfig::new(2, 0, 1);
    let held = vec![0.6; 20];
    let no_mrgia = |_: usize, _: usize, _: usize| None;
    let context = |base_cost: f64| Context {
        p: &p,
        cfg: &cfg,
        base_cost,
        base_bic: 10.0,
        penalty: 0.5,
        base_heldout: &held,
        starts: StartContext {
            current: &model,
            u: &u[..60],
            y: &y[..60],
            residual: &held,
            y_scale: p.y_scale,
            omega: 0.1,
            lattice: None,
            clip: (-1.0, 1.0),
            mrgia: &no_mrgia,
        },
    };
    let c = context(1.0)
        .judge(
            extra_delay::ID,
            vec![],
            (model.clone(), 0.4, Objective::Simulation),
        )
        .expect("the paper model simulates");
    assert_eq!(c.k, 6);
    assert!((c.bic - -274.473_437_98).abs() < 1e-6, "{}", c.bic);
    assert!(
        (c.delta_bic - -284.473_437_98).abs() < 1e-6,
        "{}",
        c.delta_bic
    );
    assert!((c.heldout_rmse - 0.3).abs() < 1e-9, "{}", c.heldout_rmse);
    assert!(
        (c.fit_rmse - 0.081_649_658_09).abs() < 1e-9,
        "{}",
        c.fit_rmse
    );
    assert!(!c.reason.contains("no valid step"), "{}", c.reason);
    let stuck = context(0.4)
        .judge(
            extra_delay::ID,
            vec![],
            (model.clone(), 0.4, Objective::Simulation),
        )
        .expect("the paper model simulates");
    assert!(stuck.reason.contains("no valid step"), "{}", stuck.reason);
    // "Equal" is relative to the current cost: 1e-7 above a cost of 1e6 is within 1e-12 of it.
    let big = context(1e6)
        .judge(
            extra_delay::ID,
            vec![],
            (model.clone(), 1e6 + 1e-7, Objective::Simulation),
        )
        .expect("the paper model simulates");
    assert!(big.reason.contains("no valid step"), "{}", big.reason);
}

/// The declared orders are refused above the plant's largest order, and the largest is accepted.
#[test]
fn declared_orders_up_to_the_largest_are_accepted() {
    let (u, sim) = paper_record(200);
    let check = |na: usize, nb: usize| check_record(&u, &sim.y, &DiagnoseConfig::new(na, nb, 1));
    assert!(check(MAX_ORDER, MAX_ORDER).is_ok());
    for (na, nb) in [(MAX_ORDER + 1, 0), (0, MAX_ORDER + 1)] {
        let e = check(na, nb)
            .expect_err("above the largest order")
            .to_string();
        assert!(e.contains(&format!("between 0 and {MAX_ORDER}")), "{e}");
    }
}

/// The longest delay to try is refused outside 1..=MAX_DELAY, in words, and accepted at both ends.
#[test]
fn the_longest_delay_to_try_is_between_1_and_the_largest() {
    let (u, sim) = paper_record(200);
    let check = |max_delay: usize| {
        let cfg = DiagnoseConfig {
            max_delay,
            ..DiagnoseConfig::new(2, 0, 1)
        };
        check_record(&u, &sim.y, &cfg)
    };
    assert!(check(1).is_ok());
    assert!(check(MAX_DELAY).is_ok());
    for bad in [0, MAX_DELAY + 1] {
        let e = check(bad).expect_err("outside the range").to_string();
        assert!(e.contains(&format!("between 1 and {MAX_DELAY}")), "{e}");
    }
}

/// A residual that is a sinusoid at a frequency the input carries is model error driven by the input: the
/// round sets the periodic disturbance aside, says so, and (every other effect excluded here, so nothing is
/// fitted) tries nothing. The input is a pure sinusoid at 0.3 rad/sample, so its periodogram at the
/// residual's peak is far above its median (the threshold is 20 times).
#[test]
fn a_residual_line_the_input_carries_is_set_aside() {
    let (n, n_fit) = (400, 300);
    let u: Vec<f64> = (0..n).map(|k| 2.0 * (0.3 * k as f64).sin()).collect();
    let model = EffectModel::plain(paper_base());
    let sim = model
        .simulate(&u, Rest::ZERO, n, 1e6)
        .expect("the paper model runs");
    let e: Vec<f64> = (0..n).map(|k| 0.5 * (0.3 * k as f64).sin()).collect();
    let y: Vec<f64> = sim.y.iter().zip(&e).map(|(s, r)| s + r).collect();
    assert!(input_line_ratio(&u[..n_fit], 0.3) > INPUT_LINE_RATIO);
    let p = Problem::new(&u, &y, n_fit, LmOptions::default());
    let cfg = DiagnoseConfig::new(2, 0, 1);
    let others: Vec<EffectId> = EffectId::all().filter(|id| *id != periodic::ID).collect();
    let found = find(
        &p,
        &cfg,
        Current {
            model: &model,
            sim: &sim,
            e: &e,
            cost: 1.0,
            bic: 0.0,
            penalty: 0.0,
            exclude: &others,
            fitted: &[],
        },
    );
    assert!(
        found
            .tests
            .iter()
            .any(|t| t.verdict.name == test_names::SPECTRUM_PEAK && t.verdict.rejects),
        "the sinusoidal residual has a spectrum peak"
    );
    assert_eq!(found.set_aside.len(), 1, "{:?}", found.set_aside);
    assert!(found.set_aside[0].starts_with("periodic-disturbance"));
    assert!(found.candidates.is_empty() && found.not_tried.is_empty());
    assert_eq!(found.chosen, None);
}

/// The linear model's errors as the report shows them: on a record whose output is the linear model's plus
/// 0.3 (n = 80, fit part 60) with a fit-part cost of 0.6, the fit RMSE is sqrt(0.6 / 60) = 0.1 and the
/// held-out RMSE 0.3; the output is the model's simulation.
#[test]
fn linear_fit_reports_the_rmse_per_sample() {
    let n = 80;
    let u = input(n);
    let lin = BaseModel {
        m2: 1.0,
        ..paper_base()
    };
    let sim = EffectModel::plain(lin.clone())
        .simulate(&u, Rest::ZERO, n, 1e6)
        .expect("the linear model runs");
    let y: Vec<f64> = sim.y.iter().map(|v| v + 0.3).collect();
    let p = Problem::new(&u, &y, 60, LmOptions::default());
    let fit = linear_fit(&p, &(lin, 0.6));
    assert!((fit.fit_rmse - 0.1).abs() < 1e-12, "{}", fit.fit_rmse);
    assert!(
        (fit.heldout_rmse - 0.3).abs() < 1e-9,
        "{}",
        fit.heldout_rmse
    );
    assert_eq!(fit.output, sim.y);
}

/// A refit of the plain model replaces it only when more than one part in a million lower.
#[test]
fn a_refit_must_be_clearly_lower() {
    let clearly_below = |cost: f64, reference: f64| below_by(cost, reference, REFIT_GAIN);
    assert!(clearly_below(0.99, 1.0));
    assert!(clearly_below(99.9998, 100.0));
    assert!(!clearly_below(99.9999, 100.0));
    assert!(!clearly_below(1.0, 1.0));
    assert!(!clearly_below(1.1, 1.0));
}

/// A candidate of effect `id` with the paper model, fitted by `error_kind` to `fit_cost`.
fn candidate(id: EffectId, error_kind: &'static str, fit_cost: f64) -> Candidate {
    Candidate {
        id,
        pointed_by: vec![],
        model: EffectModel::plain(paper_base()),
        k: 6,
        fit_rmse: 0.0,
        fit_cost,
        bic: 0.0,
        delta_bic: 0.0,
        heldout_rmse: 0.0,
        heldout_z: 0.0,
        error_kind,
        one_step: None,
        supported: false,
        reason: String::new(),
        output: vec![],
        sim: Default::default(),
    }
}

/// The plain model is refitted from a winner's base part after rounds 1 and 2 only, and only when the
/// winner extends the plain model.
#[test]
fn the_plain_model_is_refitted_from_an_extending_winner_twice_at_most() {
    let mut winner = candidate(gap_drift::ID, SIMULATION, 1.0);
    winner.model.base.b = vec![0.7];
    let plain_winner = winner.clone();
    winner.model = winner.model.with(gap_drift::extension(1e-3, 0.0));
    let start = refit_start(1, Some(&winner)).expect("round 1 refits");
    assert_eq!(start, EffectModel::plain(winner.model.base.clone()));
    assert!(refit_start(2, Some(&winner)).is_some());
    assert_eq!(refit_start(3, Some(&winner)), None);
    assert_eq!(refit_start(1, Some(&plain_winner)), None);
    assert_eq!(refit_start(1, None), None);
}

/// Only an earlier simulation fit of the same effect is judged again as it is; a noise model's prediction
/// fit of the same effect, or another effect's, is not.
#[test]
fn only_simulation_fits_of_the_same_effect_are_judged_again() {
    let fitted = [
        candidate(coloured_noise::ID, "one-step prediction", 1.0),
        candidate(gap_drift::ID, SIMULATION, 2.0),
        candidate(coloured_noise::ID, SIMULATION, 3.0),
    ];
    let found = |id| judged_as_is(&fitted, id).map(|c| c.fit_cost);
    assert_eq!(found(coloured_noise::ID), Some(3.0));
    assert_eq!(found(gap_drift::ID), Some(2.0));
    assert_eq!(found(saturation::ID), None);
    assert_eq!(
        judged_as_is(&fitted[..1], coloured_noise::ID).map(|c| c.fit_cost),
        None
    );
}

/// The time budget reaches every fit, and the progress display hears from the rounds as well as from the
/// stages: on the paper model's output plus a sinusoid at a frequency the input lacks (the residual points to
/// a periodic disturbance), a generous budget fits the candidates the residual points to and tells of each;
/// a budget of a microsecond is spent before the first round, which lists them as not tried and fits none.
#[test]
fn the_budget_and_the_progress_reach_the_rounds() {
    let (u, sim) = paper_record(600);
    let y: Vec<f64> = sim
        .y
        .iter()
        .enumerate()
        .map(|(k, v)| v + 0.4 * (1.3 * k as f64).sin())
        .collect();
    let run = |budget: Duration| {
        let told = std::sync::Mutex::new(Vec::<String>::new());
        let mut cfg = DiagnoseConfig::new(2, 0, 1);
        cfg.time_budget = budget;
        let d = diagnose_with_progress(&u, &y, &cfg, &|s| told.lock().unwrap().push(s.to_string()))
            .expect("the record is diagnosed");
        (d, told.into_inner().unwrap())
    };
    let (full, told) = run(Duration::from_secs(300));
    assert!(full.not_tried.is_empty() && !full.candidates.is_empty());
    assert!(
        told.iter()
            .any(|s| s.starts_with("round 1: fitting the candidates") && !s.contains("(0 of")),
        "{told:?}"
    );
    // Round 1 tells "k of total done" for each k from 0 to total (in any order: the fits run on all cores;
    // a round judged again after the plain model is refitted from its winner tells it again).
    let mut done: Vec<(usize, usize)> = told
        .iter()
        .filter_map(|s| {
            let rest = s.strip_prefix("round 1: fitting the candidates")?;
            let (k, total) = rest
                .split_once('(')?
                .1
                .split_once(" done)")?
                .0
                .split_once(" of ")?;
            Some((k.parse().ok()?, total.parse().ok()?))
        })
        .collect();
    done.sort();
    done.dedup();
    let total = done.last().expect("round 1 told").1;
    assert!(total > 0, "{told:?}");
    assert_eq!(done, (0..=total).map(|k| (k, total)).collect::<Vec<_>>());
    let (spent, _) = run(Duration::from_micros(1));
    assert!(spent.candidates.is_empty(), "{:?}", spent.candidates);
    assert!(!spent.not_tried.is_empty());
}

/// The autocorrelation tests' lags: 20 asked of a fit part of 500 (a fifth is 100) stay 20; of 53 samples,
/// a fifth is 10; of 4, none would be left, so one.
#[test]
fn usable_lags_by_hand() {
    assert_eq!(usable_lags(20, 500), 20);
    assert_eq!(usable_lags(20, 53), 10);
    assert_eq!(usable_lags(20, 4), 1);
}

/// A quiet tail: the paper's linear block with a play of 0.6 (noise 0.02), its input scaled by 0.05 on the
/// last 35% of the record. At the split 0.7 the held-out part tests no claim; the play is judged at the
/// split that excites both parts, which finds it and says where it was judged. So too where one sample of
/// the tail keeps the input's full range (its standard deviation alone is poor). The same record without
/// the quiet tail is judged at its own split, and so is one excited only in a short stretch (no split is
/// fair: the held-out part there still tests nothing, and no other split is tried).
#[test]
fn a_quiet_held_out_part_moves_the_verdict_to_an_excited_split() {
    use crate::diagnose::fit::model::tests::with_noise;
    use crate::diagnose::search::presence::Presence;
    let n = 2000;
    let truth = EffectModel::plain(BaseModel {
        c1: 0.3,
        c2: 0.3,
        m2: 1.0,
        ..paper_base()
    });
    let judged = |scale: &dyn Fn(usize) -> f64| {
        let u: Vec<f64> = input(n)
            .iter()
            .enumerate()
            .map(|(k, v)| v * scale(k))
            .collect();
        let sim = truth.simulate(&u, Rest::ZERO, n, 1e6).expect("it runs");
        let y = with_noise(&sim.y, 0.02, 5);
        let p = Problem::new(&u, &y, 1400, LmOptions::default());
        let s = judge_play(&p, &truth, 0.7);
        (s.reasons.join(" | "), s.presence)
    };
    let moved_at = |said: &str| {
        said.starts_with("the held-out part of the split asked for is poorly excited")
            && said.contains("judged at the fit fraction 0.3")
    };
    let (said, presence) = judged(&|k| if k < 1300 { 1.0 } else { 0.05 });
    assert!(moved_at(&said), "{said}");
    assert_eq!(presence, Presence::Present, "{said}");
    let peak = input(n)
        .iter()
        .enumerate()
        .skip(1500)
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        .map(|(k, _)| k)
        .expect("samples");
    let (said, _) = judged(&|k| if k < 1300 || k == peak { 1.0 } else { 0.05 });
    assert!(moved_at(&said), "one loud sample: {said}");
    let (said, presence) = judged(&|_| 1.0);
    assert!(!said.contains("poorly excited"), "{said}");
    assert_eq!(presence, Presence::Present, "{said}");
    let (said, _) = judged(&|k| if (1000..1080).contains(&k) { 1.0 } else { 0.05 });
    assert!(
        !said.contains("judged at the fit fraction"),
        "a burst: {said}"
    );
}
