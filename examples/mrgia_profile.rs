//! MRGIA alone over the paper 000 example, for profilers (callgrind, perf) and for checking that an
//! optimisation leaves the results unchanged: prints the update fraction, the final theta in full precision
//! and the wall-clock rate.
//!
//! `cargo run --release --example mrgia_profile [N] [NA] [NB] [NOISE_STD]`
//!
//! `valgrind --tool=callgrind target/release/examples/mrgia_profile 200000` gives the instruction count per
//! sample, independent of the machine's load (the plant simulation that makes the record is in the profile
//! too, under `Plant::simulate`; `Mrgia::update` is the part to read).

use backlash::identify::mrgia::{Mrgia, MrgiaConfig, paper_input};
use backlash::plant::{Plant, PlantParams};
use std::hint::black_box;
use std::time::Instant;

fn main() {
    let mut args = std::env::args().skip(1);
    let n: usize = args
        .next()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1_000_000);
    let na: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(2);
    let nb: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(0);
    let noise: f64 = args.next().and_then(|s| s.parse().ok()).unwrap_or(0.0);
    let u = paper_input(n, 2);
    let mut p = PlantParams::PAPER;
    p.noise_std = noise;
    p.noise_seed = 7;
    let y: Vec<f64> = Plant::simulate(p, &u)
        .expect("the paper plant is valid")
        .iter()
        .map(|o| o.y)
        .collect();
    let mut m = Mrgia::new(MrgiaConfig::paper(na, nb, 1)).expect("orders in range");
    let t = Instant::now();
    let mut updates = 0u64;
    for k in 0..n {
        updates += u64::from(m.update(black_box(u[k]), black_box(y[k])).updating);
    }
    let dt = t.elapsed().as_secs_f64();
    println!(
        "n = {n}, na = {na}, nb = {nb}, noise std = {noise}: {updates} updates ({:.1}%)",
        100.0 * updates as f64 / n as f64
    );
    println!("theta = {:?}", m.theta());
    println!("sigma = {:e}", m.sigma());
    println!(
        "{:.1} ns/sample, {:.2} M samples/s (wall clock, one core)",
        dt / n as f64 * 1e9,
        n as f64 / dt / 1e6
    );
}
