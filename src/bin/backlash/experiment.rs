//! `backlash experiment`: sine experiments on a simulated plant (continuous block + polynomial-border
//! backlash) at several frequencies, identified by paper 003's estimators and plotted against the truth.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use serde::Serialize;
use serde_json::{Value, json};

use backlash::identify::frequency::analysis::BodePoint;
use backlash::identify::frequency::experiment::{
    ExperimentPlant, Matched, ModelView, SineDesign, SineRow, SteppedDesign, SteppedResult,
    SteppedRow, bode_curve, design_degree, run_sines, run_stepped,
};
use backlash::io::write_atomic;

use super::frequency::{
    CONVENTION, Curve, TrueBorders, bode_plots, border_panels, create_dir, emit, steps_plot,
    write_bode_csv, write_record,
};

/// Simulate a Wiener plant (continuous G(s) + polynomial-border backlash) under sine inputs, identify
/// each experiment (paper 003) and plot the estimates against the truth.
#[derive(clap::Args, Debug, Clone)]
pub struct ExperimentArgs {
    /// Frequencies, rad/s, comma-separated
    #[arg(long, value_delimiter = ',', default_value = "0.2,0.5,1,2")]
    pub omegas: Vec<f64>,
    /// JSON file with any of: num, den (descending powers of s), fa, fd (lowest power first), amplitude,
    /// noise_std, seed; flags override it
    #[arg(long)]
    pub plant: Option<PathBuf>,
    /// Numerator of G(s), descending powers [default: 1]
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub num: Option<Vec<f64>>,
    /// Denominator of G(s), descending powers, stable, degree at most 4 [default: 1,0.6,1]
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub den: Option<Vec<f64>>,
    /// Ascending border a0,a1,.. (degree at most 3) [default: -0.25,0.9,0.1,0.05]
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub fa: Option<Vec<f64>>,
    /// Descending border d0,d1,.. (degree at most 3) [default: 0.3,0.85,0.1,0.05]
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub fd: Option<Vec<f64>>,
    /// Sine amplitude U [default: 3]
    #[arg(long)]
    pub amplitude: Option<f64>,
    /// Degree used by the estimator [default: the borders' degree; with --stepped, chosen by the data]
    #[arg(long)]
    pub degree: Option<usize>,
    /// Standard deviation of the white output noise [default: 0.01]
    #[arg(long)]
    pub noise_std: Option<f64>,
    /// Noise seed [default: 1]
    #[arg(long)]
    pub seed: Option<u64>,
    /// Steady periods recorded per frequency (with --stepped: held periods per step)
    #[arg(long, default_value_t = 40)]
    pub periods: usize,
    /// Samples per period (Ts = 2 pi / (omega * this)); not with --stepped
    #[arg(long, default_value_t = 200)]
    pub samples_per_period: usize,
    /// Extra periods at the start for the transient [default: enough for e^-25 decay of the slowest pole]
    #[arg(long)]
    pub transient_periods: Option<usize>,
    /// One stepped-sine record through all the frequencies (ramped in and out), identified by
    /// `identify stepped-sine`, against single-frequency records of the same length
    #[arg(long)]
    pub stepped: bool,
    /// With --stepped: the common sample period, s
    #[arg(long, default_value_t = 0.02)]
    pub ts: f64,
    /// With --stepped: periods of each ramp in and out
    #[arg(long, default_value_t = 2)]
    pub ramp_periods: usize,
    /// With --stepped: rest between steps, s
    #[arg(long, default_value_t = 5.0)]
    pub pause: f64,
    /// Output folder (created): frequency.json, bode_magnitude.png, bode_phase.png, borders.png, records
    #[arg(long, default_value = "frequency-experiment")]
    pub out: PathBuf,
    /// Print the result table as one JSON object on stdout and nothing else
    #[arg(long)]
    pub json: bool,
}

/// The experiment's plant: the defaults, under the `--plant` file's values (the same keys, each optional),
/// under the flags.
fn resolve(args: &ExperimentArgs) -> Result<ExperimentPlant> {
    let mut plant = serde_json::to_value(ExperimentPlant::default())?;
    if let Some(p) = &args.plant {
        let text =
            std::fs::read_to_string(p).with_context(|| format!("{}: cannot read", p.display()))?;
        let file: Value = serde_json::from_str(&text)
            .with_context(|| format!("{}: not a valid plant description", p.display()))?;
        overlay(&mut plant, file)
            .with_context(|| format!("{}: not a valid plant description", p.display()))?;
    }
    let flags = json!({"num": args.num, "den": args.den, "fa": args.fa, "fd": args.fd,
        "amplitude": args.amplitude, "noise_std": args.noise_std, "seed": args.seed});
    overlay(&mut plant, flags)?;
    Ok(serde_json::from_value(plant)?)
}

/// The keys of the object `over` set (null: unset) replace those of `base`; a key `base` lacks is refused.
fn overlay(base: &mut Value, over: Value) -> Result<()> {
    let Value::Object(over) = over else {
        bail!("a JSON object is expected");
    };
    for (k, v) in over {
        let Some(slot) = base.get_mut(&k) else {
            let keys: Vec<&String> = base
                .as_object()
                .into_iter()
                .flat_map(|o| o.keys())
                .collect();
            bail!("unknown key {k}: the keys are {keys:?}");
        };
        if !v.is_null() {
            *slot = v;
        }
    }
    Ok(())
}

#[derive(Serialize)]
struct ExperimentJson<'a> {
    method: &'static str,
    plant: &'a ExperimentPlant,
    degree: usize,
    periods: usize,
    samples_per_period: usize,
    convention: &'static str,
    truth_note: &'static str,
    rows: Vec<RowJson<'a>>,
    plots: Vec<String>,
}

#[derive(Serialize)]
struct RowJson<'a> {
    #[serde(flatten)]
    row: &'a SineRow,
    data: String,
}

const TRUTH_NOTE: &str = "truth = the zero-order-hold frequency response of the sampled block (what the samples \
     carry); gain_continuous/phase_continuous = G(jw) for reference";

/// `backlash experiment ...`: simulate, identify at every frequency, plot, write the table.
pub fn run_experiment(args: &ExperimentArgs) -> Result<()> {
    let plant = resolve(args)?;
    if args.stepped {
        return run_stepped_experiment(args, &plant);
    }
    let design = SineDesign {
        omegas: args.omegas.clone(),
        degree: args.degree,
        periods: args.periods,
        samples_per_period: args.samples_per_period,
        transient_periods: args.transient_periods,
    };
    let rows = run_sines(&plant, &design)?;
    let degree = design_degree(&plant, args.degree)?;
    create_dir(&args.out)?;
    let mut data = Vec::new();
    for r in &rows {
        let path = args.out.join(format!("sine_w{}.csv", r.omega));
        write_record(&path, &r.record)?;
        data.push(path.display().to_string());
    }
    let points = matched_points(&rows, plant.amplitude, |r| r.matched.as_ref());
    let truths = true_borders(&rows, &plant, |r| r.matched.is_some());
    let curve = truth_curve(args, &plant, degree)?;
    let mut plots = bode_plots(
        &args.out,
        Some(&curve),
        &[("estimated (paper 003)", &points)],
    )?;
    plots.extend(border_panels(&args.out, &points, Some(&truths))?);
    let out = ExperimentJson {
        method: "frequency-experiment",
        plant: &plant,
        degree,
        periods: args.periods,
        samples_per_period: args.samples_per_period,
        convention: CONVENTION,
        truth_note: TRUTH_NOTE,
        rows: rows
            .iter()
            .zip(data)
            .map(|(row, data)| RowJson { row, data })
            .collect(),
        plots,
    };
    let table = write_table(&args.out, &out)?;
    answer(args.json, &out, || summary(&out, &table))
}

/// The estimated Bode points of the rows that `pick` finds matched, as the true model's member.
fn matched_points<R>(
    rows: &[R],
    amplitude: f64,
    pick: impl Fn(&R) -> Option<&Matched>,
) -> Vec<BodePoint>
where
    R: HasOmega,
{
    rows.iter()
        .filter_map(|r| pick(r).map(|m| point(r.omega(), &m.as_model, amplitude)))
        .collect()
}

/// The true borders of the rows `keep` keeps, with the x range their data excite.
fn true_borders<R: HasOmega>(
    rows: &[R],
    plant: &ExperimentPlant,
    keep: impl Fn(&R) -> bool,
) -> Vec<TrueBorders> {
    rows.iter()
        .filter(|r| keep(r))
        .map(|r| {
            let t = r.truth();
            (t.fa.clone(), t.fd.clone(), plant.amplitude * t.gain)
        })
        .collect()
}

/// What the rows of both kinds of experiment share.
trait HasOmega {
    fn omega(&self) -> f64;
    fn truth(&self) -> &ModelView;
}

impl HasOmega for SineRow {
    fn omega(&self) -> f64 {
        self.omega
    }
    fn truth(&self) -> &ModelView {
        &self.truth
    }
}

impl HasOmega for SteppedRow {
    fn omega(&self) -> f64 {
        self.omega
    }
    fn truth(&self) -> &ModelView {
        &self.truth
    }
}

/// The true Bode curve over the experiment's frequencies (an octave beyond each end).
fn truth_curve(args: &ExperimentArgs, plant: &ExperimentPlant, degree: usize) -> Result<Curve> {
    let (lo, hi) = span(&args.omegas);
    Ok(bode_curve(plant, degree, lo, hi, 300)?)
}

/// frequency.json in the output folder: the whole answer, pretty-printed; its path.
fn write_table(dir: &Path, out: &impl Serialize) -> Result<PathBuf> {
    let json = serde_json::to_string_pretty(out)?;
    let path = dir.join("frequency.json");
    write_atomic(&path, |f| writeln!(f, "{json}"))
        .with_context(|| format!("{}: cannot write", path.display()))?;
    Ok(path)
}

/// The answer on standard output: one JSON object, or the text `describe` makes.
fn answer(json: bool, out: &impl Serialize, describe: impl FnOnce() -> String) -> Result<()> {
    if json {
        emit(&format!("{}\n", serde_json::to_string(out)?))
    } else {
        emit(&describe())
    }
}

fn span(omegas: &[f64]) -> (f64, f64) {
    let lo = omegas.iter().copied().fold(f64::INFINITY, f64::min) / 2.0;
    let hi = omegas.iter().copied().fold(0.0, f64::max) * 2.0;
    (lo, hi)
}

fn point(omega: f64, m: &ModelView, amplitude: f64) -> BodePoint {
    BodePoint {
        omega,
        gain: m.gain,
        phase: m.phase,
        member: "model".to_string(),
        fa: m.fa.clone(),
        fd: m.fd.clone(),
        explained: true,
        amplitude,
    }
}

fn summary(out: &ExperimentJson, table: &Path) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "paper 003 frequency experiment: G(s) = [{}]/[{}], f_a = {:?}, f_d = {:?}, U = {}, noise std {}",
        join(&out.plant.num),
        join(&out.plant.den),
        out.plant.fa,
        out.plant.fd,
        out.plant.amplitude,
        out.plant.noise_std
    );
    let _ = writeln!(
        s,
        "{:>8} {:>5} {:>6} {:>10} {:>10} {:>10} {:>10} {:>9} {:>9} {:>8}",
        "omega", "path", "as", "phase", "true", "gain", "true", "max|dfa|", "max|dfd|", "periods"
    );
    for r in out.rows.iter().map(|r| r.row) {
        match (&r.estimate, &r.matched) {
            (Some(e), Some(m)) => {
                let _ = writeln!(
                    s,
                    "{:>8.4} {:>5} {:>6} {:>10.5} {:>10.5} {:>10.5} {:>10.5} {:>9.2e} {:>9.2e} {:>8}",
                    r.omega,
                    format!("{:?}", e.path).to_lowercase(),
                    m.reported,
                    m.as_model.phase,
                    r.truth.phase,
                    m.as_model.gain,
                    r.truth.gain,
                    m.errors.fa,
                    m.errors.fd,
                    e.periods_used
                );
            }
            _ => {
                let _ = writeln!(
                    s,
                    "{:>8.4} failed: {}",
                    r.omega,
                    r.error.as_deref().unwrap_or("?")
                );
            }
        }
    }
    let _ = writeln!(
        s,
        "(phases and gains in the true model's convention; truth = ZOH-sampled response)"
    );
    let _ = writeln!(s, "table: {}", table.display());
    for p in &out.plots {
        let _ = writeln!(s, "plot: {p}");
    }
    s
}

fn join(v: &[f64]) -> String {
    v.iter()
        .map(|x| x.to_string())
        .collect::<Vec<_>>()
        .join(", ")
}

#[derive(Serialize)]
struct SteppedExperimentJson<'a> {
    method: &'static str,
    plant: &'a ExperimentPlant,
    design: &'a SteppedDesign,
    #[serde(flatten)]
    result: &'a SteppedResult,
    convention: &'static str,
    truth_note: &'static str,
    data: String,
    csv: String,
    plots: Vec<String>,
}

fn run_stepped_experiment(args: &ExperimentArgs, plant: &ExperimentPlant) -> Result<()> {
    let design = SteppedDesign {
        omegas: args.omegas.clone(),
        degree: args.degree,
        ts: args.ts,
        hold_periods: args.periods,
        ramp_periods: args.ramp_periods,
        pause: args.pause,
    };
    let result = run_stepped(plant, &design)?;
    create_dir(&args.out)?;
    let data = args.out.join("stepped.csv");
    write_record(&data, &result.record)?;
    let csv = args.out.join("bode.csv");
    write_bode_csv(&csv, &result.analysis.bode)?;
    let plots = stepped_plots(args, plant, &result)?;
    let out = SteppedExperimentJson {
        method: "stepped-sine-experiment",
        plant,
        design: &design,
        result: &result,
        convention: CONVENTION,
        truth_note: TRUTH_NOTE,
        data: data.display().to_string(),
        csv: csv.display().to_string(),
        plots,
    };
    let table = write_table(&args.out, &out)?;
    answer(args.json, &out, || {
        describe_stepped_experiment(&out, &table)
    })
}

/// The Bode plots of the stepped record against single-frequency records, the borders and the record.
fn stepped_plots(
    args: &ExperimentArgs,
    plant: &ExperimentPlant,
    result: &SteppedResult,
) -> Result<Vec<String>> {
    let stepped = matched_points(&result.rows, plant.amplitude, |r| r.stepped.as_ref());
    let single = matched_points(&result.rows, plant.amplitude, |r| r.single.as_ref());
    let curve = truth_curve(args, plant, result.analysis.degree)?;
    let mut plots = bode_plots(
        &args.out,
        Some(&curve),
        &[
            ("stepped-sine record", &stepped),
            ("single-frequency records", &single),
        ],
    )?;
    let truths = true_borders(&result.rows, plant, |r| r.stepped.is_some());
    plots.extend(border_panels(&args.out, &stepped, Some(&truths))?);
    let (t, u) = (&result.record.t, &result.record.u);
    plots.push(steps_plot(
        &args.out,
        t,
        u,
        ["time [s]", "u"],
        &result.analysis,
    )?);
    Ok(plots)
}

fn describe_stepped_experiment(out: &SteppedExperimentJson, table: &Path) -> String {
    let (design, result) = (out.design, out.result);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "stepped-sine experiment: {} steps, Ts = {} s, {} held periods, ramps of {} periods, degree {} ({})",
        design.omegas.len(),
        design.ts,
        design.hold_periods,
        design.ramp_periods,
        result.analysis.degree,
        result.analysis.degree_rule
    );
    let _ = writeln!(
        s,
        "{:>8} {:>12} {:>12} {:>12} {:>12}",
        "omega", "phase err", "single", "gain err", "single"
    );
    for r in &result.rows {
        let e = |m: &Option<Matched>| m.as_ref().map(|m| (m.errors.phase, m.errors.gain));
        let _ = match (e(&r.stepped), e(&r.single)) {
            (Some(a), Some(b)) => writeln!(
                s,
                "{:>8.4} {:>12.3e} {:>12.3e} {:>12.3e} {:>12.3e}",
                r.omega, a.0, b.0, a.1, b.1
            ),
            _ => writeln!(
                s,
                "{:>8.4} failed: {}",
                r.omega,
                r.error.as_deref().unwrap_or("the step was not found")
            ),
        };
    }
    let _ = writeln!(s, "table: {}", table.display());
    let _ = writeln!(s, "data: {}, csv: {}", out.data, out.csv);
    for p in &out.plots {
        let _ = writeln!(s, "plot: {p}");
    }
    s
}
