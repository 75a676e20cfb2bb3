//! Evidence that belongs to the input (issue 12, item 6). When the input is periodic, a model that lacks an
//! input-related effect leaves a residual that repeats with the input: its spectrum peaks at the input's
//! frequencies. That peak is model error driven by the input, not a disturbance, so the record must not be
//! diagnosed `periodic-disturbance`. The control: a sinusoid at a frequency the (white) input does not carry
//! is still named `periodic-disturbance`.

use backlash::diagnose::bench;
use backlash::diagnose::effects;
use backlash::diagnose::engine::{DiagnoseConfig, Diagnosis, diagnose};
use backlash::identify::mrgia::paper_input;
use backlash::plant::PlantParams;
use backlash::plant::effects::{CurvedBorders, Effects, simulate_with_effects};
use backlash::stats::std_dev;

const N: usize = 3000;

/// Two sines whose periods (50 and 40 samples) divide the record's length.
fn two_sines(n: usize) -> Vec<f64> {
    let tau = 2.0 * std::f64::consts::PI;
    (0..n)
        .map(|k| {
            let k = k as f64;
            1.5 * (tau * k / 50.0).sin() + 1.0 * (tau * 3.0 * k / 40.0 + 0.4).sin()
        })
        .collect()
}

/// A 100-sample stretch of the paper's (white) input, repeated: a test rig's repeated trajectory.
fn repeated_trajectory(n: usize) -> Vec<f64> {
    let one = paper_input(100, 77);
    (0..n).map(|k| one[k % one.len()]).collect()
}

/// The paper plant with `effects` (and `arx` changes) driven by `u`, white noise at SNR 30.
fn measured(params: PlantParams, effects: &Effects, u: &[f64], seed: u64) -> Vec<f64> {
    let clean = simulate_with_effects(&params, effects, u, 0).expect("valid plant");
    let f: Vec<f64> = clean.iter().map(|o| o.f).collect();
    let noisy = PlantParams {
        noise_std: std_dev(&f) / 30.0,
        ..params
    };
    simulate_with_effects(&noisy, effects, u, seed)
        .expect("valid plant")
        .iter()
        .map(|o| o.y)
        .collect()
}

/// Borders 10% (quadratic) and 4% (cubic) off straight at two standard deviations of x, as in the bench.
fn curved(u: &[f64]) -> Effects {
    let x = simulate_with_effects(&PlantParams::PAPER, &Effects::default(), u, 0)
        .expect("valid plant")
        .iter()
        .map(|o| o.x)
        .collect::<Vec<_>>();
    let s = 2.0 * std_dev(&x);
    let bl = PlantParams::PAPER.backlash;
    Effects {
        curved_borders: Some(CurvedBorders {
            upper: [0.1 * bl.m1 / s, 0.04 * bl.m1 / (s * s)],
            lower: [-0.1 * bl.m2 / s, 0.04 * bl.m2 / (s * s)],
        }),
        ..Effects::default()
    }
}

fn explain(d: &Diagnosis) -> String {
    let cands: Vec<String> = d
        .candidates
        .iter()
        .map(|c| format!("{} ({})", c.id, c.reason))
        .collect();
    format!(
        "effect {:?}; set aside {:?}; candidates {}",
        d.effect_id(),
        d.set_aside,
        cands.join(" | ")
    )
}

/// The diagnosis with the paper's structure declared; it must not be `periodic-disturbance`, and the residual's
/// peak must have been recognised as the input's (set aside), so the rule, not luck, decided.
fn not_periodic(u: &[f64], y: &[f64], what: &str) -> Diagnosis {
    let d = diagnose(u, y, &DiagnoseConfig::new(2, 0, 1)).expect("diagnosis runs");
    assert_ne!(
        d.effect_id(),
        Some(effects::periodic::ID),
        "{what}: {}",
        explain(&d)
    );
    assert!(
        d.set_aside
            .iter()
            .any(|s| s.starts_with("periodic-disturbance")),
        "{what}: the input's line was not set aside: {}",
        explain(&d)
    );
    d
}

#[test]
fn periodic_input_and_curved_borders_is_not_a_periodic_disturbance() {
    let u = two_sines(N);
    let y = measured(PlantParams::PAPER, &curved(&u), &u, 11);
    not_periodic(&u, &y, "two sines");
    // A repeated trajectory excites the borders over their range: the missing effect itself is named.
    let u = repeated_trajectory(N);
    let y = measured(PlantParams::PAPER, &curved(&u), &u, 11);
    let d = not_periodic(&u, &y, "repeated trajectory");
    assert_eq!(
        d.effect_id(),
        Some(effects::curved_borders::ID),
        "{}",
        explain(&d)
    );
}

/// (Two sines cannot show a longer b polynomial: at two frequencies the declared model matches it exactly.)
#[test]
fn periodic_input_and_a_longer_linear_order_is_not_a_periodic_disturbance() {
    let mut params = PlantParams::PAPER;
    params.arx.nb = 1;
    params.arx.b[1] = 0.45 * params.arx.b[0];
    let u = repeated_trajectory(N);
    let y = measured(params, &Effects::default(), &u, 12);
    let d = not_periodic(&u, &y, "repeated trajectory");
    assert_eq!(
        d.effect_id(),
        Some(effects::linear_order::ID),
        "{}",
        explain(&d)
    );
}
#[test]
fn a_disturbance_the_input_does_not_carry_is_still_named() {
    for seed in [10_000, 10_001, 10_002] {
        let s = bench::scenario(Some(effects::periodic::ID), seed, N);
        let (na, nb, delay) = s.declared;
        let d = diagnose(&s.u, &s.y, &DiagnoseConfig::new(na, nb, delay)).expect("diagnosis runs");
        assert_eq!(
            d.effect_id(),
            Some(effects::periodic::ID),
            "seed {seed} ({}): {}",
            s.description,
            explain(&d)
        );
        assert!(d.set_aside.is_empty(), "seed {seed}: {:?}", d.set_aside);
    }
}
