//! Each effect's draw is what its description says, inside the ranges the bench documents.

use super::*;
use crate::diagnose::effects::linear_order::stable;
use crate::diagnose::effects::{
    coloured_noise, direction_dependent, extra_delay, friction, gap_drift, linear_order, periodic,
    quantization, saturation,
};

const SEEDS: std::ops::Range<u64> = 0..6;
const N: usize = 300;

/// The clean paper plant's backlash output for a scenario's input.
fn clean_w(s: &Scenario) -> Vec<f64> {
    Plant::simulate(PlantParams::PAPER, &s.u)
        .expect("the paper plant is valid")
        .iter()
        .map(|o| o.w)
        .collect()
}

/// The number written right after `key` in `text`.
fn number_after(text: &str, key: &str) -> f64 {
    let rest = &text[text.find(key).unwrap_or_else(|| panic!("{key} in {text}")) + key.len()..];
    let end = rest
        .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-'))
        .unwrap_or(rest.len());
    rest[..end]
        .parse()
        .unwrap_or_else(|_| panic!("a number after {key} in {text}"))
}

#[test]
fn direction_dependent_scales_the_poles_and_keeps_the_gain() {
    let paper = PlantParams::PAPER.arx;
    let gain = |a: &[f64], b: &[f64]| b.iter().sum::<f64>() / (1.0 + a.iter().sum::<f64>());
    for seed in SEEDS {
        let s = scenario(Some(direction_dependent::ID), seed, N);
        let fall = s.effects.direction_dependent.as_ref().expect("drawn");
        let r = fall.a[0] / paper.a[0];
        assert!((0.4..=0.7).contains(&r), "{seed}: {r}");
        assert!((fall.a[1] - paper.a[1] * r * r).abs() < 1e-12, "{seed}");
        assert!(
            (gain(&fall.a, &fall.b) - gain(&paper.a, &paper.b)).abs() < 1e-12,
            "{seed}"
        );
        assert!((number_after(&s.description, "falling poles ") - r).abs() <= 0.005 + 1e-12);
    }
}

#[test]
fn extra_delay_adds_one_to_three_samples() {
    let mut seen = [false; 3];
    for seed in 0..30 {
        let s = scenario(Some(extra_delay::ID), seed, N);
        let extra = s.params.arx.delay - PlantParams::PAPER.arx.delay;
        assert!((1..=3).contains(&extra), "{seed}: {extra}");
        seen[extra - 1] = true;
        assert_eq!(
            number_after(&s.description, "true delay "),
            s.params.arx.delay as f64
        );
    }
    assert_eq!(seen, [true; 3]);
}

#[test]
fn linear_order_adds_a_stable_a3_or_a_proportional_b1() {
    let paper = PlantParams::PAPER.arx;
    let (mut with_a3, mut with_b1) = (0, 0);
    for seed in 0..20 {
        let s = scenario(Some(linear_order::ID), seed, N);
        let arx = s.params.arx;
        if arx.na == 3 {
            with_a3 += 1;
            assert_eq!(arx.nb, paper.nb);
            assert!((0.1..=0.25).contains(&arx.a[2].abs()), "{seed}");
            assert!(stable(&arx.a[..3]), "{seed}");
            assert!((number_after(&s.description, "a3 = ") - arx.a[2]).abs() <= 5e-4);
        } else {
            with_b1 += 1;
            assert_eq!((arx.na, arx.nb), (paper.na, 1));
            assert!((0.3..=0.6).contains(&(arx.b[1] / arx.b[0]).abs()), "{seed}");
            assert!((number_after(&s.description, "b1 = ") - arx.b[1]).abs() <= 5e-4);
        }
    }
    assert!(with_a3 >= 3 && with_b1 >= 3, "{with_a3} {with_b1}");
}

#[test]
fn saturation_clips_at_the_described_quantiles() {
    for seed in SEEDS {
        let s = scenario(Some(saturation::ID), seed, N);
        let w0 = clean_w(&s);
        let sat = s.effects.saturation.as_ref().expect("drawn");
        let below = |v: f64| w0.iter().filter(|w| **w < v).count() as f64 / N as f64;
        let (ql, qh) = (
            number_after(&s.description, "clipped at the "),
            number_after(&s.description, "% / "),
        );
        assert!(
            (5.0..=15.0).contains(&ql) && (85.0..=95.0).contains(&qh),
            "{seed}"
        );
        // The quantiles of w0 to within the rounding of the percents and one sample.
        assert!(
            (100.0 * below(sat.lo) - ql).abs() <= 1.5,
            "{seed}: {}",
            below(sat.lo)
        );
        assert!(
            (100.0 * below(sat.hi) - qh).abs() <= 1.5,
            "{seed}: {}",
            below(sat.hi)
        );
        assert_eq!(
            s.description.contains("end stop (before the noise)"),
            sat.before_noise
        );
    }
}

#[test]
fn periodic_disturbance_is_a_multiple_of_the_noise() {
    for seed in SEEDS {
        let s = scenario(Some(periodic::ID), seed, N);
        let p = s.effects.periodic.as_ref().expect("drawn");
        let snr = std_dev(&s.f) / s.params.noise_std;
        // The noise is set from the noise-free output's spread; the amplitude from w's (the clean backlash
        // output), both over the same SNR.
        let rel = p.amplitude / (std_dev(&clean_w(&s)) / snr);
        assert!((0.5..=2.0).contains(&rel), "{seed}: {rel}");
        assert!((0.05..=3.0).contains(&p.omega), "{seed}");
        assert!((number_after(&s.description, "amplitude ") - rel).abs() <= 0.005 + 1e-9);
        assert!((number_after(&s.description, "omega ") - p.omega).abs() <= 5e-4 + 1e-12);
    }
}

/// The periodic disturbance's phase is uniform over the whole circle: over 40 draws every quarter of it
/// is hit.
#[test]
fn periodic_phases_cover_the_circle() {
    let mut quarters = [false; 4];
    for seed in 0..40 {
        let s = scenario(Some(periodic::ID), seed, 50);
        let phase = s.effects.periodic.as_ref().expect("drawn").phase;
        assert!(
            (0.0..2.0 * std::f64::consts::PI).contains(&phase),
            "{seed}: {phase}"
        );
        quarters[(phase / std::f64::consts::FRAC_PI_2) as usize] = true;
    }
    assert_eq!(quarters, [true; 4]);
}

#[test]
fn quantization_step_and_noise_follow_the_description() {
    for seed in SEEDS {
        let s = scenario(Some(quantization::ID), seed, N);
        let q = s.effects.quantization.as_ref().expect("drawn");
        let rel = q.step / std_dev(&clean_w(&s));
        assert!((0.1..=0.3).contains(&rel), "{seed}: {rel}");
        assert!((0.0..q.step).contains(&q.offset), "{seed}");
        let ratio = q.step / s.params.noise_std;
        assert!((6.0..=20.0).contains(&ratio), "{seed}: {ratio}");
        assert!((number_after(&s.description, "step ") - rel).abs() <= 5e-4 + 1e-12);
        assert!((number_after(&s.description, "noise step/") - ratio).abs() <= 0.05 + 1e-9);
    }
}

#[test]
fn coloured_noise_is_ar1_at_a_lower_snr() {
    for seed in SEEDS {
        let s = scenario(Some(coloured_noise::ID), seed, N);
        let phi = s.effects.coloured_noise.as_ref().expect("drawn").phi;
        assert!((0.5..=0.9).contains(&phi), "{seed}");
        let snr = std_dev(&s.f) / s.params.noise_std;
        assert!((10.0..=30.0).contains(&snr), "{seed}: {snr}");
        assert!((number_after(&s.description, "phi ") - phi).abs() <= 0.005 + 1e-12);
    }
}

#[test]
fn gap_drift_rates_are_positive_fractions_of_the_gaps() {
    for seed in SEEDS {
        let s = scenario(Some(gap_drift::ID), seed, N);
        let g = s.effects.gap_drift.as_ref().expect("drawn");
        let bl = PlantParams::PAPER.backlash;
        for (rate, c) in [(g.c1_rate, bl.c1), (g.c2_rate, bl.c2)] {
            let whole = rate * (N - 1) as f64 / c;
            assert!((0.3..=0.8).contains(&whole), "{seed}: {whole}");
        }
    }
}

/// Friction slips at a drawn 30-70% of the clean backlash output's half range (scaled by k_e), each way,
/// as the description says.
#[test]
fn friction_slips_within_the_elastic_range() {
    for seed in SEEDS {
        let s = scenario(Some(friction::ID), seed, N);
        let (lo, hi) = clean_w(&s)
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(*v), b.max(*v))
            });
        let f = s.effects.friction.as_ref().expect("friction drawn");
        let scale = f.k_e * 0.5 * (hi - lo);
        let (p, m) = (100.0 * f.f_plus / scale, 100.0 * f.f_minus / scale);
        assert!((30.0..=70.0).contains(&p), "{seed}: {p}");
        assert!((30.0..=70.0).contains(&m), "{seed}: {m}");
        let said = format!("slip at +{p:.0}% / -{m:.0}%");
        assert!(s.description.contains(&said), "{said} in {}", s.description);
    }
}
