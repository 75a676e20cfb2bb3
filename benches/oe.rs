//! Cost of the output-error fit on the paper 000 example (N = 3000, SNR 43), as criterion measures it, with
//! one MRGIA pass over the same record as the baseline of the group (the fit runs MRGIA first).
//!
//! `cargo bench --bench oe`

use backlash::identify::mrgia::{self, MrgiaConfig, paper_input};
use backlash::identify::oe::{OeConfig, crb, fit, fit_from};
use backlash::plant::{Plant, PlantParams};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;

const N: usize = 3000;

fn record() -> (Vec<f64>, Vec<f64>, f64) {
    let u = paper_input(N, 1);
    let w: Vec<f64> = Plant::simulate(PlantParams::PAPER, &u)
        .expect("the paper plant is valid")
        .iter()
        .map(|o| o.w)
        .collect();
    let mean = w.iter().sum::<f64>() / N as f64;
    let std = (w.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / N as f64).sqrt() / 43.0;
    let mut p = PlantParams::PAPER;
    p.noise_std = std;
    p.noise_seed = 99;
    let y = Plant::simulate(p, &u)
        .expect("valid")
        .iter()
        .map(|o| o.y)
        .collect();
    (u, y, std)
}

fn output_error(c: &mut Criterion) {
    let (u, y, std) = record();
    let cfg = OeConfig::new(2, 0, 1);
    let single = OeConfig {
        extra_starts: false,
        ..cfg
    };
    let (start, _) = mrgia::identify(MrgiaConfig::recommended(2, 0, 1), &u, &y).expect("valid");
    let mut g = c.benchmark_group("oe");
    g.throughput(Throughput::Elements(N as u64));
    g.bench_function("MRGIA recommended pass (baseline)", |b| {
        b.iter(|| mrgia::identify(MrgiaConfig::recommended(2, 0, 1), black_box(&u), &y))
    });
    g.bench_function("LM from the MRGIA estimate", |b| {
        b.iter(|| fit_from(&single, black_box(&u), &y, &[("given", start.clone())]))
    });
    g.bench_function("fit, single start", |b| {
        b.iter(|| fit(&single, black_box(&u), &y))
    });
    g.bench_function("fit, default (three starts)", |b| {
        b.iter(|| fit(&cfg, black_box(&u), &y))
    });
    g.bench_function("Cramer-Rao bound", |b| {
        b.iter(|| crb(&PlantParams::PAPER, black_box(&u), std))
    });
    g.finish();
}

criterion_group!(benches, output_error);
criterion_main!(benches);
