//! Paper 003 on the command line: `identify frequency` (one sine experiment from a CSV file) and the
//! frequency experiment (a simulated plant identified at several frequencies, with Bode and border plots).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};

use backlash::identify::frequency::{
    FrequencyEstimate, FrequencyOptions, SineRecord, dual_borders, estimate, normalize,
};
use backlash::io::{Table, write_atomic};
use backlash::plant::continuous::{ContinuousLinear, TransferFunction, gain_phase_of};
use backlash::plant::poly::{PolyBacklash, PolyBacklashParams, poly_eval};
use backlash::report::plot::{Panel, Series, grid_plot, line_plot};

/// What a frequency estimate means (printed with every result).
const CONVENTION: &str = "phase in [0, pi): the model (G, F) if -arg G(jw) mod 2pi is in [0, pi), else its dual \
     (-G, F[-x]) (paper 003 eqs. (6)-(7)); scaled by eqs. (29)-(30a) so that sum_i |a_i|^(n/i) = 1 for the \
     reported ascending border, gain = |G(jw)|/K";

/// Identify one sine experiment (paper 003): phase lag, gain and polynomial borders.
#[derive(clap::Args, Debug, Clone)]
pub struct IdentifyFrequencyArgs {
    /// CSV file with a header line; columns time, u, y (names configurable)
    pub file: PathBuf,
    /// Excitation frequency omega, rad/s, against the time column
    #[arg(long)]
    pub omega: f64,
    /// Excitation amplitude U (the input is U cos(omega t); the u column must agree within 5 %)
    #[arg(long)]
    pub amplitude: f64,
    /// Degree n of the border polynomials f_a, f_d (1..=6)
    #[arg(long)]
    pub degree: usize,
    /// Seconds to discard at the start of the record (default: detect the transient)
    #[arg(long)]
    pub transient: Option<f64>,
    /// Name of the time column
    #[arg(long, default_value = "time")]
    pub time_col: String,
    /// Name of the input column
    #[arg(long, default_value = "u")]
    pub u_col: String,
    /// Name of the output column
    #[arg(long, default_value = "y")]
    pub y_col: String,
    /// Print one JSON object on stdout and nothing else
    #[arg(long)]
    pub json: bool,
}

#[derive(Serialize)]
struct IdentifyJson<'a> {
    method: &'static str,
    file: String,
    #[serde(flatten)]
    estimate: &'a FrequencyEstimate,
    convention: &'static str,
}

/// `backlash identify frequency FILE --omega W --amplitude U --degree n [--json]`.
pub fn run_identify(args: &IdentifyFrequencyArgs) -> Result<()> {
    let cols = [
        args.time_col.as_str(),
        args.u_col.as_str(),
        args.y_col.as_str(),
    ];
    let table = Table::read(&args.file, &cols)?;
    let col = |name: &str| {
        table
            .column(name)
            .with_context(|| format!("{}: no column '{name}'", args.file.display()))
    };
    let (time, u, y) = (col(cols[0])?, col(cols[1])?, col(cols[2])?);
    let est = estimate(
        &SineRecord {
            time,
            u: Some(u),
            y,
        },
        &FrequencyOptions {
            omega: args.omega,
            amplitude: args.amplitude,
            degree: args.degree,
            transient: args.transient,
        },
    )
    .with_context(|| format!("{}: frequency identification failed", args.file.display()))?;
    if args.json {
        let out = IdentifyJson {
            method: "frequency",
            file: args.file.display().to_string(),
            estimate: &est,
            convention: CONVENTION,
        };
        emit(&format!("{}\n", serde_json::to_string(&out)?))
    } else {
        emit(&describe(&args.file, &est))
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

fn describe(file: &Path, e: &FrequencyEstimate) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{}: paper 003 frequency identification at omega = {} rad/s, U = {}, degree {}",
        file.display(),
        e.omega,
        e.amplitude,
        e.degree
    );
    let path = match e.path {
        backlash::identify::frequency::EstimatorPath::Ls => format!(
            "LS, eq. (23) (constant stages: tau_a = {:.4} s, tau_d = {:.4} s)",
            e.tau_a, e.tau_d
        ),
        backlash::identify::frequency::EstimatorPath::Sls => {
            "separable LS, eqs. (24)-(25) (no constant stages)".to_string()
        }
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
    let _ = writeln!(s, "  convention: {CONVENTION}");
    for w in &e.warnings {
        let _ = writeln!(s, "  warning: {w}");
    }
    s
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
    /// Denominator of G(s), descending powers, stable, degree <= 4 [default: 1,0.6,1]
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub den: Option<Vec<f64>>,
    /// Ascending border a0,a1,..  (degree <= 3) [default: -0.25,0.9,0.1,0.05]
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub fa: Option<Vec<f64>>,
    /// Descending border d0,d1,.. (degree <= 3) [default: 0.3,0.85,0.1,0.05]
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub fd: Option<Vec<f64>>,
    /// Sine amplitude U [default: 3]
    #[arg(long)]
    pub amplitude: Option<f64>,
    /// Degree used by the estimator [default: the borders' degree]
    #[arg(long)]
    pub degree: Option<usize>,
    /// Standard deviation of the white output noise [default: 0.01]
    #[arg(long)]
    pub noise_std: Option<f64>,
    /// Noise seed [default: 1]
    #[arg(long)]
    pub seed: Option<u64>,
    /// Steady periods recorded per frequency
    #[arg(long, default_value_t = 40)]
    pub periods: usize,
    /// Samples per period (Ts = 2 pi / (omega * this))
    #[arg(long, default_value_t = 200)]
    pub samples_per_period: usize,
    /// Extra periods at the start for the transient [default: enough for e^-25 decay of the slowest pole]
    #[arg(long)]
    pub transient_periods: Option<usize>,
    /// Output folder (created): frequency.json, bode_magnitude.png, bode_phase.png, borders.png, sine_w*.csv
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

#[derive(Debug, Clone, Serialize)]
struct Plant {
    num: Vec<f64>,
    den: Vec<f64>,
    fa: Vec<f64>,
    fd: Vec<f64>,
    amplitude: f64,
    noise_std: f64,
    seed: u64,
    samples_per_period: usize,
    periods: usize,
}

#[derive(Debug, Clone, Serialize)]
struct ModelView {
    phase: f64,
    gain: f64,
    fa: Vec<f64>,
    fd: Vec<f64>,
}

#[derive(Debug, Clone, Serialize)]
struct RowErrors {
    phase: f64,
    gain: f64,
    fa: f64,
    fd: f64,
}

#[derive(Debug, Clone, Serialize)]
struct Row {
    omega: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    estimate: Option<FrequencyEstimate>,
    /// "model" or "dual": which one the estimate is.
    #[serde(skip_serializing_if = "Option::is_none")]
    reported: Option<&'static str>,
    /// The estimate in the true model's convention (converted with the dual map if needed).
    #[serde(skip_serializing_if = "Option::is_none")]
    as_model: Option<ModelView>,
    /// The truth for the sampled data: the zero-order-hold frequency response, normalised (29)-(30a).
    truth: ModelView,
    /// |G(jw)|/K and -arg G(jw) of the continuous-time block, for reference.
    gain_continuous: f64,
    phase_continuous: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    errors: Option<RowErrors>,
    #[serde(skip_serializing_if = "Option::is_none")]
    error: Option<String>,
    data: String,
}

#[derive(Debug, Clone, Serialize)]
struct ExperimentJson {
    method: &'static str,
    plant: Plant,
    degree: usize,
    convention: &'static str,
    truth_note: &'static str,
    rows: Vec<Row>,
    plots: Vec<String>,
}

fn resolve(args: &ExperimentArgs) -> Result<Plant> {
    let spec: PlantSpec = match &args.plant {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("{}: cannot read", p.display()))?;
            serde_json::from_str(&text)
                .with_context(|| format!("{}: not a valid plant description", p.display()))?
        }
        None => PlantSpec::default(),
    };
    let pick = |flag: &Option<Vec<f64>>, file: &Option<Vec<f64>>, default: &[f64]| {
        flag.clone()
            .or_else(|| file.clone())
            .unwrap_or_else(|| default.to_vec())
    };
    Ok(Plant {
        num: pick(&args.num, &spec.num, &[1.0]),
        den: pick(&args.den, &spec.den, &[1.0, 0.6, 1.0]),
        fa: pick(&args.fa, &spec.fa, &[-0.25, 0.9, 0.1, 0.05]),
        fd: pick(&args.fd, &spec.fd, &[0.3, 0.85, 0.1, 0.05]),
        amplitude: args.amplitude.or(spec.amplitude).unwrap_or(3.0),
        noise_std: args.noise_std.or(spec.noise_std).unwrap_or(0.01),
        seed: args.seed.or(spec.seed).unwrap_or(1),
        samples_per_period: args.samples_per_period,
        periods: args.periods,
    })
}

/// Standard normal deviates from a seeded ChaCha8 stream.
struct Noise {
    rng: rand_chacha::ChaCha8Rng,
}

impl Noise {
    fn new(seed: u64) -> Self {
        use rand_core::SeedableRng;
        Self {
            rng: rand_chacha::ChaCha8Rng::seed_from_u64(seed),
        }
    }

    fn next(&mut self) -> f64 {
        use rand_distr::Distribution;
        rand_distr::StandardNormal.sample(&mut self.rng)
    }
}

struct Record {
    t: Vec<f64>,
    u: Vec<f64>,
    x: Vec<f64>,
    w: Vec<f64>,
    y: Vec<f64>,
}

fn simulate(
    tf: &TransferFunction,
    borders: &PolyBacklashParams,
    plant: &Plant,
    omega: f64,
    periods: usize,
    seed: u64,
) -> Result<(Record, ContinuousLinear)> {
    let spp = plant.samples_per_period;
    let ts = std::f64::consts::TAU / omega / spp as f64;
    let mut lin = ContinuousLinear::new(tf.clone(), ts)?;
    let sampled = lin.clone();
    let mut op = PolyBacklash::new(*borders)?;
    let mut noise = Noise::new(seed);
    let n = periods * spp;
    let mut r = Record {
        t: Vec::with_capacity(n),
        u: Vec::with_capacity(n),
        x: Vec::with_capacity(n),
        w: Vec::with_capacity(n),
        y: Vec::with_capacity(n),
    };
    for k in 0..n {
        let t = k as f64 * ts;
        let u = plant.amplitude * (omega * t).cos();
        let x = lin.step(u);
        let w = op.step(x);
        r.t.push(t);
        r.u.push(u);
        r.x.push(x);
        r.w.push(w);
        r.y.push(w + plant.noise_std * noise.next());
    }
    Ok((r, sampled))
}

fn write_csv(path: &Path, r: &Record) -> Result<()> {
    write_atomic(path, |f| {
        writeln!(f, "time,u,x,w,y")?;
        for i in 0..r.t.len() {
            writeln!(f, "{},{},{},{},{}", r.t[i], r.u[i], r.x[i], r.w[i], r.y[i])?;
        }
        Ok(())
    })
    .with_context(|| format!("{}: cannot write", path.display()))
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

fn wrap_pi(d: f64) -> f64 {
    let d = d.rem_euclid(std::f64::consts::TAU);
    d.min(std::f64::consts::TAU - d)
}

/// The normalised truth (model, dual) for a frequency response `g` and degree `n`.
fn truth_pair(
    g: nalgebra::Complex<f64>,
    plant: &Plant,
    n: usize,
) -> Result<(ModelView, ModelView)> {
    let (gain, phase) = gain_phase_of(g);
    let (mg, ma, md) = normalize(gain, &plant.fa, &plant.fd, n)
        .context("the true ascending border is constant: nothing to normalise")?;
    let (da, dd) = dual_borders(&ma, &md);
    let (dg, da, dd) = normalize(mg, &da, &dd, n)
        .context("the true descending border is constant: the dual cannot be normalised")?;
    Ok((
        ModelView {
            phase,
            gain: mg,
            fa: ma,
            fd: md,
        },
        ModelView {
            phase: (phase + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU),
            gain: dg,
            fa: da,
            fd: dd,
        },
    ))
}

/// `backlash experiment ...`: simulate, identify at every frequency, plot, write the table.
pub fn run_experiment(args: &ExperimentArgs) -> Result<()> {
    let plant = resolve(args)?;
    if args.omegas.is_empty() || args.omegas.iter().any(|w| !(w.is_finite() && *w > 0.0)) {
        bail!("--omegas must list frequencies > 0 (rad/s)");
    }
    if !(plant.amplitude.is_finite() && plant.amplitude > 0.0) {
        bail!("the amplitude U must be > 0 (got {})", plant.amplitude);
    }
    if !(plant.noise_std.is_finite() && plant.noise_std >= 0.0) {
        bail!("the noise std must be >= 0 (got {})", plant.noise_std);
    }
    if args.periods == 0 || args.samples_per_period < 8 {
        bail!("--periods must be >= 1 and --samples-per-period >= 8");
    }
    let tf = TransferFunction::new(&plant.num, &plant.den).context("invalid G(s)")?;
    let borders = PolyBacklashParams::new(&plant.fa, &plant.fd).context("invalid borders")?;
    let degree = args.degree.unwrap_or(borders.degree().max(1));
    let slowest = tf
        .poles()
        .iter()
        .map(|p| -p.re)
        .fold(f64::INFINITY, f64::min);
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create the folder", args.out.display()))?;

    let mut rows = Vec::new();
    for (i, &omega) in args.omegas.iter().enumerate() {
        let period = std::f64::consts::TAU / omega;
        let transient = args.transient_periods.unwrap_or_else(|| {
            if slowest.is_finite() && slowest > 0.0 {
                ((25.0 / slowest / period).ceil() as usize).clamp(1, 400)
            } else {
                1
            }
        });
        let (rec, sampled) = simulate(
            &tf,
            &borders,
            &plant,
            omega,
            transient + args.periods,
            plant.seed.wrapping_add(i as u64),
        )?;
        let data = args.out.join(format!("sine_w{omega}.csv"));
        write_csv(&data, &rec)?;
        let (truth, truth_dual) = truth_pair(sampled.sampled_response(omega), &plant, degree)?;
        let (gc, pc) = gain_phase_of(tf.response(omega));
        let kc = truth.gain / gain_phase_of(sampled.sampled_response(omega)).0;
        let result = estimate(
            &SineRecord {
                time: &rec.t,
                u: Some(&rec.u),
                y: &rec.y,
            },
            &FrequencyOptions {
                omega,
                amplitude: plant.amplitude,
                degree,
                transient: None,
            },
        );
        let mut row = Row {
            omega,
            estimate: None,
            reported: None,
            as_model: None,
            truth: truth.clone(),
            gain_continuous: gc * kc,
            phase_continuous: pc,
            errors: None,
            error: None,
            data: data.display().to_string(),
        };
        match result {
            Ok(est) => {
                let is_model =
                    wrap_pi(est.phase - truth.phase) <= wrap_pi(est.phase - truth_dual.phase);
                let view = if is_model { est.clone() } else { est.dual() };
                let reference = if is_model { &truth } else { &truth_dual };
                row.errors = Some(RowErrors {
                    phase: wrap_pi(est.phase - reference.phase),
                    gain: (est.gain - reference.gain).abs(),
                    fa: max_abs_diff(&est.fa, &reference.fa),
                    fd: max_abs_diff(&est.fd, &reference.fd),
                });
                row.reported = Some(if is_model { "model" } else { "dual" });
                row.as_model = Some(ModelView {
                    phase: view.phase,
                    gain: view.gain,
                    fa: view.fa,
                    fd: view.fd,
                });
                row.estimate = Some(est);
            }
            Err(e) => row.error = Some(e.to_string()),
        }
        rows.push(row);
    }

    let plots = plot_all(&args.out, &tf, &plant, degree, &args.omegas, &rows)?;
    let out = ExperimentJson {
        method: "frequency-experiment",
        plant,
        degree,
        convention: CONVENTION,
        truth_note: "truth = the zero-order-hold frequency response of the sampled block (what the \
                     samples carry); gain_continuous/phase_continuous = G(jw) for reference",
        rows,
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
    for r in &out.rows {
        match (&r.estimate, &r.as_model, &r.errors) {
            (Some(e), Some(m), Some(err)) => {
                let _ = writeln!(
                    s,
                    "{:>8.4} {:>5} {:>6} {:>10.5} {:>10.5} {:>10.5} {:>10.5} {:>9.2e} {:>9.2e} {:>8}",
                    r.omega,
                    format!("{:?}", e.path).to_lowercase(),
                    r.reported.unwrap_or("?"),
                    m.phase,
                    r.truth.phase,
                    m.gain,
                    r.truth.gain,
                    err.fa,
                    err.fd,
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

fn plot_all(
    dir: &Path,
    tf: &TransferFunction,
    plant: &Plant,
    degree: usize,
    omegas: &[f64],
    rows: &[Row],
) -> Result<Vec<String>> {
    // The continuous |G(jw)|/K and phase lag on a log grid, in the normalised model's scale.
    let (kinv, _, _) = normalize(1.0, &plant.fa, &plant.fd, degree)
        .context("the true ascending border is constant")?;
    let lo = omegas.iter().copied().fold(f64::INFINITY, f64::min) / 2.0;
    let hi = omegas.iter().copied().fold(0.0, f64::max) * 2.0;
    let grid: Vec<f64> = (0..=300)
        .map(|i| lo * (hi / lo).powf(i as f64 / 300.0))
        .collect();
    let mut phase_prev: Option<f64> = None;
    let mut true_gain = Vec::new();
    let mut true_phase = Vec::new();
    for &w in &grid {
        let (g, mut p) = gain_phase_of(tf.response(w));
        if let Some(pp) = phase_prev {
            p += ((pp - p) / std::f64::consts::TAU).round() * std::f64::consts::TAU;
        }
        phase_prev = Some(p);
        true_gain.push((w, g * kinv));
        true_phase.push((w, p.to_degrees()));
    }
    let ok: Vec<(&Row, &ModelView)> = rows
        .iter()
        .filter_map(|r| r.as_model.as_ref().map(|m| (r, m)))
        .collect();
    let est_gain: Vec<(f64, f64)> = ok.iter().map(|(r, m)| (r.omega, m.gain)).collect();
    // Estimated phase placed on the branch of the unwrapped true curve.
    let est_phase: Vec<(f64, f64)> = ok
        .iter()
        .map(|(r, m)| {
            let (_, mut p_true) = gain_phase_of(tf.response(r.omega));
            if let Some(&(_, deg)) = true_phase
                .iter()
                .min_by(|a, b| (a.0 - r.omega).abs().total_cmp(&(b.0 - r.omega).abs()))
            {
                p_true = deg.to_radians();
            }
            let p = m.phase
                + ((p_true - m.phase) / std::f64::consts::TAU).round() * std::f64::consts::TAU;
            (r.omega, p.to_degrees())
        })
        .collect();
    let mag = dir.join("bode_magnitude.png");
    line_plot(
        &mag,
        "Bode magnitude: estimated |G(jw)|/K against the truth",
        "omega (rad/s)",
        "|G(jw)| / K",
        &[
            Series::line("true |G(jw)|/K", true_gain),
            Series::points("estimated (paper 003)", est_gain).color(3),
        ],
        true,
        true,
    )?;
    let ph = dir.join("bode_phase.png");
    line_plot(
        &ph,
        "Bode phase: estimated phase lag against the truth",
        "omega (rad/s)",
        "phase lag -arg G(jw) (deg)",
        &[
            Series::line("true phase lag", true_phase),
            Series::points("estimated (paper 003)", est_phase).color(3),
        ],
        true,
        false,
    )?;
    // Borders: one panel per frequency, truth over the whole excited range, estimates over theirs.
    let titles: Vec<String> = ok
        .iter()
        .map(|(r, _)| format!("omega = {} rad/s", r.omega))
        .collect();
    let mut panels = Vec::new();
    for ((r, m), title) in ok.iter().zip(&titles) {
        let reach = plant.amplitude * r.truth.gain;
        let xs = |x_max: f64| -> Vec<f64> {
            (0..=200)
                .map(|i| -x_max + 2.0 * x_max * i as f64 / 200.0)
                .collect()
        };
        let curve = |c: &[f64], x_max: f64| -> Vec<(f64, f64)> {
            xs(x_max)
                .into_iter()
                .map(|x| (x, poly_eval(c, x)))
                .collect()
        };
        let est_reach = plant.amplitude * m.gain;
        panels.push(Panel {
            title: title.as_str(),
            x_label: "x (normalised)",
            y_label: "w",
            series: vec![
                Series::line("true f_a", curve(&r.truth.fa, 1.15 * reach)),
                Series::line("true f_d", curve(&r.truth.fd, 1.15 * reach)).color(1),
                Series::dashed("estimated f_a", curve(&m.fa, est_reach)).color(2),
                Series::dashed("estimated f_d", curve(&m.fd, est_reach)).color(3),
            ],
            log_x: false,
            log_y: false,
        });
    }
    let mut plots = vec![mag.display().to_string(), ph.display().to_string()];
    if !panels.is_empty() {
        let borders = dir.join("borders.png");
        grid_plot(
            &borders,
            "Borders: estimated (dashed, over the excited range) against the truth",
            &panels,
            2,
        )?;
        plots.push(borders.display().to_string());
    }
    Ok(plots)
}
