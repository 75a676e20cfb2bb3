//! Tests of the MRGIA: the paper's example (noise-free and SNR 43), the decisions listed in the module docs,
//! the degenerate cases, wear tracking, other plants, and the FMU-state round trip.

use super::rls::{MAX_N, Rls};
use super::*;
use crate::plant::{Arx, ArxParams, BacklashParams, Mode, Plant, PlantParams};
use nalgebra::{DMatrix, SMatrix, SVector};
use proptest::prelude::*;
use rand_chacha::ChaCha8Rng;
use rand_core::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

const PAPER_TRUTH: [f64; 6] = [0.45, 0.55, 0.8, 0.5, 0.5, 1.0]; // theta: a1, a2, b0, m2 - 1, c1, c2

fn paper_clean(n: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let u = paper_input(n, seed);
    let y = Plant::simulate(PlantParams::PAPER, &u)
        .unwrap()
        .iter()
        .map(|o| o.w)
        .collect();
    (u, y)
}

fn run(cfg: MrgiaConfig, u: &[f64], y: &[f64]) -> Mrgia {
    identify(cfg, u, y).unwrap().1
}

/// P as an n x n matrix.
fn p_matrix(est: &Mrgia) -> DMatrix<f64> {
    let n = est.theta().len();
    DMatrix::from_row_slice(n, n, &est.covariance())
}

fn assert_spd(est: &Mrgia, what: &str) {
    let p = p_matrix(est);
    assert!(p.iter().all(|v| v.is_finite()), "{what}: P not finite");
    assert!(
        (&p - p.transpose()).abs().max() == 0.0,
        "{what}: P not symmetric"
    );
    assert!(
        p.clone().cholesky().is_some(),
        "{what}: P not positive definite: {p}"
    );
}

fn fmt(v: (f64, f64, f64)) -> String {
    format!("{:.2e} / {:.2e} / {:.2e}", v.0, v.1, v.2)
}

// ---------------------------------------------------------------------------------------------------------
// Configuration and API

#[test]
fn paper_and_recommended_settings() {
    let p = MrgiaConfig::paper(2, 0, 1);
    assert_eq!(
        (p.p0, p.rho_exp, p.rho_min, p.eps, p.sigma0),
        (1e6, 0.25, 0.0, 0.0, 1.0)
    );
    assert!(p.c_init > 0.0 && p.c_init <= 0.01);
    let r = MrgiaConfig::recommended(2, 0, 1);
    assert_eq!(r.rho_exp, 0.75);
    assert_eq!(MrgiaConfig { rho_exp: 0.25, ..r }, p);
    p.validate().unwrap();
    r.validate().unwrap();
}

#[test]
fn bad_settings_are_refused_with_their_name() {
    let base = MrgiaConfig::paper(2, 0, 1);
    let cases: Vec<(MrgiaConfig, &str)> = vec![
        (MrgiaConfig { na: 5, ..base }, "na"),
        (MrgiaConfig { nb: 5, ..base }, "nb"),
        (MrgiaConfig { delay: 0, ..base }, "delay"),
        (MrgiaConfig { delay: 65, ..base }, "delay"),
        (MrgiaConfig { p0: 0.0, ..base }, "p0"),
        (
            MrgiaConfig {
                p0: f64::INFINITY,
                ..base
            },
            "p0",
        ),
        (
            MrgiaConfig {
                rho_exp: 0.0,
                ..base
            },
            "rho_exp",
        ),
        (
            MrgiaConfig {
                rho_exp: 1.5,
                ..base
            },
            "rho_exp",
        ),
        (
            MrgiaConfig {
                rho_min: -0.1,
                ..base
            },
            "rho_min",
        ),
        (
            MrgiaConfig {
                rho_min: 1.0,
                ..base
            },
            "rho_min",
        ),
        (MrgiaConfig { eps: -1e-3, ..base }, "eps"),
        (
            MrgiaConfig {
                eps: f64::NAN,
                ..base
            },
            "eps",
        ),
        (
            MrgiaConfig {
                sigma0: 0.0,
                ..base
            },
            "sigma0",
        ),
        (
            MrgiaConfig {
                c_init: f64::NAN,
                ..base
            },
            "c_init",
        ),
    ];
    for (cfg, name) in cases {
        assert_eq!(cfg.validate().unwrap_err().name, name, "{cfg:?}");
        assert_eq!(Mrgia::new(cfg).unwrap_err().name, name);
    }
    for (na, nb, d) in [(0, 0, 1), (4, 4, 64), (1, 3, 7)] {
        MrgiaConfig::paper(na, nb, d).validate().unwrap();
    }
}

#[test]
fn initial_state_and_parameter_layout() {
    let cfg = MrgiaConfig::paper(3, 2, 4);
    let est = Mrgia::new(cfg).unwrap();
    // [a1 a2 a3, b0 b1 b2, m2 - 1, c1, c2]
    assert_eq!(
        est.theta(),
        &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.01, 0.01]
    );
    let e = est.estimate();
    assert_eq!(e.a, vec![0.0; 3]);
    assert_eq!(e.b, vec![1.0, 0.0, 0.0]);
    assert_eq!((e.m1, e.m2, e.c1, e.c2), (1.0, 1.0, 0.01, 0.01));
    assert_eq!(est.samples(), 0);
    assert_eq!(est.last(), StepResult::default());
    assert_eq!(est.sigma(), 1.0);
    let p = p_matrix(&est);
    assert_eq!(p, DMatrix::identity(9, 9) * 1e6);
}

#[test]
fn rho_and_mu_schedule() {
    let cfg = MrgiaConfig::paper(2, 0, 1);
    assert_eq!(cfg.rho(0), 1.0);
    assert!((cfg.rho(1) - 2f64.powf(-0.25)).abs() < 1e-15);
    assert!((cfg.rho(3000) - 3001f64.powf(-0.25)).abs() < 1e-15);
    let floored = MrgiaConfig {
        rho_min: 0.2,
        ..cfg
    };
    assert_eq!(floored.rho(3000), 0.2);
    // rho_exp = 1: mu(k) = rho(k-1)/rho(k) (1 - rho(k)) = 1 exactly in exact arithmetic.
    let ls = MrgiaConfig {
        rho_exp: 1.0,
        ..cfg
    };
    for k in 1..1000u64 {
        let mu = ls.rho(k - 1) / ls.rho(k) * (1.0 - ls.rho(k));
        assert!((mu - 1.0).abs() < 1e-14, "k {k}: {mu}");
    }
}

/// rho(k) = (k + 1)^-rho_exp for every exponent: the common ones computed without `powf` (1, 0.5, 0.25,
/// 0.75) and any other through it.
#[test]
fn rho_for_every_exponent() {
    for rho_exp in [1.0, 0.5, 0.25, 0.75, 0.6, 0.9] {
        let cfg = MrgiaConfig {
            rho_exp,
            ..MrgiaConfig::paper(2, 0, 1)
        };
        for k in [0u64, 1, 7, 999] {
            let want = ((k + 1) as f64).powf(-rho_exp);
            let got = cfg.rho(k);
            assert!(
                (got - want).abs() < 1e-15,
                "rho_exp {rho_exp}, k {k}: {got}"
            );
        }
    }
}

#[test]
fn batch_identify_equals_stepping_and_checks_lengths() {
    let (u, y) = paper_clean(500, 3);
    let cfg = MrgiaConfig::paper(2, 0, 1);
    let (e, est) = identify(cfg, &u, &y).unwrap();
    let mut step = Mrgia::new(cfg).unwrap();
    for (a, b) in u.iter().zip(&y) {
        step.update(*a, *b);
    }
    assert_eq!(est, step);
    assert_eq!(e, step.estimate());
    assert_eq!(est.samples(), 500);
    assert_eq!(identify(cfg, &u, &y[..10]).unwrap_err().name, "y");
}

// ---------------------------------------------------------------------------------------------------------
// The equations, worked by hand

/// First update worked by hand on a static backlash (na = 0, nb = 0, d = 1):
/// theta(0) = [b0, m2 - 1, c1, c2] = [1, 0, 0.01, 0.01].
#[test]
fn first_updates_worked_by_hand() {
    for rho_exp in [1.0, 0.25] {
        let cfg = MrgiaConfig {
            rho_exp,
            ..MrgiaConfig::paper(0, 0, 1)
        };
        let mut est = Mrgia::new(cfg).unwrap();
        // Sample 0: u = 2, y = 0. x^(0) = b0 u(-1) = 0: nothing moves, nothing to update, y_hat = y(-1) = 0.
        let r0 = est.update(2.0, 0.0);
        assert_eq!(r0, StepResult::default());
        // Sample 1: u = 0, y = 1. x^(1) = b0 u(0) = 2, dx = 2 > 0: g3 = 0, m^ = 1;
        // g1^ = [y(0) + c1^ < x^] = [0.01 < 2] = 1; g4 = [1 - 0 > 0] = 1: Phi = 1.
        // h = [u(0), g3 x^, -0.5 m^ (sgn + 1) g1 g4, 0.5 m^ (1 - sgn) g2 g5] = [2, 0, -1, 0].
        let h = SVector::<f64, 4>::new(2.0, 0.0, -1.0, 0.0);
        let theta0 = SVector::<f64, 4>::new(1.0, 0.0, 0.01, 0.01);
        let y_hat = h.dot(&theta0); // 1.99
        let e = 1.0 - y_hat;
        // This is sample k = 2 of the recursion (k counts samples, the first being k = 1).
        let (rho1, rho2) = (2f64.powf(-rho_exp), 3f64.powf(-rho_exp));
        let mu = rho1 / rho2 * (1.0 - rho2); // (30)
        let sigma = 1.0 + rho2 * (e * e - 1.0); // (22)
        let p0 = SMatrix::<f64, 4, 4>::identity() * 1e6;
        let s = (h.transpose() * p0 * h)[0] + mu * sigma; // (19)
        let k = p0 * h / s; // (20)
        let theta1 = theta0 + k * e; // (18)
        let mut p1 = (p0 - p0 * h * h.transpose() * p0 / s) / mu; // (21), standard form
        if p1.trace() > 4e6 {
            p1 *= 4e6 / p1.trace(); // the trace cap n p0
        }
        let r1 = est.update(0.0, 1.0);
        assert!(r1.updating);
        assert!((r1.y_hat - 1.99).abs() < 1e-15 && (r1.e - e).abs() < 1e-15);
        for i in 0..4 {
            assert!(
                (est.theta()[i] - theta1[i]).abs() < 1e-14,
                "rho_exp {rho_exp}"
            );
        }
        assert!((est.sigma() - sigma).abs() < 1e-15);
        let p = p_matrix(&est);
        for i in 0..4 {
            for j in 0..4 {
                assert!(
                    (p[(i, j)] - p1[(i, j)]).abs() < 1e-9 * 1e6,
                    "rho_exp {rho_exp} P[{i},{j}] {} vs {}",
                    p[(i, j)],
                    p1[(i, j)]
                );
            }
        }
        assert_eq!(est.samples(), 2);
        assert_eq!(est.last(), r1);
    }
}

/// Eq. (21) read as `(1/mu)(I-Kh^T)P(I-Kh^T)^T + Sigma K K^T` satisfies the appendix's (47) and (48):
/// `P(k) h = Sigma P(k-1) h / S` and `P^-1(k) = mu P^-1(k-1) + h h^T / Sigma`, and theta moves by
/// `P(k) h e / Sigma`.
#[test]
fn covariance_update_matches_the_appendix() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut normal = || -> f64 { StandardNormal.sample(&mut rng) };
    for trial in 0..20 {
        let a = SMatrix::<f64, 6, 6>::from_fn(|_, _| normal());
        let p_old = a * a.transpose() + SMatrix::identity() * 0.1;
        let theta_old = SVector::<f64, 6>::from_fn(|_, _| normal());
        let mut rls = Rls::<6> {
            theta: theta_old,
            p: p_old,
        };
        let mut hbuf = [0.0; MAX_N];
        for v in hbuf.iter_mut().take(6) {
            *v = normal();
        }
        let h = SVector::<f64, 6>::from_fn(|i, _| hbuf[i]);
        let (e, mu, sigma) = (
            normal(),
            0.7 + 0.01 * trial as f64,
            0.5 + 0.1 * trial as f64,
        );
        assert!(rls.update(&hbuf, e, mu, sigma, f64::INFINITY));
        let s = (h.transpose() * p_old * h)[0] + mu * sigma;
        let lhs = rls.p * h;
        let rhs = p_old * h * (sigma / s);
        assert!((lhs - rhs).norm() < 1e-9 * rhs.norm(), "(47)");
        let info = rls.p.try_inverse().unwrap();
        let want = p_old.try_inverse().unwrap() * mu + h * h.transpose() / sigma;
        assert!((info - want).norm() < 1e-8 * want.norm(), "(48)");
        let step = rls.theta - theta_old;
        let want = rls.p * h * (e / sigma);
        assert!(
            (step - want).norm() < 1e-9 * (1.0 + want.norm()),
            "(18)/(47)"
        );
        assert_eq!(rls.p, rls.p.transpose());
    }
}

/// The noise estimate's floor is relative to the output's size, SIGMA_REL_FLOOR max|y|^2: a zero error on a
/// zero estimate lands on 1e-6 at max|y| = 1000 and on 1e-12 at max|y| = 1, on the smallest normal float
/// for an output that never left zero.
#[test]
fn sigma_floor_scales_with_the_output() {
    let cfg = MrgiaConfig::paper(0, 0, 1);
    let h = SVector::<f64, 4>::new(1.0, 0.0, 0.0, 0.0);
    for (y_max, floor) in [(1e3, 1e-6), (1.0, 1e-12), (0.0, f64::MIN_POSITIVE)] {
        let mut rls = Rls::<4>::new(&[1.0, 0.0, 0.01, 0.01], 1.0);
        let mut sigma = 0.0;
        assert!(update(&cfg, &mut rls, &h, 0.0, 5, y_max, &mut sigma));
        assert!((sigma - floor).abs() <= 1e-12 * floor, "{y_max}: {sigma}");
    }
}

#[test]
fn trace_cap_and_refused_updates() {
    let mut rls = Rls::<4>::new(&[0.0, 1.0, 0.0, 0.0], 1.0);
    let mut h = [0.0; MAX_N];
    h[0] = 1.0;
    // mu = 0.1 inflates P tenfold; the cap brings the trace back to 4.
    assert!(rls.update(&h, 1.0, 0.1, 1.0, 4.0));
    assert!((rls.p.trace() - 4.0).abs() < 1e-12);
    // S = 0 (h = 0 and Sigma = 0) and overflow are refused, leaving the state alone.
    let before = rls.clone();
    assert!(!rls.update(&[0.0; MAX_N], 1.0, 1.0, 0.0, 4.0));
    h[0] = 1e200;
    assert!(!rls.update(&h, 1e300, 1.0, 1.0, 4.0));
    assert_eq!(rls, before);
}

// ---------------------------------------------------------------------------------------------------------
// Decisions on the switching functions

/// Eqs. (35)-(38): with eps = 0 a held output (y(k) = y(k-1)) sets neither g4 nor g5 (the strict forms), even
/// when the model says the backlash is engaged; with eps > 0 the output must move by at least eps.
#[test]
fn output_motion_thresholds() {
    let cfg = MrgiaConfig::paper(0, 0, 1);
    // After sample 0 (u = 2, y = 0), x^(1) = 2 and g1^ = 1 (0 + 0.01 < 2).
    let mut est = Mrgia::new(cfg).unwrap();
    est.update(2.0, 0.0);
    let r = est.update(0.0, 0.0);
    assert!(!r.updating, "held output must not count as engaged");
    assert_eq!((r.y_hat, r.e), (0.0, 0.0));
    for (eps, dy, updates) in [(0.5, 0.3, false), (0.5, 0.5, true), (0.5, 0.6, true)] {
        let mut est = Mrgia::new(MrgiaConfig { eps, ..cfg }).unwrap();
        est.update(2.0, 0.0);
        assert_eq!(est.update(0.0, dy).updating, updates, "eps {eps} dy {dy}");
    }
    // A downward move with the model on the upper border is no update either (g1^ g4 = 0, g2^ = 0).
    let mut est = Mrgia::new(cfg).unwrap();
    est.update(2.0, 0.0);
    let r = est.update(0.0, -1.0);
    assert!(!r.updating);
    assert_eq!((r.y_hat, r.e), (0.0, -1.0));
}

/// With m^(k) in (28), y1^(k) = h^(k)^T theta(k-1); so when Phi = 0 the model output (40) is exactly
/// y(k-1) and e = y(k) - y(k-1). After convergence on noise-free data the gate (42) is exactly the true
/// regime: updates on the borders, none in the memory zone, and e = 0 everywhere.
#[test]
fn gate_equals_the_true_regime_after_convergence() {
    let (u, _) = paper_clean(6000, 1);
    let out = Plant::simulate(PlantParams::PAPER, &u).unwrap();
    let mut est = Mrgia::new(MrgiaConfig::paper(2, 0, 1)).unwrap();
    let mut y_prev = 0.0;
    for (k, (uk, o)) in u.iter().zip(&out).enumerate() {
        let r = est.update(*uk, o.w);
        if !r.updating {
            assert_eq!(r.y_hat, y_prev);
            assert_eq!(r.e, o.w - y_prev);
        }
        if k >= 3000 {
            assert_eq!(r.updating, o.mode != Mode::Held, "sample {k}");
            assert!(r.e.abs() < 1e-9, "sample {k}: e = {}", r.e);
        }
        y_prev = o.w;
    }
}

// ---------------------------------------------------------------------------------------------------------
// The paper's example

/// Target 1: noise-free, paper settings, every parameter within 1e-6 relative by 3000 samples. This holds
/// on 19 of 20 input seeds; the exception is the gate trap described in the module docs (a, b, c1 exact, the
/// lower border estimated outside the data so that its samples never pass the gate). The recommended
/// setting converges on all 20 (by 10000 samples: its slower forgetting needs longer to shed the transient).
#[test]
fn noise_free_paper_example_converges() {
    let ns = [3000, 10000];
    let paper = paper_study(20, &ns, || MrgiaConfig::paper(2, 0, 1), None);
    let converged = paper[0].iter().filter(|e| **e < 1e-6).count();
    assert!(converged >= 19, "paper setting: {:?}", paper[0]);
    for (s, err) in paper[0].iter().enumerate() {
        if *err >= 1e-6 {
            let (u, y) = paper_clean(3000, s as u64);
            let est = run(MrgiaConfig::paper(2, 0, 1), &u, &y);
            let t = est.theta();
            for i in [0, 1, 2, 4] {
                let rel = ((t[i] - PAPER_TRUTH[i]) / PAPER_TRUTH[i]).abs();
                assert!(rel < 1e-6, "seed {s}: not the lower-border trap: {t:?}");
            }
            // The lower border is estimated so far out that, after the transient, no sample on the true
            // lower border passes the gate, while the upper-border samples do.
            let modes = Plant::simulate(PlantParams::PAPER, &u).unwrap();
            let mut est = Mrgia::new(MrgiaConfig::paper(2, 0, 1)).unwrap();
            let (mut up, mut down) = (0, 0);
            for k in 0..u.len() {
                let r = est.update(u[k], y[k]);
                if k >= 1000 && r.updating {
                    match modes[k].mode {
                        Mode::Up => up += 1,
                        Mode::Down => down += 1,
                        Mode::Held => panic!("seed {s}: update in the memory zone at {k}"),
                    }
                }
            }
            assert!(up > 100 && down == 0, "seed {s}: {up} {down} {t:?}");
            assert!(t[3] > 1.0 && t[5] > 2.0, "seed {s}: {t:?}");
        }
    }
    assert!(paper[1].iter().filter(|e| **e < 1e-6).count() >= converged);
    let rec = paper_study(20, &ns, || MrgiaConfig::recommended(2, 0, 1), None);
    assert!(
        rec[1].iter().all(|e| *e < 1e-6),
        "recommended: {:?}",
        rec[1]
    );
    for (u, y) in (0..5).map(|s| paper_clean(3000, s)) {
        assert_spd(
            &run(MrgiaConfig::paper(2, 0, 1), &u, &y),
            "noise-free paper",
        );
    }
}

/// Median over noise draws of the max relative error of an efficient estimator at sample count `n`: the
/// Cramer-Rao bound of the output-error model y = w(theta) + noise (sensitivities by central differences of
/// the plant simulation), noise std = std(w over `n_noise` samples) / 43 as in `paper_study`.
fn crb_median(n: usize, n_noise: usize, seed: u64) -> f64 {
    let th0 = [0.45, 0.55, 0.8, 1.5, 0.5, 1.0];
    let sim = |th: &[f64; 6], u: &[f64]| -> Vec<f64> {
        let mut p = PlantParams::PAPER;
        (p.arx.a[0], p.arx.a[1], p.arx.b[0]) = (th[0], th[1], th[2]);
        (p.backlash.m2, p.backlash.c1, p.backlash.c2) = (th[3], th[4], th[5]);
        Plant::simulate(p, u).unwrap().iter().map(|o| o.w).collect()
    };
    let u = paper_input(n_noise.max(n), seed);
    let w = sim(&th0, &u[..n_noise]);
    let mean = w.iter().sum::<f64>() / w.len() as f64;
    let var = w.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / w.len() as f64;
    let noise_var = var / 43.0 / 43.0;
    let u = &u[..n];
    let mut jac = DMatrix::<f64>::zeros(n, 6);
    for i in 0..6 {
        let step = 1e-6 * th0[i];
        let (mut tp, mut tm) = (th0, th0);
        tp[i] += step;
        tm[i] -= step;
        let (wp, wm) = (sim(&tp, u), sim(&tm, u));
        for k in 0..n {
            jac[(k, i)] = (wp[k] - wm[k]) / (2.0 * step);
        }
    }
    let fim = jac.transpose() * &jac / noise_var;
    let l = fim.try_inverse().unwrap().cholesky().unwrap().l();
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let mut mx: Vec<f64> = (0..2001)
        .map(|_| {
            let z = DMatrix::<f64>::from_fn(6, 1, |_, _| StandardNormal.sample(&mut rng));
            let e = &l * z;
            (0..6).map(|i| (e[i] / th0[i]).abs()).fold(0.0, f64::max)
        })
        .collect();
    mx.sort_by(f64::total_cmp);
    mx[1000]
}

/// Target 2: SNR 43 over 20 seeds. Paper settings: median at N = 10000 <= 4e-2. Recommended: median at
/// N = 3000 <= 2.62e-2 (the paper's figure) and within 3x the Cramer-Rao bound.
/// `cargo test --release --lib noisy_paper_example -- --nocapture` prints the distributions.
#[test]
fn noisy_paper_example() {
    let ns = [1000, 3000, 10000];
    let paper = paper_study(20, &ns, || MrgiaConfig::paper(2, 0, 1), Some(43.0));
    let rec = paper_study(20, &ns, || MrgiaConfig::recommended(2, 0, 1), Some(43.0));
    let crb: Vec<f64> = ns.iter().map(|&n| crb_median(n, 10000, 0)).collect();
    for (i, n) in ns.iter().enumerate() {
        println!(
            "N = {n:5}: paper {} | recommended {} | CRB median {:.2e}",
            fmt(summary(&paper[i])),
            fmt(summary(&rec[i])),
            crb[i]
        );
    }
    assert!(summary(&paper[2]).1 <= 4e-2, "{:?}", paper[2]);
    let rec_med = summary(&rec[1]).1;
    assert!(rec_med <= 2.62e-2, "{:?}", rec[1]);
    assert!(
        rec_med <= 3.0 * crb[1],
        "recommended {rec_med} vs CRB {}",
        crb[1]
    );
    // The recommended setting is better than the paper's at every length, also in the worst case.
    for i in 0..3 {
        assert!(summary(&rec[i]).1 < summary(&paper[i]).1);
        assert!(summary(&rec[i]).2 < summary(&paper[i]).2);
    }
    assert!(
        summary(&rec[1]).2 <= 2.62e-2,
        "worst seed at N = 3000: {:?}",
        rec[1]
    );
}

#[test]
fn paper_input_has_the_papers_distribution() {
    let u = paper_input(200_000, 1);
    let a = (3.0 * 1.93f64).sqrt();
    assert!(u.iter().all(|v| v.abs() <= a));
    let mean = u.iter().sum::<f64>() / u.len() as f64;
    let var = u.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / u.len() as f64;
    assert!(
        mean.abs() < 0.01 && (var - 1.93).abs() < 0.02,
        "{mean} {var}"
    );
    assert_eq!(paper_input(10, 7), paper_input(10, 7));
    assert_ne!(paper_input(10, 7), paper_input(10, 8));
}

#[test]
fn max_rel_error_and_summary() {
    let truth = PlantParams::PAPER;
    let mut e = Estimate {
        a: vec![0.45, 0.55],
        b: vec![0.8],
        m1: 1.0,
        m2: 1.5,
        c1: 0.5,
        c2: 1.0,
    };
    assert_eq!(max_rel_error(&e, &truth), 0.0);
    e.c1 = 0.51;
    assert!((max_rel_error(&e, &truth) - 0.02).abs() < 1e-12);
    e.b.push(0.03); // b1 is 0 in the truth: absolute error
    assert!((max_rel_error(&e, &truth) - 0.03).abs() < 1e-12);
    assert_eq!(summary(&[3.0, 1.0, 2.0]), (1.0, 2.0, 3.0));
    assert_eq!(summary(&[4.0, 1.0, 2.0, 3.0]), (1.0, 2.5, 4.0));
}

// ---------------------------------------------------------------------------------------------------------
// Degenerate cases

/// No excitation: nothing ever moves, nothing is updated, theta, P and Sigma stay at their initial values.
/// After a run, a long stretch of u = 0 (or a constant) lets the plant settle; once the output holds, the
/// gate stays shut: the state is frozen, finite, P positive definite (no wind-up).
#[test]
fn no_excitation_freezes_the_estimator() {
    let cfg = MrgiaConfig::paper(2, 0, 1);
    let fresh = Mrgia::new(cfg).unwrap();
    let mut est = fresh.clone();
    for _ in 0..100_000 {
        let r = est.update(0.0, 0.0);
        assert!(!r.updating);
        assert_eq!((r.y_hat, r.e), (0.0, 0.0));
    }
    assert_eq!(est.theta(), fresh.theta());
    assert_eq!(est.covariance(), fresh.covariance());
    assert_eq!(est.sigma(), fresh.sigma());

    for (tail_u, seed) in [(0.0, 2), (1.3, 3)] {
        let mut u = paper_input(3000, seed);
        u.extend(std::iter::repeat_n(tail_u, 200_000));
        let y: Vec<f64> = Plant::simulate(PlantParams::PAPER, &u)
            .unwrap()
            .iter()
            .map(|o| o.w)
            .collect();
        let mut est = Mrgia::new(cfg).unwrap();
        let mut last_update = 0;
        let mut frozen = None;
        for k in 0..u.len() {
            if est.update(u[k], y[k]).updating {
                last_update = k;
            }
            if k == 3500 {
                frozen = Some(est.clone());
            }
        }
        assert!(last_update < 3500, "updates continued to {last_update}");
        let frozen = frozen.unwrap();
        assert_eq!(est.theta(), frozen.theta());
        assert_eq!(est.covariance(), frozen.covariance());
        assert!(est.theta().iter().all(|t| t.is_finite()));
        assert_spd(&est, "after no excitation");
        assert!(max_rel_error(&est.estimate(), &PlantParams::PAPER) < 1e-6);
    }
}

/// m2^ near zero or negative: the slope used in (26) and (33) is floored at M2_FLOOR; no division blows up.
#[test]
fn tiny_or_negative_slope_estimate_is_guarded() {
    let (u, y) = paper_clean(3000, 4);
    for m2 in [1e-300, 0.0, -0.5, -50.0] {
        let mut est = Mrgia::new(MrgiaConfig::paper(2, 0, 1)).unwrap();
        for k in 0..100 {
            est.update(u[k], y[k]);
        }
        let mut t = est.theta().to_vec();
        t[3] = m2 - 1.0;
        est.core.set_theta(&t);
        for k in 100..3000 {
            let r = est.update(u[k], y[k]);
            assert!(r.y_hat.is_finite() && r.e.is_finite(), "m2 {m2} sample {k}");
        }
        assert!(est.theta().iter().all(|t| t.is_finite()));
        assert_spd(&est, "after m2 near 0");
    }
}

#[test]
fn non_finite_samples_are_ignored() {
    let (u, y) = paper_clean(400, 5);
    let mut est = run(MrgiaConfig::paper(2, 0, 1), &u[..200], &y[..200]);
    let before = est.clone();
    for (a, b) in [
        (f64::NAN, 0.0),
        (0.0, f64::INFINITY),
        (f64::NEG_INFINITY, f64::NAN),
    ] {
        let r = est.update(a, b);
        assert!(!r.updating);
        assert_eq!(r.y_hat, before.last().y_hat);
    }
    assert_eq!(est, before);
}

/// Finite but enormous data: no NaN anywhere (overflowing updates are refused).
#[test]
fn huge_finite_data_never_gives_nan() {
    for scale in [1e100, 1e150, 1e200, 1e300] {
        let (u, y) = paper_clean(2000, 6);
        let mut est = Mrgia::new(MrgiaConfig::paper(2, 0, 1)).unwrap();
        for k in 0..u.len() {
            let r = est.update(u[k] * scale, y[k] * scale);
            assert!(
                !r.y_hat.is_nan() && !r.e.is_nan(),
                "scale {scale}, sample {k}"
            );
        }
        assert!(est.theta().iter().all(|t| t.is_finite()));
        assert!(est.covariance().iter().all(|t| t.is_finite()));
        assert!(est.sigma().is_finite());
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// Any finite data, any orders and delay: no panic, no NaN, P stays symmetric and finite.
    #[test]
    fn arbitrary_finite_data_is_safe(
        na in 0usize..=4,
        nb in 0usize..=4,
        delay in 1usize..=64,
        rho_exp in 0.05f64..=1.0,
        eps in prop_oneof![Just(0.0), 0.0f64..1.0],
        data in proptest::collection::vec((-1e3f64..1e3, -1e3f64..1e3), 1..400),
    ) {
        let cfg = MrgiaConfig { rho_exp, eps, ..MrgiaConfig::paper(na, nb, delay) };
        let mut est = Mrgia::new(cfg).unwrap();
        for (u, y) in data {
            let r = est.update(u, y);
            prop_assert!(r.y_hat.is_finite() && r.e.is_finite());
        }
        prop_assert!(est.theta().iter().all(|t| t.is_finite()));
        let p = p_matrix(&est);
        prop_assert!(p.iter().all(|t| t.is_finite()));
        prop_assert_eq!(&p, &p.transpose());
    }
}

// ---------------------------------------------------------------------------------------------------------
// Wear, other plants, FMU state

/// The paper plant with c1, c2 multiplied by `factor` from sample `k_switch` on (the state continues), plus
/// white Gaussian noise of std `noise_std`; returns y.
pub(crate) fn wear_data(
    u: &[f64],
    k_switch: usize,
    factor: f64,
    noise_std: f64,
    seed: u64,
) -> Vec<f64> {
    let mut arx = Arx::new(ArxParams::PAPER);
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xABCD);
    let mut w = 0.0;
    u.iter()
        .enumerate()
        .map(|(k, &uk)| {
            let mut b = BacklashParams::PAPER;
            if k >= k_switch {
                b.c1 *= factor;
                b.c2 *= factor;
            }
            w = b.step(arx.step(uk), w).0;
            let z: f64 = StandardNormal.sample(&mut rng);
            w + noise_std * z
        })
        .collect()
}

/// Samples after `k_switch` from which both gap estimates stay within `tol` (relative) of `c1`, `c2` up to
/// the end of the record (None: not settled by then).
fn settle_time(cfg: MrgiaConfig, u: &[f64], y: &[f64], k_switch: usize, tol: f64) -> Option<usize> {
    let mut m = Mrgia::new(cfg).unwrap();
    let step = |u, y| {
        m.update(u, y);
        m.estimate()
    };
    settle_time_of(step, u, y, k_switch, tol)
}

/// [`settle_time`] of any on-line estimator (plain or refined): `step(u, y)` takes one sample and returns
/// the estimate after it.
pub(crate) fn settle_time_of(
    mut step: impl FnMut(f64, f64) -> Estimate,
    u: &[f64],
    y: &[f64],
    k_switch: usize,
    tol: f64,
) -> Option<usize> {
    let (c1, c2) = (0.75, 1.5);
    let mut last_bad = None;
    for k in 0..u.len() {
        let e = step(u[k], y[k]);
        if k >= k_switch && (((e.c1 - c1) / c1).abs() > tol || ((e.c2 - c2) / c2).abs() > tol) {
            last_bad = Some(k);
        }
    }
    match last_bad {
        None => Some(0),
        Some(k) if k + 1 == u.len() => None,
        Some(k) => Some(k + 1 - k_switch),
    }
}

/// Target 3: a +50% step in both gaps at sample 5000 is tracked with rho_min > 0 (numbers in the doc of
/// `MrgiaConfig::rho_min`); without a floor the estimator, its gain decayed, does not get there in 5000
/// samples.
#[test]
fn wear_step_in_the_gaps_is_tracked() {
    let (n, k_switch) = (10_000, 5000);
    let mut noisy = vec![];
    let mut clean = vec![];
    for s in 0..5 {
        let u = paper_input(n, s);
        let w = wear_data(&u, k_switch, 1.5, 0.0, s);
        let std = {
            let m = w[..k_switch].iter().sum::<f64>() / k_switch as f64;
            (w[..k_switch].iter().map(|v| (v - m).powi(2)).sum::<f64>() / k_switch as f64).sqrt()
        };
        let y = wear_data(&u, k_switch, 1.5, std / 43.0, s);
        let track = |rho_min| MrgiaConfig {
            rho_min,
            ..MrgiaConfig::recommended(2, 0, 1)
        };
        noisy.push(settle_time(track(0.01), &u, &y, k_switch, 0.05));
        clean.push(settle_time(track(0.02), &u, &w, k_switch, 0.05));
        assert_eq!(
            settle_time(MrgiaConfig::recommended(2, 0, 1), &u, &y, k_switch, 0.05),
            None
        );
    }
    println!(
        "settling after the step: SNR 43, rho_min 0.01: {noisy:?}; noise-free, rho_min 0.02: {clean:?}"
    );
    assert!(
        noisy.iter().all(|t| t.is_some_and(|t| t <= 2000)),
        "{noisy:?}"
    );
    assert!(
        clean.iter().all(|t| t.is_some_and(|t| t <= 3000)),
        "{clean:?}"
    );
}

/// A random plant for these tests: na, nb <= 4, delays from 1 to 64.
fn random_plant(rng: &mut ChaCha8Rng) -> PlantParams {
    crate::identify::test_plants::random_plant(rng, 4, 4, &[1, 2, 3, 5, 17, 64])
}

/// Target 4: random stable plants, noise-free, matching orders and delay. MRGIA does not converge exactly
/// on all of them (zone misclassification), so only boundedness is asserted: finite estimates, P symmetric
/// positive definite, prediction errors finite; the errors are printed.
#[test]
fn random_stable_plants_stay_finite() {
    let mut rng = ChaCha8Rng::seed_from_u64(2024);
    let mut errors = vec![];
    for i in 0..16 {
        let plant = random_plant(&mut rng);
        let x_scale = 2.0 * (plant.backlash.c1 + plant.backlash.c2);
        let u: Vec<f64> = paper_input(5000, 100 + i)
            .iter()
            .map(|v| v * x_scale)
            .collect();
        let y: Vec<f64> = Plant::simulate(plant, &u)
            .unwrap()
            .iter()
            .map(|o| o.w)
            .collect();
        let arx = &plant.arx;
        for cfg in [
            MrgiaConfig::paper(arx.na, arx.nb, arx.delay),
            MrgiaConfig::recommended(arx.na, arx.nb, arx.delay),
        ] {
            let mut est = Mrgia::new(cfg).unwrap();
            for k in 0..u.len() {
                let r = est.update(u[k], y[k]);
                assert!(
                    r.y_hat.is_finite() && r.e.is_finite(),
                    "plant {i} sample {k}"
                );
            }
            assert!(
                est.theta().iter().all(|t| t.is_finite() && t.abs() < 1e6),
                "plant {i}: {:?}",
                est.theta()
            );
            assert_spd(&est, &format!("plant {i}"));
            errors.push(max_rel_error(&est.estimate(), &plant));
        }
    }
    let shown: Vec<String> = errors.iter().map(|e| format!("{e:.1e}")).collect();
    println!("random plants, max relative error (paper, recommended pairs): {shown:?}");
}

/// Target 5: the FMU state. A serde_json round trip mid-run continues bit-identically.
#[test]
fn serde_round_trip_mid_run_is_bit_identical() {
    for (na, nb, d) in [(2, 0, 1), (4, 4, 64), (0, 1, 3)] {
        let mut p = PlantParams::PAPER;
        p.noise_std = 0.03;
        p.noise_seed = 11;
        let u = paper_input(3000, 9);
        let y: Vec<f64> = Plant::simulate(p, &u)
            .unwrap()
            .iter()
            .map(|o| o.y)
            .collect();
        let mut a = Mrgia::new(MrgiaConfig::recommended(na, nb, d)).unwrap();
        for k in 0..1500 {
            a.update(u[k], y[k]);
        }
        let json = serde_json::to_string(&a).unwrap();
        let mut b: Mrgia = serde_json::from_str(&json).unwrap();
        assert_eq!(a, b);
        for k in 1500..3000 {
            let (ra, rb) = (a.update(u[k], y[k]), b.update(u[k], y[k]));
            assert_eq!(ra.y_hat.to_bits(), rb.y_hat.to_bits());
            assert_eq!(ra.e.to_bits(), rb.e.to_bits());
            assert_eq!(ra.updating, rb.updating);
        }
        let bits = |m: &Mrgia| m.theta().iter().map(|t| t.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&a), bits(&b));
        assert_eq!(a, b);
        // The configuration and the estimate serialise too (for the CLI's JSON).
        let cfg: MrgiaConfig =
            serde_json::from_str(&serde_json::to_string(a.config()).unwrap()).unwrap();
        assert_eq!(&cfg, a.config());
        assert!(
            serde_json::to_string(&a.estimate())
                .unwrap()
                .contains("\"m1\":1.0")
        );
    }
}

/// A corrupted FMU state is refused by deserialisation instead of making `update` panic later.
#[test]
fn inconsistent_state_is_refused() {
    let est = Mrgia::new(MrgiaConfig::paper(2, 0, 1)).unwrap();
    let good = serde_json::to_value(&est).unwrap();
    let _: Mrgia = serde_json::from_value(good.clone()).unwrap();
    let mut wrong_dim = good.clone();
    wrong_dim["cfg"]["na"] = 3.into();
    let mut bad_cfg = good.clone();
    bad_cfg["cfg"]["delay"] = 0.into();
    let mut short_ring = good.clone();
    short_ring["u_hist"]["buf"] = serde_json::json!([0.0, 1.0]);
    let mut bad_sigma = good.clone();
    bad_sigma["sigma"] = serde_json::json!(-1.0);
    for (what, v) in [
        ("dimension", wrong_dim),
        ("settings", bad_cfg),
        ("ring", short_ring),
        ("sigma", bad_sigma),
    ] {
        assert!(serde_json::from_value::<Mrgia>(v).is_err(), "{what}");
    }
}

/// Every supported dimension (4..=12) runs; noise-free data from a plant of those orders give finite
/// estimates and the prediction on the paper plant with extra (zero) coefficients still converges.
#[test]
fn all_orders_and_delays_run() {
    let u = paper_input(4000, 12);
    for na in 0..=4 {
        for nb in 0..=4 {
            for delay in [1, 64] {
                let est = run(MrgiaConfig::recommended(na, nb, delay), &u, &u);
                assert_eq!(est.theta().len(), na + nb + 4);
                assert!(est.theta().iter().all(|t| t.is_finite()));
            }
        }
    }
    // Over-parameterised model of the paper plant (na = 2, nb = 2): the extra b's go to zero.
    let y: Vec<f64> = Plant::simulate(PlantParams::PAPER, &u)
        .unwrap()
        .iter()
        .map(|o| o.w)
        .collect();
    let est = run(MrgiaConfig::recommended(2, 2, 1), &u, &y);
    let e = est.estimate();
    assert!(max_rel_error(&e, &PlantParams::PAPER) < 1e-3, "{e:?}");
}

/// Plant timing (delay d > 1): sample k pairs u(k) with y(k), y depending on u up to k - d.
#[test]
fn longer_delay_is_identified() {
    let mut p = PlantParams::PAPER;
    p.arx.delay = 5;
    let u = paper_input(10_000, 13);
    let y: Vec<f64> = Plant::simulate(p, &u)
        .unwrap()
        .iter()
        .map(|o| o.w)
        .collect();
    let est = run(MrgiaConfig::recommended(2, 0, 5), &u, &y);
    assert!(
        max_rel_error(&est.estimate(), &p) < 1e-6,
        "{:?}",
        est.estimate()
    );
    // A wrong delay does not fit.
    let est = run(MrgiaConfig::recommended(2, 0, 1), &u, &y);
    assert!(max_rel_error(&est.estimate(), &p) > 1e-2);
}
