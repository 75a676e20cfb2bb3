//! Structure selection (issue 12, item 1): with no orders declared, `diagnose` chooses a structure whose
//! held-out free-run error is within a few percent of the true structure's on the paper plant, finds the
//! static structure and the delay of a static plant, and `identify oe` without orders reports the orders it
//! chose in its JSON.

use std::process::{Command, Stdio};

use backlash::diagnose::engine::{DiagnoseConfig, diagnose};
use backlash::identify::mrgia::paper_input;
use backlash::plant::{ArxParams, Plant, PlantParams};
use backlash::stats::std_dev;

/// A record of `params` driven by the paper's input, with white noise at a signal-to-noise ratio of 40
/// (std of the noise-free output over the noise's std).
fn record(params: PlantParams, n: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let u = paper_input(n, seed);
    let clean: Vec<f64> = Plant::simulate(params, &u)
        .expect("valid plant")
        .iter()
        .map(|o| o.y)
        .collect();
    let noisy = PlantParams {
        noise_std: std_dev(&clean) / 40.0,
        noise_seed: seed ^ 0x5EED,
        ..params
    };
    let y = Plant::simulate(noisy, &u)
        .expect("valid plant")
        .iter()
        .map(|o| o.y)
        .collect();
    (u, y)
}

#[test]
fn chosen_structure_predicts_as_well_as_the_true_one_on_the_paper_plant() {
    for seed in [1, 2] {
        let (u, y) = record(PlantParams::PAPER, 3000, seed);
        let auto = diagnose(&u, &y, &DiagnoseConfig::auto()).expect("diagnosis runs");
        let declared = diagnose(&u, &y, &DiagnoseConfig::new(2, 0, 1)).expect("diagnosis runs");
        assert_eq!(auto.structure.chosen_by, "selected");
        assert!(
            !auto.structure.candidates.is_empty(),
            "the candidates compared are reported"
        );
        let (a, d) = (auto.base_heldout_rmse, declared.base_heldout_rmse);
        assert!(
            a <= 1.05 * d,
            "seed {seed}: chosen {} gives held-out {a:.4e}, the true structure {d:.4e}",
            auto.structure.chosen
        );
        // The delay of the paper plant is one sample; a structure with a longer one cannot simulate it.
        assert_eq!(auto.structure.chosen.delay, 1, "seed {seed}");
    }
}

#[test]
fn a_static_plant_gets_no_dynamics_and_its_delay() {
    let params = PlantParams {
        arx: ArxParams {
            na: 0,
            nb: 0,
            delay: 2,
            a: [0.0; 4],
            b: [1.0, 0.0, 0.0, 0.0, 0.0],
        },
        ..PlantParams::PAPER
    };
    for seed in [3, 4] {
        let (u, y) = record(params, 2000, seed);
        let d = diagnose(&u, &y, &DiagnoseConfig::auto()).expect("diagnosis runs");
        let s = d.structure.chosen;
        assert_eq!(
            (s.na, s.nb, s.delay),
            (0, 0, 2),
            "seed {seed}: {}",
            d.structure.reason
        );
    }
}

/// A fresh file under the system temp dir, removed on drop.
struct TempFile(std::path::PathBuf);

impl Drop for TempFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

#[test]
fn identify_oe_without_orders_reports_the_chosen_ones() {
    let (u, y) = record(PlantParams::PAPER, 2000, 5);
    let mut csv = String::from("time,u,y\n");
    for (k, (a, b)) in u.iter().zip(&y).enumerate() {
        csv.push_str(&format!("{k},{a},{b}\n"));
    }
    let file =
        TempFile(std::env::temp_dir().join(format!("backlash-oe-auto-{}.csv", std::process::id())));
    std::fs::write(&file.0, csv).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_backlash"))
        .args(["identify", "oe"])
        .arg(&file.0)
        .arg("--json")
        .stdin(Stdio::null())
        .output()
        .expect("run backlash");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    for key in ["na", "nb", "delay"] {
        assert!(v[key].is_u64(), "{key} missing or not a count: {v}");
    }
    // The orders reported are the ones estimated: as many a's and b's as they say.
    let na = v["na"].as_u64().unwrap() as usize;
    let nb = v["nb"].as_u64().unwrap() as usize;
    assert_eq!(v["a"].as_array().map(Vec::len), Some(na), "{v}");
    assert_eq!(v["b"].as_array().map(Vec::len), Some(nb + 1), "{v}");
    assert_eq!(v["delay"], 1, "the paper plant's delay: {v}");
}
