//! `backlash identify mrgia` reads its file in one streaming pass (`backlash::io::RowReader`). These tests hold
//! it to the in-memory computation done here independently: `Table::read` of the same file, then
//! `Mrgia::update` over the columns. The JSON (every key), the `--trace` file (every byte) must agree, on the
//! paper's example with and without noise and with other estimator settings; and a malformed file is refused
//! with exactly the message `Table::read` gives, leaving no trace file.

use backlash::identify::mrgia::{Mrgia, MrgiaConfig, paper_input};
use backlash::io::Table;
use backlash::plant::{Plant, PlantParams};
use serde_json::{Value, json};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

const BIN: &str = env!("CARGO_BIN_EXE_backlash");

/// A fresh directory under the system temp dir, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> TempDir {
        let p =
            std::env::temp_dir().join(format!("backlash-cli-stream-{}-{tag}", std::process::id()));
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

fn identify(file: &Path, args: &[&str]) -> Output {
    Command::new(BIN)
        .args(["identify", "mrgia"])
        .arg(file)
        .args(args)
        .stdin(Stdio::null())
        .output()
        .expect("run backlash")
}

/// The paper's plant on the paper's input: (time, u, y).
fn paper_record(n: usize, seed: u64, noise_std: f64) -> Vec<(f64, f64, f64)> {
    let u = paper_input(n, seed);
    let params = PlantParams {
        noise_std,
        noise_seed: seed + 100,
        ..PlantParams::PAPER
    };
    let out = Plant::simulate(params, &u).unwrap();
    u.iter()
        .zip(&out)
        .enumerate()
        .map(|(k, (&u, o))| (k as f64 * 0.01, u, o.y))
        .collect()
}

/// What the command must print and write, computed in memory from the file as `Table::read` sees it.
fn in_memory(file: &Path, cfg: MrgiaConfig, setting: &str) -> (Value, String) {
    let table = Table::read(file, &["time", "u", "y"]).unwrap();
    let (t, u, y) = (
        table.column("time").unwrap(),
        table.column("u").unwrap(),
        table.column("y").unwrap(),
    );
    let mut est = Mrgia::new(cfg).unwrap();
    let mut trace = String::from("time");
    for i in 1..=cfg.na {
        write!(trace, ",a{i}").unwrap();
    }
    for j in 0..=cfg.nb {
        write!(trace, ",b{j}").unwrap();
    }
    trace.push_str(",m2,c1,c2,y_hat,e,updating\n");
    let mut updates = 0u64;
    for k in 0..u.len() {
        let r = est.update(u[k], y[k]);
        updates += u64::from(r.updating);
        let e = est.estimate();
        write!(trace, "{:?}", t[k]).unwrap();
        for v in e.a.iter().chain(&e.b).chain([&e.m2, &e.c1, &e.c2]) {
            write!(trace, ",{v:?}").unwrap();
        }
        writeln!(trace, ",{:?},{:?},{}", r.y_hat, r.e, u8::from(r.updating)).unwrap();
    }
    let e = est.estimate();
    let json = json!({
        "method": "mrgia",
        "a": e.a,
        "b": e.b,
        "m1": e.m1,
        "m2": e.m2,
        "c1": e.c1,
        "c2": e.c2,
        "samples": u.len(),
        "updates": updates,
        "setting": setting,
        "config": cfg,
        "file": file.display().to_string(),
        // These records move the input up and down through both borders: nothing to warn about.
        "warnings": [],
    });
    (json, trace)
}

#[test]
fn streaming_identify_equals_the_in_memory_computation() {
    let dir = TempDir::new("equal");
    let noisy = paper_record(10_000, 3, 0.03);
    let mut files: Vec<(PathBuf, String)> = Vec::new();
    // The paper's example without noise, full precision.
    let clean = paper_record(3000, 1, 0.0);
    let mut text = String::from("time,u,y\n");
    for (t, u, y) in &clean {
        writeln!(text, "{t:?},{u:?},{y:?}").unwrap();
    }
    files.push((dir.0.join("paper_clean.csv"), text));
    // With noise (std 0.03, about the paper's SNR 43), longer than the plot keeps: full precision.
    let mut text = String::from("time,u,y\n");
    for (t, u, y) in &noisy {
        writeln!(text, "{t:?},{u:?},{y:?}").unwrap();
    }
    files.push((dir.0.join("paper_noisy.csv"), text));
    // The same record rounded to 6 decimals, columns reordered, an extra column, CRLF, blank lines, a BOM.
    let mut text = String::from("\u{feff}y,note,time,u\r\n");
    for (k, (t, u, y)) in noisy.iter().enumerate() {
        writeln!(text, "{y:.6},n{k},{t:.2},{u:.6}\r").unwrap();
        if k % 1000 == 0 {
            text.push_str("\r\n");
        }
    }
    files.push((dir.0.join("paper_noisy_rounded.csv"), text));
    for (path, text) in &files {
        std::fs::write(path, text).unwrap();
    }
    let settings: [(&[&str], MrgiaConfig, &str); 3] = [
        (
            &["--na", "2", "--nb", "0", "--delay", "1"],
            MrgiaConfig::paper(2, 0, 1),
            "paper",
        ),
        (
            &["--na", "2", "--nb", "0", "--delay", "1", "--recommended"],
            MrgiaConfig::recommended(2, 0, 1),
            "recommended",
        ),
        (
            &["--na", "1", "--nb", "2", "--delay", "2", "--eps", "0.01"],
            MrgiaConfig {
                eps: 0.01,
                ..MrgiaConfig::paper(1, 2, 2)
            },
            "paper",
        ),
    ];
    for (file, _) in &files {
        for (args, cfg, setting) in &settings {
            let ctx = format!("{} {args:?}", file.display());
            let trace = dir.0.join("trace.csv");
            let plot = dir.0.join("plot.png");
            let mut all: Vec<&str> = args.to_vec();
            all.extend([
                "--json",
                "--trace",
                trace.to_str().unwrap(),
                "--plot",
                plot.to_str().unwrap(),
            ]);
            let out = identify(file, &all);
            assert!(
                out.status.success(),
                "{ctx}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
            let got: Value = serde_json::from_slice(&out.stdout).unwrap();
            let (want_json, want_trace) = in_memory(file, *cfg, setting);
            assert_eq!(got, want_json, "{ctx}: JSON");
            let got_trace = std::fs::read_to_string(&trace).unwrap();
            assert!(got_trace == want_trace, "{ctx}: the trace differs");
            assert!(std::fs::read(&plot).unwrap().starts_with(b"\x89PNG"));
            std::fs::remove_file(&trace).unwrap();
            std::fs::remove_file(&plot).unwrap();
        }
    }
}

#[test]
fn streaming_refusals_are_those_of_the_table() {
    let dir = TempDir::new("refuse");
    let mut good = String::from("time,u,y\n");
    for (t, u, y) in paper_record(5000, 2, 0.0) {
        writeln!(good, "{t:?},{u:?},{y:?}").unwrap();
    }
    let bad_rows: [&[u8]; 7] = [
        b"49.98,1,2\n",
        b"1e9,1\n",
        b"1e9,1,2,3\n",
        b"1e9,x,2\n",
        b"1e9,1,inf\n",
        b"1e9,1,\xe92\n",
        b"1e9,NaN,2\n",
    ];
    for (i, bad) in bad_rows.iter().enumerate() {
        // The fault comes after 5000 good rows: the estimator has run, and must leave nothing behind.
        let f = dir.0.join(format!("bad{i}.csv"));
        let mut content = good.clone().into_bytes();
        content.extend_from_slice(bad);
        content.extend_from_slice(b"1e10,0,0\n");
        std::fs::write(&f, &content).unwrap();
        let want = match Table::read(&f, &["time", "u", "y"]) {
            Ok(t) => panic!("bad{i}.csv accepted ({} rows)", t.rows()),
            Err(e) => e.to_string(),
        };
        assert!(want.contains("line 5002"), "{want}");
        let trace = dir.0.join("trace.csv");
        let out = identify(
            &f,
            &[
                "--na",
                "2",
                "--nb",
                "0",
                "--delay",
                "1",
                "--json",
                "--trace",
                trace.to_str().unwrap(),
            ],
        );
        assert!(!out.status.success());
        assert!(out.stdout.is_empty());
        assert_eq!(
            String::from_utf8_lossy(&out.stderr).trim(),
            format!("error: {want}")
        );
        assert!(!trace.exists());
    }
    let left: Vec<String> = std::fs::read_dir(&dir.0)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| !n.starts_with("bad"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}
