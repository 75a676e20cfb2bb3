//! The verdict on play (`backlash.presence`) on simulated classes of records with and without play: a
//! confusion table (issue 55, item 4). Not part of the test suite: it runs the whole diagnosis on hundreds of
//! records.
//!
//! ```sh
//! cargo run --release --example verdict_confusion -- --records 20 --out docs/verdict_confusion.csv
//! ```
//!
//! Each record: a random stable linear block (first order, or second order with real or complex poles,
//! static gain 0.5..2, delay 1..3) driven by the paper's white uniform input (the tanks and the loop: random
//! steps), then the class's element; the same noise-free record at two noise levels (SNR 40 dB and 20 dB,
//! std(noise-free output) / noise std = 100 and 10), diagnosed by `backlash::api::diagnose` with
//! `DiagnoseConfig::auto()`. Saturation, dead zone, direction-dependent dynamics and the friction after the
//! play are the test bench's own effects, drawn by the catalogue's `draw` on this plant; the other elements
//! are written here. For the records with play, the truth: the gap c1 + c2 as a share of the travel (1st to
//! 99th percentile of the linear block's output) and the reversals of the play's output (each one a crossing
//! of the gap), both on the fit part (the first 70%), as the rule counts them.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Parser;
use rand_chacha::ChaCha8Rng;
use rand_core::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;

use backlash::api::diagnose;
use backlash::diagnose::effects::rig::{Draw, Rig};
use backlash::diagnose::effects::{EffectId, dead_zone, direction_dependent, friction, saturation};
use backlash::diagnose::engine::DiagnoseConfig;
use backlash::diagnose::search::presence::{BacklashSupport, Presence};
use backlash::identify::mrgia::paper_input;
use backlash::plant::backlash::BacklashParams;
use backlash::plant::effects::Effects;
use backlash::plant::linear::ArxParams;
use backlash::plant::{Plant, PlantParams};
use backlash::stats::std_dev;

mod sim;
use sim::{backlash_of, effect_names, linear_block, reversals, run, travel};

#[derive(Parser)]
struct Cli {
    /// Records per class and noise level.
    #[arg(long, default_value_t = 20)]
    records: usize,
    /// Samples per record.
    #[arg(long, default_value_t = 3000)]
    samples: usize,
    /// Only these classes (comma-separated names as in the table).
    #[arg(long, value_delimiter = ',')]
    classes: Vec<String>,
    /// One line per record (CSV).
    #[arg(long)]
    out: Option<PathBuf>,
    /// A folder for each diagnosis's JSON (CLASS-SNR-SEED.json).
    #[arg(long)]
    json: Option<PathBuf>,
}

/// The noise levels, in dB (20 log10 of std(noise-free output) / noise std).
const SNR_DB: [f64; 2] = [40.0, 20.0];
/// A play the targets count: at least this share of the travel ...
const MIN_SHARE: f64 = 0.02;
/// ... crossed at least this often.
const MIN_CROSSINGS: usize = 20;

#[derive(Clone, Copy, PartialEq)]
enum Class {
    Play,
    Friction,
    Saturation,
    DeadZone,
    BoucWen,
    RiseFall,
    AbsSensor,
    Tanks,
    Duffing,
    Curve,
    SecondInput,
    PlayFriction,
    PlayLoop,
}

const CLASSES: [Class; 13] = [
    Class::Play,
    Class::PlayFriction,
    Class::PlayLoop,
    Class::Friction,
    Class::Saturation,
    Class::DeadZone,
    Class::BoucWen,
    Class::RiseFall,
    Class::AbsSensor,
    Class::Tanks,
    Class::Duffing,
    Class::Curve,
    Class::SecondInput,
];

impl Class {
    fn name(self) -> &'static str {
        match self {
            Class::Play => "play",
            Class::Friction => "coulomb-viscous",
            Class::Saturation => "saturation",
            Class::DeadZone => "dead-zone",
            Class::BoucWen => "bouc-wen",
            Class::RiseFall => "rise-faster-than-fall",
            Class::AbsSensor => "abs-sensor",
            Class::Tanks => "sqrt-tanks",
            Class::Duffing => "duffing",
            Class::Curve => "smooth-curve",
            Class::SecondInput => "second-input",
            Class::PlayFriction => "play+friction",
            Class::PlayLoop => "play-closed-loop",
        }
    }

    fn has_play(self) -> bool {
        matches!(self, Class::Play | Class::PlayFriction | Class::PlayLoop)
    }
}

/// The play of a record with play, as the targets read it.
#[derive(Clone, Copy)]
struct Truth {
    /// c1 + c2 over the travel of the linear block's output (fit part).
    share: f64,
    /// Reversals of the play's output on the fit part.
    crossings: usize,
}

impl Truth {
    fn counts(&self) -> bool {
        self.share >= MIN_SHARE && self.crossings >= MIN_CROSSINGS
    }
}

/// A noise-free record; the loop's record carries its noisy output per noise level.
struct Sim {
    u: Vec<f64>,
    f: Vec<f64>,
    truth: Option<Truth>,
    what: String,
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    let classes: Vec<Class> = CLASSES
        .into_iter()
        .filter(|c| cli.classes.is_empty() || cli.classes.iter().any(|n| n == c.name()))
        .collect();
    let mut rows = Vec::new();
    let start = Instant::now();
    for class in classes {
        let t = Instant::now();
        let out: Vec<Row> = (0..cli.records)
            .into_par_iter()
            .flat_map_iter(|i| record_rows(class, i as u64, cli.samples, cli.json.as_deref()))
            .collect();
        let present = out
            .iter()
            .filter(|r| r.presence == Presence::Present)
            .count();
        let absent = out
            .iter()
            .filter(|r| r.presence == Presence::Absent)
            .count();
        println!(
            "{:>22}: {} records, present {present}, absent {absent}, undetermined {} [{:.0} s]",
            class.name(),
            out.len(),
            out.len() - present - absent,
            t.elapsed().as_secs_f64()
        );
        rows.extend(out);
    }
    println!("\n{}", table(&rows));
    println!("total {:.0} s", start.elapsed().as_secs_f64());
    if let Some(path) = cli.out {
        write_csv(&path, &rows).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

/// One diagnosed record.
struct Row {
    class: Class,
    snr_db: f64,
    seed: u64,
    presence: Presence,
    truth: Option<Truth>,
    b: BacklashSupport,
    /// The effects the diagnosis named, in order.
    effects: String,
    what: String,
}

/// The record `i` of `class` at both noise levels (the same noise-free record), diagnosed.
fn record_rows(class: Class, i: u64, n: usize, json: Option<&std::path::Path>) -> Vec<Row> {
    let seed = 1000 * (CLASSES.iter().position(|c| *c == class).unwrap_or(0) as u64) + i;
    let open = (class != Class::PlayLoop)
        .then(|| simulate(class, &mut Draw(ChaCha8Rng::seed_from_u64(seed)), n, seed));
    SNR_DB
        .iter()
        .map(|&db| {
            let snr = 10f64.powf(db / 20.0);
            let (sim, y) = match &open {
                Some(sim) => (sim, noisy(&sim.f, snr, seed ^ db.to_bits())),
                None => {
                    let mut d = Draw(ChaCha8Rng::seed_from_u64(seed));
                    let (sim, y) = play_loop(&mut d, n, snr, seed ^ db.to_bits());
                    return row(class, db, seed, &sim, &y, json);
                }
            };
            row(class, db, seed, sim, &y, json)
        })
        .collect()
}

/// The diagnosis of one noisy record.
fn row(
    class: Class,
    db: f64,
    seed: u64,
    sim: &Sim,
    y: &[f64],
    json: Option<&std::path::Path>,
) -> Row {
    let diag = diagnose(&sim.u, y, &DiagnoseConfig::auto()).expect("the record is valid");
    if let Some(dir) = json {
        let path = dir.join(format!("{}-{db:.0}-{seed}.json", class.name()));
        let text = serde_json::to_string_pretty(&diag.to_json(None)).expect("JSON");
        std::fs::write(&path, text).unwrap_or_else(|e| panic!("writing {}: {e}", path.display()));
    }
    Row {
        class,
        snr_db: db,
        seed,
        presence: diag.backlash.presence,
        truth: sim.truth,
        effects: effect_names(&diag),
        b: diag.backlash,
        what: sim.what.clone(),
    }
}

/// `f` plus white Gaussian noise of std std(f) / snr.
fn noisy(f: &[f64], snr: f64, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let s = std_dev(f) / snr;
    f.iter()
        .map(|v| {
            let z: f64 = StandardNormal.sample(&mut rng);
            v + s * z
        })
        .collect()
}

/// The noise-free record of `class` (any but the loop).
fn simulate(class: Class, d: &mut Draw, n: usize, seed: u64) -> Sim {
    let u = if class == Class::Tanks {
        steps(d, n, 20, 100)
    } else {
        paper_input(n, seed)
    };
    let arx = linear_block(d);
    let x: Vec<f64> = run(arx, backlash_of(d, 0.0), &Effects::default(), &u)
        .iter()
        .map(|o| o.x)
        .collect();
    let block = format!(
        "a {:.3} {:.3}, b0 {:.3}, delay {}",
        arx.a[0], arx.a[1], arx.b[0], arx.delay
    );
    let (f, truth, what) = match class {
        Class::Play | Class::PlayFriction => with_play(class, d, arx, &u, &x),
        Class::Saturation | Class::DeadZone | Class::RiseFall => {
            bench_effect(class, d, arx, &u, &x)
        }
        Class::Friction => coulomb_viscous(d, &x),
        Class::BoucWen => bouc_wen(d, &x),
        Class::AbsSensor => {
            let c = d.uniform(-0.3, 0.3) * std_dev(&x);
            (
                x.iter().map(|v| (v + c).abs()).collect(),
                None,
                format!("|x + {c:.3}|"),
            )
        }
        Class::Tanks => tanks(d, &u),
        Class::Duffing => duffing(d, &x),
        Class::Curve => curve(d, &x),
        Class::SecondInput => second_input(d, &x),
        Class::PlayLoop => unreachable!("the loop is simulated with its noise"),
    };
    let what = if class == Class::Tanks {
        what
    } else {
        format!("{block}; {what}")
    };
    Sim { u, f, truth, what }
}

/// The rig of the test bench on this plant, for an effect's own draw.
fn rig(arx: ArxParams, bl: BacklashParams, u: &[f64]) -> Rig {
    let clean = run(arx, bl, &Effects::default(), u);
    Rig {
        params: PlantParams {
            arx,
            backlash: bl,
            noise_std: 0.0,
            noise_seed: 0,
        },
        effects: Effects::default(),
        snr: 0.0,
        fixed_noise: None,
        w0: clean.iter().map(|o| o.w).collect(),
        x0: clean.iter().map(|o| o.x).collect(),
        u: u.to_vec(),
        n: u.len(),
    }
}

/// Play of 1..25% of the travel; with friction after it (the bench's friction draw).
fn with_play(
    class: Class,
    d: &mut Draw,
    arx: ArxParams,
    u: &[f64],
    x: &[f64],
) -> (Vec<f64>, Option<Truth>, String) {
    let share = d.uniform(0.01, 0.25);
    let bl = backlash_of(d, share * travel(x));
    let mut r = rig(arx, bl, u);
    let mut what = format!("play {:.1}% of the travel", 100.0 * share);
    if class == Class::PlayFriction {
        what = format!("{what}; {}", friction::ID.effect().draw(&mut r, d));
    }
    let out = run(arx, bl, &r.effects, u);
    let w: Vec<f64> = out.iter().map(|o| o.w).collect();
    let truth = Truth {
        share,
        crossings: reversals(&w),
    };
    (out.iter().map(|o| o.f).collect(), Some(truth), what)
}

/// The bench's saturation, dead zone or direction-dependent dynamics on a play-free plant.
fn bench_effect(
    class: Class,
    d: &mut Draw,
    arx: ArxParams,
    u: &[f64],
    _x: &[f64],
) -> (Vec<f64>, Option<Truth>, String) {
    let id: EffectId = match class {
        Class::Saturation => saturation::ID,
        Class::DeadZone => dead_zone::ID,
        _ => direction_dependent::ID,
    };
    let bl = backlash_of(d, 0.0);
    let mut r = rig(arx, bl, u);
    let what = id.effect().draw(&mut r, d);
    let f = run(arx, bl, &r.effects, u).iter().map(|o| o.f).collect();
    (f, None, what)
}

/// A unit mass driven by the force x against viscous friction c v and Coulomb friction Fc sign(v) (sticking
/// while |x| <= Fc at rest); the velocity is measured. Ten Euler steps per sample.
fn coulomb_viscous(d: &mut Draw, x: &[f64]) -> (Vec<f64>, Option<Truth>, String) {
    let c = d.uniform(0.1, 0.5);
    let fc = d.uniform(0.2, 0.6) * std_dev(x);
    let h = 0.1;
    let mut v: f64 = 0.0;
    let f = x
        .iter()
        .map(|&force| {
            for _ in 0..10 {
                if v == 0.0 && force.abs() <= fc {
                    continue;
                }
                let dir = if v != 0.0 { v.signum() } else { force.signum() };
                let next = v + h * (force - c * v - fc * dir);
                v = if v != 0.0 && next.signum() != v.signum() {
                    0.0
                } else {
                    next
                };
            }
            v
        })
        .collect();
    (f, None, format!("viscous {c:.2}, Coulomb {fc:.3}"))
}

/// Bouc-Wen hysteresis (n = 1, A = 1) on x: dz = dx - beta |dx| z - gamma dx |z|, z bounded by
/// 1 / (beta + gamma) = 5..30% of the travel; output alpha x + (1 - alpha) z, in steps small enough for Euler.
fn bouc_wen(d: &mut Draw, x: &[f64]) -> (Vec<f64>, Option<Truth>, String) {
    let zmax = d.uniform(0.05, 0.3) * travel(x);
    let split = d.uniform(0.5, 0.9);
    let (beta, gamma) = (split / zmax, (1.0 - split) / zmax);
    let alpha = d.uniform(0.2, 0.8);
    let mut z: f64 = 0.0;
    let mut prev = x[0];
    let f = x
        .iter()
        .map(|&xk| {
            let dx_all = xk - prev;
            let parts = (dx_all.abs() / zmax * 20.0).ceil().max(1.0);
            let dx = dx_all / parts;
            for _ in 0..parts as usize {
                z += dx - beta * dx.abs() * z - gamma * dx * z.abs();
            }
            prev = xk;
            alpha * xk + (1.0 - alpha) * z
        })
        .collect();
    (
        f,
        None,
        format!("z bound {zmax:.3}, beta/(beta+gamma) {split:.2}, alpha {alpha:.2}"),
    )
}

/// Random steps in [-1, 1], each held `lo..hi` samples.
fn steps(d: &mut Draw, n: usize, lo: usize, hi: usize) -> Vec<f64> {
    let mut v = Vec::with_capacity(n);
    while v.len() < n {
        let level = d.uniform(-1.0, 1.0);
        let hold = d.uniform(lo as f64, hi as f64) as usize;
        v.extend(std::iter::repeat_n(level, hold.min(n - v.len())));
    }
    v
}

/// Two tanks in cascade, each draining through sqrt(level): A1 h1' = q - k1 sqrt(h1),
/// A2 h2' = k1 sqrt(h1) - k2 sqrt(h2), inflow q = 1 + 0.6 u (u random steps), the lower level measured;
/// time constants of 5..30 samples. Ten Euler steps per sample.
fn tanks(d: &mut Draw, u: &[f64]) -> (Vec<f64>, Option<Truth>, String) {
    let (k1, k2) = (d.uniform(0.8, 1.2), d.uniform(0.8, 1.2));
    let (a1, a2) = (d.uniform(3.0, 15.0), d.uniform(3.0, 15.0));
    let (mut h1, mut h2) = (1.0 / (k1 * k1), 1.0 / (k2 * k2));
    let h = 0.1;
    let f = u
        .iter()
        .map(|&uk| {
            let q = 1.0 + 0.6 * uk;
            for _ in 0..10 {
                let out1 = k1 * f64::sqrt(h1.max(0.0));
                h1 += h * (q - out1) / a1;
                h2 += h * (out1 - k2 * f64::sqrt(h2.max(0.0))) / a2;
            }
            h2
        })
        .collect();
    (
        f,
        None,
        format!("k {k1:.2} / {k2:.2}, areas {a1:.1} / {a2:.1}"),
    )
}

/// x'' + 2 zeta w x' + w^2 (p + kappa p^3) = w^2 x: a cubic spring in feedback, the stiffening kappa p^2
/// 0.3..1.5 at the travel's half; semi-implicit Euler, twenty steps per sample.
fn duffing(d: &mut Draw, x: &[f64]) -> (Vec<f64>, Option<Truth>, String) {
    let w = d.uniform(0.2, 0.6);
    let zeta = d.uniform(0.1, 0.5);
    let half = 0.5 * travel(x);
    let kappa = d.uniform(0.3, 1.5) / (half * half);
    let h = 0.05;
    let (mut p, mut v): (f64, f64) = (0.0, 0.0);
    let f = x
        .iter()
        .map(|&force| {
            for _ in 0..20 {
                v += h * (w * w * (force - p - kappa * p.powi(3)) - 2.0 * zeta * w * v);
                p += h * v;
            }
            p
        })
        .collect();
    (
        f,
        None,
        format!("w {w:.2}, zeta {zeta:.2}, kappa {kappa:.3}"),
    )
}

/// A smooth memoryless curve after the linear block: s tanh(x / s) (s = 0.5..1.5 std(x)) or x + k x^3
/// (k std(x)^2 = 0.1..0.5).
fn curve(d: &mut Draw, x: &[f64]) -> (Vec<f64>, Option<Truth>, String) {
    let sd = std_dev(x);
    if d.uniform(0.0, 1.0) < 0.5 {
        let s = d.uniform(0.5, 1.5) * sd;
        let f = x.iter().map(|v| s * (v / s).tanh()).collect();
        (f, None, format!("{s:.3} tanh(x / {s:.3})"))
    } else {
        let k = d.uniform(0.1, 0.5) / (sd * sd);
        let f = x.iter().map(|v| v + k * v.powi(3)).collect();
        (f, None, format!("x + {k:.3} x^3"))
    }
}

/// x plus an unmeasured input: random steps (held 20..200 samples) through a first-order block (pole
/// 0.8..0.98), scaled to 0.3..1 std(x).
fn second_input(d: &mut Draw, x: &[f64]) -> (Vec<f64>, Option<Truth>, String) {
    let raw = steps(d, x.len(), 20, 200);
    let pole = d.uniform(0.8, 0.98);
    let mut state = 0.0;
    let v: Vec<f64> = raw
        .iter()
        .map(|r| {
            state = pole * state + (1.0 - pole) * r;
            state
        })
        .collect();
    let scale = d.uniform(0.3, 1.0) * std_dev(x) / std_dev(&v).max(1e-12);
    let f = x.iter().zip(&v).map(|(a, b)| a + scale * b).collect();
    (
        f,
        None,
        format!("steps through pole {pole:.3}, {scale:.3} times"),
    )
}

/// The largest gain of the linear block over frequency (200 points).
fn peak_gain(arx: &ArxParams) -> f64 {
    (0..200)
        .map(|i| {
            let w = std::f64::consts::PI * f64::from(i) / 199.0;
            let (mut re, mut im) = (1.0, 0.0);
            for (j, a) in arx.a().iter().enumerate() {
                let ph = w * (j + 1) as f64;
                re += a * ph.cos();
                im -= a * ph.sin();
            }
            arx.b[0] / (re * re + im * im).sqrt()
        })
        .fold(0.0, f64::max)
}

/// Play in a loop: u = Kp (r - y), r random steps (held 10..60 samples), y the measured output (noise in
/// the loop); Kp so that Kp times the largest slope times the block's peak gain is 0.3..0.8 (stable by the
/// small-gain theorem). The noise std is std(noise-free loop output) / snr.
fn play_loop(d: &mut Draw, n: usize, snr: f64, seed: u64) -> (Sim, Vec<f64>) {
    let r = steps(d, n, 10, 60);
    let arx = linear_block(d);
    let bl0 = backlash_of(d, 0.0);
    let x0 = closed_loop(arx, bl0, 0.5 / peak_gain(&arx), &r, 0.0, seed).2;
    let share = d.uniform(0.01, 0.25);
    let bl = backlash_of(d, share * travel(&x0));
    let kp = d.uniform(0.3, 0.8) / (bl.m1.max(bl.m2) * peak_gain(&arx));
    let (_, f, _, _) = closed_loop(arx, bl, kp, &r, 0.0, seed);
    let (u, y, _, w) = closed_loop(arx, bl, kp, &r, std_dev(&f) / snr, seed);
    let truth = Truth {
        share,
        crossings: reversals(&w),
    };
    let what = format!(
        "a {:.3} {:.3}, b0 {:.3}, delay {}; play {:.1}% of the travel, Kp {kp:.3}",
        arx.a[0],
        arx.a[1],
        arx.b[0],
        arx.delay,
        100.0 * share
    );
    let sim = Sim {
        u,
        f,
        truth: Some(truth),
        what,
    };
    (sim, y)
}

/// The loop's input, measured output, linear block output and play output.
fn closed_loop(
    arx: ArxParams,
    bl: BacklashParams,
    kp: f64,
    r: &[f64],
    noise: f64,
    seed: u64,
) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) {
    let mut plant = Plant::new(PlantParams {
        arx,
        backlash: bl,
        noise_std: noise,
        noise_seed: seed,
    })
    .expect("the drawn plant is valid");
    let mut out = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for &rk in r {
        let o = plant.output();
        let u = kp * (rk - o.y);
        plant.advance(u);
        out.0.push(u);
        out.1.push(o.y);
        out.2.push(o.x);
        out.3.push(o.w);
    }
    out
}

/// Counts of one class at one noise level.
#[derive(Default)]
struct Cell {
    n: usize,
    present: usize,
    absent: usize,
    /// Play records whose gap counts (`Truth::counts`), and `present` among them.
    counted: usize,
    counted_present: usize,
    /// Play-free records whose reversals cross (the rule's fit-part count at least 20), and `absent` among them.
    crossing: usize,
    crossing_absent: usize,
}

impl Cell {
    fn add(&mut self, r: &Row) {
        self.n += 1;
        self.present += usize::from(r.presence == Presence::Present);
        self.absent += usize::from(r.presence == Presence::Absent && r.b.play_bound.is_some());
        match r.truth {
            Some(t) if t.counts() => {
                self.counted += 1;
                self.counted_present += usize::from(r.presence == Presence::Present);
            }
            Some(_) => {}
            None if r.b.reversals[0] >= MIN_CROSSINGS => {
                self.crossing += 1;
                self.crossing_absent += usize::from(r.presence == Presence::Absent);
            }
            None => {}
        }
    }
}

/// The confusion table in Markdown: per class and noise level, the three answers and the targets' counts.
fn table(rows: &[Row]) -> String {
    let mut s = String::from(
        "| class | SNR dB | records | present | absent (with bound) | undetermined | \
         play >= 2% crossed >= 20: present / records | play-free, reversals cross: absent / records |\n\
         | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n",
    );
    for class in CLASSES {
        for db in SNR_DB {
            let mut c = Cell::default();
            rows.iter()
                .filter(|r| r.class == class && r.snr_db == db)
                .for_each(|r| c.add(r));
            if c.n == 0 {
                continue;
            }
            let (play, free) = if class.has_play() {
                (
                    format!("{} / {}", c.counted_present, c.counted),
                    "-".to_string(),
                )
            } else {
                (
                    "-".to_string(),
                    format!("{} / {}", c.crossing_absent, c.crossing),
                )
            };
            s += &format!(
                "| {} | {db:.0} | {} | {} | {} | {} | {play} | {free} |\n",
                class.name(),
                c.n,
                c.present,
                c.absent,
                c.n - c.present - c.absent,
            );
        }
    }
    s
}

/// A CSV field, quoted.
fn field(s: &str) -> String {
    format!("\"{}\"", s.replace('"', "\"\""))
}

/// One line per record: the class, the truth, the answer and its evidence.
fn write_csv(path: &std::path::Path, rows: &[Row]) -> std::io::Result<()> {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(
        f,
        "class,snr_db,seed,true_share,true_crossings,presence,play,play_se,play_bound,reversals_fit,\
         reversals_heldout,travel,effects,undecided_by,reasons,record"
    )?;
    let opt = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x:.6}"));
    for r in rows {
        writeln!(
            f,
            "{},{},{},{},{},{:?},{:.6},{},{},{},{},{:.6},{},{},{},{}",
            r.class.name(),
            r.snr_db,
            r.seed,
            opt(r.truth.map(|t| t.share)),
            r.truth.map_or(String::new(), |t| t.crossings.to_string()),
            r.presence,
            r.b.play,
            opt(r.b.play_se),
            opt(r.b.play_bound),
            r.b.reversals[0],
            r.b.reversals[1],
            r.b.travel,
            field(&r.effects),
            field(&r.b.undecided_by.join("; ")),
            field(&r.b.reasons.join(" | ")),
            field(&r.what),
        )?;
    }
    f.flush()
}
