//! Monte Carlo study of the paper 000, section 4 example: MRGIA (paper and recommended settings), MRGIA with
//! `refine` (the on-line output-error estimator of [`super::online`], the FMU's default settings plus
//! refine), the output-error fit started from MRGIA, and the Cramer-Rao bound, against the record length N.
//!
//! For each seed s: the input is [`paper_input`]`(max N, s)`, the plant [`PlantParams::PAPER`], the noise
//! white Gaussian with standard deviation `std(w) / snr` (w the noise-free output over the longest record:
//! the paper's "SNR 43" is the square root of the ratio of the output and noise variances) from seed
//! `s + 0x5EED_0000_0000`. Every record of length N is the first N samples of that run. MRGIA runs once per
//! setting (and refine) and is read at each N; the OE fit runs on each prefix from the MRGIA estimates at that N (the
//! same starts as [`super::fit`]); the CRB is computed for each prefix at the truth with the true noise std.
//!
//! [`grid_study`] runs the same experiment over a grid of plants ([`PLANT_VARIANTS`]), SNRs and seeds, one
//! cell (plant, SNR, seed) per rayon task, and returns a tidy table (one [`Row`] per plant, SNR, N, seed,
//! method and parameter) as well as the aggregated [`StudyResult`] of every (plant, SNR). A cell is seeded by
//! its seed alone (same input and noise streams for every plant and SNR: common random numbers), and the
//! cells are collected in grid order, so the result does not depend on the number of threads.

mod output;

use super::online::Refined;
use super::{OeConfig, OeFit, crb, default_starts, fit_from, param_names, theta_of};
use crate::identify::mrgia::{Mrgia, MrgiaConfig, paper_input};
use crate::plant::{Plant, PlantParams};
use crate::stats::std_dev;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Same offset as `mrgia::paper_study_with`: independent ChaCha8 streams for input and noise.
const NOISE_SEED_OFFSET: u64 = 0x5EED_0000_0000;

/// What to run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StudyConfig {
    /// Number of Monte Carlo runs (seeds `first_seed .. first_seed + seeds`).
    pub seeds: u64,
    pub first_seed: u64,
    /// Record lengths.
    pub ns: Vec<usize>,
    /// Signal-to-noise ratio std(w) / noise std; paper: 43.
    pub snr: f64,
}

impl StudyConfig {
    /// The paper's noisy example (SNR 43) at N = 300, 1000, 3000, 10000.
    pub fn paper(seeds: u64) -> Self {
        Self {
            seeds,
            first_seed: 0,
            ns: vec![300, 1000, 3000, 10000],
            snr: 43.0,
        }
    }
}

/// Statistics of one method at one N over the runs, per parameter in theta order (a1, a2, b0, m2, c1, c2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MethodStats {
    /// `mrgia-paper`, `mrgia-recommended`, `refine`, `oe` or `crb`.
    pub method: String,
    pub n: usize,
    /// Root mean square error over the runs; for `crb` the root mean CRB variance (the RMSE an efficient
    /// unbiased estimator would have on these inputs).
    pub rmse: Vec<f64>,
    /// Mean error (0 for `crb`).
    pub bias: Vec<f64>,
    /// Median over runs of the largest relative error (for `crb`: of the largest relative CRB std).
    pub median_max_rel: f64,
    /// `oe` and `refine` only: fraction of runs whose interval estimate +/- 1.96 std_err covers the truth.
    pub coverage: Option<Vec<f64>>,
    /// `oe` and `refine` only: root mean square of the reported standard errors.
    pub rms_std_err: Option<Vec<f64>>,
    /// When the CRB was computed (method `crb` listed), for the estimators: each run's worst parameter error
    /// in units of that parameter's CRB std, `max_i |error_i| / crb_std_i`; its median, the share of runs
    /// above 10 and above 100, and its largest value.
    #[serde(default)]
    pub crb_units: Option<CrbUnits>,
    /// Runs whose method failed (excluded from the statistics).
    pub failures: usize,
    /// Runs included.
    pub runs: usize,
}

/// Statistics of the worst-parameter error in CRB std units over the runs (see [`MethodStats::crb_units`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CrbUnits {
    pub median: f64,
    pub share_over_10: f64,
    pub share_over_100: f64,
    pub max: f64,
}

/// Everything the study measured.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StudyResult {
    /// Name of the plant variant ([`PLANT_VARIANTS`]); `paper` for [`monte_carlo`].
    #[serde(default = "paper_name")]
    pub plant: String,
    pub config: StudyConfig,
    pub names: Vec<String>,
    pub truth: Vec<f64>,
    pub stats: Vec<MethodStats>,
}

fn paper_name() -> String {
    "paper".to_string()
}

/// The method names, in plotting order.
pub const METHODS: [&str; 5] = ["mrgia-paper", "mrgia-recommended", "refine", "oe", "crb"];

/// A named plant of a [`grid_study`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantVariant {
    pub name: &'static str,
    pub description: &'static str,
    /// Noise-free parameters (the study sets the noise from the SNR).
    pub params: PlantParams,
}

/// The paper plant with `b1` (nb = 1 when it is not 0) and the backlash `m2, c1, c2` (m1 = 1).
const fn variant(
    name: &'static str,
    description: &'static str,
    b1: f64,
    m2: f64,
    c1: f64,
    c2: f64,
) -> PlantVariant {
    use crate::plant::{ArxParams, BacklashParams};
    let mut arx = ArxParams::PAPER;
    arx.b[1] = b1;
    arx.nb = if b1 != 0.0 { 1 } else { 0 };
    PlantVariant {
        name,
        description,
        params: PlantParams {
            arx,
            backlash: BacklashParams {
                m1: 1.0,
                m2,
                c1,
                c2,
            },
            noise_std: 0.0,
            noise_seed: 0,
        },
    }
}

/// The plants a study can run. All keep the paper's denominator and delay, m1 = 1, and the borders' crossing
/// point `x* = (c1 + m2 c2) / (1 - m2)` outside (or at the edge of) the range the paper input drives x over
/// (|x| <= 4.2 on 10000 samples), so that the output-error model is identifiable (see the module docs of
/// [`super`]).
pub const PLANT_VARIANTS: [PlantVariant; 5] = [
    variant(
        "paper",
        "paper 000, section 4: a = 0.45, 0.55; b0 = 0.8; m1 = 1, m2 = 1.5, c1 = 0.5, c2 = 1",
        0.0,
        1.5,
        0.5,
        1.0,
    ),
    variant(
        "wide-gaps",
        "the paper plant with twice the gaps: c1 = 1, c2 = 2 (x* = -8)",
        0.0,
        1.5,
        1.0,
        2.0,
    ),
    variant(
        "symmetric",
        "the paper plant with equal slopes m2 = m1 = 1 (the borders never cross)",
        0.0,
        1.0,
        0.5,
        1.0,
    ),
    variant(
        "reversed-slopes",
        "the lower border flatter than the upper: m2 = 0.75 (x* = +5)",
        0.0,
        0.75,
        0.5,
        1.0,
    ),
    variant(
        "second-order-b",
        "the paper plant with a second b coefficient: b0 = 0.8, b1 = 0.4 (nb = 1)",
        0.4,
        1.5,
        0.5,
        1.0,
    ),
];

/// The variant called `name`.
pub fn plant_variant(name: &str) -> Option<&'static PlantVariant> {
    PLANT_VARIANTS.iter().find(|v| v.name == name)
}

/// Why a grid cannot run.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum StudyError {
    #[error("unknown plant variant '{0}'; known: {known}", known = variant_names())]
    UnknownPlant(String),
    #[error("unknown method '{0}'; known: {known}", known = METHODS.join(", "))]
    UnknownMethod(String),
    #[error("the grid is empty: {0}")]
    Empty(&'static str),
    #[error("record length N = {0} is too short: every N must be at least 10")]
    ShortRecord(usize),
    #[error("SNR {0} must be a finite number > 0")]
    Snr(f64),
    #[error("{what} '{value}' is listed twice")]
    Duplicate { what: &'static str, value: String },
}

fn variant_names() -> String {
    PLANT_VARIANTS
        .iter()
        .map(|v| v.name)
        .collect::<Vec<_>>()
        .join(", ")
}

/// A grid of Monte Carlo runs: every (plant, SNR, seed) is one cell, read at every N.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GridConfig {
    /// Seeds `first_seed .. first_seed + seeds`.
    pub seeds: u64,
    pub first_seed: u64,
    /// Record lengths (each run is read at every N).
    pub ns: Vec<usize>,
    /// Signal-to-noise ratios std(w) / noise std.
    pub snrs: Vec<f64>,
    /// Names of [`PLANT_VARIANTS`].
    pub plants: Vec<String>,
    /// Methods to report, a subset of [`METHODS`] (refine, the OE fit and the CRB are only computed when
    /// listed; both MRGIA settings always run, they are the OE fit's starts).
    pub methods: Vec<String>,
}

impl GridConfig {
    /// The single cell of [`monte_carlo`]: the paper plant at one SNR, all methods.
    pub fn of_study(cfg: &StudyConfig) -> Self {
        Self {
            seeds: cfg.seeds,
            first_seed: cfg.first_seed,
            ns: cfg.ns.clone(),
            snrs: vec![cfg.snr],
            plants: vec!["paper".to_string()],
            methods: METHODS.iter().map(|m| m.to_string()).collect(),
        }
    }

    pub fn validate(&self) -> Result<(), StudyError> {
        if self.seeds == 0 {
            return Err(StudyError::Empty("no seeds"));
        }
        for (what, empty) in [
            ("no record lengths", self.ns.is_empty()),
            ("no SNRs", self.snrs.is_empty()),
            ("no plants", self.plants.is_empty()),
            ("no methods", self.methods.is_empty()),
        ] {
            if empty {
                return Err(StudyError::Empty(what));
            }
        }
        if let Some(&n) = self.ns.iter().find(|&&n| n < 10) {
            return Err(StudyError::ShortRecord(n));
        }
        if let Some(&r) = self.snrs.iter().find(|r| !(r.is_finite() && **r > 0.0)) {
            return Err(StudyError::Snr(r));
        }
        if let Some(p) = self.plants.iter().find(|p| plant_variant(p).is_none()) {
            return Err(StudyError::UnknownPlant(p.clone()));
        }
        if let Some(m) = self.methods.iter().find(|m| !METHODS.contains(&m.as_str())) {
            return Err(StudyError::UnknownMethod(m.clone()));
        }
        let dup = |what, v: Vec<String>| {
            let mut seen = std::collections::HashSet::new();
            match v.into_iter().find(|x| !seen.insert(x.clone())) {
                Some(value) => Err(StudyError::Duplicate { what, value }),
                None => Ok(()),
            }
        };
        dup("N", self.ns.iter().map(|n| n.to_string()).collect())?;
        dup("SNR", self.snrs.iter().map(|r| format!("{r:?}")).collect())?;
        dup("plant", self.plants.clone())?;
        dup("method", self.methods.clone())?;
        Ok(())
    }

    /// Number of cells (runs): plants x SNRs x seeds.
    pub fn runs(&self) -> u64 {
        self.plants.len() as u64 * self.snrs.len() as u64 * self.seeds
    }

    fn wants(&self, method: &str) -> bool {
        self.methods.iter().any(|m| m == method)
    }
}

/// One line of the tidy table: one parameter of one method's result at one N of one run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Row {
    pub plant: String,
    pub snr: f64,
    pub n: usize,
    pub seed: u64,
    /// The run's measurement noise std (std(w) / snr over the longest record).
    pub noise_std: f64,
    pub method: String,
    pub param: String,
    pub truth: f64,
    /// None for `crb` and for a failed fit.
    pub estimate: Option<f64>,
    /// `oe` and `refine`: the reported standard error; `crb`: the Cramer-Rao bound std; None otherwise.
    pub std_err: Option<f64>,
}

impl Row {
    /// estimate - truth.
    pub fn error(&self) -> Option<f64> {
        self.estimate.map(|e| e - self.truth)
    }
}

/// The header of [`GridResult::rows_csv`].
pub const ROWS_HEADER: &str =
    "plant,snr,n,seed,noise_std,method,param,truth,estimate,error,std_err";

/// What a [`grid_study`] measured.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GridResult {
    pub config: GridConfig,
    /// One per (plant, SNR), plants outer, in the configuration's order.
    pub groups: Vec<StudyResult>,
    /// The tidy table, in (plant, SNR, seed, N, method, parameter) order.
    #[serde(skip)]
    pub rows: Vec<Row>,
}

/// Accumulates per-run errors of one method at one N.
#[derive(Default)]
struct Acc {
    err: Vec<Vec<f64>>,
    max_rel: Vec<f64>,
    covered: Vec<Vec<bool>>,
    std_err: Vec<Vec<f64>>,
    /// Per run: worst |error| / CRB std (runs with a CRB only).
    crb_units: Vec<f64>,
    failures: usize,
}

impl Acc {
    fn push(&mut self, est: &[f64], truth: &[f64]) {
        self.push_err(est.iter().zip(truth).map(|(e, t)| e - t).collect(), truth);
    }

    /// A run's estimate with its standard errors: also the interval coverage.
    fn push_with_se(&mut self, est: &[f64], se: Vec<f64>, truth: &[f64]) {
        self.covered.push(
            (0..truth.len())
                .map(|j| (est[j] - truth[j]).abs() <= 1.96 * se[j])
                .collect(),
        );
        self.std_err.push(se);
        self.push(est, truth);
    }

    /// The latest run's worst error in units of the CRB std (variances `var`).
    fn push_crb_units(&mut self, var: &[f64]) {
        if let Some(e) = self.err.last() {
            let worst = e
                .iter()
                .zip(var)
                .map(|(e, v)| e.abs() / v.sqrt())
                .fold(0.0, f64::max);
            self.crb_units.push(worst);
        }
    }

    fn push_err(&mut self, e: Vec<f64>, truth: &[f64]) {
        self.max_rel.push(
            e.iter()
                .zip(truth)
                .map(|(e, t)| (e / t).abs())
                .fold(0.0, f64::max),
        );
        self.err.push(e);
    }

    fn stats(&self, method: &str, n: usize, p: usize) -> MethodStats {
        let runs = self.err.len();
        let mean = |f: &dyn Fn(&Vec<f64>, usize) -> f64| -> Vec<f64> {
            (0..p)
                .map(|i| {
                    if runs == 0 {
                        f64::NAN
                    } else {
                        self.err.iter().map(|e| f(e, i)).sum::<f64>() / runs as f64
                    }
                })
                .collect()
        };
        let rmse = mean(&|e, i| e[i] * e[i]).iter().map(|v| v.sqrt()).collect();
        let bias = if method == "crb" {
            vec![0.0; p]
        } else {
            mean(&|e, i| e[i])
        };
        let coverage = (!self.covered.is_empty()).then(|| {
            (0..p)
                .map(|i| {
                    self.covered.iter().filter(|c| c[i]).count() as f64 / self.covered.len() as f64
                })
                .collect()
        });
        let rms_std_err = (!self.std_err.is_empty()).then(|| {
            (0..p)
                .map(|i| {
                    (self.std_err.iter().map(|s| s[i] * s[i]).sum::<f64>()
                        / self.std_err.len() as f64)
                        .sqrt()
                })
                .collect()
        });
        let crb_units = (!self.crb_units.is_empty()).then(|| {
            let m = self.crb_units.len() as f64;
            let share = |t: f64| self.crb_units.iter().filter(|&&v| v > t).count() as f64 / m;
            CrbUnits {
                median: median(&self.crb_units),
                share_over_10: share(10.0),
                share_over_100: share(100.0),
                max: self.crb_units.iter().copied().fold(0.0, f64::max),
            }
        });
        MethodStats {
            method: method.to_string(),
            n,
            rmse,
            bias,
            median_max_rel: median(&self.max_rel),
            coverage,
            rms_std_err,
            crb_units,
            failures: self.failures,
            runs,
        }
    }
}

/// The median, NaN for no values (a study cell in which every run failed).
fn median(v: &[f64]) -> f64 {
    crate::stats::median(v).unwrap_or(f64::NAN)
}

/// One N of one run: the estimates of the two MRGIA settings, refine's estimate and standard errors (when
/// asked for), the OE fit (or its error) and the CRB variances.
#[derive(Debug, Clone, Default)]
struct AtN {
    paper: Vec<f64>,
    rec: Vec<f64>,
    refine: Option<(Vec<f64>, Vec<f64>)>,
    oe: Option<OeFit>,
    bound: Option<Vec<f64>>,
}

/// One run of the study: the record of seed `s`, truncated at each N, and the fits, per N.
type RunResult = Vec<AtN>;

/// Which of the optional methods a run computes.
#[derive(Debug, Clone, Copy)]
struct Wants {
    refine: bool,
    oe: bool,
    crb: bool,
}

/// The run of seed `s` on plant `truth` at `snr`, read at each of `ns`; the OE fit and the CRB only when
/// asked for. Returns the noise std and the per-N results.
fn one_run(truth: PlantParams, ns: &[usize], snr: f64, s: u64, want: Wants) -> (f64, RunResult) {
    let (na, nb, d) = (truth.arx.na, truth.arx.nb, truth.arx.delay);
    let n_max = ns.iter().copied().max().unwrap_or(0);
    let u = paper_input(n_max, s);
    let clean = Plant::simulate(truth, &u).expect("study plants are valid");
    let w: Vec<f64> = clean.iter().map(|o| o.w).collect();
    let noise_std = std_dev(&w) / snr;
    let mut p = truth;
    p.noise_std = noise_std;
    p.noise_seed = s.wrapping_add(NOISE_SEED_OFFSET);
    let y: Vec<f64> = Plant::simulate(p, &u)
        .expect("noise std is finite")
        .iter()
        .map(|o| o.y)
        .collect();
    let mut paper = Mrgia::new(MrgiaConfig::paper(na, nb, d)).expect("valid");
    let mut rec = Mrgia::new(MrgiaConfig::recommended(na, nb, d)).expect("valid");
    let mut refine = want
        .refine
        .then(|| Refined::new(MrgiaConfig::paper(na, nb, d)).expect("valid"));
    let mut order: Vec<usize> = (0..ns.len()).collect();
    order.sort_by_key(|&i| ns[i]);
    let mut out: RunResult = vec![AtN::default(); ns.len()];
    let mut done = 0;
    let oe_cfg = OeConfig::new(na, nb, d);
    for &i in &order {
        let n = ns[i];
        while done < n {
            paper.update(u[done], y[done]);
            rec.update(u[done], y[done]);
            if let Some(r) = &mut refine {
                r.update(u[done], y[done]);
            }
            done += 1;
        }
        let (ep, er) = (paper.estimate(), rec.estimate());
        let oe = want
            .oe
            .then(|| {
                let starts = default_starts(er.clone(), Some(ep.clone()));
                fit_from(&oe_cfg, &u[..n], &y[..n], &starts).ok()
            })
            .flatten();
        let bound = want
            .crb
            .then(|| {
                crb(&truth, &u[..n], noise_std)
                    .ok()
                    .map(|c| c.std.iter().map(|s| s * s).collect())
            })
            .flatten();
        let p = ep.a.len() + ep.b.len() + 3;
        out[i] = AtN {
            paper: theta_of(&ep),
            rec: theta_of(&er),
            refine: refine
                .as_ref()
                .map(|r| (r.values()[..p].to_vec(), r.std_err_values()[..p].to_vec())),
            oe,
            bound,
        };
    }
    (noise_std, out)
}

/// Run the study sequentially; `progress(done)` is called after each run.
pub fn monte_carlo(cfg: &StudyConfig, mut progress: impl FnMut(u64)) -> StudyResult {
    let mut runs = Vec::with_capacity(cfg.seeds as usize);
    for (done, s) in (cfg.first_seed..cfg.first_seed + cfg.seeds).enumerate() {
        let all = Wants {
            refine: true,
            oe: true,
            crb: true,
        };
        runs.push(one_run(PlantParams::PAPER, &cfg.ns, cfg.snr, s, all).1);
        progress(done as u64 + 1);
    }
    aggregate("paper", &PlantParams::PAPER, cfg, &METHODS, runs.iter())
}

/// The statistics of `methods` over `runs` (seed order) of plant `truth`.
fn aggregate<'a>(
    plant: &str,
    truth_p: &PlantParams,
    cfg: &StudyConfig,
    methods: &[&str],
    runs: impl Iterator<Item = &'a RunResult>,
) -> StudyResult {
    let names = param_names(truth_p.arx.na, truth_p.arx.nb);
    let truth = theta_of(&super::estimate_of(truth_p));
    let p = truth.len();
    let k = cfg.ns.len();
    let mut acc: Vec<[Acc; 5]> = (0..k).map(|_| Default::default()).collect();
    for run in runs {
        for (i, r) in run.iter().enumerate() {
            let [a_paper, a_rec, a_refine, a_oe, a_crb] = &mut acc[i];
            a_paper.push(&r.paper, &truth);
            a_rec.push(&r.rec, &truth);
            let mut estimators: Vec<&mut Acc> = vec![a_paper, a_rec];
            match &r.refine {
                Some((est, se)) => {
                    a_refine.push_with_se(est, se.clone(), &truth);
                    estimators.push(a_refine);
                }
                None => a_refine.failures += 1,
            }
            match &r.oe {
                Some(f) => {
                    let est = theta_of(&f.estimate);
                    a_oe.push_with_se(&est, f.uncertainty.std.clone(), &truth);
                    estimators.push(a_oe);
                }
                None => a_oe.failures += 1,
            }
            match &r.bound {
                // The CRB std as the error: its RMS is the root mean CRB variance.
                Some(var) => {
                    for a in estimators {
                        a.push_crb_units(var);
                    }
                    a_crb.push_err(var.iter().map(|v| v.sqrt()).collect(), &truth);
                }
                None => a_crb.failures += 1,
            }
        }
    }
    let mut stats = Vec::new();
    for (i, a) in acc.iter().enumerate() {
        for (m, ai) in METHODS.iter().zip(a.iter()) {
            if methods.contains(m) {
                stats.push(ai.stats(m, cfg.ns[i], p));
            }
        }
    }
    StudyResult {
        plant: plant.to_string(),
        config: cfg.clone(),
        names,
        truth,
        stats,
    }
}

/// The tidy rows of one run.
fn rows_of(
    v: &PlantVariant,
    cfg: &StudyConfig,
    methods: &[&str],
    seed: u64,
    noise_std: f64,
    run: &RunResult,
    out: &mut Vec<Row>,
) {
    let names = param_names(v.params.arx.na, v.params.arx.nb);
    let truth = theta_of(&super::estimate_of(&v.params));
    for (i, r) in run.iter().enumerate() {
        let oe_est = r.oe.as_ref().map(|f| theta_of(&f.estimate));
        let oe_se = r.oe.as_ref().map(|f| &f.uncertainty.std);
        for m in METHODS.iter().filter(|m| methods.contains(m)) {
            for (j, name) in names.iter().enumerate() {
                let (estimate, std_err) = match *m {
                    "mrgia-paper" => (Some(r.paper[j]), None),
                    "mrgia-recommended" => (Some(r.rec[j]), None),
                    "refine" => match &r.refine {
                        Some((e, s)) => (Some(e[j]), Some(s[j])),
                        None => (None, None),
                    },
                    "oe" => (oe_est.as_ref().map(|e| e[j]), oe_se.map(|s| s[j])),
                    _ => (None, r.bound.as_ref().map(|v| v[j].sqrt())),
                };
                out.push(Row {
                    plant: v.name.to_string(),
                    snr: cfg.snr,
                    n: cfg.ns[i],
                    seed,
                    noise_std,
                    method: m.to_string(),
                    param: name.clone(),
                    truth: truth[j],
                    estimate,
                    std_err,
                });
            }
        }
    }
}

/// Run the grid on the current rayon thread pool (install a pool to choose the number of threads);
/// `progress()` is called from the worker threads after each finished run (cell).
pub fn grid_study(
    cfg: &GridConfig,
    progress: &(dyn Fn() + Sync),
) -> Result<GridResult, StudyError> {
    cfg.validate()?;
    let variants: Vec<&PlantVariant> = cfg
        .plants
        .iter()
        .map(|p| plant_variant(p).expect("validated"))
        .collect();
    let methods: Vec<&str> = METHODS.iter().copied().filter(|m| cfg.wants(m)).collect();
    let want = Wants {
        refine: cfg.wants("refine"),
        oe: cfg.wants("oe"),
        crb: cfg.wants("crb"),
    };
    let cells: Vec<(usize, usize, u64)> = (0..variants.len())
        .flat_map(|p| {
            (0..cfg.snrs.len()).flat_map(move |r| {
                (cfg.first_seed..cfg.first_seed + cfg.seeds).map(move |s| (p, r, s))
            })
        })
        .collect();
    // Order-preserving collect: the same Vec whatever the number of threads.
    let results: Vec<(f64, RunResult)> = cells
        .par_iter()
        .map(|&(p, r, s)| {
            let out = one_run(variants[p].params, &cfg.ns, cfg.snrs[r], s, want);
            progress();
            out
        })
        .collect();
    let per_group = cfg.seeds as usize;
    let mut groups = Vec::with_capacity(variants.len() * cfg.snrs.len());
    let mut rows = Vec::new();
    for (g, chunk) in results.chunks(per_group).enumerate() {
        let (p, r) = (g / cfg.snrs.len(), g % cfg.snrs.len());
        let v = variants[p];
        let study = StudyConfig {
            seeds: cfg.seeds,
            first_seed: cfg.first_seed,
            ns: cfg.ns.clone(),
            snr: cfg.snrs[r],
        };
        for (k, (noise_std, run)) in chunk.iter().enumerate() {
            let seed = cfg.first_seed + k as u64;
            rows_of(v, &study, &methods, seed, *noise_std, run, &mut rows);
        }
        let runs = chunk.iter().map(|(_, r)| r);
        groups.push(aggregate(v.name, &v.params, &study, &methods, runs));
    }
    Ok(GridResult {
        config: cfg.clone(),
        groups,
        rows,
    })
}
