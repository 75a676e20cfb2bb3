//! Time the output-error fit on the paper example (N = 3000, SNR 43) in the library, without CLI start-up.
//!
//! `cargo run --release --example oe_timing [N] [REPEATS]`

use backlash::identify::mrgia::{self, MrgiaConfig, paper_input};
use backlash::identify::oe::{OeConfig, fit, fit_from};
use backlash::plant::{Plant, PlantParams};
use std::time::Instant;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let mut args = std::env::args().skip(1);
    let n: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(3000);
    let reps: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(51);
    let u = paper_input(n, 1);
    let w: Vec<f64> = Plant::simulate(PlantParams::PAPER, &u)
        .unwrap()
        .iter()
        .map(|o| o.w)
        .collect();
    let mean = w.iter().sum::<f64>() / n as f64;
    let std = (w.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
    let mut p = PlantParams::PAPER;
    p.noise_std = std / 43.0;
    p.noise_seed = 99;
    let y: Vec<f64> = Plant::simulate(p, &u)
        .unwrap()
        .iter()
        .map(|o| o.y)
        .collect();

    let time = |f: &mut dyn FnMut()| -> f64 {
        let v: Vec<f64> = (0..reps)
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed().as_secs_f64()
            })
            .collect();
        median(v)
    };
    let cfg = OeConfig::new(2, 0, 1);
    let single = OeConfig {
        extra_starts: false,
        ..cfg
    };
    let t_mrgia = time(&mut || {
        std::hint::black_box(mrgia::identify(MrgiaConfig::recommended(2, 0, 1), &u, &y).unwrap());
    });
    let (rec, _) = mrgia::identify(MrgiaConfig::recommended(2, 0, 1), &u, &y).unwrap();
    let t_lm = time(&mut || {
        std::hint::black_box(fit_from(&single, &u, &y, &[("given", rec.clone())]).unwrap());
    });
    let t_single = time(&mut || {
        std::hint::black_box(fit(&single, &u, &y).unwrap());
    });
    let t_full = time(&mut || {
        std::hint::black_box(fit(&cfg, &u, &y).unwrap());
    });
    let f = fit(&cfg, &u, &y).unwrap();
    let s = fit(&single, &u, &y).unwrap();
    println!("N = {n}, median of {reps} runs");
    println!(
        "  MRGIA (recommended) pass:            {:8.3} ms",
        t_mrgia * 1e3
    );
    println!(
        "  LM from the MRGIA estimate:          {:8.3} ms ({} iterations)",
        t_lm * 1e3,
        s.iterations
    );
    println!(
        "  fit, single start (MRGIA + LM):      {:8.3} ms",
        t_single * 1e3
    );
    println!(
        "  fit, default (3 starts, 2 MRGIA):    {:8.3} ms (winner {}, {} iterations)",
        t_full * 1e3,
        f.start_method,
        f.iterations
    );
}
