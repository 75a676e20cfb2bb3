//! The wear monitor's study: false-alarm run lengths, detection delays against the threshold rule and the
//! Kullback-Leibler bound, and alarms on changes that are not wear. Prints the Markdown tables of
//! docs/RESULTS.md ("Wear monitoring").
//!
//! ```sh
//! cargo run --release --example monitor_study -- [--threads 2] [--runs 40] [--alarms 100]
//!     [--per-record 20] [--max-periods 1000] [--max-period 1e5]
//! ```
//!
//! All runs of a table go to `--threads` worker threads of this one process (a shared job counter). A
//! false-alarm cell runs records of `--per-record` periods (a new seed each; the test restarts on the same
//! reference after each alarm) until `--alarms` alarms or `--max-periods` periods: with 100 alarms the 95%
//! interval of the mean run length is about +/-20%.

use backlash::identify::oe::online::monitor::MonitorConfig;
use backlash::identify::oe::online::monitor::study::{
    Change, Detection, Run, arl_interval, arrival_delays, detect, drift_delay_bound, false_alarms,
    kl_per_sample, noise_std, rule_crossings, rule_delay, step_delay_bound,
};
use backlash::identify::oe::plant_variant;
use backlash::plant::PlantParams;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Forgetting of the threshold rule's estimator (memory about 500 samples).
const RULE_RHO_MIN: f64 = 0.002;
/// Samples after the reference at which a change comes in the delay runs.
const AFTER: u64 = 2000;

fn parallel<T: Send>(threads: usize, jobs: usize, f: impl Fn(usize) -> T + Sync) -> Vec<T> {
    let next = AtomicUsize::new(0);
    let out: Mutex<Vec<Option<T>>> = Mutex::new((0..jobs).map(|_| None).collect());
    std::thread::scope(|s| {
        for _ in 0..threads {
            s.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    if i >= jobs {
                        break;
                    }
                    let r = f(i);
                    out.lock().unwrap()[i] = Some(r);
                }
            });
        }
    });
    out.into_inner()
        .unwrap()
        .into_iter()
        .map(|r| r.expect("every job ran"))
        .collect()
}

fn plant(name: &str) -> PlantParams {
    plant_variant(name).expect("a study plant").params
}

fn cfg(period: f64) -> MonitorConfig {
    MonitorConfig {
        alarm_period: period,
        ..MonitorConfig::default()
    }
}

/// How long the false-alarm cells run: records of `per_record` periods each (a new seed per record) until
/// `alarms` alarms or `max_periods` periods in all.
struct FalseAlarmRuns {
    per_record: f64,
    alarms: u64,
    max_periods: f64,
    max_period: f64,
}

/// One cell of table 1: records until enough alarms (the stopping rule of [`FalseAlarmRuns`]); (samples
/// tested, alarms, records).
fn false_alarm_cell(
    plant: PlantParams,
    sigma: f64,
    period: f64,
    runs: &FalseAlarmRuns,
) -> (u64, u64, u64) {
    let n = (runs.per_record * period) as u64;
    let cap = (runs.max_periods * period) as u64;
    let (mut samples, mut alarms, mut records) = (0, 0, 0);
    while alarms < runs.alarms && samples < cap {
        let (s, a) = false_alarms(plant, sigma, 1000 + records, cfg(period), n);
        samples += s;
        alarms += a;
        records += 1;
    }
    (samples, alarms, records)
}

/// Table 1: mean run length to a false alarm, per (plant, SNR, period); the cells go to the worker threads.
fn false_alarm_table(threads: usize, runs: &FalseAlarmRuns) -> Vec<(String, f64, f64, f64, f64)> {
    let plants = ["paper", "wide-gaps", "reversed-slopes"];
    let snrs = [20.0, 43.0];
    let periods: Vec<f64> = [1e3, 1e4, 1e5]
        .into_iter()
        .filter(|p| *p <= runs.max_period)
        .collect();
    let mut cells = Vec::new();
    for p in plants {
        for snr in snrs {
            for &period in &periods {
                cells.push((p, snr, period));
            }
        }
    }
    // The longest cells first, so that the threads finish together.
    let mut order: Vec<usize> = (0..cells.len()).collect();
    order.sort_by(|a, b| cells[*b].2.total_cmp(&cells[*a].2));
    let got = parallel(threads, cells.len(), |i| {
        let (p, snr, period) = cells[order[i]];
        let pl = plant(p);
        false_alarm_cell(pl, noise_std(pl, snr), period, runs)
    });
    let mut by_cell = vec![(0, 0, 0); cells.len()];
    for (i, g) in got.into_iter().enumerate() {
        by_cell[order[i]] = g;
    }
    cells
        .iter()
        .zip(by_cell)
        .map(|(&(p, snr, period), (s, a, records))| {
            let (arl, lo, hi) = arl_interval(s, a);
            println!(
                "| {p} | {snr} | {period:.0e} | {records} | {s} | {a} | {arl:.0} | {lo:.0} - {hi:.0} | {:.2} |",
                arl / period
            );
            (p.to_string(), snr, period, arl, a as f64)
        })
        .collect()
}

struct Delays {
    ours: Vec<u64>,
    early: usize,
    missed: usize,
    onset_err: Vec<f64>,
}

/// The play changes of the delay table: label, ratio (a step) or rate per sample (a drift), drift.
const PLAY_CHANGES: [(&str, f64, bool); 4] = [
    ("+10% step", 0.10, false),
    ("+25% step", 0.25, false),
    ("+50% step", 0.50, false),
    ("drift +10% per 1000 samples", 1e-4, true),
];

/// The play change of [`PLAY_CHANGES`] with `ratio` and `drift`, beginning at sample `at`.
fn play_change(ratio: f64, drift: bool, at: u64) -> Change {
    if drift {
        Change::PlayDrift { at, rate: ratio }
    } else {
        Change::PlayStep { at, ratio }
    }
}

/// The delay bound with the offset and the gain unknown, from the test's efficient information per sample
/// `info` at the change (one per run; module docs of the monitor).
fn efficient_bound(info: &[f64], sigma: f64, ratio: f64, drift: bool, period: f64) -> f64 {
    let unit = info.iter().sum::<f64>() / info.len().max(1) as f64 / (2.0 * sigma * sigma);
    if drift {
        drift_delay_bound(unit * 0.01, 0.1, ratio, period)
    } else {
        step_delay_bound(unit * ratio * ratio, period)
    }
}

/// The monitor on each job's record: (change of [`PLAY_CHANGES`], run) -> its detection.
fn monitor_runs(
    threads: usize,
    (pl, sigma): (PlantParams, f64),
    period: f64,
    jobs: &[(usize, u64)],
    horizon: u64,
) -> Vec<Detection> {
    parallel(threads, jobs.len(), |i| {
        let (c, r) = jobs[i];
        let (_, ratio, drift) = PLAY_CHANGES[c];
        let change = move |at| play_change(ratio, drift, at);
        detect(pl, sigma, 2000 + r, cfg(period), AFTER, horizon, change)
    })
}

/// The runs of a delay table: (change, run) of each job, the monitor's detection, the threshold rule's
/// delay and the arrival delays (offset and gain known, may change) on the same record.
struct DelayRuns<'a> {
    jobs: &'a [(usize, u64)],
    got: &'a [Detection],
    rule: &'a [Option<u64>],
    arrival: &'a [(Option<u64>, Option<u64>)],
}

/// One run of a delay table: (change, run), the monitor's detection, the rule's delay, the arrival delays.
type RunOf<'a> = (
    &'a (usize, u64),
    &'a Detection,
    &'a Option<u64>,
    &'a (Option<u64>, Option<u64>),
);

/// The monitor's delays, the rule's delays and misses, the arrival delays (known, efficient) of one change.
type ChangeDelays = (Delays, Vec<u64>, usize, Vec<u64>, Vec<u64>);

impl DelayRuns<'_> {
    /// The runs of change `c`.
    fn of(&self, c: usize) -> impl Iterator<Item = RunOf<'_>> {
        self.jobs
            .iter()
            .zip(self.got)
            .zip(self.rule)
            .zip(self.arrival)
            .map(|(((j, g), r), a)| (j, g, r, a))
            .filter(move |(j, ..)| j.0 == c)
    }

    /// The delays of change `c`, collected over its runs.
    fn of_change(&self, c: usize) -> ChangeDelays {
        let mut d = Delays {
            ours: vec![],
            early: 0,
            missed: 0,
            onset_err: vec![],
        };
        let (mut rd, mut rule_missed) = (vec![], 0);
        let (mut known, mut efficient) = (vec![], vec![]);
        for (_, g, r, a) in self.of(c) {
            known.extend(a.0);
            efficient.extend(a.1);
            d.early += usize::from(g.early);
            match (g.delay, &g.alarm) {
                (Some(x), Some(a)) if !g.early => {
                    d.ours.push(x);
                    d.onset_err.push(a.onset_sample as f64 - g.at as f64);
                }
                (None, _) => d.missed += 1,
                _ => {}
            }
            match r {
                Some(x) => rd.push(*x),
                None => rule_missed += 1,
            }
        }
        (d, rd, rule_missed, known, efficient)
    }
}

fn mean(v: &[u64]) -> f64 {
    v.iter().sum::<u64>() as f64 / v.len().max(1) as f64
}

/// The threshold rule's tau on the play of `pl`: the smallest whose up-crossings on unchanged records (8
/// records, 100 times `arl` in all, the reference at `freeze`) come no more often than once per `arl`.
fn rule_tau(threads: usize, pl: PlantParams, sigma: f64, freeze: u64, arl: f64) -> f64 {
    let play = pl.backlash.c1 + pl.backlash.c2;
    let taus: Vec<f64> = (1..=400).map(|j| j as f64 * 0.0025 * play).collect();
    let tune_runs = 8u64;
    let tune_len = ((arl * 100.0) / tune_runs as f64) as u64;
    let counts = parallel(threads, tune_runs as usize, |r| {
        rule_crossings(
            pl,
            sigma,
            3000 + r as u64,
            RULE_RHO_MIN,
            freeze,
            tune_len,
            &taus,
        )
    });
    let total = tune_len * tune_runs;
    taus.iter()
        .enumerate()
        .find(|(j, _)| {
            let n: u64 = counts.iter().map(|c| c[*j]).sum();
            n == 0 || total as f64 / n as f64 >= arl
        })
        .map_or(f64::INFINITY, |(_, t)| *t)
}

/// Table 2: detection delays on `name` at `snr`, period `period`, `runs` runs per change.
fn delay_table(threads: usize, name: &str, snr: f64, period: f64, runs: u64, arl: f64) {
    let pl = plant(name);
    let sigma = noise_std(pl, snr);
    let changes = PLAY_CHANGES;
    let make = |ratio: f64, drift: bool| move |at: u64| play_change(ratio, drift, at);
    let horizon = 20 * AFTER;
    // Our monitor.
    let jobs: Vec<(usize, u64)> = (0..changes.len())
        .flat_map(|c| (0..runs).map(move |r| (c, r)))
        .collect();
    let got = monitor_runs(threads, (pl, sigma), period, &jobs, horizon);
    let freeze = got[0].at - AFTER;
    // Run i's record: its seed, its change and the change's sample.
    let record = |i: usize| {
        let (c, r) = jobs[i];
        let (_, ratio, drift) = changes[c];
        let at = got[i].at;
        (2000 + r, make(ratio, drift)(at), at)
    };
    // The information as it arrives on each run's record (known; offset and gain may change with the play).
    let arrival = parallel(threads, jobs.len(), |i| {
        let (seed, change, at) = record(i);
        arrival_delays(pl, sigma, seed, change, at, (period, horizon))
    });
    let tau = rule_tau(threads, pl, sigma, freeze, arl);
    let rule = parallel(threads, jobs.len(), |i| {
        let (seed, change, at) = record(i);
        rule_delay(
            pl,
            sigma,
            seed,
            RULE_RHO_MIN,
            freeze,
            tau,
            change,
            at,
            horizon,
        )
    });
    let runs = DelayRuns {
        jobs: &jobs,
        got: &got,
        rule: &rule,
        arrival: &arrival,
    };
    let kl10 = kl_per_sample(pl, 0.1, sigma, 20_000);
    for (c, (label, ratio, drift)) in changes.iter().enumerate() {
        let (d, rd, rule_missed, known, efficient) = runs.of_change(c);
        let bound = if *drift {
            drift_delay_bound(kl10, 0.1, *ratio, period)
        } else {
            step_delay_bound(kl_per_sample(pl, *ratio, sigma, 20_000), period)
        };
        let info: Vec<f64> = runs.of(c).filter_map(|(_, g, ..)| g.information).collect();
        let eff = efficient_bound(&info, sigma, *ratio, *drift, period);
        let onset =
            d.onset_err.iter().map(|e| e.abs()).sum::<f64>() / d.onset_err.len().max(1) as f64;
        println!(
            "| {name} | {snr} | {label} | {:.0} | {:.1} | {:.2} | {:.1} | {:.2} | {:.1} | {:.1} | {:.2} | {:.0} ({rule_missed} missed) | {} | {} | {onset:.0} |",
            mean(&d.ours),
            bound,
            mean(&d.ours) / bound,
            eff,
            mean(&d.ours) / eff,
            mean(&known),
            mean(&efficient),
            mean(&d.ours) / mean(&efficient),
            mean(&rd),
            d.early,
            d.missed,
        );
    }
    println!(
        "(threshold rule: tau = {tau:.4} on the play, rho_min = {RULE_RHO_MIN}; reference frozen at sample {freeze})"
    );
}

/// The alarms on one record (seed `seed`) within `span` samples after `change` (its time set to AFTER
/// samples after the reference; the test restarts on the same reference after each alarm).
fn not_wear_alarms(
    (pl, sigma): (PlantParams, f64),
    seed: u64,
    change: Change,
    period: f64,
    span: u64,
) -> u64 {
    let cfg = MonitorConfig {
        follow: false,
        ..cfg(period)
    };
    let mut run = Run::new(pl, sigma, seed, Change::None, cfg);
    run.learn(100_000);
    let at = run.k + AFTER;
    let change = match change {
        Change::InputAmplitude { factor, .. } => Change::InputAmplitude { at, factor },
        Change::LinearGain { factor, .. } => Change::LinearGain { at, factor },
        Change::OutputOffset { offset, .. } => Change::OutputOffset { at, offset },
        other => other,
    };
    let mut run = Run::new(pl, sigma, seed, change, cfg);
    let mut alarms = 0u64;
    while run.k < at + span {
        let a = run.step();
        if run.k > at {
            alarms += u64::from(a.is_some());
        }
    }
    alarms
}

/// Table 3: alarms after changes that are not wear (the test restarts on the same reference after each).
fn not_wear_table(threads: usize, name: &str, snr: f64, period: f64, runs: u64) {
    let pl = plant(name);
    let sigma = noise_std(pl, snr);
    let span = (10.0 * period) as u64;
    let changes = [
        (
            "input amplitude x2",
            Change::InputAmplitude { at: 0, factor: 2.0 },
        ),
        (
            "input amplitude x0.5",
            Change::InputAmplitude { at: 0, factor: 0.5 },
        ),
        (
            "linear gain +10%",
            Change::LinearGain { at: 0, factor: 1.1 },
        ),
        (
            "linear gain -10%",
            Change::LinearGain { at: 0, factor: 0.9 },
        ),
        (
            "output offset +5 sigma",
            Change::OutputOffset {
                at: 0,
                offset: 5.0 * sigma,
            },
        ),
        ("none", Change::None),
    ];
    let jobs: Vec<(usize, u64)> = (0..changes.len())
        .flat_map(|c| (0..runs).map(move |r| (c, r)))
        .collect();
    let got = parallel(threads, jobs.len(), |i| {
        let (c, r) = jobs[i];
        not_wear_alarms((pl, sigma), 4000 + r, changes[c].1, period, span)
    });
    for (c, (label, _)) in changes.iter().enumerate() {
        let a: u64 = jobs
            .iter()
            .zip(&got)
            .filter(|(j, _)| j.0 == c)
            .map(|(_, g)| g)
            .sum();
        let (arl, lo, hi) = arl_interval(span * runs, a);
        println!(
            "| {label} | {a} | {arl:.0} | {lo:.0} - {hi:.0} | {:.2} |",
            arl / period
        );
    }
}

/// The README's example record: the paper plant at SNR 20, 8000 samples, the gaps 50% wider from sample 5000.
fn write_record(path: &str) {
    use backlash::identify::oe::online::monitor::study::Scenario;
    use std::io::Write;
    let pl = plant("paper");
    let change = Change::PlayStep {
        at: 5000,
        ratio: 0.5,
    };
    let mut sc = Scenario::new(pl, noise_std(pl, 20.0), 1, change);
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).expect("writable record"));
    writeln!(f, "time,u,y").unwrap();
    for k in 0..8000 {
        let (u, y) = sc.next_sample();
        writeln!(f, "{k},{u:?},{y:?}").unwrap();
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let get = |name: &str, default: f64| -> f64 {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .map_or(default, |v| v.parse().expect("a number"))
    };
    if let Some(i) = args.iter().position(|a| a == "--record") {
        write_record(&args[i + 1]);
        return;
    }
    let threads = get("--threads", 2.0) as usize;
    let runs = get("--runs", 40.0) as u64;
    let runs_fa = FalseAlarmRuns {
        per_record: get("--per-record", 20.0),
        alarms: get("--alarms", 100.0) as u64,
        max_periods: get("--max-periods", 1000.0),
        max_period: get("--max-period", 1e5),
    };
    println!("## False alarms\n");
    println!(
        "| plant | SNR | alarm_period | records | samples tested | alarms | mean run length | 95% interval | ratio to setting |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- | --- | --- |");
    let fa = false_alarm_table(threads, &runs_fa);
    println!("\n## Detection delay (alarm_period 1e4)\n");
    println!(
        "| plant | SNR | change | monitor delay | bound, offset and gain known | monitor / bound | bound, offset and gain unknown | monitor / bound | arrival, offset and gain known | arrival, offset and gain may change | monitor / arrival | threshold rule delay | early alarms | missed | mean abs onset error |"
    );
    println!(
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    );
    for snr in [20.0, 43.0] {
        let arl = fa
            .iter()
            .find(|r| r.0 == "paper" && r.1 == snr && r.2 == 1e4)
            .map_or(1e4, |r| r.3.min(1e6));
        delay_table(threads, "paper", snr, 1e4, runs, arl);
    }
    println!(
        "\n## Changes that are not wear (paper plant, SNR 20, alarm_period 1e4, 10 periods after the change)\n"
    );
    println!("| change | alarms | mean run length | 95% interval | ratio to setting |");
    println!("| --- | --- | --- | --- | --- |");
    not_wear_table(threads, "paper", 20.0, 1e4, runs.min(20));
}
