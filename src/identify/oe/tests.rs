//! Tests of the output-error fit: sensitivities against finite differences, the simulation against the
//! plant, the paper example (noise-free and a Monte Carlo study at SNR 43 against the CRB), random plants,
//! the degenerate cases and the planning arithmetic.
//!
//! `cargo test --release --lib identify::oe -- --nocapture` prints the measured numbers.

use super::*;
use crate::identify::mrgia::{max_rel_error, paper_input};
use crate::plant::Plant;
use rand_chacha::ChaCha8Rng;
use rand_core::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

fn paper_record(n: usize, seed: u64, snr: Option<f64>) -> (Vec<f64>, Vec<f64>, f64) {
    let u = paper_input(n, seed);
    let clean: Vec<f64> = Plant::simulate(PlantParams::PAPER, &u)
        .unwrap()
        .iter()
        .map(|o| o.w)
        .collect();
    match snr {
        None => (u, clean, 0.0),
        Some(r) => {
            let std = study_std(&clean) / r;
            let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xABCD);
            let y = clean
                .iter()
                .map(|w| {
                    let z: f64 = StandardNormal.sample(&mut rng);
                    w + std * z
                })
                .collect();
            (u, y, std)
        }
    }
}

fn study_std(v: &[f64]) -> f64 {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / n).sqrt()
}

fn truth_est(p: &PlantParams) -> Estimate {
    estimate_of(p)
}

#[test]
fn simulation_matches_the_plant() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for i in 0..20 {
        let plant = if i == 0 {
            PlantParams::PAPER
        } else {
            random_plant(&mut rng)
        };
        let u = paper_input(2000, i);
        let w_plant: Vec<f64> = Plant::simulate(plant, &u)
            .unwrap()
            .iter()
            .map(|o| o.w)
            .collect();
        let w = simulate(&truth_est(&plant), plant.arx.delay, &u).unwrap();
        assert_eq!(w, w_plant, "plant {i}");
    }
}

#[test]
fn m1_scaling_is_invisible_in_the_output() {
    // (b, m1, m2, c1, c2) and (s b, m1/s, m2/s, s c1, s c2) give the same output; normalise picks s = m1.
    let mut p = PlantParams::PAPER;
    p.backlash.m1 = 2.5;
    p.backlash.m2 = 0.7;
    let q = normalise(&p);
    assert_eq!(q.backlash.m1, 1.0);
    let u = paper_input(3000, 3);
    let wp: Vec<f64> = Plant::simulate(p, &u)
        .unwrap()
        .iter()
        .map(|o| o.w)
        .collect();
    let wq: Vec<f64> = Plant::simulate(q, &u)
        .unwrap()
        .iter()
        .map(|o| o.w)
        .collect();
    for (a, b) in wp.iter().zip(&wq) {
        assert!((a - b).abs() <= 1e-12 * (1.0 + a.abs()), "{a} vs {b}");
    }
    // simulate() normalises an estimate with m1 != 1 the same way.
    let mut est = truth_est(&PlantParams::PAPER);
    est.m1 = 2.5;
    est.m2 = 0.7;
    let w = simulate(&est, 1, &u).unwrap();
    for (a, b) in wp.iter().zip(&w) {
        assert!((a - b).abs() <= 1e-12 * (1.0 + a.abs()));
    }
}

/// The exact sensitivities equal central differences of the simulation (away from the measure-zero set
/// where a sample sits on a switching threshold; the step is small enough that no sample switches mode).
#[test]
fn sensitivities_match_finite_differences() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut plants = vec![PlantParams::PAPER];
    while plants.len() < 8 {
        let p = random_plant(&mut rng);
        if p.arx.na >= 1 {
            plants.push(p);
        }
    }
    for (pi, plant) in plants.iter().enumerate() {
        let est = truth_est(plant);
        let d = plant.arx.delay;
        let x_scale = 2.0 * (plant.backlash.c1 + plant.backlash.c2);
        let u: Vec<f64> = paper_input(1500, 40 + pi as u64)
            .iter()
            .map(|v| v * x_scale)
            .collect();
        let (w, jac) = sensitivities(&est, d, &u).unwrap();
        assert_eq!(w, simulate(&est, d, &u).unwrap());
        let th = theta_of(&est);
        let names = param_names(est.a.len(), est.b.len() - 1);
        for i in 0..th.len() {
            let h = 1e-7 * th[i].abs().max(0.1);
            let at = |delta: f64| {
                let mut t = th.clone();
                t[i] += delta;
                let (na, nb) = (est.a.len(), est.b.len() - 1);
                let p = t.len();
                let e = Estimate {
                    a: t[..na].to_vec(),
                    b: t[na..=na + nb].to_vec(),
                    m1: 1.0,
                    m2: t[p - 3],
                    c1: t[p - 2],
                    c2: t[p - 1],
                };
                simulate(&e, d, &u).unwrap()
            };
            let (wp, wm) = (at(h), at(-h));
            let col_max = (0..u.len()).map(|k| jac[(k, i)].abs()).fold(0.0, f64::max);
            assert!(col_max > 0.0, "plant {pi}: {} has no sensitivity", names[i]);
            let mut worst = 0.0f64;
            for k in 0..u.len() {
                let fd = (wp[k] - wm[k]) / (2.0 * h);
                worst = worst.max((fd - jac[(k, i)]).abs());
            }
            assert!(
                worst <= 1e-5 * (1.0 + col_max),
                "plant {pi}, d w / d {}: worst difference {worst:.2e} (column max {col_max:.2e})",
                names[i]
            );
        }
    }
}

#[test]
fn noise_free_paper_example_is_recovered_exactly() {
    let (u, y, _) = paper_record(3000, 1, None);
    let fit = fit(&OeConfig::new(2, 0, 1), &u, &y).unwrap();
    let err = max_rel_error(&fit.estimate, &PlantParams::PAPER);
    println!(
        "noise-free paper example: max rel error {err:.1e} after {} iterations from {} (start rmse {:.2e})",
        fit.iterations, fit.start_method, fit.start_rmse
    );
    assert!(err < 1e-9, "{:?}", fit.estimate);
    assert!(fit.converged);
    assert!(fit.rmse < 1e-10);
    assert_eq!(fit.estimate.m1, 1.0);
    assert_eq!(fit.modes.iter().sum::<usize>(), 3000);
}

#[test]
fn fit_never_increases_the_cost_and_reports_consistent_numbers() {
    let (u, y, std) = paper_record(2000, 4, Some(43.0));
    let cfg = OeConfig::new(2, 0, 1);
    let fit = fit(&cfg, &u, &y).unwrap();
    assert!(fit.rmse <= fit.start_rmse);
    assert!(fit.converged);
    let w = simulate(&fit.estimate, 1, &u).unwrap();
    let v: f64 = y.iter().zip(&w).map(|(a, b)| (a - b).powi(2)).sum();
    assert!((v - fit.cost).abs() <= 1e-9 * v);
    assert!((fit.sigma - (v / (2000.0 - 6.0)).sqrt()).abs() < 1e-12);
    // The residual std estimates the noise std.
    assert!(
        (fit.sigma / std - 1.0).abs() < 0.1,
        "{} vs {std}",
        fit.sigma
    );
    assert_eq!(fit.std_err.flat(), fit.uncertainty.std);
    assert_eq!(fit.uncertainty.std_err(), fit.std_err);
    // A far start (gaps never engaged, m2 <= 0) is repaired and still reaches the same optimum.
    let bad = Estimate {
        a: vec![0.0, 0.0],
        b: vec![1.0],
        m1: 1.0,
        m2: -1.0,
        c1: 100.0,
        c2: 100.0,
    };
    let far = fit_from(&cfg, &u, &y, &[("given", bad)]).unwrap();
    println!(
        "far start: cost {:.6e} vs {:.6e}, {} iterations",
        far.cost, fit.cost, far.iterations
    );
    assert!(far.start.m2 > 0.0 && far.start.c1 < 100.0 && far.start.c2 < 100.0);
    // Both stop within STEP_SE = 0.1 standard errors of the optimum.
    let (a, b) = (theta_of(&far.estimate), theta_of(&fit.estimate));
    for i in 0..6 {
        assert!(
            (a[i] - b[i]).abs() <= 0.3 * fit.uncertainty.std[i],
            "{a:?} vs {b:?}"
        );
    }
}

/// Issue 5, item 4: 300 runs of the paper example at N = 3000, SNR 43 (noise std = std(w)/43). The RMSE of
/// every OE parameter is within 1.2x its CRB std and the 95% intervals cover the truth in 90-98% of runs.
/// Measured on these 300 runs (RMSE known to ~4%, coverage to ~1.3%): ratios 0.95-1.09, coverages
/// 0.93-0.96; the first 100 alone gave 0.96-1.13 and 0.90-0.96; 1000 runs of `backlash study` give
/// 0.97-1.04 and 0.941-0.958.
#[test]
fn monte_carlo_oe_is_efficient_and_its_intervals_cover() {
    let cfg = StudyConfig {
        seeds: 300,
        first_seed: 0,
        ns: vec![3000],
        snr: 43.0,
    };
    let r = monte_carlo(&cfg, |_| {});
    let (oe, crb, rec) = (
        r.get("oe", 3000).unwrap(),
        r.get("crb", 3000).unwrap(),
        r.get("mrgia-recommended", 3000).unwrap(),
    );
    assert_eq!((oe.failures, crb.failures), (0, 0));
    let cov = oe.coverage.as_ref().unwrap();
    for (i, name) in r.names.iter().enumerate() {
        println!(
            "{name:>3}: OE RMSE {:.3e}  CRB {:.3e}  ratio {:.3}  coverage {:.2}  rms std_err / CRB {:.3} | \
             MRGIA rec RMSE / CRB {:.2}",
            oe.rmse[i],
            crb.rmse[i],
            oe.rmse[i] / crb.rmse[i],
            cov[i],
            oe.rms_std_err.as_ref().unwrap()[i] / crb.rmse[i],
            rec.rmse[i] / crb.rmse[i],
        );
    }
    for (i, name) in r.names.iter().enumerate() {
        assert!(
            oe.rmse[i] <= 1.2 * crb.rmse[i],
            "{name}: RMSE {} vs CRB {}",
            oe.rmse[i],
            crb.rmse[i]
        );
        assert!(
            (0.90..=0.98).contains(&cov[i]),
            "{name}: coverage {}",
            cov[i]
        );
    }
}

/// A random plant for these tests: na <= 3, nb <= 2, delay 1..=3.
fn random_plant(rng: &mut ChaCha8Rng) -> PlantParams {
    crate::identify::test_plants::random_plant(rng, 3, 2, &[1, 2, 3])
}

/// Largest |theta_i - ref_i| / max(|ref_i|, 0.05).
fn max_rel_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs() / y.abs().max(0.05))
        .fold(0.0, f64::max)
}

/// Samples of a noise-free run at which the two borders are crossed at x (`m2 (x + c2) < x - c1`): there the
/// contract's rule is discontinuous (the output alternates between the borders even for a constant x).
fn inverted_samples(plant: &PlantParams, u: &[f64]) -> usize {
    let bl = plant.backlash;
    Plant::simulate(*plant, u)
        .unwrap()
        .iter()
        .filter(|o| bl.lower(o.x) < bl.upper(o.x))
        .count()
}

/// A random plant with an input that keeps x on the play side of the border crossing (no inverted sample):
/// the paper input scaled by 2 (c1 + c2), shrunk by 0.8 until no sample is inverted; plants that need a
/// scale below 0.5 (c1 + c2), which would hardly leave the memory zone, are redrawn.
fn random_physical_record(rng: &mut ChaCha8Rng, n: usize, seed: u64) -> (PlantParams, Vec<f64>) {
    loop {
        let plant = random_plant(rng);
        let base = paper_input(n, seed);
        let mut scale = 2.0 * (plant.backlash.c1 + plant.backlash.c2);
        while scale >= 0.5 * (plant.backlash.c1 + plant.backlash.c2) {
            let u: Vec<f64> = base.iter().map(|v| v * scale).collect();
            if inverted_samples(&plant, &u) == 0 {
                return (plant, u);
            }
            scale *= 0.8;
        }
    }
}

/// Outcome counts of one regime of `random_plants_are_recovered`.
#[derive(Debug, Default, Clone, Copy, PartialEq)]
struct Rates {
    ok: usize,
    ok_single: usize,
    mrgia_within_1pct: usize,
    plants: usize,
}

fn recover_rates(label: &str, records: &[(PlantParams, Vec<f64>)], snr: Option<f64>) -> Rates {
    let mut r = Rates {
        plants: records.len(),
        ..Rates::default()
    };
    for (i, (plant, u)) in records.iter().enumerate() {
        let w: Vec<f64> = Plant::simulate(*plant, u)
            .unwrap()
            .iter()
            .map(|o| o.w)
            .collect();
        let y: Vec<f64> = match snr {
            None => w,
            Some(snr) => {
                let std = study_std(&w) / snr;
                let mut nrng = ChaCha8Rng::seed_from_u64(900 + i as u64);
                w.iter()
                    .map(|v| {
                        let z: f64 = StandardNormal.sample(&mut nrng);
                        v + std * z
                    })
                    .collect()
            }
        };
        let arx = &plant.arx;
        let cfg = OeConfig::new(arx.na, arx.nb, arx.delay);
        let reference = fit_from(&cfg, u, &y, &[("given", truth_est(plant))]).unwrap();
        let tol = if snr.is_none() { 1e-6 } else { 1e-3 };
        // Costs closer than the stopping resolution STEP_SE^2 s^2 are statistically equal.
        let resolution = STEP_SE * STEP_SE * reference.sigma * reference.sigma;
        let success = |f: &OeFit| {
            max_rel_diff(&theta_of(&f.estimate), &theta_of(&reference.estimate)) <= tol
                || f.cost <= reference.cost + resolution
        };
        let full = fit(&cfg, u, &y).unwrap();
        let single = fit(
            &OeConfig {
                extra_starts: false,
                ..cfg
            },
            u,
            &y,
        )
        .unwrap();
        let (rec, _) =
            mrgia::identify(MrgiaConfig::recommended(arx.na, arx.nb, arx.delay), u, &y).unwrap();
        let mrgia_err = max_rel_error(&rec, plant);
        r.mrgia_within_1pct += usize::from(mrgia_err <= 1e-2);
        r.ok += usize::from(success(&full));
        r.ok_single += usize::from(success(&single));
        if !success(&full) {
            println!(
                "  {label}: plant {i} (na {}, nb {}, d {}, m2 {:.2}, {} inverted samples) not recovered: \
                 rel diff {:.2e} ({:.1} std errors), cost {:.4e} vs {:.4e} from the truth; MRGIA max rel \
                 error {mrgia_err:.2e}",
                arx.na,
                arx.nb,
                arx.delay,
                plant.backlash.m2,
                inverted_samples(plant, u),
                max_rel_diff(&theta_of(&full.estimate), &theta_of(&reference.estimate)),
                theta_of(&full.estimate)
                    .iter()
                    .zip(theta_of(&reference.estimate))
                    .zip(&reference.uncertainty.std)
                    .map(|((a, b), s)| (a - b).abs() / s)
                    .fold(0.0, f64::max),
                full.cost,
                reference.cost,
            );
        }
    }
    println!(
        "{label}: OE recovered {}/{} (single MRGIA start: {}/{}); MRGIA alone within 1% on {}/{}",
        r.ok, r.plants, r.ok_single, r.plants, r.mrgia_within_1pct, r.plants
    );
    r
}

/// Issue 5, item 4: random stable plants (na <= 3, nb <= 2, delay 1..3), N = 3000, noise-free and at
/// SNR 100, in two regimes:
///
/// - physical: the input keeps x on the play side of the crossing point of the two borders (as in any real
///   backlash, where the borders do not cross inside the travel);
/// - crossing: the input of the MRGIA random-plant test (paper input times 2 (c1 + c2)), which drives most
///   plants with m2 != 1 beyond the crossing point `x* = (c1 + m2 c2) / (1 - m2)`, where the contract's rule
///   is discontinuous: the output alternates between the two borders, the cost is discontinuous in theta
///   and has many local minima within a few percent of the truth.
///
/// Success: the fit from MRGIA reaches the optimum that the same optimiser reaches from the truth (the
/// global minimum's basin): parameters within 1e-6 (noise-free) / 1e-3 (noisy) relative, or a cost no
/// higher than that optimum's plus the stopping resolution `STEP_SE^2 s^2` (statistically equal).
/// Measured (60 plants each): physical 60/60 noise-free and 60/60 at SNR 100; crossing 56/60 and 54/60,
/// every failure on a plant with over 1000 of its 3000 samples beyond the crossing point. With only the
/// recommended MRGIA start the counts are the same.
#[test]
fn random_plants_are_recovered() {
    let mut rng = ChaCha8Rng::seed_from_u64(2025);
    let crossing: Vec<(PlantParams, Vec<f64>)> = (0..60)
        .map(|i| {
            let plant = random_plant(&mut rng);
            let x_scale = 2.0 * (plant.backlash.c1 + plant.backlash.c2);
            let u = paper_input(3000, 500 + i)
                .iter()
                .map(|v| v * x_scale)
                .collect();
            (plant, u)
        })
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(7070);
    let physical: Vec<(PlantParams, Vec<f64>)> = (0..60)
        .map(|i| random_physical_record(&mut rng, 3000, 700 + i))
        .collect();
    let mut measured = vec![];
    for (label, records, min) in [
        ("physical", &physical, MIN_PHYSICAL),
        ("crossing", &crossing, MIN_CROSSING),
    ] {
        for (noise, snr) in [("noise-free", None), ("SNR 100", Some(100.0))] {
            let r = recover_rates(&format!("{label}, {noise}"), records, snr);
            measured.push((label, noise, r, min));
        }
    }
    for (label, noise, r, min) in &measured {
        assert!(r.ok >= *min, "{label}, {noise}: {r:?}");
    }
}

/// Asserted successes of 60 (see `random_plants_are_recovered` for the measured numbers).
const MIN_PHYSICAL: usize = 58;
const MIN_CROSSING: usize = 54;

#[test]
fn unexcited_records_are_refused_with_the_parameters_named() {
    let cfg = OeConfig::new(2, 0, 1);
    // No input at all: nothing moves, every parameter is unexcited.
    let u = vec![0.0; 500];
    let y = vec![0.0; 500];
    match fit(&cfg, &u, &y) {
        Err(OeError::NotExcited { params, .. }) => assert_eq!(params.len(), 6, "{params:?}"),
        other => panic!("{other:?}"),
    }
    // An input that only ever drives the output up: the lower border is never seen.
    let u: Vec<f64> = (0..500).map(|k| 0.01 * k as f64).collect();
    let y: Vec<f64> = Plant::simulate(PlantParams::PAPER, &u)
        .unwrap()
        .iter()
        .map(|o| o.w)
        .collect();
    let err = fit(&cfg, &u, &y).unwrap_err();
    match &err {
        OeError::NotExcited { params, .. } => {
            assert!(
                params.contains(&"m2".to_string()) && params.contains(&"c2".to_string()),
                "{params:?}"
            );
        }
        other => panic!("{other:?}"),
    }
    assert!(err.to_string().contains("does not excite"), "{err}");
    // The CRB says the same for the same input.
    assert!(matches!(
        crb(&PlantParams::PAPER, &u, 0.01),
        Err(OeError::NotExcited { .. })
    ));
}

#[test]
fn bad_records_and_settings_are_refused() {
    let cfg = OeConfig::new(2, 0, 1);
    let u = paper_input(100, 1);
    assert!(matches!(
        fit(&cfg, &u, &u[..99]),
        Err(OeError::Length { u: 100, y: 99 })
    ));
    assert!(matches!(
        fit(&cfg, &u[..6], &u[..6]),
        Err(OeError::TooShort { n: 6, min: 7, p: 6 })
    ));
    let mut y = u.clone();
    y[17] = f64::NAN;
    assert!(matches!(
        fit(&cfg, &u, &y),
        Err(OeError::NonFinite {
            signal: "y",
            index: 17
        })
    ));
    let bad = OeConfig::new(5, 0, 1);
    assert!(matches!(fit(&bad, &u, &u), Err(OeError::Param(_))));
    let bad = OeConfig::new(2, 0, 0);
    assert!(matches!(fit(&bad, &u, &u), Err(OeError::Param(_))));
    assert!(matches!(
        crb(&PlantParams::PAPER, &u, 0.0),
        Err(OeError::NoiseStd(_))
    ));
    // The CRB accepts any finite gap (a fitted gap may be slightly negative) but needs positive slopes.
    let mut p = PlantParams::PAPER;
    p.backlash.c1 = -0.01;
    assert!(crb(&p, &u, 0.01).is_ok());
    p.backlash.m2 = 0.0;
    assert!(matches!(crb(&p, &u, 0.01), Err(OeError::Param(_))));
    let wrong = Estimate {
        a: vec![0.1],
        b: vec![1.0],
        m1: 1.0,
        m2: 1.0,
        c1: 0.1,
        c2: 0.1,
    };
    assert!(fit_from(&cfg, &u, &u, &[("given", wrong)]).is_err());
}

/// The CRB scales as 1/sqrt(N) on the paper input, `samples_for` inverts that scaling, and the standard
/// errors of a fit agree with the CRB at the fitted values and the estimated noise.
#[test]
fn crb_scaling_and_planning() {
    let truth = PlantParams::PAPER;
    let u = paper_input(12000, 9);
    let c3 = crb(&truth, &u[..3000], 0.02).unwrap();
    let c12 = crb(&truth, &u, 0.02).unwrap();
    for i in 0..6 {
        let ratio = c3.std[i] / c12.std[i];
        assert!((ratio - 2.0).abs() < 0.2, "{}: {ratio}", c3.names[i]);
    }
    // Halving the target accuracy quadruples the samples.
    let (per, all) = c3.samples_for(1e-2).unwrap();
    let (per2, all2) = c3.samples_for(5e-3).unwrap();
    assert!(all2 >= 4 * all - 4 && all2 <= 4 * all + 4, "{all} {all2}");
    let worst = (0..6)
        .max_by(|&a, &b| (c3.std[a] / c3.theta[a]).total_cmp(&(c3.std[b] / c3.theta[b])))
        .unwrap();
    assert_eq!(per[worst], Some(all));
    assert_eq!(per2.len(), 6);
    // At the N it asks for, the CRB meets the target (within the extrapolation's accuracy).
    let u_long = paper_input(all.max(7), 9);
    let c_n = crb(&truth, &u_long, 0.02).unwrap();
    let rel = (0..6)
        .map(|i| c_n.std[i] / c_n.theta[i])
        .fold(0.0, f64::max);
    assert!(rel <= 1.1e-2, "{rel} at N = {all}");
    assert!(matches!(c3.samples_for(0.0), Err(OeError::Target(_))));
    // Standard errors of a fit = CRB at the estimate with the residual noise estimate.
    let (u, y, _) = paper_record(3000, 2, Some(43.0));
    let f = fit(&OeConfig::new(2, 0, 1), &u, &y).unwrap();
    let at = plant_of(&f.estimate, 1).unwrap();
    let c = crb(&at, &u, f.sigma).unwrap();
    for i in 0..6 {
        assert!(
            (c.std[i] / f.uncertainty.std[i] - 1.0).abs() < 1e-8,
            "{i}: {} vs {}",
            c.std[i],
            f.uncertainty.std[i]
        );
    }
}

#[test]
fn study_writes_a_table_and_a_plot() {
    let cfg = StudyConfig {
        seeds: 3,
        first_seed: 7,
        ns: vec![300, 1000],
        snr: 43.0,
    };
    let mut calls = vec![];
    let r = monte_carlo(&cfg, |d| calls.push(d));
    assert_eq!(calls, vec![1, 2, 3]);
    assert_eq!(r.stats.len(), 10);
    let csv = r.to_csv();
    assert_eq!(csv.lines().count(), 1 + 10 * 6);
    assert!(csv.starts_with("method,n,param,truth,rmse"));
    let dir = std::env::temp_dir().join(format!("oe-study-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let png = dir.join("rmse.png");
    r.plot(&png).unwrap();
    assert!(std::fs::metadata(&png).unwrap().len() > 1000);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A small grid over two plants and two SNRs, all methods.
fn small_grid() -> GridConfig {
    GridConfig {
        seeds: 4,
        first_seed: 3,
        ns: vec![1000, 300],
        snrs: vec![43.0, 20.0],
        plants: vec!["paper".into(), "second-order-b".into()],
        methods: METHODS.iter().map(|m| m.to_string()).collect(),
    }
}

fn grid_on(threads: usize, cfg: &GridConfig) -> (GridResult, u64) {
    use std::sync::atomic::{AtomicU64, Ordering};
    let ticks = AtomicU64::new(0);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let r = pool
        .install(|| {
            grid_study(cfg, &|| {
                ticks.fetch_add(1, Ordering::Relaxed);
            })
        })
        .unwrap();
    (r, ticks.into_inner())
}

/// Issue 8: the parallel grid gives exactly the single-thread result (tidy table, summary and JSON, byte
/// for byte), and the progress callback ticks once per run.
#[test]
fn grid_study_does_not_depend_on_the_thread_count() {
    let cfg = small_grid();
    let (one, t1) = grid_on(1, &cfg);
    let (four, t4) = grid_on(4, &cfg);
    assert_eq!((t1, t4), (16, 16));
    assert_eq!(cfg.runs(), 16);
    assert_eq!(one.rows_csv(), four.rows_csv());
    assert_eq!(one.summary_csv(), four.summary_csv());
    assert_eq!(
        serde_json::to_string(&one).unwrap(),
        serde_json::to_string(&four).unwrap()
    );
    // 2 plants x 2 SNRs x 4 seeds x 2 N x 5 methods x (6 or 7 parameters).
    assert_eq!(one.rows.len(), 2 * 4 * 2 * 5 * (6 + 7));
    assert_eq!(one.groups.len(), 4);
    assert_eq!(one.group("second-order-b", 20.0).unwrap().names.len(), 7);
}

/// The grid's cell for the paper plant is the sequential `monte_carlo` study, exactly.
#[test]
fn grid_cell_equals_the_sequential_study() {
    let study = StudyConfig {
        seeds: 5,
        first_seed: 11,
        ns: vec![300, 3000, 1000],
        snr: 30.0,
    };
    let seq = monte_carlo(&study, |_| {});
    let (grid, _) = grid_on(3, &GridConfig::of_study(&study));
    assert_eq!(grid.groups, vec![seq]);
}

/// The rows of the tidy table's CSV, parsed back (the error column checked against estimate - truth).
fn parse_rows(csv: &str) -> Vec<Row> {
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some(ROWS_HEADER));
    let opt = |s: &str| (!s.is_empty()).then(|| s.parse::<f64>().unwrap());
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            assert_eq!(f.len(), 11, "{l}");
            let row = Row {
                plant: f[0].into(),
                snr: f[1].parse().unwrap(),
                n: f[2].parse().unwrap(),
                seed: f[3].parse().unwrap(),
                noise_std: f[4].parse().unwrap(),
                method: f[5].into(),
                param: f[6].into(),
                truth: f[7].parse().unwrap(),
                estimate: opt(f[8]),
                std_err: opt(f[10]),
            };
            assert_eq!(opt(f[9]), row.estimate.map(|e| e - row.truth));
            row
        })
        .collect()
}

/// The tidy table, parsed back from its CSV and aggregated here, gives exactly the reported statistics.
#[test]
fn tidy_table_aggregates_to_the_reported_statistics() {
    let (r, _) = grid_on(2, &small_grid());
    let rows = parse_rows(&r.rows_csv());
    assert_eq!(rows, r.rows);
    let mut checked = 0;
    for g in &r.groups {
        for st in &g.stats {
            let crb = st.method == "crb";
            let sel = |param: &str| -> Vec<&Row> {
                rows.iter()
                    .filter(|x| {
                        x.plant == g.plant
                            && x.snr == g.config.snr
                            && x.method == st.method
                            && x.n == st.n
                            && x.param == param
                    })
                    .collect()
            };
            let mut max_rel = vec![0.0f64; g.config.seeds as usize];
            for (i, name) in g.names.iter().enumerate() {
                let all = sel(name);
                assert_eq!(all.len() as u64, g.config.seeds);
                let ok: Vec<&Row> = all
                    .iter()
                    .copied()
                    .filter(|x| {
                        if crb {
                            x.std_err.is_some()
                        } else {
                            x.estimate.is_some()
                        }
                    })
                    .collect();
                assert_eq!((ok.len(), all.len() - ok.len()), (st.runs, st.failures));
                let e: Vec<f64> = ok
                    .iter()
                    .map(|x| {
                        if crb {
                            x.std_err.unwrap()
                        } else {
                            x.error().unwrap()
                        }
                    })
                    .collect();
                for (k, x) in ok.iter().enumerate() {
                    assert_eq!(x.truth, g.truth[i]);
                    let slot = (x.seed - g.config.first_seed) as usize;
                    max_rel[slot] = max_rel[slot].max((e[k] / x.truth).abs());
                }
                let m = ok.len() as f64;
                let rmse = (e.iter().map(|v| v * v).sum::<f64>() / m).sqrt();
                let bias = if crb { 0.0 } else { e.iter().sum::<f64>() / m };
                assert_eq!((st.rmse[i], st.bias[i]), (rmse, bias), "{}", st.method);
                if st.method == "oe" || st.method == "refine" {
                    let cov = ok
                        .iter()
                        .filter(|x| x.error().unwrap().abs() <= 1.96 * x.std_err.unwrap())
                        .count() as f64
                        / m;
                    let rms =
                        (ok.iter().map(|x| x.std_err.unwrap().powi(2)).sum::<f64>() / m).sqrt();
                    assert_eq!(st.coverage.as_ref().unwrap()[i], cov);
                    assert_eq!(st.rms_std_err.as_ref().unwrap()[i], rms);
                } else {
                    assert!(ok.iter().all(|x| x.std_err.is_some() == crb));
                    assert!(st.coverage.is_none());
                }
                checked += 1;
            }
            max_rel.sort_by(f64::total_cmp);
            let h = max_rel.len() / 2;
            assert_eq!(st.median_max_rel, 0.5 * (max_rel[h - 1] + max_rel[h]));
        }
    }
    // 5 methods x 2 N x (6 + 7 parameters) x 2 SNRs.
    assert_eq!(checked, 5 * 2 * 13 * 2);
}

/// Every plant variant is identifiable on the paper input: over 60 runs at SNR 43 and N = 3000 the OE fit
/// never fails and its RMSE is within 1.35x the CRB std for every parameter (measured on these 60 runs:
/// 0.86-1.23, the largest the paper plant's m2, 0.98 over 1000 runs; an RMSE over 60 runs is known to ~9%).
#[test]
fn every_plant_variant_is_fitted_at_the_bound() {
    let cfg = GridConfig {
        seeds: 60,
        first_seed: 0,
        ns: vec![3000],
        snrs: vec![43.0],
        plants: PLANT_VARIANTS.iter().map(|v| v.name.to_string()).collect(),
        methods: vec!["oe".into(), "crb".into()],
    };
    let (r, _) = grid_on(2, &cfg);
    for g in &r.groups {
        let v = plant_variant(&g.plant).unwrap();
        v.params.validate().unwrap();
        assert_eq!(g.stats.len(), 2, "only the methods asked for");
        let (oe, bound) = (g.get("oe", 3000).unwrap(), g.get("crb", 3000).unwrap());
        assert_eq!((oe.failures, bound.failures), (0, 0), "{}", g.plant);
        for (i, name) in g.names.iter().enumerate() {
            let ratio = oe.rmse[i] / bound.rmse[i];
            println!("{:>16} {name:>3}: RMSE / CRB {ratio:.3}", g.plant);
            assert!(ratio < 1.35, "{} {name}: {ratio}", g.plant);
        }
    }
}

#[test]
fn grid_refuses_bad_settings_with_the_reason() {
    let ok = small_grid();
    assert_eq!(ok.validate(), Ok(()));
    let mut c = ok.clone();
    c.plants.push("tiny-gaps".into());
    let e = grid_study(&c, &|| {}).unwrap_err();
    assert_eq!(e, StudyError::UnknownPlant("tiny-gaps".into()));
    assert!(e.to_string().contains("known: paper, wide-gaps"), "{e}");
    let mut c = ok.clone();
    c.methods = vec!["oe".into(), "ls".into()];
    assert_eq!(c.validate(), Err(StudyError::UnknownMethod("ls".into())));
    let mut c = ok.clone();
    c.ns.push(5);
    assert_eq!(c.validate(), Err(StudyError::ShortRecord(5)));
    let mut c = ok.clone();
    c.snrs.push(f64::INFINITY);
    assert_eq!(c.validate(), Err(StudyError::Snr(f64::INFINITY)));
    let mut c = ok.clone();
    c.snrs.push(43.0);
    assert_eq!(
        c.validate(),
        Err(StudyError::Duplicate {
            what: "SNR",
            value: "43.0".into()
        })
    );
    let mut c = ok;
    c.seeds = 0;
    assert_eq!(c.validate(), Err(StudyError::Empty("no seeds")));
}

/// `identify oe` and `diagnose` without orders choose the same structure on 20 random plants (one
/// selection, on the same fit part), and `identify oe` never refuses the structure it chose.
#[test]
fn identify_oe_and_diagnose_choose_the_same_structure() {
    let mut rng = ChaCha8Rng::seed_from_u64(3131);
    for i in 0..20u64 {
        let plant = PlantParams {
            noise_std: 0.02,
            noise_seed: i,
            ..random_plant(&mut rng)
        };
        let u = paper_input(700, 500 + i);
        let y: Vec<f64> = Plant::simulate(plant, &u)
            .unwrap()
            .iter()
            .map(|o| o.y)
            .collect();
        let oe = crate::api::identify_oe(&u, &y, &crate::api::OeOptions::default())
            .unwrap_or_else(|e| panic!("plant {i}: identify oe refused its own choice: {e}"));
        let cfg = crate::diagnose::engine::DiagnoseConfig {
            max_effects: 1,
            ..crate::diagnose::engine::DiagnoseConfig::auto()
        };
        let d = crate::api::diagnose(&u, &y, &cfg).unwrap();
        // The one exception: the whole record refused the common choice and `identify oe` replaced it,
        // which it says.
        if oe.structure.chosen != d.structure.chosen {
            let replaced = oe.structure.replaced.as_ref().map(|r| r.structure);
            assert_eq!(replaced, Some(d.structure.chosen), "plant {i}: {plant:?}");
        }
    }
}
