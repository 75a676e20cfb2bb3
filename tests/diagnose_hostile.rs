//! `diagnose` under hostile small records (issue 12, item 3): integer counts, constant input or output,
//! step inputs, a spike a million times the rest, values near 1e12 and near 1e-12, 120 to 400 samples. Every
//! call, with the structure chosen from the data and with a declared one, returns a diagnosis or a refusal in
//! words; none panics, and each is bounded by a small time budget. The command line gets one such record
//! too, under a timeout.

use std::io::Read;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use backlash::diagnose::engine::{DiagnoseConfig, Diagnosis, diagnose};
use backlash::plant::{Plant, PlantParams};
use proptest::prelude::*;

/// The budget of one diagnosis: small, so the whole property stays bounded.
const BUDGET: Duration = Duration::from_secs(20);

/// What is hostile about a record.
#[derive(Debug, Clone, Copy)]
enum Hostility {
    /// Output rounded to integer counts (an encoder), input rounded too.
    IntegerCounts,
    ConstantInput,
    ConstantOutput,
    /// The input steps once from one level to another.
    StepInput,
    /// One output sample a million times the rest.
    Spike,
    /// Input and output scaled by this factor.
    Scaled(f64),
}

fn hostility() -> impl Strategy<Value = Hostility> {
    prop_oneof![
        Just(Hostility::IntegerCounts),
        Just(Hostility::ConstantInput),
        Just(Hostility::ConstantOutput),
        Just(Hostility::StepInput),
        Just(Hostility::Spike),
        prop_oneof![Just(1e12), Just(3e11), Just(1e-12), Just(4e-13)].prop_map(Hostility::Scaled),
    ]
}

/// A small deterministic generator (the record's values are not what is tested, only their shape).
fn uniform(seed: u64, n: usize) -> Vec<f64> {
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    (0..n)
        .map(|_| {
            s = s
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        })
        .collect()
}

/// The paper's plant driven by `u`, with a little measurement noise.
fn plant_output(u: &[f64], seed: u64) -> Vec<f64> {
    let y = Plant::simulate(PlantParams::PAPER, u).expect("the paper plant is valid");
    let noise = uniform(seed ^ 0xABCD, u.len());
    y.iter().zip(noise).map(|(o, e)| o.y + 0.05 * e).collect()
}

/// A record of `n` samples with the hostility applied.
fn record(h: Hostility, n: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let u: Vec<f64> = uniform(seed, n).iter().map(|v| 2.4 * v).collect();
    match h {
        Hostility::IntegerCounts => {
            let u: Vec<f64> = u.iter().map(|v| (3.0 * v).round()).collect();
            let y = plant_output(&u, seed).iter().map(|v| v.round()).collect();
            (u, y)
        }
        Hostility::ConstantInput => {
            let u = vec![1.5; n];
            let y = plant_output(&u, seed);
            (u, y)
        }
        Hostility::ConstantOutput => (u, vec![-2.0; n]),
        Hostility::StepInput => {
            let u: Vec<f64> = (0..n).map(|k| if k < n / 3 { 0.0 } else { 2.0 }).collect();
            let y = plant_output(&u, seed);
            (u, y)
        }
        Hostility::Spike => {
            let mut y = plant_output(&u, seed);
            let k = (seed as usize) % n;
            let rest = y.iter().map(|v| v.abs()).fold(0.0, f64::max).max(1.0);
            y[k] = 1e6 * rest;
            (u, y)
        }
        Hostility::Scaled(f) => {
            let y = plant_output(&u, seed).iter().map(|v| v * f).collect();
            (u.iter().map(|v| v * f).collect(), y)
        }
    }
}

/// A refusal must be a sentence: non-empty, with words, and no Rust range notation.
fn assert_in_words(msg: &str) -> Result<(), TestCaseError> {
    prop_assert!(!msg.trim().is_empty(), "empty error message");
    prop_assert!(
        msg.split_whitespace()
            .filter(|w| w.chars().any(char::is_alphabetic))
            .count()
            >= 3,
        "not in words: {msg}"
    );
    prop_assert!(!msg.contains("..="), "Rust range notation: {msg}");
    Ok(())
}

/// The answer's numbers are what the JSON will carry: a diagnosis never reports NaN errors.
fn assert_sane(d: &Diagnosis, n: usize) -> Result<(), TestCaseError> {
    prop_assert_eq!(d.n, n);
    prop_assert!(d.n_fit > 0 && d.n_fit < n);
    prop_assert!(!d.base_heldout_rmse.is_nan(), "before is NaN");
    prop_assert!(!d.after_rmse().is_nan(), "after is NaN");
    prop_assert!(!d.structure.reason.trim().is_empty());
    for c in &d.candidates {
        prop_assert!(!c.reason.trim().is_empty(), "{} has no reason", c.id);
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 256,
        max_shrink_iters: 8,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// Every hostile record gets an answer or a refusal in words, with the structure chosen or declared.
    #[test]
    fn hostile_records_get_an_answer_or_a_clear_refusal(
        h in hostility(),
        n in prop_oneof![Just(150usize), Just(120), Just(151), Just(273), Just(400)],
        seed in 0u64..1000,
        declared in prop_oneof![
            Just(None),
            Just(Some((0usize, 0usize, 1usize))),
            Just(Some((2, 0, 1))),
            Just(Some((1, 1, 2))),
        ],
    ) {
        let (u, y) = record(h, n, seed);
        let mut cfg = match declared {
            Some((na, nb, d)) => DiagnoseConfig::new(na, nb, d),
            None => DiagnoseConfig::auto(),
        };
        cfg.time_budget = BUDGET;
        match diagnose(&u, &y, &cfg) {
            Ok(d) => assert_sane(&d, n)?,
            Err(e) => assert_in_words(&e.to_string())?,
        }
    }
}

/// A fresh directory under the system temp dir, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> TempDir {
        let p = std::env::temp_dir().join(format!(
            "backlash-diagnose-hostile-{}-{tag}",
            std::process::id()
        ));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).unwrap();
        TempDir(p)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The record of the hang in small: 150 samples of integer encoder counts, through the command line
/// with the structure chosen by the tool; it must finish (a timeout of 120 s against its 20 s budget) with
/// JSON on stdout (exit 0) or a refusal on stderr (exit 1).
#[test]
fn cli_diagnoses_integer_counts_within_a_timeout() {
    let dir = TempDir::new("counts");
    let (u, y) = record(Hostility::IntegerCounts, 150, 7);
    let mut csv = String::from("time,u,y\n");
    for (k, (a, b)) in u.iter().zip(&y).enumerate() {
        csv.push_str(&format!("{k},{a},{b}\n"));
    }
    let file = dir.0.join("counts.csv");
    std::fs::write(&file, csv).unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_backlash"))
        .arg("diagnose")
        .arg(&file)
        .args(["--json", "--time-budget", "20"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run backlash");
    // Read the pipes on their own threads so a full pipe cannot stall the child.
    let mut out = child.stdout.take().unwrap();
    let mut err = child.stderr.take().unwrap();
    let out_t = std::thread::spawn(move || {
        let mut s = String::new();
        out.read_to_string(&mut s).map(|_| s)
    });
    let err_t = std::thread::spawn(move || {
        let mut s = String::new();
        err.read_to_string(&mut s).map(|_| s)
    });
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if start.elapsed() > Duration::from_secs(120) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("backlash diagnose did not finish within 120 s on 150 integer counts");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let stdout = out_t.join().unwrap().unwrap();
    let stderr = err_t.join().unwrap().unwrap();
    match status.code() {
        Some(0) => {
            let v: serde_json::Value = serde_json::from_str(&stdout)
                .unwrap_or_else(|e| panic!("stdout is not one JSON object ({e}): {stdout}"));
            for key in [
                "before", "effect", "effects", "after", "na", "nb", "delay", "linear",
            ] {
                assert!(v.get(key).is_some(), "JSON lacks {key}: {stdout}");
            }
            assert!(v["before"]["rmse"].is_number(), "{stdout}");
        }
        Some(1) => {
            assert!(stdout.is_empty(), "a refusal printed on stdout: {stdout}");
            assert!(
                stderr.split_whitespace().count() >= 3,
                "a refusal without a message: {stderr:?}"
            );
        }
        other => panic!("exit status {other:?}; stderr: {stderr}"),
    }
}
