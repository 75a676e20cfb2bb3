//! The tables of docs/RESULTS.md, "Compensating the play": tracking RMSE of the loops none / fixed / adaptive /
//! no play on the paper plant (wear as a ramp and as a step, SNR 20 and 43, with and without smoothing), the
//! estimator's memory against noise and lag, the chattering of the inverse, and its cost per sample.
//!
//! `cargo run --release --example compensate_study` prints the tables;
//! `cargo run --release --example compensate_study reference N STD SEED PATH` writes the reference of the
//! measurements (time, r) as CSV, for `backlash compensate`.

use backlash::compensate::adaptive::{LoopSettings, Mode, Wear, low_pass_reference, simulate};
use backlash::compensate::{BacklashInverse, chattering};
use backlash::plant::{BacklashParams, PlantParams};
use std::hint::black_box;
use std::io::Write;
use std::time::Instant;

const N: usize = 20_000;
const STD: f64 = 1.5;
const SEEDS: [u64; 3] = [1, 2, 3];

fn plant(snr: f64, seed: u64) -> PlantParams {
    PlantParams {
        noise_std: STD / snr,
        noise_seed: 100 + seed,
        ..PlantParams::PAPER
    }
}

/// The loop on the paper plant's structure.
fn settings(memory: Option<f64>, smoothing: f64) -> LoopSettings {
    LoopSettings::for_structure(&PlantParams::PAPER.arx, memory, smoothing)
}

/// Mean over the seeds of (whole-record RMSE, last-quarter RMSE) of `mode`.
fn mean_rmse(wear: Wear, snr: f64, mode: Mode, s: &LoopSettings) -> (f64, f64) {
    let (mut all, mut last) = (0.0, 0.0);
    for seed in SEEDS {
        let r = low_pass_reference(N, STD, seed);
        let run = simulate(&r, &plant(snr, seed), wear, mode, s).expect("valid loop");
        all += run.rmse;
        last += run.rmse_last_quarter;
    }
    let k = SEEDS.len() as f64;
    (all / k, last / k)
}

fn modes_table() {
    println!(
        "| wear | SNR | smoothing | none | fixed | adaptive | no play | adaptive / no play | adaptive / fixed |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- | --- | --- |");
    for (wname, wear) in [
        ("ramp +50%", Wear::Ramp { ratio: 0.5 }),
        ("step +50% at N/2", Wear::Step { ratio: 0.5 }),
    ] {
        for snr in [20.0, 43.0] {
            for smooth in [0.0, 4.0 * STD / snr] {
                let s = settings(Some(500.0), smooth);
                let q: Vec<f64> = Mode::ALL
                    .iter()
                    .map(|&m| mean_rmse(wear, snr, m, &s).1)
                    .collect();
                println!(
                    "| {wname} | {snr} | {smooth:.3} | {:.4} | {:.4} | {:.4} | {:.4} | {:.2} | {:.3} |",
                    q[0],
                    q[1],
                    q[2],
                    q[3],
                    q[2] / q[3],
                    q[2] / q[1]
                );
            }
        }
    }
}

fn memory_table() {
    println!(
        "\n| memory (samples) | rho_min | no wear, last quarter | ramp +50%, last quarter | step +50%, last quarter |"
    );
    println!("| --- | --- | --- | --- | --- |");
    for memory in [
        None,
        Some(5000.0),
        Some(2000.0),
        Some(1000.0),
        Some(500.0),
        Some(200.0),
        Some(100.0),
    ] {
        let s = settings(memory, 0.0);
        let none = mean_rmse(Wear::None, 43.0, Mode::Adaptive, &s).1;
        let ramp = mean_rmse(Wear::Ramp { ratio: 0.5 }, 43.0, Mode::Adaptive, &s).1;
        let step = mean_rmse(Wear::Step { ratio: 0.5 }, 43.0, Mode::Adaptive, &s).1;
        let name = memory.map_or("none".to_string(), |m| format!("{m}"));
        let rho = memory.map_or(0.0, |m| 1.0 / m);
        println!("| {name} | {rho} | {none:.4} | {ramp:.4} | {step:.4} |");
    }
}

/// Chattering of v on a constant reference 1 with noise std sigma, and the inverse's cost per sample.
fn inverse_table() {
    let p = BacklashParams::PAPER;
    let gap = p.c1 + p.c2;
    let sigma = 0.05;
    let r: Vec<f64> = white(N, sigma, 11).iter().map(|e| 1.0 + e).collect();
    println!(
        "\n| smoothing / sigma | chattering (share of samples v moves > gap/2) | max abs(w - r) |"
    );
    println!("| --- | --- | --- |");
    for k in [0.0, 1.0, 2.0, 3.0, 4.0, 6.0] {
        let mut inv = BacklashInverse::new(k * sigma).unwrap();
        let mut v = Vec::with_capacity(N);
        let mut worst = 0.0f64;
        for &rk in &r {
            let a = inv.commit(rk, &p);
            worst = worst.max((a.w - rk).abs());
            v.push(a.v);
        }
        println!("| {k} | {:.4} | {worst:.3} |", chattering(&v, gap));
    }
    let reps = 200;
    let big = low_pass_reference(100_000, STD, 4);
    let t = Instant::now();
    for _ in 0..reps {
        let mut inv = BacklashInverse::new(0.0).unwrap();
        for &rk in &big {
            black_box(inv.commit(black_box(rk), black_box(&p)));
        }
    }
    let ns = t.elapsed().as_secs_f64() * 1e9 / (reps * big.len()) as f64;
    println!(
        "\ninverse cost: {ns:.1} ns per sample (commit, {} samples)",
        reps * big.len()
    );
}

/// White Gaussian noise of standard deviation `std`: the innovations of the reference generator.
fn white(n: usize, std: f64, seed: u64) -> Vec<f64> {
    let r = low_pass_reference(n + 1, 1.0, seed);
    let g = (1.0f64 - 0.81).sqrt();
    r.windows(2)
        .map(|w| std * (w[1] - 0.9 * w[0]) / g)
        .collect()
}

fn write_reference(args: &[String]) {
    let n: usize = args[0].parse().expect("N");
    let std: f64 = args[1].parse().expect("STD");
    let seed: u64 = args[2].parse().expect("SEED");
    let r = low_pass_reference(n, std, seed);
    let mut f = std::io::BufWriter::new(std::fs::File::create(&args[3]).expect("PATH"));
    writeln!(f, "time,r").unwrap();
    for (k, x) in r.iter().enumerate() {
        writeln!(f, "{k},{x}").unwrap();
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("reference") {
        write_reference(&args[1..]);
        return;
    }
    modes_table();
    memory_table();
    inverse_table();
}
