//! Every command that reads a record reads it the same way: `--time-col`, `--u-col`, `--y-col` and
//! `--decimate` on each, a unit in a header cell (`y [kN]`) answering to its name, a `t` column taken for
//! the time when there is no `time`; answers carry `warnings` for records that cannot support them; the plant
//! takes every parameter of the plant FMU by name and refuses an unknown one in words.
#![cfg(target_os = "linux")]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_backlash");

fn run(args: &[&str]) -> Output {
    Command::new(BIN).args(args).output().expect("run backlash")
}

fn json(args: &[&str]) -> serde_json::Value {
    let out = run(args);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one JSON object")
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("backlash-cli-records-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// A record of the paper's plant under a deterministic, reversing input, with the header given.
fn record(path: &Path, header: &str, n: usize, constant: bool) {
    let mut text = format!("{header}\n");
    let (mut x1, mut x2, mut y) = (0.0f64, 0.0f64, 0.0f64);
    let mut u_prev = 0.0;
    for k in 0..n {
        let u = if constant {
            0.7
        } else {
            2.0 * ((k as f64) * 0.37).sin() + ((k as f64) * 0.05).cos()
        };
        let x = -0.45 * x1 - 0.55 * x2 + 0.8 * u_prev;
        (x2, x1, u_prev) = (x1, x, u);
        y = if x > y + 0.5 {
            x - 0.5
        } else if x < y / 1.5 - 1.0 {
            1.5 * (x + 1.0)
        } else {
            y
        };
        text.push_str(&format!("{},{u:?},{y:?}\n", 0.01 * k as f64));
    }
    std::fs::write(path, text).unwrap();
}

#[test]
fn every_record_command_takes_the_record_options() {
    for cmd in [
        &["identify", "mrgia"][..],
        &["identify", "oe"],
        &["identify", "frequency"],
        &["identify", "stepped-sine"],
        &["simulate"],
        &["crb"],
        &["diagnose"],
    ] {
        let mut args = cmd.to_vec();
        args.push("--help");
        let help = String::from_utf8(run(&args).stdout).unwrap();
        for flag in ["--time-col", "--u-col", "--y-col", "--decimate"] {
            assert!(help.contains(flag), "{cmd:?} lacks {flag}");
        }
    }
}

#[test]
fn a_t_column_with_units_is_read_by_name_and_decimated() {
    let f = temp("damper.csv");
    record(&f, "t [s],u [V],y [kN]", 600, false);
    let f = f.to_str().unwrap();
    let model = ["--na", "2", "--nb", "0", "--delay", "1", "--json"];
    let plain = json(&[&["identify", "oe", f][..], &model].concat());
    let named = json(&[&["identify", "oe", f, "--time-col", "t"][..], &model].concat());
    assert_eq!(plain["c1"], named["c1"]);
    assert!(
        (plain["c1"].as_f64().unwrap() - 0.5).abs() < 1e-3,
        "{}",
        plain["c1"]
    );
    assert_eq!(plain["samples"], 600);
    let halved = json(&[&["identify", "mrgia", f, "--decimate", "2"][..], &model].concat());
    assert_eq!(halved["samples"], 300);
    assert_eq!(plain["warnings"], serde_json::json!([]));
}

#[test]
fn a_constant_input_is_warned_about() {
    let f = temp("constant.csv");
    record(&f, "time,u,y", 400, true);
    let f = f.to_str().unwrap();
    let model = ["--na", "2", "--nb", "0", "--delay", "1", "--json"];
    let budget = ["--max-effects", "1", "--time-budget", "30"];
    for args in [
        [&["identify", "mrgia", f][..], &model].concat(),
        [&["diagnose", f][..], &model, &budget].concat(),
    ] {
        let out = json(&args);
        let w = out["warnings"][0].as_str().unwrap_or_default();
        assert!(
            w.starts_with("the input is constant (0.7 in every sample)"),
            "{args:?}: {out}"
        );
    }
    // The output-error fit refuses it outright: nothing is identifiable.
    let out = run(&[&["identify", "oe", f][..], &model].concat());
    assert!(String::from_utf8_lossy(&out.stderr).contains("does not excite"));
}

#[test]
fn overflowing_values_are_quoted() {
    let f = temp("overflow.csv");
    std::fs::write(&f, "time,u,y\n0,1,2\n1,1e400,2\n").unwrap();
    let out = run(&["identify", "oe", f.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("line 3, column 'u': '1e400' overflows a 64-bit float"),
        "{err}"
    );
}

#[test]
fn simulate_takes_every_fmu_parameter_and_refuses_an_unknown_one() {
    let input = temp("input.csv");
    record(&input, "time,u,y", 50, false);
    let input = input.to_str().unwrap();
    let plain = run(&["simulate", input]);
    let quantised = run(&["simulate", input, "--quant-step", "0.25"]);
    assert!(plain.status.success() && quantised.status.success());
    let text = String::from_utf8(quantised.stdout).unwrap();
    for line in text.lines().skip(1) {
        let y: f64 = line.rsplit(',').next().unwrap().parse().unwrap();
        assert_eq!((y / 0.25).fract(), 0.0, "{line}");
    }
    assert_ne!(plain.stdout, text.as_bytes());
    let params = temp("params.json");
    std::fs::write(&params, r#"{"a": [0.5], "c1_rat": 0.1}"#).unwrap();
    let out = run(&["simulate", input, "--params", params.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("the plant has no parameter named c1_rat (did you mean c1_rate?)"),
        "{err}"
    );
}
