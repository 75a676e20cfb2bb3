//! Tests against a simulated ground truth. The data are made by an independent simulator written here:
//! a second-order `G(s)` integrated by RK4 with a continuous input `U cos(omega t - phase)` and many
//! sub-steps per sample, and the border operator of paper 003 section 2 applied at every sub-step (so it
//! sees the continuous-time extremes of x). Nothing of `crate::plant` is used to make the data.

use super::*;
use rand_chacha::ChaCha8Rng;
use rand_core::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

/// `G(s) = (b1 s + b0) / (s^2 + a1 s + a0)` and the borders (lowest power first).
#[derive(Clone)]
struct Truth {
    b1: f64,
    b0: f64,
    a1: f64,
    a0: f64,
    fa: Vec<f64>,
    fd: Vec<f64>,
}

fn poly(c: &[f64], x: f64) -> f64 {
    let mut acc = 0.0;
    let mut xp = 1.0;
    for &ci in c {
        acc += ci * xp;
        xp *= x;
    }
    acc
}

fn lowpass(fa: &[f64], fd: &[f64]) -> Truth {
    Truth {
        b1: 0.0,
        b0: 1.0,
        a1: 0.6,
        a0: 1.0,
        fa: fa.to_vec(),
        fd: fd.to_vec(),
    }
}

/// The border operator, continuous-time rules applied on a fine monotone path.
struct Border {
    w: f64,
    on: i8,
    xp: f64,
}

impl Border {
    fn step(&mut self, tr: &Truth, x: f64) -> f64 {
        let meets = |c: &[f64]| (poly(c, self.xp) - self.w) * (poly(c, x) - self.w) <= 0.0;
        if x > self.xp {
            if self.on == 1 || meets(&tr.fa) {
                self.on = 1;
                self.w = poly(&tr.fa, x);
            } else {
                self.on = 0;
            }
        } else if x < self.xp {
            if self.on == -1 || meets(&tr.fd) {
                self.on = -1;
                self.w = poly(&tr.fd, x);
            } else {
                self.on = 0;
            }
        }
        self.xp = x;
        self.w
    }
}

struct Experiment {
    omega: f64,
    amplitude: f64,
    /// Samples per period (need not be an integer).
    spp: f64,
    periods: f64,
    noise: f64,
    seed: u64,
    /// Phase of the input: u = U cos(omega t - input_phase).
    input_phase: f64,
}

impl Experiment {
    fn new(omega: f64, amplitude: f64, periods: f64, noise: f64, seed: u64) -> Self {
        Self {
            omega,
            amplitude,
            spp: 200.0,
            periods,
            noise,
            seed,
            input_phase: 0.0,
        }
    }
}

fn simulate(tr: &Truth, e: &Experiment) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let ts = TAU / e.omega / e.spp;
    let samples = (e.periods * e.spp).round() as usize;
    // Sub-steps per sample: the operator sees x's extremes to (pi / (spp sub))^2 / 2 relative; finer for
    // the noise-free (exactness) tests.
    let sub = if e.noise == 0.0 { 16 } else { 8 };
    let h = ts / sub as f64;
    let u = |t: f64| e.amplitude * (e.omega * t - e.input_phase).cos();
    let f = |t: f64, z: [f64; 2]| [z[1], -tr.a0 * z[0] - tr.a1 * z[1] + u(t)];
    let out = |z: [f64; 2]| tr.b0 * z[0] + tr.b1 * z[1];
    let mut z = [0.0f64; 2];
    let mut op = Border {
        w: poly(&tr.fa, 0.0),
        on: 0,
        xp: 0.0,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(e.seed);
    let (mut tv, mut uv, mut yv) = (Vec::new(), Vec::new(), Vec::new());
    for k in 0..samples {
        let t0 = k as f64 * ts;
        let noise: f64 = StandardNormal.sample(&mut rng);
        tv.push(t0);
        uv.push(u(t0));
        yv.push(op.w + e.noise * noise);
        for s in 0..sub {
            let t = t0 + s as f64 * h;
            let k1 = f(t, z);
            let k2 = f(
                t + h / 2.0,
                [z[0] + h / 2.0 * k1[0], z[1] + h / 2.0 * k1[1]],
            );
            let k3 = f(
                t + h / 2.0,
                [z[0] + h / 2.0 * k2[0], z[1] + h / 2.0 * k2[1]],
            );
            let k4 = f(t + h, [z[0] + h * k3[0], z[1] + h * k3[1]]);
            for i in 0..2 {
                z[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
            }
            op.step(tr, out(z));
        }
    }
    (tv, uv, yv)
}

/// The true (phase, gain, fa, fd) of the model and of its dual, each normalised by (29)-(30a); written
/// here independently of the library's helpers.
fn truths(tr: &Truth, omega: f64, n: usize) -> [(f64, f64, Vec<f64>, Vec<f64>); 2] {
    // G(jw) = (b0 + j b1 w) / (a0 - w^2 + j a1 w).
    let (nr, ni) = (tr.b0, tr.b1 * omega);
    let (dr, di) = (tr.a0 - omega * omega, tr.a1 * omega);
    let den = dr * dr + di * di;
    let (gr, gi) = ((nr * dr + ni * di) / den, (ni * dr - nr * di) / den);
    let gain = gr.hypot(gi);
    let phi = (-gi.atan2(gr)).rem_euclid(TAU);
    let pad = |c: &[f64]| -> Vec<f64> { (0..=n).map(|i| *c.get(i).unwrap_or(&0.0)).collect() };
    let norm = |g: f64, a: Vec<f64>, d: Vec<f64>| {
        let s: f64 = (1..=n).map(|i| a[i].abs().powf(n as f64 / i as f64)).sum();
        let k = s.powf(-1.0 / n as f64);
        let sc = |c: Vec<f64>| -> Vec<f64> {
            c.into_iter()
                .enumerate()
                .map(|(i, v)| v * k.powi(i as i32))
                .collect()
        };
        (g / k, sc(a), sc(d))
    };
    let (g1, a1, d1) = norm(gain, pad(&tr.fa), pad(&tr.fd));
    // Dual: f_a^-(x) = f_d(-x), f_d^-(x) = f_a(-x), phase + pi.
    let neg = |c: Vec<f64>| -> Vec<f64> {
        c.into_iter()
            .enumerate()
            .map(|(i, v)| if i % 2 == 1 { -v } else { v })
            .collect()
    };
    let (g2, a2, d2) = norm(gain, neg(pad(&tr.fd)), neg(pad(&tr.fa)));
    [(phi, g1, a1, d1), ((phi + PI).rem_euclid(TAU), g2, a2, d2)]
}

/// Largest error (phase, gain, coefficients) of the estimate against the closer of model and dual.
#[derive(Debug, Clone, Copy)]
struct Errors {
    phase: f64,
    gain: f64,
    coeffs: f64,
}

impl Errors {
    fn max(&self) -> f64 {
        self.phase.max(self.gain).max(self.coeffs)
    }
}

fn errors(est: &FrequencyEstimate, tr: &Truth) -> Errors {
    let mut best: Option<Errors> = None;
    for (phi, g, a, d) in truths(tr, est.omega, est.degree) {
        let dp = (est.phase - phi).rem_euclid(TAU);
        let e = Errors {
            phase: dp.min(TAU - dp),
            gain: (est.gain - g).abs(),
            coeffs: est
                .fa
                .iter()
                .zip(&a)
                .chain(est.fd.iter().zip(&d))
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f64::max),
        };
        if best.is_none_or(|b| e.max() < b.max()) {
            best = Some(e);
        }
    }
    best.unwrap()
}

fn run(tr: &Truth, e: &Experiment, n: usize) -> Result<FrequencyEstimate, FrequencyError> {
    let (t, u, y) = simulate(tr, e);
    estimate(
        &SineRecord {
            time: &t,
            u: Some(&u),
            y: &y,
        },
        &FrequencyOptions {
            omega: e.omega,
            amplitude: e.amplitude,
            degree: n,
            transient: None,
        },
    )
}

fn hard() -> Truth {
    // f_a = x - 0.3, f_d = 0.8 (x + 0.4).
    lowpass(&[-0.3, 1.0], &[0.32, 0.8])
}

fn curved() -> Truth {
    lowpass(&[-0.25, 0.9, 0.15, 0.08], &[0.3, 0.8, 0.2, 0.05])
}

fn static_noninvertible() -> Truth {
    // f'(x) = 0 at x = 0.787 and -0.565: not monotone on the cycle's range |x| <= 1.25.
    let f = [0.1, 1.2, 0.3, -0.9];
    lowpass(&f, &f)
}

fn crossing() -> Truth {
    // f_d - f_a = 0.4 x^2 - 0.2 < 0 for |x| < 0.707: the borders cross twice inside the cycle (|x| <= 1.5).
    lowpass(&[0.2, 1.0, -0.2, -0.2], &[0.0, 1.0, 0.2, -0.2])
}

/// (name, truth, omega, U, degree, expected path).
fn cases() -> Vec<(&'static str, Truth, f64, f64, usize, EstimatorPath)> {
    vec![
        ("hard", hard(), 1.0, 1.0, 1, EstimatorPath::Ls),
        ("curved", curved(), 0.5, 1.0, 3, EstimatorPath::Ls),
        (
            "static non-invertible",
            static_noninvertible(),
            1.0,
            0.75,
            3,
            EstimatorPath::Sls,
        ),
        ("crossing", crossing(), 1.0, 0.9, 3, EstimatorPath::Ls),
    ]
}

#[test]
fn truth_helpers_agree_with_the_library() {
    // Library normalisation and dual against the test's own.
    let tr = curved();
    let [(phi, g, a, d), (phi2, g2, a2, d2)] = truths(&tr, 0.5, 3);
    let (lg, la, ld) = normalize(gain_of(&tr, 0.5), &tr.fa, &tr.fd, 3).unwrap();
    assert!((lg - g).abs() < 1e-14);
    for i in 0..4 {
        assert!((la[i] - a[i]).abs() < 1e-14 && (ld[i] - d[i]).abs() < 1e-14);
    }
    let s: f64 = (1..=3).map(|i| la[i].abs().powf(3.0 / i as f64)).sum();
    assert!((s - 1.0).abs() < 1e-14);
    let est = FrequencyEstimate {
        omega: 0.5,
        amplitude: 1.0,
        degree: 3,
        phase: phi,
        gain: lg,
        fa: la,
        fd: ld,
        path: EstimatorPath::Ls,
        alpha: vec![0.0; 4],
        delta: vec![0.0; 4],
        tau_a: 0.0,
        tau_d: 0.0,
        periods_used: 1,
        transient_periods: 0,
        samples_per_period: 1,
        residual_rms: 0.0,
        noise_std: 0.0,
        chi2: 0.0,
        dof: 1.0,
        samples_averaged: 1.0,
        parameters: 9,
        input_amplitude: None,
        input_phase: None,
        warnings: vec![],
    };
    let du = est.dual();
    assert!((du.phase - phi2).abs() < 1e-14 && (du.gain - g2).abs() < 1e-14);
    for i in 0..4 {
        assert!((du.fa[i] - a2[i]).abs() < 1e-14 && (du.fd[i] - d2[i]).abs() < 1e-14);
    }
    let back = du.dual();
    assert!((back.gain - est.gain).abs() < 1e-13);
    // Recovery (35)-(37) from exact lumped parameters alpha_i = a_i X^i, delta_i = d_i X^i.
    let x: f64 = 1.7;
    let alpha: Vec<f64> = tr
        .fa
        .iter()
        .enumerate()
        .map(|(i, a)| a * x.powi(i as i32))
        .collect();
    let delta: Vec<f64> = tr
        .fd
        .iter()
        .enumerate()
        .map(|(i, d)| d * x.powi(i as i32))
        .collect();
    let (gr, ar, dr) = recover(&alpha, &delta, 2.0).unwrap();
    let (gn, an, dn) = normalize(x / 2.0, &tr.fa, &tr.fd, 3).unwrap();
    assert!((gr - gn).abs() < 1e-14);
    for i in 0..4 {
        assert!((ar[i] - an[i]).abs() < 1e-14 && (dr[i] - dn[i]).abs() < 1e-14);
    }
}

fn gain_of(tr: &Truth, w: f64) -> f64 {
    let (dr, di) = (tr.a0 - w * w, tr.a1 * w);
    (tr.b0.hypot(tr.b1 * w)) / dr.hypot(di)
}

#[test]
fn noise_free_records_are_identified_exactly() {
    for (name, tr, omega, amp, n, path) in cases() {
        let est = run(&tr, &Experiment::new(omega, amp, 40.0, 0.0, 0), n).unwrap();
        let e = errors(&est, &tr);
        eprintln!(
            "{name}: path {:?}, periods {} (+{} transient), errors {e:?}, residual {:.1e}",
            est.path, est.periods_used, est.transient_periods, est.residual_rms
        );
        assert_eq!(est.path, path, "{name}");
        assert!(e.max() < 1e-7, "{name}: {e:?}");
        assert!(est.phase >= 0.0 && est.phase < PI);
        assert!(est.warnings.is_empty(), "{name}: {:?}", est.warnings);
    }
}

#[test]
fn noisy_records_meet_the_accuracy_target() {
    // Noise std 0.01, 40 steady periods of 200 samples (plus the transient the record starts with).
    for (name, tr, omega, amp, n, path) in cases() {
        for seed in [1, 2] {
            let est = run(&tr, &Experiment::new(omega, amp, 45.0, 0.01, seed), n).unwrap();
            let e = errors(&est, &tr);
            eprintln!(
                "{name} seed {seed}: path {:?}, periods {}, noise {:.4}, errors {e:?}",
                est.path, est.periods_used, est.noise_std
            );
            assert!(est.periods_used >= 40, "{name}: {}", est.periods_used);
            assert_eq!(est.path, path, "{name}");
            assert!(e.max() < 2e-2, "{name} seed {seed}: {e:?}");
            assert!((est.noise_std - 0.01).abs() < 1e-3);
        }
    }
}

#[test]
fn error_shrinks_as_more_periods_are_averaged() {
    let tr = curved();
    let mut means = Vec::new();
    for periods in [4.0, 16.0, 64.0] {
        let mut sum = 0.0;
        let seeds = [11, 12, 13, 14];
        for seed in seeds {
            let est = run(
                &tr,
                &Experiment::new(0.5, 1.0, periods + 6.0, 0.05, seed),
                3,
            )
            .unwrap();
            sum += errors(&est, &tr).max();
        }
        means.push(sum / seeds.len() as f64);
    }
    eprintln!("mean max-error for 4, 16, 64 periods: {means:?}");
    assert!(means[1] < 0.75 * means[0], "{means:?}");
    assert!(means[2] < 0.75 * means[1], "{means:?}");
}

#[test]
fn incommensurate_sampling_and_a_shifted_input() {
    let tr = curved();
    let mut e = Experiment::new(0.5, 1.0, 45.0, 0.01, 5);
    e.spp = 173.37;
    e.input_phase = PI / 2.0; // u = U sin(omega t)
    let est = run(&tr, &e, 3).unwrap();
    let err = errors(&est, &tr);
    eprintln!("incommensurate: {err:?}, input phase {:?}", est.input_phase);
    assert!((est.input_phase.unwrap() - PI / 2.0).abs() < 1e-6);
    assert!(err.max() < 2e-2, "{err:?}");
}

#[test]
fn too_small_an_amplitude_is_refused_with_advice_to_raise_u() {
    // x stays within +-0.17, inside the gap [-0.4, 0.3]: the output is constant in steady state.
    for noise in [0.0, 0.01] {
        let err = run(&hard(), &Experiment::new(1.0, 0.1, 20.0, noise, 3), 1).unwrap_err();
        assert!(
            matches!(err, FrequencyError::NonAdmissible { .. }),
            "{err:?}"
        );
        let msg = err.to_string();
        assert!(msg.contains("raise the amplitude U"), "{msg}");
    }
}

#[test]
fn a_record_shorter_than_a_period_is_refused() {
    let err = run(&hard(), &Experiment::new(1.0, 1.0, 0.8, 0.0, 0), 1).unwrap_err();
    assert!(
        matches!(err, FrequencyError::NoFullPeriod { .. }),
        "{err:?}"
    );
    assert!(err.to_string().contains("record more periods"));
}

#[test]
fn inconsistent_settings_are_refused() {
    let (t, u, y) = simulate(&hard(), &Experiment::new(1.0, 1.0, 5.0, 0.0, 0));
    let rec = SineRecord {
        time: &t,
        u: Some(&u),
        y: &y,
    };
    let opts = FrequencyOptions {
        omega: 1.0,
        amplitude: 1.0,
        degree: 1,
        transient: None,
    };
    let with = |f: &dyn Fn(&mut FrequencyOptions)| {
        let mut o = opts.clone();
        f(&mut o);
        estimate(&rec, &o).unwrap_err()
    };
    assert!(matches!(
        with(&|o| o.amplitude = 2.0),
        FrequencyError::AmplitudeMismatch { .. }
    ));
    assert!(matches!(
        with(&|o| o.omega = 1.7),
        FrequencyError::InputNotSine { .. }
    ));
    assert!(matches!(
        with(&|o| o.degree = 0),
        FrequencyError::InvalidOption { name: "degree", .. }
    ));
    assert!(matches!(
        with(&|o| o.transient = Some(100.0)),
        FrequencyError::NoFullPeriod { .. }
    ));
    // 20 samples per period (omega ten times higher for the same time stamps) cannot carry degree 6.
    let no_u = SineRecord { u: None, ..rec };
    let o = FrequencyOptions {
        omega: 10.0,
        degree: 6,
        ..opts.clone()
    };
    assert!(matches!(
        estimate(&no_u, &o).unwrap_err(),
        FrequencyError::TooFewSamples {
            per_period: 20,
            needed: 28,
            ..
        }
    ));
}

/// Every case, noise-free and noisy, commensurate and not, at its degree and at degree 6: `check(what,
/// noise, fast, reference)` with the estimate of the production path and the one with `reference` set.
fn against_reference(
    reference: &'static std::thread::LocalKey<std::cell::Cell<bool>>,
    check: impl Fn(
        &str,
        f64,
        Result<FrequencyEstimate, FrequencyError>,
        Result<FrequencyEstimate, FrequencyError>,
    ),
) {
    for (name, tr, omega, amplitude, n, _) in cases() {
        for (noise, spp) in [(0.0, 200.0), (0.01, 200.0), (0.02, 173.3)] {
            let e = Experiment {
                spp,
                ..Experiment::new(omega, amplitude, 10.0, noise, 5)
            };
            for degree in [n, 6] {
                reference.set(true);
                let slow = run(&tr, &e, degree);
                reference.set(false);
                let fast = run(&tr, &e, degree);
                check(
                    &format!("{name}, noise {noise}, degree {degree}"),
                    noise,
                    fast,
                    slow,
                );
            }
        }
    }
}

#[test]
fn the_fast_phase_grid_gives_the_exact_grids_estimates() {
    // The estimate (LS and SLS paths, the constant-stage candidates) is the exact grid's, bit for bit.
    against_reference(&super::fit::EXACT_GRID, |what, _, fast, exact| {
        assert_eq!(fast, exact, "{what}")
    });
}

/// The numbers of two estimates agree within `tol` (relative above 1), their path and warnings exactly.
fn assert_close(a: &FrequencyEstimate, b: &FrequencyEstimate, tol: f64, what: &str) {
    assert_eq!(a.path, b.path, "{what}");
    assert_eq!(a.warnings, b.warnings, "{what}");
    let all = |e: &FrequencyEstimate| {
        let mut v = vec![e.phase, e.gain, e.tau_a, e.tau_d, e.residual_rms, e.dof];
        v.extend(e.fa.iter().chain(&e.fd).chain(&e.alpha).chain(&e.delta));
        v
    };
    for (x, y) in all(a).iter().zip(all(b)) {
        assert!(
            (x - y).abs() <= tol * x.abs().max(1.0),
            "{what}: {x} against {y}"
        );
    }
}

#[test]
fn the_derivative_refinement_gives_the_golden_sections_estimates() {
    // Every case, noise-free and noisy, commensurate and not, at its degree and at degree 6, against the
    // golden section on the cost (the reference). Noise-free records: every number to 1e-9 (their cost is
    // rounding, so costs are not compared). Noisy ones: the cost is never higher than the reference's by
    // more than 1e-9 (a minimum on a kink of the cost is approached to about 1e-11 rad) and the phases
    // agree to 1e-6: the golden section only locates a smooth minimum to the square root of the cost's
    // rounding (up to 1.5e-7 rad apart here, with costs equal to 1e-15), which the derivative does not
    // suffer; the borders' coefficients follow the phase (ill-conditioned at degree 6). The derivative's
    // sign change at the new answer is tested in `fit`.
    against_reference(&super::fit::GOLDEN, |what, noise, fast, golden| {
        match (fast, golden) {
            (Ok(f), Ok(r)) if noise == 0.0 => assert_close(&f, &r, 1e-9, what),
            (Ok(f), Ok(r)) => {
                assert!(f.chi2 <= r.chi2 * (1.0 + 1e-9), "{what}: {f:?} {r:?}");
                assert!((f.phase - r.phase).abs() < 1e-6, "{what}");
            }
            (f, r) => assert_eq!(f, r, "{what}"),
        }
    });
}
