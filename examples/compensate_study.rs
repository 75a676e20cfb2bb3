//! The tables of docs/RESULTS.md, "Compensating the play": tracking RMSE of the loops none / fixed / adaptive /
//! no play on the paper plant (wear as a ramp and as a step, SNR 20 and 43, with and without smoothing), the
//! estimator's memory against noise and lag, the chattering of the inverse, and its cost per sample.
//!
//! `cargo run --release --example compensate_study` prints the tables;
//! `cargo run --release --example compensate_study -- more` prints the tables added after them: the
//! noise-free output's error (why SNR 20 misses 0.1x the fixed inverse), the memory at SNR 20, the estimate
//! lag of a Jacobi master, and the test bench's plant (G(s) = 1/(s^2 + 0.6 s + 1) at Ts = 1 s);
//! `cargo run --release --example compensate_study reference N STD SEED PATH` writes the reference of the
//! measurements (time, r) as CSV, for `backlash compensate`.

use backlash::compensate::adaptive::{LoopSettings, Mode, Wear, low_pass_reference, simulate};
use backlash::compensate::{BacklashInverse, chattering};
use backlash::plant::{
    ArxParams, BacklashParams, ContinuousLinear, MAX_ORDER, PlantParams, TransferFunction,
};
use std::hint::black_box;
use std::io::Write;
use std::time::Instant;

const N: usize = 20_000;
const STD: f64 = 1.5;
const SEEDS: [u64; 3] = [1, 2, 3];

fn plant(snr: f64, seed: u64) -> PlantParams {
    noisy(PlantParams::PAPER, snr, seed)
}

/// `base` with the noise of the SNR (reference std / noise std) and the seed's noise.
fn noisy(base: PlantParams, snr: f64, seed: u64) -> PlantParams {
    PlantParams {
        noise_std: STD / snr,
        noise_seed: 100 + seed,
        ..base
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

/// Mean over the seeds of the last-quarter RMSE of y - r and of f - r (f the noise-free output) of `mode` on
/// `base`.
fn mean_last(base: PlantParams, wear: Wear, snr: f64, mode: Mode, s: &LoopSettings) -> (f64, f64) {
    let (mut y, mut f) = (0.0, 0.0);
    for seed in SEEDS {
        let r = low_pass_reference(N, STD, seed);
        let run = simulate(&r, &noisy(base, snr, seed), wear, mode, s).expect("valid loop");
        y += run.rmse_last_quarter;
        f += run.rmse_clean_last_quarter;
    }
    let k = SEEDS.len() as f64;
    (y / k, f / k)
}

const WEARS: [(&str, Wear); 2] = [
    ("ramp +50%", Wear::Ramp { ratio: 0.5 }),
    ("step +50% at N/2", Wear::Step { ratio: 0.5 }),
];

/// The test bench's plant: G(s) = 1/(s^2 + 0.6 s + 1) sampled at Ts = 1 s (the plant FMU's `linear = 1`) with
/// paper 000's backlash, as its exact zero-order-hold ARX (na 2, nb 1, delay 1): the poles e^{p Ts}, the
/// numerator from the block's step response x(1) = b0, x(2) = -a1 x(1) + b0 + b1.
fn bench_plant() -> PlantParams {
    let (re, im) = (-0.3f64, 0.91f64.sqrt());
    let (a1, a2) = (-2.0 * re.exp() * im.cos(), (2.0 * re).exp());
    let mut g =
        ContinuousLinear::new(TransferFunction::example(), 1.0).expect("the example is stable");
    let step: Vec<f64> = (0..3).map(|_| g.step(1.0)).collect();
    let (b0, b1) = (step[1], step[2] + a1 * step[1] - step[1]);
    let mut a = [0.0; MAX_ORDER];
    let mut b = [0.0; MAX_ORDER + 1];
    (a[0], a[1], b[0], b[1]) = (a1, a2, b0, b1);
    PlantParams {
        arx: ArxParams {
            na: 2,
            nb: 1,
            delay: 1,
            a,
            b,
        },
        ..PlantParams::PAPER
    }
}

/// The largest difference between the continuous block and its ARX on the reference of seed 1 as input.
fn bench_arx_error(p: &PlantParams) -> f64 {
    let mut g = ContinuousLinear::new(TransferFunction::example(), 1.0).expect("stable");
    let mut arx = backlash::plant::Arx::new(p.arx);
    low_pass_reference(2000, STD, 1)
        .iter()
        .map(|&u| (g.step(u) - arx.step(u)).abs())
        .fold(0.0, f64::max)
}

/// Tracking on `base` (the paper's plant or the bench's), with the noise-free output's error beside y's.
fn tracking_table(base: PlantParams, name: &str) {
    println!(
        "\n{name}: last quarter, RMS of y - r (noise-free f - r in brackets)\n\n| wear | SNR | smoothing | none | fixed | adaptive | no play | adaptive / no play | adaptive / fixed | adaptive / fixed, noise-free |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |");
    for (wname, wear) in WEARS {
        for snr in [20.0, 43.0] {
            for smooth in [0.0, 4.0 * STD / snr] {
                let s = LoopSettings::for_structure(&base.arx, Some(500.0), smooth);
                let q: Vec<(f64, f64)> = Mode::ALL
                    .iter()
                    .map(|&m| mean_last(base, wear, snr, m, &s))
                    .collect();
                let cell = |(y, f): (f64, f64)| format!("{y:.4} ({f:.4})");
                println!(
                    "| {wname} | {snr} | {smooth:.3} | {} | {} | {} | {} | {:.2} | {:.3} | {:.3} |",
                    cell(q[0]),
                    cell(q[1]),
                    cell(q[2]),
                    cell(q[3]),
                    q[2].0 / q[3].0,
                    q[2].0 / q[1].0,
                    q[2].1 / q[1].1
                );
            }
        }
    }
}

/// SNR 20, paper plant: the memory against the error of y and of the noise-free output.
fn memory_at_snr20() {
    println!(
        "\n| memory (samples) | ramp: y - r | ramp: f - r | ramp: adaptive / fixed | step: y - r | step: f - r | step: adaptive / fixed |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- |");
    let fixed: Vec<f64> = WEARS
        .iter()
        .map(|&(_, w)| {
            let s = settings(Some(500.0), 0.0);
            mean_last(PlantParams::PAPER, w, 20.0, Mode::Fixed, &s).0
        })
        .collect();
    for memory in [250.0, 500.0, 1000.0, 2000.0, 4000.0] {
        let s = settings(Some(memory), 0.0);
        let row: Vec<(f64, f64)> = WEARS
            .iter()
            .map(|&(_, w)| mean_last(PlantParams::PAPER, w, 20.0, Mode::Adaptive, &s))
            .collect();
        println!(
            "| {memory} | {:.4} | {:.4} | {:.3} | {:.4} | {:.4} | {:.3} |",
            row[0].0,
            row[0].1,
            row[0].0 / fixed[0],
            row[1].0,
            row[1].1,
            row[1].0 / fixed[1]
        );
    }
}

/// The adaptive loop with the estimate of the sample before (a Jacobi master) against the latest.
fn lag_table() {
    println!(
        "\n| wear | SNR | adaptive, lag 0 | adaptive, lag 1 | lag 1 / lag 0 | noise-free, lag 0 | noise-free, lag 1 |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- |");
    for (wname, wear) in WEARS {
        for snr in [20.0, 43.0] {
            let at = |lag| {
                let s = LoopSettings {
                    estimate_lag: lag,
                    ..settings(Some(500.0), 0.0)
                };
                mean_last(PlantParams::PAPER, wear, snr, Mode::Adaptive, &s)
            };
            let (l0, l1) = (at(0), at(1));
            println!(
                "| {wname} | {snr} | {:.4} | {:.4} | {:.3} | {:.4} | {:.4} |",
                l0.0,
                l1.0,
                l1.0 / l0.0,
                l0.1,
                l1.1
            );
        }
    }
}

fn more() {
    tracking_table(PlantParams::PAPER, "paper 000's plant");
    memory_at_snr20();
    lag_table();
    let bench = bench_plant();
    let (a, b) = (bench.arx.a, bench.arx.b);
    println!(
        "\ntest bench's plant as ARX: a1 {:.6}, a2 {:.6}, b0 {:.6}, b1 {:.6} (zero at {:.4}); largest difference from the continuous block over 2000 samples {:.1e}",
        a[0],
        a[1],
        b[0],
        b[1],
        -b[1] / b[0],
        bench_arx_error(&bench)
    );
    tracking_table(bench, "test bench's plant");
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("reference") {
        write_reference(&args[1..]);
        return;
    }
    if args.first().map(String::as_str) == Some("more") {
        more();
        return;
    }
    modes_table();
    memory_table();
    inverse_table();
}
