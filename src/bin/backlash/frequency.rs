//! Paper 003 on the command line: `identify frequency` (one sine experiment from a CSV file),
//! `identify stepped-sine` (every step of a stepped-sine record) and `experiment` (a simulated plant
//! identified at several frequencies). Parsing, the library's calls, printing and plots only: the science
//! is in `backlash::identify::frequency`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};

use backlash::api::{ApiError, FREQUENCY_CONVENTION, frequency_json, identify_frequency};
use backlash::identify::frequency::analysis::{
    Analysis, AnalysisOptions, BodePoint, SteppedAnalysis, analyse_steps,
};
use backlash::identify::frequency::experiment::{
    ExperimentPlant, Matched, ModelView, Record, SineDesign, SineRow, SteppedDesign, SteppedResult,
    SteppedRow, bode_curve, design_degree, run_sines, run_stepped,
};
use backlash::identify::frequency::{EstimatorPath, FrequencyError, FrequencyEstimate, SineRecord};
use backlash::io::{RowReader, Table, write_atomic};
use backlash::plant::poly::poly_eval;
use backlash::report::plot::{Axes, Panel, Series, grid_plot, line_plot};

/// What a frequency estimate means (printed with every result).
const CONVENTION: &str = FREQUENCY_CONVENTION;

/// Columns of a sine record.
#[derive(clap::Args, Debug, Clone)]
pub struct Columns {
    /// Name of the time column [default: time, or t when the file has no time column]
    #[arg(long)]
    pub time_col: Option<String>,
    /// Name of the input column
    #[arg(long, default_value = "u")]
    pub u_col: String,
    /// Name of the output column
    #[arg(long, default_value = "y")]
    pub y_col: String,
}

/// Identify one sine experiment (paper 003): the steady window, the degree, the phase lag, gain and
/// polynomial borders, and whether the model explains the record.
#[derive(clap::Args, Debug, Clone)]
pub struct IdentifyFrequencyArgs {
    /// CSV file with a header line; columns time (or t), u, y (names configurable)
    pub file: PathBuf,
    /// Excitation frequency omega, rad/s, against the time column [default: the input's, in the window]
    #[arg(long)]
    pub omega: Option<f64>,
    /// Excitation amplitude U [default: the input's fitted amplitude in the window; if given, the u column
    /// must agree within 5 %]
    #[arg(long)]
    pub amplitude: Option<f64>,
    /// Degree n of the border polynomials f_a, f_d, between 1 and 6 [default: chosen by the data (BIC)]
    #[arg(long)]
    pub degree: Option<usize>,
    /// Start of the part of the record to use, s [default: detected: whole cycles of a steady sine]
    #[arg(long, allow_negative_numbers = true)]
    pub start: Option<f64>,
    /// End of the part of the record to use, s (inclusive) [default: detected]
    #[arg(long, allow_negative_numbers = true)]
    pub end: Option<f64>,
    /// Seconds to discard at the window's start as transient [default: detect the transient]
    #[arg(long)]
    pub transient: Option<f64>,
    #[command(flatten)]
    pub columns: Columns,
    /// Print one JSON object on stdout and nothing else
    #[arg(long)]
    pub json: bool,
}

/// Identify every step of a stepped-sine record (several frequencies one after another): the Bode points,
/// the borders per step and their spread, with plots and a CSV of (omega, gain, phase).
#[derive(clap::Args, Debug, Clone)]
pub struct SteppedSineArgs {
    /// CSV file with a header line; columns time (or t), u, y (names configurable)
    pub file: PathBuf,
    /// Degree n of the border polynomials, between 1 and 6 [default: chosen by the data over all steps]
    #[arg(long)]
    pub degree: Option<usize>,
    /// Seconds to discard at each step's window start as transient [default: detect]
    #[arg(long)]
    pub transient: Option<f64>,
    #[command(flatten)]
    pub columns: Columns,
    /// Output folder (created): bode.csv, bode_magnitude.png, bode_phase.png, borders.png, steps.png
    #[arg(long, default_value = "stepped-sine")]
    pub out: PathBuf,
    /// Print one JSON object on stdout and nothing else
    #[arg(long)]
    pub json: bool,
}

/// The time column: the one named, else `time`, else `t` when the file has `t` and no `time`.
fn time_column(file: &Path, columns: &Columns) -> Result<String> {
    if let Some(c) = &columns.time_col {
        return Ok(c.clone());
    }
    let reader = RowReader::open(file, &[])?;
    let header = reader.header();
    let has = |n: &str| header.iter().any(|h| h == n);
    Ok(if !has("time") && has("t") {
        "t"
    } else {
        "time"
    }
    .to_string())
}

/// The columns time, u, y of a file.
fn read_record(file: &Path, columns: &Columns) -> Result<(Vec<f64>, Vec<f64>, Vec<f64>)> {
    let time = time_column(file, columns)?;
    let names = [
        time.as_str(),
        columns.u_col.as_str(),
        columns.y_col.as_str(),
    ];
    let table = Table::read(file, &names)?;
    let col = |name: &str| {
        table
            .column(name)
            .map(<[f64]>::to_vec)
            .with_context(|| format!("{}: no column '{name}'", file.display()))
    };
    Ok((col(names[0])?, col(names[1])?, col(names[2])?))
}

/// `backlash identify frequency FILE [--omega W] [--amplitude U] [--degree n] [--json]`.
pub fn run_identify(args: &IdentifyFrequencyArgs) -> Result<()> {
    let (time, u, y) = read_record(&args.file, &args.columns)?;
    let rec = SineRecord {
        time: &time,
        u: Some(&u),
        y: &y,
    };
    let opts = AnalysisOptions {
        omega: args.omega,
        amplitude: args.amplitude,
        degree: args.degree,
        start: args.start,
        end: args.end,
        transient: args.transient,
    };
    let file = args.file.display();
    let analysis = identify_frequency(rec.time, rec.u, rec.y, &opts).map_err(|e| match e {
        ApiError::Frequency(e @ FrequencyError::SeveralSteps { .. }) => anyhow::anyhow!(
            "{file}: {e}: `backlash identify stepped-sine {file}` identifies them all, `--omega W` picks one"
        ),
        e => anyhow::anyhow!("{file}: frequency identification failed: {e}"),
    })?;
    if args.json {
        let mut out = frequency_json(&analysis);
        out["file"] = serde_json::json!(file.to_string());
        emit(&format!("{out}\n"))
    } else {
        emit(&describe(&args.file, &analysis))
    }
}

/// Write to stdout; a closed pipe (`| head`) is not an error.
fn emit(text: &str) -> Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|_| out.flush()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        r => r.context("cannot write to stdout"),
    }
}

fn poly_text(name: &str, c: &[f64]) -> String {
    let mut s = format!("{name}(x) = {:.6}", c[0]);
    for (i, v) in c.iter().enumerate().skip(1) {
        let sign = if *v < 0.0 { '-' } else { '+' };
        let pow = if i == 1 {
            "x".to_string()
        } else {
            format!("x^{i}")
        };
        let _ = write!(s, " {sign} {:.6} {pow}", v.abs());
    }
    s
}

fn describe_estimate(s: &mut String, e: &FrequencyEstimate) {
    let path = match e.path {
        EstimatorPath::Ls => format!(
            "LS, eq. (23) (constant stages: tau_a = {:.4} s, tau_d = {:.4} s)",
            e.tau_a, e.tau_d
        ),
        EstimatorPath::Sls => "separable LS, eqs. (24)-(25) (no constant stages)".to_string(),
    };
    let _ = writeln!(s, "  estimator: {path}");
    let _ = writeln!(
        s,
        "  phase lag phi = {:.6} rad ({:.3} deg), gain |G(jw)|/K = {:.6}",
        e.phase,
        e.phase.to_degrees(),
        e.gain
    );
    let _ = writeln!(s, "  {}", poly_text("f_a", &e.fa));
    let _ = writeln!(s, "  {}", poly_text("f_d", &e.fd));
    let _ = writeln!(
        s,
        "  {} steady periods averaged ({} transient dropped), {} samples per period",
        e.periods_used, e.transient_periods, e.samples_per_period
    );
    let _ = writeln!(
        s,
        "  noise std {:.3e}, residual RMS of the averaged output {:.3e}",
        e.noise_std, e.residual_rms
    );
    for w in &e.warnings {
        let _ = writeln!(s, "  warning: {w}");
    }
}

fn describe_analysis(s: &mut String, a: &Analysis) {
    let w = &a.window;
    let _ = writeln!(
        s,
        "  window: t = {:.4} to {:.4} s ({:?}: {} samples, {:.2} periods), input amplitude {}",
        w.start,
        w.end,
        w.source,
        w.samples,
        w.periods,
        w.input_amplitude
            .map_or("unknown".to_string(), |v| format!("{v:.6}"))
    );
    let rule = if a.degree_choice.rule == "declared" {
        "declared".to_string()
    } else {
        let tried: Vec<String> = a
            .degree_choice
            .candidates
            .iter()
            .map(|c| match c.bic {
                Some(b) => format!("{}: {b:.4e}", c.degree),
                None => format!("{}: not fitted", c.degree),
            })
            .collect();
        format!("smallest BIC of {}", tried.join(", "))
    };
    let _ = writeln!(s, "  degree {} ({rule})", a.estimate.degree);
    describe_estimate(s, &a.estimate);
    let _ = writeln!(s, "  verdict: {}", a.verdict.summary);
    if !a.verdict.explained {
        let _ = writeln!(
            s,
            "  `backlash diagnose` fits the time-domain model and names the effect it lacks"
        );
    }
}

fn describe(file: &Path, a: &Analysis) -> String {
    let e = &a.estimate;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{}: paper 003 frequency identification at omega = {} rad/s, U = {}, degree {}",
        file.display(),
        e.omega,
        e.amplitude,
        e.degree
    );
    describe_analysis(&mut s, a);
    let _ = writeln!(s, "  convention: {CONVENTION}");
    s
}

#[derive(Serialize)]
struct SteppedJson<'a> {
    method: &'static str,
    file: String,
    #[serde(flatten)]
    analysis: &'a SteppedAnalysis,
    convention: &'static str,
    bode_convention: &'static str,
    csv: String,
    plots: Vec<String>,
}

const BODE_CONVENTION: &str = "bode: steps by increasing omega, each as the member of its model/dual pair whose phase \
     continues the previous step's (the lowest step as reported); the phase is not wrapped";

/// `backlash identify stepped-sine FILE [--out DIR] [--json]`.
pub fn run_stepped_sine(args: &SteppedSineArgs) -> Result<()> {
    let (time, u, y) = read_record(&args.file, &args.columns)?;
    let rec = SineRecord {
        time: &time,
        u: Some(&u),
        y: &y,
    };
    let file = args.file.display();
    let analysis = analyse_steps(&rec, args.degree, args.transient)
        .with_context(|| format!("{file}: stepped-sine identification failed"))?;
    create_dir(&args.out)?;
    let csv = args.out.join("bode.csv");
    write_bode_csv(&csv, &analysis.bode)?;
    let mut plots = bode_plots(
        &args.out,
        None,
        &[("estimated (paper 003)", &analysis.bode)],
    )?;
    plots.extend(border_panels(&args.out, &analysis.bode, None)?);
    plots.push(steps_plot(&args.out, &time, &u, &analysis)?);
    let out = SteppedJson {
        method: "stepped-sine",
        file: file.to_string(),
        analysis: &analysis,
        convention: CONVENTION,
        bode_convention: BODE_CONVENTION,
        csv: csv.display().to_string(),
        plots,
    };
    if args.json {
        emit(&format!("{}\n", serde_json::to_string(&out)?))
    } else {
        emit(&describe_stepped(&out))
    }
}

fn describe_stepped(out: &SteppedJson) -> String {
    let a = out.analysis;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{}: {} steps, degree {} ({}), {} explained by paper 003's model",
        out.file,
        a.steps.len(),
        a.degree,
        a.degree_rule,
        a.explained_steps
    );
    let _ = writeln!(
        s,
        "{:>10} {:>10} {:>10} {:>8} {:>10} {:>9}",
        "omega", "t start", "t end", "periods", "gain", "phase"
    );
    for p in &a.bode {
        let w = a
            .steps
            .iter()
            .find(|st| {
                st.analysis
                    .as_ref()
                    .is_some_and(|x| x.estimate.omega == p.omega)
            })
            .map(|st| &st.window);
        let (t0, t1, per) = w.map_or((f64::NAN, f64::NAN, f64::NAN), |w| {
            (w.start, w.end, w.periods)
        });
        let _ = writeln!(
            s,
            "{:>10.5} {:>10.3} {:>10.3} {:>8.2} {:>10.5} {:>9.5}{}",
            p.omega,
            t0,
            t1,
            per,
            p.gain,
            p.phase,
            if p.explained { "" } else { "  (not explained)" }
        );
    }
    for st in a.steps.iter().filter(|st| st.error.is_some()) {
        let _ = writeln!(
            s,
            "step at omega = {:.5}: {}",
            st.window.omega,
            st.error.as_deref().unwrap_or("")
        );
    }
    if let Some(sp) = &a.border_spread {
        let _ = writeln!(s, "borders over the steps (mean, std):");
        let _ = writeln!(
            s,
            "  {}   std {:?}",
            poly_text("f_a", &sp.fa_mean),
            sp.fa_std
        );
        let _ = writeln!(
            s,
            "  {}   std {:?}",
            poly_text("f_d", &sp.fd_mean),
            sp.fd_std
        );
    }
    let _ = writeln!(s, "{BODE_CONVENTION}");
    let _ = writeln!(s, "csv: {}", out.csv);
    for p in &out.plots {
        let _ = writeln!(s, "plot: {p}");
    }
    s
}

fn create_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("{}: cannot create the folder", dir.display()))
}

fn write_bode_csv(path: &Path, points: &[BodePoint]) -> Result<()> {
    write_atomic(path, |f| {
        writeln!(f, "omega,gain,phase")?;
        for p in points {
            writeln!(f, "{},{},{}", p.omega, p.gain, p.phase)?;
        }
        Ok(())
    })
    .with_context(|| format!("{}: cannot write", path.display()))
}

fn write_record(path: &Path, r: &Record) -> Result<()> {
    write_atomic(path, |f| {
        writeln!(f, "time,u,x,w,y")?;
        for i in 0..r.t.len() {
            writeln!(f, "{},{},{},{},{}", r.t[i], r.u[i], r.x[i], r.w[i], r.y[i])?;
        }
        Ok(())
    })
    .with_context(|| format!("{}: cannot write", path.display()))
}

/// A true Bode curve: (omega, |G|/K, phase lag rad).
type Curve = Vec<(f64, f64, f64)>;

/// True borders of a Bode point and the x range its data excite: (f_a, f_d, U |G|/K).
type TrueBorders = (Vec<f64>, Vec<f64>, f64);

/// bode_magnitude.png and bode_phase.png: the truth (if known) and sets of estimated points.
fn bode_plots(
    dir: &Path,
    truth: Option<&Curve>,
    estimates: &[(&str, &[BodePoint])],
) -> Result<Vec<String>> {
    let mut mag = Vec::new();
    let mut ph = Vec::new();
    if let Some(c) = truth {
        mag.push(Series::line(
            "true |G(jw)|/K",
            c.iter().map(|p| (p.0, p.1)).collect(),
        ));
        ph.push(Series::line(
            "true phase lag",
            c.iter().map(|p| (p.0, p.2.to_degrees())).collect(),
        ));
    }
    for (i, (label, points)) in estimates.iter().enumerate() {
        // Estimated phases placed on the branch of the true curve (or of the first point).
        let reference = |w: f64| -> Option<f64> {
            truth.and_then(|c| {
                c.iter()
                    .min_by(|a, b| (a.0 - w).abs().total_cmp(&(b.0 - w).abs()))
                    .map(|p| p.2)
            })
        };
        let phases: Vec<(f64, f64)> = points
            .iter()
            .map(|p| {
                let q = reference(p.omega).unwrap_or(p.phase);
                let ph = p.phase
                    + ((q - p.phase) / std::f64::consts::TAU).round() * std::f64::consts::TAU;
                (p.omega, ph.to_degrees())
            })
            .collect();
        let color = 3 + i;
        mag.push(
            Series::points(label, points.iter().map(|p| (p.omega, p.gain)).collect()).color(color),
        );
        ph.push(Series::points(label, phases).color(color));
    }
    let mag_path = dir.join("bode_magnitude.png");
    line_plot(
        &mag_path,
        "Bode magnitude: estimated |G(jw)|/K",
        "omega (rad/s)",
        "gain |G(jw)| / K",
        &mag,
        Axes::LOG_LOG,
    )?;
    let ph_path = dir.join("bode_phase.png");
    line_plot(
        &ph_path,
        "Bode phase: estimated phase lag",
        "omega (rad/s)",
        "phase lag -arg G(jw) (deg)",
        &ph,
        Axes::LOG_X,
    )?;
    Ok(vec![
        mag_path.display().to_string(),
        ph_path.display().to_string(),
    ])
}

/// borders.png: one panel per point, the estimate over its excited range and the truth (if known) a
/// little beyond.
fn border_panels(
    dir: &Path,
    points: &[BodePoint],
    truth: Option<&[TrueBorders]>,
) -> Result<Vec<String>> {
    if points.is_empty() {
        return Ok(Vec::new());
    }
    let titles: Vec<String> = points
        .iter()
        .map(|p| format!("omega = {:.4} rad/s", p.omega))
        .collect();
    let curve = |c: &[f64], reach: f64| -> Vec<(f64, f64)> {
        (0..=200)
            .map(|i| -reach + 2.0 * reach * i as f64 / 200.0)
            .map(|x| (x, poly_eval(c, x)))
            .collect()
    };
    let panels: Vec<Panel> = points
        .iter()
        .zip(&titles)
        .enumerate()
        .map(|(i, (p, title))| {
            let mut series = Vec::new();
            let mut reach = p.gain * p.amplitude;
            if let Some((fa, fd, r)) = truth.and_then(|t| t.get(i)) {
                series.push(Series::line("true f_a", curve(fa, 1.15 * r)));
                series.push(Series::line("true f_d", curve(fd, 1.15 * r)).color(1));
                reach = reach.min(1.15 * r);
            }
            series.push(Series::dashed("estimated f_a", curve(&p.fa, reach)).color(2));
            series.push(Series::dashed("estimated f_d", curve(&p.fd, reach)).color(3));
            Panel {
                title: title.as_str(),
                x_label: "x (normalised)",
                y_label: "w",
                series,
                log_x: false,
                log_y: false,
            }
        })
        .collect();
    let path = dir.join("borders.png");
    grid_plot(
        &path,
        "Borders: estimated (dashed, over the excited range)",
        &panels,
        2,
    )?;
    Ok(vec![path.display().to_string()])
}

/// steps.png: the input with each step's window.
fn steps_plot(dir: &Path, t: &[f64], u: &[f64], a: &SteppedAnalysis) -> Result<String> {
    let stride = (t.len() / 20_000).max(1);
    let input: Vec<(f64, f64)> = t
        .iter()
        .zip(u)
        .step_by(stride)
        .map(|(a, b)| (*a, *b))
        .collect();
    let top = u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut marks = Vec::new();
    for st in &a.steps {
        let w = &st.window;
        marks.push((w.start, 1.1 * top));
        marks.push((w.end, 1.1 * top));
        marks.push((f64::NAN, f64::NAN));
    }
    let marks: Vec<(f64, f64)> = marks.into_iter().filter(|p| p.0.is_finite()).collect();
    let path = dir.join("steps.png");
    let mut series = vec![Series::line("u", input)];
    for (i, pair) in marks.chunks(2).enumerate() {
        series.push(Series::line(if i == 0 { "window used" } else { "" }, pair.to_vec()).color(3));
    }
    line_plot(
        &path,
        "Stepped-sine record: the input and the windows used",
        "time (s)",
        "u",
        &series,
        Axes::LINEAR,
    )?;
    Ok(path.display().to_string())
}

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

/// Plant and excitation of an experiment (the `--plant` file's format; every field optional there).
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlantSpec {
    pub num: Option<Vec<f64>>,
    pub den: Option<Vec<f64>>,
    pub fa: Option<Vec<f64>>,
    pub fd: Option<Vec<f64>>,
    pub amplitude: Option<f64>,
    pub noise_std: Option<f64>,
    pub seed: Option<u64>,
}

/// Flags over the `--plant` file over the defaults.
fn resolve(args: &ExperimentArgs) -> Result<ExperimentPlant> {
    let spec: PlantSpec = match &args.plant {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("{}: cannot read", p.display()))?;
            serde_json::from_str(&text)
                .with_context(|| format!("{}: not a valid plant description", p.display()))?
        }
        None => PlantSpec::default(),
    };
    let d = ExperimentPlant::default();
    let pick = |flag: &Option<Vec<f64>>, file: &Option<Vec<f64>>, default: Vec<f64>| {
        flag.clone().or_else(|| file.clone()).unwrap_or(default)
    };
    Ok(ExperimentPlant {
        num: pick(&args.num, &spec.num, d.num),
        den: pick(&args.den, &spec.den, d.den),
        fa: pick(&args.fa, &spec.fa, d.fa),
        fd: pick(&args.fd, &spec.fd, d.fd),
        amplitude: args.amplitude.or(spec.amplitude).unwrap_or(d.amplitude),
        noise_std: args.noise_std.or(spec.noise_std).unwrap_or(d.noise_std),
        seed: args.seed.or(spec.seed).unwrap_or(d.seed),
    })
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
    let points: Vec<BodePoint> = rows
        .iter()
        .filter_map(|r| {
            let m = r.matched.as_ref()?;
            Some(point(r.omega, &m.as_model, plant.amplitude))
        })
        .collect();
    let (lo, hi) = span(&args.omegas);
    let curve = bode_curve(&plant, degree, lo, hi, 300)?;
    let mut plots = bode_plots(
        &args.out,
        Some(&curve),
        &[("estimated (paper 003)", &points)],
    )?;
    let truths: Vec<TrueBorders> = rows
        .iter()
        .filter(|r| r.matched.is_some())
        .map(|r| {
            (
                r.truth.fa.clone(),
                r.truth.fd.clone(),
                plant.amplitude * r.truth.gain,
            )
        })
        .collect();
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
    let json = serde_json::to_string_pretty(&out)?;
    let table_path = args.out.join("frequency.json");
    write_atomic(&table_path, |f| writeln!(f, "{json}"))
        .with_context(|| format!("{}: cannot write", table_path.display()))?;
    if args.json {
        emit(&format!("{}\n", serde_json::to_string(&out)?))
    } else {
        emit(&summary(&out, &table_path))
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
    let as_points = |pick: &dyn Fn(&SteppedRow) -> Option<&Matched>| -> Vec<BodePoint> {
        result
            .rows
            .iter()
            .filter_map(|r| pick(r).map(|m| point(r.omega, &m.as_model, plant.amplitude)))
            .collect()
    };
    let stepped = as_points(&|r| r.stepped.as_ref());
    let single = as_points(&|r| r.single.as_ref());
    let (lo, hi) = span(&args.omegas);
    let curve = bode_curve(plant, result.analysis.degree, lo, hi, 300)?;
    let mut plots = bode_plots(
        &args.out,
        Some(&curve),
        &[
            ("stepped-sine record", &stepped),
            ("single-frequency records", &single),
        ],
    )?;
    let truths: Vec<TrueBorders> = result
        .rows
        .iter()
        .filter(|r| r.stepped.is_some())
        .map(|r| {
            (
                r.truth.fa.clone(),
                r.truth.fd.clone(),
                plant.amplitude * r.truth.gain,
            )
        })
        .collect();
    plots.extend(border_panels(&args.out, &stepped, Some(&truths))?);
    plots.push(steps_plot(
        &args.out,
        &result.record.t,
        &result.record.u,
        &result.analysis,
    )?);
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
    let json = serde_json::to_string_pretty(&out)?;
    let table_path = args.out.join("frequency.json");
    write_atomic(&table_path, |f| writeln!(f, "{json}"))
        .with_context(|| format!("{}: cannot write", table_path.display()))?;
    if args.json {
        return emit(&format!("{}\n", serde_json::to_string(&out)?));
    }
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
        match (e(&r.stepped), e(&r.single)) {
            (Some(a), Some(b)) => {
                let _ = writeln!(
                    s,
                    "{:>8.4} {:>12.3e} {:>12.3e} {:>12.3e} {:>12.3e}",
                    r.omega, a.0, b.0, a.1, b.1
                );
            }
            _ => {
                let _ = writeln!(
                    s,
                    "{:>8.4} failed: {}",
                    r.omega,
                    r.error.as_deref().unwrap_or("the step was not found")
                );
            }
        }
    }
    let _ = writeln!(s, "table: {}", table_path.display());
    let _ = writeln!(s, "data: {}, csv: {}", out.data, out.csv);
    for p in &out.plots {
        let _ = writeln!(s, "plot: {p}");
    }
    emit(&s)
}
