//! `backlash monitor`: the wear monitor of MrgiaEstimator.fmu on a data file, streamed.

use super::common::RecordArgs;
use super::identify::Decimated;
use super::structure::OrderArgs;
use anyhow::{Context, Result};
use backlash::api::{InputCheck, monitor_json};
use backlash::identify::mrgia::MrgiaConfig;
use backlash::identify::oe::online::monitor::{Alarm, MonitorConfig, Session, play_of};
use backlash::io::ReadAhead;
use backlash::report::plot::{Panel, Series, grid_plot};
use serde_json::json;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct MonitorArgs {
    /// Data file: CSV with columns time,u,y (any order; other columns ignored).
    pub file: PathBuf,
    #[command(flatten)]
    pub orders: OrderArgs,
    /// Relative growth of the play c1 + c2 to detect (0.1: 10%).
    #[arg(long, default_value_t = 0.1)]
    pub wear_ratio: f64,
    /// Mean number of samples between false alarms on an unchanged plant.
    #[arg(long, default_value_t = 1e6)]
    pub alarm_period: f64,
    /// Samples of the refined estimator (after its warm-up of 500) before the reference model is frozen.
    #[arg(long, default_value_t = 2000)]
    pub learn: u64,
    /// The reference play c1 + c2 when known (default: learned).
    #[arg(long)]
    pub reference_play: Option<f64>,
    /// The estimator's warm-up with the project's recommended MRGIA setting instead of the paper's.
    #[arg(long)]
    pub recommended: bool,
    #[command(flatten)]
    pub record: RecordArgs,
    /// Print one JSON object on stdout and nothing else there.
    #[arg(long)]
    pub json: bool,
    /// Write a PNG of the play with its 95% band and the statistic against time, with the alarms.
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

/// Plotted per sample: time, play, play - 1.96 se, play + 1.96 se, statistic / threshold, the monitor's
/// reference play. All but the time are NaN (not drawn) before the reference is frozen: the warm-up's swings
/// of the estimate would set the axes and squash the monitored part.
const PLOTTED: usize = 6;

fn plotted(t: f64, s: &Session) -> [f64; PLOTTED] {
    let Some((reference, _)) = s.monitor().reference() else {
        return [t, f64::NAN, f64::NAN, f64::NAN, f64::NAN, f64::NAN];
    };
    let (p, se) = play_of(s.estimator());
    let stat = s.monitor().statistic();
    [t, p, p - 1.96 * se, p + 1.96 * se, stat, reference]
}

pub fn run(args: &MonitorArgs) -> Result<()> {
    let cfg = MonitorConfig {
        wear_ratio: args.wear_ratio,
        alarm_period: args.alarm_period,
        learn: args.learn,
        reference_play: args.reference_play,
        follow: true,
    };
    let (na, nb, d) = (args.orders.na, args.orders.nb, args.orders.delay);
    let est = if args.recommended {
        MrgiaConfig::recommended(na, nb, d)
    } else {
        MrgiaConfig::paper(na, nb, d)
    };
    let mut session = Session::new(est, cfg).context("invalid monitor setting")?;
    let options = args.record.options();
    let (rows, cols) = options.open(&args.file, true)?;
    let mut block = options.block(3);
    let mut plot = args.plot.as_ref().map(|_| Decimated::new(PLOTTED));
    let (mut k, mut last_t) = (0u64, f64::NAN);
    let mut check = InputCheck::default();
    let mut rows = ReadAhead::spawn(rows);
    while let Some(batch) = rows.next_batch()? {
        for row in batch.values.chunks_exact(3) {
            let Some(&[t, u, y]) = block.push(row) else {
                continue;
            };
            check.push(u);
            if let Some(a) = session.push(t, u, y)
                && !args.json
            {
                print_alarm(&a);
            }
            if let Some(p) = &mut plot
                && p.wants(k)
            {
                p.push(k, &plotted(t, &session));
            }
            last_t = t;
            k += 1;
        }
        rows.recycle(batch);
    }
    if let (Some(path), Some(mut p)) = (&args.plot, plot)
        && k > 0
    {
        p.finish(k - 1, &plotted(last_t, &session));
        draw(path, args, &cols.names[0], &p, &session)?;
    }
    let mut out = monitor_json(&session, &check)?;
    out["file"] = json!(args.file.display().to_string());
    out["decimate"] = json!(args.record.decimate());
    if args.json {
        println!("{out}");
    } else {
        print_summary(&session, &args.file);
        for w in out["warnings"].as_array().into_iter().flatten() {
            println!("  warning: {}", w.as_str().unwrap_or_default());
        }
    }
    Ok(())
}

fn print_alarm(a: &Alarm) {
    println!(
        "alarm at time {} (sample {}): the change began about {} (sample {}); play {:.4} +/- {:.4} -> {:.4} +/- {:.4}",
        a.time,
        a.sample,
        a.onset,
        a.onset_sample,
        a.play_before,
        a.play_before_se,
        a.play_after,
        a.play_after_se
    );
}

fn print_summary(s: &Session, file: &std::path::Path) {
    let sum = s.summary();
    println!(
        "wear monitor on {}: {} samples, {} alarm(s); play {:.4} +/- {:.4}",
        file.display(),
        sum.samples,
        sum.alarms.len(),
        sum.play,
        sum.play_se
    );
    match (sum.reference_play, sum.reference_play_se) {
        (Some(p), Some(se)) => println!("  reference play {p:.4} +/- {se:.4}"),
        _ => println!("  no reference yet: the record ended during the warm-up or the learning"),
    }
}

/// Two panels against the file's time: the play with its band (alarms marked), and the statistic.
fn draw(
    path: &std::path::Path,
    args: &MonitorArgs,
    time_label: &str,
    p: &Decimated,
    s: &Session,
) -> Result<()> {
    let t = p.series(0);
    let against_time = |i: usize| -> Vec<(f64, f64)> {
        t.iter()
            .zip(p.series(i))
            .map(|(a, b)| (a.1, b.1))
            .filter(|v| v.1.is_finite())
            .collect()
    };
    let monitored = against_time(PLOTTED - 1);
    let summary = s.summary();
    let alarms: Vec<(f64, f64)> = summary
        .alarms
        .iter()
        .map(|a| (a.time, a.play_after))
        .collect();
    let onsets: Vec<(f64, f64)> = summary
        .alarms
        .iter()
        .map(|a| (a.onset, a.play_before))
        .collect();
    let span = (
        monitored.first().map_or(0.0, |v| v.0),
        t.last().map_or(1.0, |v| v.1),
    );
    let play = Panel {
        title: "estimated play c1 + c2, 95% band (from the reference on)",
        x_label: time_label,
        y_label: "play c1 + c2",
        series: vec![
            Series::line("estimated play", against_time(1)),
            Series::dashed("95% band", against_time(2)).color(1),
            Series::dashed("", against_time(3)).color(1),
            Series::line("reference play of the test", monitored).color(4),
            Series::points("alarm (play after)", alarms).color(3),
            Series::points("onset (play before)", onsets).color(2),
        ],
        log_x: false,
        log_y: false,
    };
    let stat = Panel {
        title: "largest CUSUM statistic / its threshold (alarm at 1)",
        x_label: time_label,
        y_label: "statistic / threshold",
        series: vec![
            Series::line("statistic", against_time(4)),
            Series::dashed("threshold", vec![(span.0, 1.0), (span.1, 1.0)]).color(3),
        ],
        log_x: false,
        log_y: false,
    };
    let title = format!("wear monitor, {}", args.file.display());
    grid_plot(path, &title, &[play, stat], 1)?;
    Ok(())
}
