//! Paper 003 on real sine tests: the experiment's plant against the library plant and BacklashPlant.fmu,
//! the steady window of ramped records, stepped sines against single-frequency records of the same length,
//! and the measured damper record brfd/char_0.5Hz_36lb_1in.csv (found by tests/records.rs).
//!
//! Needs `cargo build --release` first (the FMU test reads target/fmu/BacklashPlant.fmu).

use std::f64::consts::TAU;
use std::path::PathBuf;
use std::process::Command;

use backlash::identify::frequency::SineRecord;
use backlash::identify::frequency::analysis::{AnalysisOptions, analyse};
use backlash::identify::frequency::experiment::{
    ExperimentPlant, SteppedDesign, match_truth, run_stepped, stepped_input, truth_pair,
};
use backlash::identify::frequency::window::WindowSource;
use backlash::io::Table;
use backlash::plant::continuous::{ContinuousLinear, TransferFunction};
use backlash::plant::poly::{PolyBacklash, PolyBacklashParams};
use fmi::fmi2::import::Fmi2Import;
use fmi::fmi2::instance::{CoSimulation, Common};

const BIN: &str = env!("CARGO_BIN_EXE_backlash");

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A plant with a second-order block, cubic borders and noise, and a stepped input through it.
fn plant_and_input() -> (ExperimentPlant, Vec<f64>, f64) {
    let plant = ExperimentPlant {
        noise_std: 0.02,
        seed: 7,
        ..ExperimentPlant::default()
    };
    let design = SteppedDesign {
        omegas: vec![0.4, 1.3],
        degree: None,
        ts: 0.05,
        hold_periods: 3,
        ramp_periods: 1,
        pause: 2.0,
    };
    let (u, _) = stepped_input(plant.amplitude, &design);
    (plant, u, design.ts)
}

/// The experiment's plant, composed here from its parts as the command line once did: the sampled block,
/// the polynomial-border operator and seeded standard normal noise.
#[test]
fn the_experiment_plant_is_the_library_plant_and_its_parts() {
    use rand_core::SeedableRng;
    use rand_distr::Distribution;
    let (plant, u, ts) = plant_and_input();
    let rec = plant.simulate(&u, ts, plant.seed).unwrap();
    let tf = TransferFunction::new(&plant.num, &plant.den).unwrap();
    let mut lin = ContinuousLinear::new(tf, ts).unwrap();
    let mut op = PolyBacklash::new(PolyBacklashParams::new(&plant.fa, &plant.fd).unwrap()).unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(plant.seed);
    for (k, &uk) in u.iter().enumerate() {
        let x = lin.step(uk);
        let w = op.step(x);
        let z: f64 = rand_distr::StandardNormal.sample(&mut rng);
        let y = w + plant.noise_std * z;
        assert_eq!([rec.x[k], rec.w[k], rec.y[k]], [x, w, y], "sample {k}");
    }
}

fn fmu(name: &str) -> PathBuf {
    let dir = std::env::var_os("BACKLASH_FMU_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join("target/fmu"));
    let p = dir.join(format!("{name}.fmu"));
    assert!(
        p.exists(),
        "{} is missing: run `cargo build --release` first",
        p.display()
    );
    p
}

#[test]
fn the_experiment_plant_is_the_fmu() {
    use fmi::traits::FmiImport;
    let (plant, u, ts) = plant_and_input();
    let rec = plant.simulate(&u, ts, plant.seed).unwrap();
    let import: Fmi2Import = fmi::import::from_path(fmu("BacklashPlant")).unwrap();
    let vr = |name: &str| {
        import
            .model_description()
            .model_variables
            .variables
            .iter()
            .find(|v| v.name == name)
            .unwrap_or_else(|| panic!("no variable {name}"))
            .value_reference
    };
    let mut inst = import.instantiate_cs("plant", false, true).unwrap();
    inst.setup_experiment(None, 0.0, None).unwrap();
    // The FMU takes G(s) by ascending powers of s (num0 = coefficient of s^0).
    let mut reals = vec![("Ts", ts), ("noise_std", plant.noise_std)];
    let num0 = format!("num{}", 0);
    let asc = |c: &[f64]| c.iter().rev().copied().collect::<Vec<f64>>();
    let names: Vec<(String, f64)> = asc(&plant.num)
        .iter()
        .enumerate()
        .map(|(i, v)| (format!("num{i}"), *v))
        .chain(
            asc(&plant.den)
                .iter()
                .enumerate()
                .map(|(i, v)| (format!("den{i}"), *v)),
        )
        .chain(
            plant
                .fa
                .iter()
                .enumerate()
                .map(|(i, v)| (format!("fa{i}"), *v)),
        )
        .chain(
            plant
                .fd
                .iter()
                .enumerate()
                .map(|(i, v)| (format!("fd{i}"), *v)),
        )
        .collect();
    assert_eq!(names[0].0, num0);
    for (n, v) in &names {
        reals.push((n.as_str(), *v));
    }
    for (n, v) in reals {
        inst.set_real(&[vr(n)], &[v]).unwrap();
    }
    inst.set_integer(
        &[vr("noise_seed"), vr("linear"), vr("border")],
        &[plant.seed as i32, 1, 1],
    )
    .unwrap();
    inst.enter_initialization_mode().unwrap();
    inst.exit_initialization_mode().unwrap();
    let outs = [vr("x"), vr("w"), vr("y")];
    for (k, &uk) in u.iter().enumerate() {
        let mut got = [0.0; 3];
        inst.get_real(&outs, &mut got).unwrap();
        assert_eq!(got, [rec.x[k], rec.w[k], rec.y[k]], "sample {k}");
        inst.set_real(&[vr("u")], &[uk]).unwrap();
        inst.do_step(k as f64 * ts, ts, true).unwrap();
    }
}

/// A noise-free sine ramped in and out between pauses, as a rig runs it: the window is its steady part,
/// the answers are the truth, and the verdict says the model explains it.
#[test]
fn a_ramped_record_is_identified_on_its_steady_window() {
    let plant = ExperimentPlant {
        noise_std: 0.0,
        ..ExperimentPlant::default()
    };
    let omega = 0.8;
    let design = SteppedDesign {
        omegas: vec![omega],
        degree: None,
        ts: TAU / omega / 250.0,
        hold_periods: 30,
        ramp_periods: 3,
        pause: 10.0,
    };
    let (u, _) = stepped_input(plant.amplitude, &design);
    let rec = plant.simulate(&u, design.ts, 1).unwrap();
    let a = analyse(&rec.as_sine_record(), &AnalysisOptions::default()).unwrap();
    assert_eq!(a.window.source, WindowSource::Detected);
    let ramp = 3.0 * TAU / omega;
    assert!(
        a.window.start >= ramp - 1e-9 && a.window.end <= ramp + 30.0 * TAU / omega,
        "{:?}",
        a.window
    );
    assert!((a.window.periods - 30.0).abs() < 0.01, "{:?}", a.window);
    assert!((a.window.omega / omega - 1.0).abs() < 1e-9);
    assert_eq!(a.estimate.degree, 3, "{:?}", a.degree_choice);
    let sampled = ContinuousLinear::new(plant.transfer_function().unwrap(), design.ts).unwrap();
    let (truth, dual) =
        truth_pair(sampled.sampled_response(omega), &plant.fa, &plant.fd, 3).unwrap();
    let m = match_truth(&a.estimate, &truth, &dual);
    assert!(m.errors.phase < 1e-3 && m.errors.gain < 1e-3, "{m:?}");
    assert!(a.verdict.explained, "{:?}", a.verdict);
}

/// Done-when of the stepped sines: each step's gain and phase within the accuracy of single-frequency
/// records of the same length (their RMS error over seeds, times 3).
#[test]
fn stepped_sine_steps_are_as_accurate_as_single_frequency_records() {
    let omegas = vec![0.3, 0.5, 0.8, 1.2, 1.6, 2.2];
    let design = SteppedDesign {
        omegas: omegas.clone(),
        degree: Some(3),
        ts: 0.02,
        hold_periods: 12,
        ramp_periods: 2,
        pause: 5.0,
    };
    let seeds = 6u64;
    let mut single_sq = vec![(0.0, 0.0); omegas.len()];
    let mut stepped = Vec::new();
    for seed in 0..seeds {
        let plant = ExperimentPlant {
            seed: 100 * seed + 1,
            ..ExperimentPlant::default()
        };
        let r = run_stepped(&plant, &design).unwrap();
        assert_eq!(
            r.analysis.steps.len(),
            omegas.len(),
            "{:?}",
            r.analysis.steps
        );
        for (i, row) in r.rows.iter().enumerate() {
            let s = row.single.as_ref().expect("single record identified");
            single_sq[i].0 += s.errors.phase.powi(2) / seeds as f64;
            single_sq[i].1 += s.errors.gain.powi(2) / seeds as f64;
        }
        if seed == 0 {
            stepped = r.rows.clone();
        }
    }
    for (i, row) in stepped.iter().enumerate() {
        let st = row.stepped.as_ref().expect("step identified");
        let (p, g) = (single_sq[i].0.sqrt(), single_sq[i].1.sqrt());
        assert!(
            st.errors.phase <= 3.0 * p && st.errors.gain <= 3.0 * g,
            "omega {}: stepped errors {:?} against single RMS phase {p:.3e}, gain {g:.3e}",
            row.omega,
            st.errors
        );
    }
}

fn brfd() -> PathBuf {
    crate::records::record("brfd/char_0.5Hz_36lb_1in.csv")
}

/// The measured friction damper: the window is the steady 6 s between the ramps, and the verdict says
/// the model does not explain it, because of its residual.
#[test]
fn the_measured_damper_record_gets_its_window_and_a_negative_verdict() {
    let table = Table::read(&brfd(), &["t", "u", "y"]).unwrap();
    let rec = SineRecord {
        time: table.column("t").unwrap(),
        u: table.column("u"),
        y: table.column("y").unwrap(),
    };
    let a = analyse(&rec, &AnalysisOptions::default()).unwrap();
    let w = &a.window;
    assert_eq!(w.source, WindowSource::Detected);
    assert!(
        w.start > 3.9 && w.start < 4.1 && w.end > 9.9 && w.end < 10.1,
        "{w:?}"
    );
    assert!((w.omega / std::f64::consts::PI - 1.0).abs() < 1e-3, "{w:?}");
    assert!(!a.verdict.residual.pass, "{:?}", a.verdict.residual);
    assert!(!a.verdict.explained);
    // The averaged output's residual is more than twice what its noise leaves (2.3 times).
    assert!(a.verdict.residual.residual_rms > 2.0 * a.verdict.residual.noise_rms);
}

#[test]
fn the_cli_runs_the_measured_record_as_a_whole_file_with_no_options() {
    let out = Command::new(BIN)
        .args(["identify", "frequency"])
        .arg(brfd())
        .arg("--json")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    for key in ["phase", "gain", "fa", "fd", "degree", "window", "verdict"] {
        assert!(v.get(key).is_some(), "no key {key} in {v}");
    }
    assert_eq!(v["window"]["source"], "detected");
    assert_eq!(v["verdict"]["explained"], false);
    assert_eq!(v["verdict"]["residual"]["pass"], false);
    // The contract's form still works (declared omega and amplitude, a degree).
    let out = Command::new(BIN)
        .args(["identify", "frequency"])
        .arg(brfd())
        .args([
            "--omega",
            "3.14159265",
            "--amplitude",
            "1",
            "--degree",
            "3",
            "--json",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["degree"], 3);
    assert_eq!(v["degree_choice"]["rule"], "declared");
}

#[test]
fn a_bad_degree_is_refused_in_words() {
    let out = Command::new(BIN)
        .args(["identify", "frequency"])
        .arg(brfd())
        .args(["--degree", "9"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("between 1 and 6"), "{err}");
}
