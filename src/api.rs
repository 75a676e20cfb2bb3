//! The command line's results as JSON objects, computed from arrays: one implementation shared by the program
//! (`backlash ... --json`, which reads a file and adds its name) and the Python package (which calls these
//! functions on NumPy arrays). The keys are those of the contract; the program and the package differ only in
//! what belongs to a file (`file`, `decimate`, `validate_on`, `report`).

mod compensate;
mod plant;
mod record;

pub use compensate::{CompensateOptions, compensate, mode_named};
pub use plant::{LIST_NAMES, PlantSpec, SpecValue, simulate_plant};
pub use record::{
    InputCheck, MIN_SAMPLES_PER_PARAMETER, Record, RecordColumns, RecordOptions, sample_period,
};

use std::time::{Duration, Instant};

use serde_json::{Value, json};

use crate::diagnose::engine::{DiagnoseConfig, DiagnoseError, Diagnosis};
pub use crate::diagnose::fit::rate::Rate;
use crate::diagnose::output::DiagnosisOut;
/// A model structure (orders and delay), as the commands declare it.
pub use crate::diagnose::structure::Structure;
use crate::diagnose::structure::{Replacement, StructureChoice, fit_len, select_for_record};
use crate::identify::frequency::analysis::{Analysis, AnalysisOptions, analyse};
use crate::identify::frequency::{FrequencyError, SineRecord};
use crate::identify::mrgia::{Estimate, MrgiaConfig};
use crate::identify::oe::online::OnlineEstimator;
use crate::identify::oe::online::monitor::{Session, Status};
use crate::identify::oe::{
    self, OeConfig, OeError, OeFit, StdErr, Uncertainty, estimate_of, param_names, plant_of,
};
use crate::io::CsvError;
use crate::plant::{MAX_DELAY, ParamError, PlantOutput, PlantParams};

/// Why a computation could not run: the message names what was wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ApiError {
    /// The arrays: lengths, non-finite values.
    #[error("{0}")]
    Record(String),
    /// A setting outside its range.
    #[error("{0}")]
    Setting(String),
    #[error(transparent)]
    Param(#[from] ParamError),
    #[error(transparent)]
    Oe(#[from] OeError),
    #[error(transparent)]
    Diagnose(#[from] DiagnoseError),
    #[error(transparent)]
    Frequency(#[from] FrequencyError),
    /// A data file that cannot be read as a record: the message, naming the file, line and column, with its
    /// causes.
    #[error("{0}")]
    Csv(String),
}

impl From<CsvError> for ApiError {
    fn from(e: CsvError) -> Self {
        let mut message = e.to_string();
        let mut source = std::error::Error::source(&e);
        while let Some(s) = source {
            message.push_str(&format!(": {s}"));
            source = s.source();
        }
        ApiError::Csv(message)
    }
}

/// Checks named arrays of one record: the same length, every value finite, at least `min` samples. Returns the
/// length.
pub fn check_record(arrays: &[(&str, &[f64])], min: usize) -> Result<usize, ApiError> {
    let Some(&(first, a0)) = arrays.first() else {
        return Ok(0);
    };
    for &(name, a) in &arrays[1..] {
        if a.len() != a0.len() {
            return Err(ApiError::Record(format!(
                "{first} has {} samples and {name} {}: they must be the same length",
                a0.len(),
                a.len()
            )));
        }
    }
    for &(name, a) in arrays {
        if let Some(k) = a.iter().position(|v| !v.is_finite()) {
            return Err(ApiError::Record(format!(
                "{name}[{k}] is {}: every sample must be a finite number",
                a[k]
            )));
        }
    }
    if a0.len() < min {
        return Err(ApiError::Record(format!(
            "{} samples are too few: at least {min} are needed",
            a0.len()
        )));
    }
    Ok(a0.len())
}

/// The plant on an input sequence (as `backlash simulate`): the outputs of every sample.
pub fn simulate(spec: &PlantSpec, u: &[f64]) -> Result<Vec<PlantOutput>, ApiError> {
    check_record(&[("u", u)], 0)?;
    Ok(simulate_plant(spec.plant()?, u))
}

/// MRGIA's setting: paper 000's or the project's recommended one, with any value replaced.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MrgiaSettings {
    pub recommended: bool,
    /// Refine on-line to the output-error accuracy after a warm-up, with standard errors (the estimator FMU's
    /// `refine`).
    pub refine: bool,
    pub p0: Option<f64>,
    pub rho_exp: Option<f64>,
    pub rho_min: Option<f64>,
    pub eps: Option<f64>,
    pub sigma0: Option<f64>,
    pub c_init: Option<f64>,
}

impl MrgiaSettings {
    /// `paper` or `recommended`, with `, refine` when refining.
    pub fn name(&self) -> &'static str {
        match (self.recommended, self.refine) {
            (true, false) => "recommended",
            (false, false) => "paper",
            (true, true) => "recommended, refine",
            (false, true) => "paper, refine",
        }
    }

    /// The estimator's configuration for a structure, checked.
    pub fn config(&self, na: usize, nb: usize, delay: usize) -> Result<MrgiaConfig, ApiError> {
        let base = if self.recommended {
            MrgiaConfig::recommended(na, nb, delay)
        } else {
            MrgiaConfig::paper(na, nb, delay)
        };
        let cfg = MrgiaConfig {
            p0: self.p0.unwrap_or(base.p0),
            rho_exp: self.rho_exp.unwrap_or(base.rho_exp),
            rho_min: self.rho_min.unwrap_or(base.rho_min),
            eps: self.eps.unwrap_or(base.eps),
            sigma0: self.sigma0.unwrap_or(base.sigma0),
            c_init: self.c_init.unwrap_or(base.c_init),
            ..base
        };
        cfg.validate()?;
        Ok(cfg)
    }
}

/// The JSON of `identify mrgia` for an estimator that has seen `samples` samples, `updates` of them updating,
/// whose input `check` saw; a refining estimator adds `refine` and `std_err` (as the FMU's `*_se` outputs: 0
/// while unknown, during the warm-up).
pub fn mrgia_json(
    est: &OnlineEstimator,
    samples: u64,
    updates: u64,
    setting: &str,
    check: &InputCheck,
) -> Value {
    let e = est.estimate();
    let cfg = est.config();
    let mut out = json!({
        "method": "mrgia",
        "a": e.a,
        "b": e.b,
        "m1": e.m1,
        "m2": e.m2,
        "c1": e.c1,
        "c2": e.c2,
        "samples": samples,
        "updates": updates,
        "setting": setting,
        "config": cfg,
        "warnings": check.warnings(samples, cfg.n_params()),
    });
    if est.refining_kind() {
        out["refine"] = json!(true);
        let se: Vec<f64> = (0..cfg.n_params()).map(|i| est.std_err_at(i)).collect();
        out["std_err"] = json!(StdErr::from_flat(cfg.na, cfg.nb, &se));
    }
    out
}

/// The JSON of `backlash monitor` for a monitored record whose input `check` saw: the session's summary with
/// `warnings`, the input check of `identify mrgia` (what the record cannot support) and a sentence for what
/// the summary alone would leave unsaid: a negative play estimate (a play cannot be negative: the record has
/// not determined it) and a record that ended before the test ran.
pub fn monitor_json(session: &Session, check: &InputCheck) -> Result<Value, ApiError> {
    let sum = session.summary();
    let params = session.estimator().config().n_params();
    let mut warnings = check.warnings(sum.samples, params);
    if sum.play < 0.0 {
        warnings.push(format!(
            "the play estimate c1 + c2 is negative ({:.4}): a play cannot be, so the record has not \
             determined it (an input that does not move the output both ways, or the estimator still in its \
             warm-up)",
            sum.play
        ));
    }
    if sum.status == Status::Learning {
        warnings.push(
            "the record ended before the reference model was frozen (warm-up, then the learning samples): \
             no wear test ran"
                .into(),
        );
    }
    let mut out = serde_json::to_value(&sum).map_err(|e| ApiError::Setting(e.to_string()))?;
    out["warnings"] = json!(warnings);
    Ok(out)
}

/// MRGIA over a whole record: the JSON of `identify mrgia`. `progress(done, total)` is called every `every`
/// samples and at the end.
pub fn identify_mrgia(
    u: &[f64],
    y: &[f64],
    na: usize,
    nb: usize,
    delay: usize,
    settings: &MrgiaSettings,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Value, ApiError> {
    let n = check_record(&[("u", u), ("y", y)], 1)?;
    let mut est = OnlineEstimator::new(settings.config(na, nb, delay)?, settings.refine)?;
    let every = (n / 100).max(1);
    let mut updates = 0u64;
    let mut check = InputCheck::default();
    for (k, (&uk, &yk)) in u.iter().zip(y).enumerate() {
        updates += u64::from(est.update(uk, yk).updating);
        check.push(uk);
        if (k + 1) % every == 0 {
            progress(k + 1, n);
        }
    }
    if n % every != 0 {
        progress(n, n);
    }
    Ok(mrgia_json(&est, n as u64, updates, settings.name(), &check))
}

/// The settings of `identify oe`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OeOptions {
    /// The declared structure; `None`: chosen from the data.
    pub structure: Option<Structure>,
    /// The longest delay the structure selection tries (1 to 64).
    pub max_delay: usize,
    /// Start only from MRGIA's recommended estimate.
    pub single_start: bool,
    /// Levenberg-Marquardt iterations per start (default: the fit's own).
    pub max_iter: Option<usize>,
    /// The Cramer-Rao bound at the fitted model for this noise std.
    pub crb_noise_std: Option<f64>,
}

impl Default for OeOptions {
    fn default() -> Self {
        Self {
            structure: None,
            max_delay: 10,
            single_start: false,
            max_iter: None,
            crb_noise_std: None,
        }
    }
}

/// An output-error fit with what the command reports beside it.
#[derive(Debug, Clone)]
pub struct OeRun {
    pub structure: StructureChoice,
    pub cfg: OeConfig,
    pub fit: OeFit,
    /// The Cramer-Rao bound asked for with [`OeOptions::crb_noise_std`].
    pub bound: Option<Uncertainty>,
    /// Wall-clock time of the fit.
    pub seconds: f64,
    /// What the input can tell.
    pub check: InputCheck,
    /// The output's standard deviation over the record: the RMSE of predicting its mean.
    pub output_std: f64,
}

/// The output-error fit of `identify oe`: the structure (declared or chosen), the fit, the bound.
pub fn identify_oe(u: &[f64], y: &[f64], opts: &OeOptions) -> Result<OeRun, ApiError> {
    identify_oe_with_progress(u, y, opts, &|_| {})
}

/// [`identify_oe`], telling `progress` what it is doing at each stage.
pub fn identify_oe_with_progress(
    u: &[f64],
    y: &[f64],
    opts: &OeOptions,
    progress: &dyn Fn(&str),
) -> Result<OeRun, ApiError> {
    check_record(&[("u", u), ("y", y)], 0)?;
    if !(1..=MAX_DELAY).contains(&opts.max_delay) {
        return Err(ApiError::Setting(format!(
            "the longest delay to try, {}, must be between 1 and {MAX_DELAY}",
            opts.max_delay
        )));
    }
    let mut structure = match opts.structure {
        Some(s) => StructureChoice::declared(s),
        None => {
            progress("choosing the structure (orders and delay)");
            select_for_record(u, y, opts.max_delay, DiagnoseConfig::auto().fit_fraction)
        }
    };
    let started = Instant::now();
    progress(&format!(
        "fitting the output-error model ({})",
        structure.chosen
    ));
    let (cfg, fit) = fit_oe(&mut structure, opts, u, y)?;
    let seconds = started.elapsed().as_secs_f64();
    let bound = match opts.crb_noise_std {
        Some(s) => Some(oe::crb(&plant_of(&fit.estimate, cfg.delay)?, u, s)?),
        None => None,
    };
    Ok(OeRun {
        structure,
        cfg,
        fit,
        bound,
        seconds,
        check: InputCheck::of(u),
        output_std: crate::stats::std_dev(y),
    })
}

/// The output-error configuration of a structure with the settings of `opts`, checked.
fn oe_config(s: Structure, opts: &OeOptions) -> Result<OeConfig, ApiError> {
    let mut cfg = OeConfig::new(s.na, s.nb, s.delay);
    cfg.extra_starts = !opts.single_start;
    if let Some(m) = opts.max_iter {
        cfg.max_iter = m;
    }
    cfg.validate()?;
    Ok(cfg)
}

/// The fit of the chosen structure. A selected structure whose fit the record does not excite (the
/// selection checks this on the fit part; the whole record can still differ) is replaced by the best
/// identifiable smaller one among the structures fitted fully, and the choice says so; a declared structure
/// is the user's and is refused with the reason.
fn fit_oe(
    structure: &mut StructureChoice,
    opts: &OeOptions,
    u: &[f64],
    y: &[f64],
) -> Result<(OeConfig, OeFit), ApiError> {
    let first = structure.chosen;
    let cfg = oe_config(first, opts)?;
    let err = match oe::fit(&cfg, u, y) {
        Ok(fit) => return Ok((cfg, fit)),
        Err(e @ OeError::NotExcited { .. }) if structure.chosen_by == "selected" => e,
        Err(e) => return Err(e.into()),
    };
    let mut smaller: Vec<(Structure, f64)> = structure
        .candidates
        .iter()
        .filter(|c| c.structure.n_params() < first.n_params() && c.excited != Some(false))
        .filter_map(|c| c.model_rmse.map(|r| (c.structure, r)))
        .collect();
    smaller.sort_by(|a, b| a.1.total_cmp(&b.1));
    for (s, _) in smaller {
        let cfg = oe_config(s, opts)?;
        if let Ok(fit) = oe::fit(&cfg, u, y) {
            structure.replaced = Some(Replacement {
                structure: first,
                reason: format!(
                    "{first} was chosen on the fit part, but on the whole record {err}; the best identifiable \
                     smaller structure, {s}, replaces it"
                ),
            });
            for c in &mut structure.candidates {
                c.chosen = c.structure == s;
            }
            structure.chosen = s;
            return Ok((cfg, fit));
        }
    }
    Err(err.into())
}

impl OeRun {
    /// What a plan is based on: the bound when one was asked for, else the fit's standard errors.
    pub fn plan_basis(&self) -> &Uncertainty {
        self.bound.as_ref().unwrap_or(&self.fit.uncertainty)
    }

    /// The JSON of `identify oe`, with a plan for `target_rel` when given.
    pub fn json(&self, target_rel: Option<f64>) -> Result<Value, ApiError> {
        let (f, s) = (&self.fit, self.structure.chosen);
        let mut out = estimate_json(&f.estimate);
        let extra = json!({
            "method": "oe",
            "samples": f.samples,
            "std_err": f.std_err,
            "sigma": f.sigma,
            "rmse": f.rmse,
            "constant_rmse": self.output_std,
            "fit_percent": 100.0 * (1.0 - f.rmse / self.output_std),
            "cost": f.cost,
            "iterations": f.iterations,
            "converged": f.converged,
            "modes": {"up": f.modes[0], "down": f.modes[1], "held": f.modes[2]},
            "start": {
                "method": f.start_method,
                "rmse": f.start_rmse,
                "estimate": estimate_json(&f.start),
            },
            "covariance": f.uncertainty.covariance,
            "names": param_names(self.cfg.na, self.cfg.nb),
            "seconds": self.seconds,
            "config": self.cfg,
            "na": s.na,
            "nb": s.nb,
            "delay": s.delay,
            "structure": self.structure,
            "warnings": self.check.warnings(f.samples as u64, self.fit.uncertainty.names.len()),
        });
        merge(&mut out, extra);
        if let Some(c) = &self.bound {
            out["crb"] = json!({"noise_std": c.noise_std, "std": c.std_err()});
        }
        if let Some(r) = target_rel {
            out["plan"] = plan_json(self.plan_basis(), r)?;
        }
        Ok(out)
    }
}

/// The noise of a Cramer-Rao bound: its standard deviation, or a signal-to-noise ratio std(w) / noise std.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CrbNoise {
    Std(f64),
    Snr(f64),
}

/// The bound of `backlash crb` with each parameter's relative standard deviation (`None` for a zero value).
#[derive(Debug, Clone)]
pub struct CrbRun {
    pub truth: PlantParams,
    pub bound: Uncertainty,
    pub rel: Vec<Option<f64>>,
    /// What the input can tell.
    pub check: InputCheck,
}

/// The parameters of the model whose bound `crb` computes (the others of the plant are not part of it).
pub const CRB_NAMES: [&str; 7] = ["a", "b", "delay", "m1", "m2", "c1", "c2"];

/// The Cramer-Rao bound of the output-error model of `truth` (its noise settings are ignored) on input `u`.
pub fn crb(u: &[f64], truth: &PlantSpec, noise: CrbNoise) -> Result<CrbRun, ApiError> {
    check_record(&[("u", u)], 0)?;
    if let Some(name) = truth.given().find(|n| !CRB_NAMES.contains(n)) {
        return Err(ApiError::Setting(format!(
            "the bound is for the output-error model of {}; {name} is not one of its parameters",
            CRB_NAMES.join(", ")
        )));
    }
    let truth = PlantParams {
        noise_std: 0.0,
        noise_seed: 0,
        ..truth.params()?
    };
    let noise_std = match noise {
        CrbNoise::Std(s) => s,
        CrbNoise::Snr(r) => {
            if !(r.is_finite() && r > 0.0) {
                return Err(ApiError::Setting(format!(
                    "the signal-to-noise ratio {r} must be a positive finite number"
                )));
            }
            let w = oe::simulate(&estimate_of(&truth), truth.arx.delay, u)?;
            crate::stats::std_dev(&w) / r
        }
    };
    let bound = oe::crb(&truth, u, noise_std)?;
    let rel = bound
        .std
        .iter()
        .zip(&bound.theta)
        .map(|(s, t)| (*t != 0.0).then(|| s / t.abs()))
        .collect();
    Ok(CrbRun {
        truth,
        bound,
        rel,
        check: InputCheck::of(u),
    })
}

impl CrbRun {
    /// The JSON of `backlash crb`; `input` names where the input came from.
    pub fn json(&self, input: &str, target_rel: Option<f64>) -> Result<Value, ApiError> {
        let c = &self.bound;
        let mut out = json!({
            "method": "crb",
            "input": input,
            "samples": c.samples,
            "noise_std": c.noise_std,
            "truth": estimate_json(&estimate_of(&self.truth)),
            "std": c.std_err(),
            "rel_std": named(&c.names, &self.rel),
            "covariance": c.covariance,
            "names": c.names,
            "warnings": self.check.warnings(c.samples as u64, c.names.len()),
        });
        if let Some(r) = target_rel {
            out["plan"] = plan_json(c, r)?;
        }
        Ok(out)
    }
}

/// The estimate under the contract's names.
pub fn estimate_json(e: &Estimate) -> Value {
    json!({"a": e.a, "b": e.b, "m1": e.m1, "m2": e.m2, "c1": e.c1, "c2": e.c2})
}

/// `{"a1": v, ...}` for per-parameter values in theta order.
fn named<T: serde::Serialize>(names: &[String], v: &[T]) -> Value {
    Value::Object(
        names
            .iter()
            .zip(v)
            .map(|(n, x)| (n.clone(), json!(x)))
            .collect(),
    )
}

/// The samples each parameter needs for a relative standard deviation of `target` (1/sqrt(N) scaling).
fn plan_json(unc: &Uncertainty, target: f64) -> Result<Value, ApiError> {
    let (per, all) = unc.samples_for(target)?;
    Ok(json!({
        "target_rel": target,
        "basis_samples": unc.samples,
        "basis_noise_std": unc.noise_std,
        "samples": named(&unc.names, &per),
        "samples_all": all,
    }))
}

/// Adds the keys of `extra` to the object `out`.
fn merge(out: &mut Value, extra: Value) {
    if let (Value::Object(o), Value::Object(e)) = (out, extra) {
        o.extend(e);
    }
}

/// What `identify frequency` prints with every result: what a frequency estimate means.
pub const FREQUENCY_CONVENTION: &str = "phase in [0, pi): the model (G, F) if -arg G(jw) mod 2pi is in [0, pi), else its dual \
     (-G, F[-x]) (paper 003 eqs. (6)-(7)); scaled by eqs. (29)-(30a) so that sum_i |a_i|^(n/i) = 1 for the \
     reported ascending border, gain = |G(jw)|/K";

/// Paper 003 on one sine experiment: the analysis of `identify frequency`.
pub fn identify_frequency(
    time: &[f64],
    u: Option<&[f64]>,
    y: &[f64],
    opts: &AnalysisOptions,
) -> Result<Analysis, ApiError> {
    match u {
        Some(u) => check_record(&[("time", time), ("u", u), ("y", y)], 0)?,
        None => check_record(&[("time", time), ("y", y)], 0)?,
    };
    if let Some(k) = time.windows(2).position(|w| w[1] <= w[0]) {
        return Err(ApiError::Record(format!(
            "time[{}] = {} does not increase after time[{k}] = {}",
            k + 1,
            time[k + 1],
            time[k]
        )));
    }
    Ok(analyse(&SineRecord { time, u, y }, opts)?)
}

/// The JSON of `identify frequency`.
pub fn frequency_json(a: &Analysis) -> Value {
    let mut out = json!({"method": "frequency", "convention": FREQUENCY_CONVENTION});
    merge(
        &mut out,
        serde_json::to_value(a).expect("an analysis serialises"),
    );
    out
}

/// A wall-clock budget in seconds, checked (0 < budget <= 1e6), as the diagnosis takes it.
pub fn time_budget(seconds: f64) -> Result<Duration, ApiError> {
    if !(seconds.is_finite() && seconds > 0.0 && seconds <= 1e6) {
        return Err(ApiError::Setting(format!(
            "the time budget {seconds} must be a number of seconds between 0 and 1000000 (not 0)"
        )));
    }
    Ok(Duration::from_secs_f64(seconds))
}

/// `backlash diagnose` on a record.
pub fn diagnose(u: &[f64], y: &[f64], cfg: &DiagnoseConfig) -> Result<Diagnosis, ApiError> {
    diagnose_with_progress(u, y, cfg, &|_| {})
}

/// [`diagnose`], telling `progress` what it is doing at each stage (from any thread).
pub fn diagnose_with_progress(
    u: &[f64],
    y: &[f64],
    cfg: &DiagnoseConfig,
    progress: &(dyn Fn(&str) + Sync),
) -> Result<Diagnosis, ApiError> {
    check_record(&[("u", u), ("y", y)], 0)?;
    Ok(crate::diagnose::engine::diagnose_with_progress(
        u, y, cfg, progress,
    )?)
}

/// What `Ts` means in a diagnosis without a known sample period.
pub const NO_TS_NOTE: &str = "the sample period is not known (the Python functions take it as ts=): rates and \
     frequencies are given per sample, and the keys per second or in Hz (c1_rate_per_s, frequency_hz, ...) are \
     left out";

/// The JSON of `backlash diagnose` for a record with sample period `ts` (when known), decimated by
/// `decimate`, without what belongs to a file; with the record's `warnings`.
pub fn diagnosis_json(d: &Diagnosis, u: &[f64], ts: Option<f64>, decimate: usize) -> Value {
    let mut out = serde_json::to_value(DiagnosisOut::new(d, ts)).expect("a diagnosis serialises");
    out["Ts"] = json!(ts);
    if ts.is_none() {
        out["Ts_note"] = json!(NO_TS_NOTE);
    }
    out["decimate"] = json!(decimate);
    out["closest_alternative"] = json!(d.closest_alternative());
    let s = d.structure.chosen;
    let params = s.na + s.nb + 1 + 3;
    let mut warnings = InputCheck::of(u).warnings(d.n_fit as u64, params);
    warnings.extend(d.explained.warnings(d.after_rmse()));
    out["warnings"] = json!(warnings);
    out
}

/// The rate `diagnose` and `identify oe` work at: the user's decimation when given (`user`, the record already
/// decimated by it), else the one the data ask for on a record whose share `fit_fraction` is fitted (see
/// [`crate::diagnose::fit::rate`]). The program and the Python functions call this alike.
pub fn choose_rate(
    u: &[f64],
    y: &[f64],
    user: Option<usize>,
    fit_fraction: f64,
) -> Result<Rate, ApiError> {
    check_record(&[("u", u), ("y", y)], 0)?;
    match user {
        Some(d) => {
            RecordOptions {
                decimate: d,
                ..RecordOptions::default()
            }
            .check()?;
            Ok(Rate::user(d))
        }
        None if u.len() < 2 => Ok(Rate::user(1)),
        // On the record as it is: about the operating point, the rate's candidate fits rest where the
        // oversampled test records do not start, and chose every sample at 30x and 100x (11.5x the true
        // model's error); the rate is therefore not offset-invariant yet (EMPS shifted by (-3, -7): 4, not 9).
        None => Ok(crate::diagnose::fit::rate::choose(
            u,
            y,
            fit_len(u.len(), fit_fraction),
        )),
    }
}

/// Adds the linear baseline to `diagnose`'s JSON (`linear_baseline`, see
/// [`crate::diagnose::fit::baseline`]): the best ARX model with an intercept on `u`, `y` (the record at the rate
/// the rate stage saw), held against the final model of `d`, which worked on it decimated by `decimate`
/// (block means); a warning says so when the final model is behind it on the fit part.
pub fn with_linear_baseline(
    out: &mut Value,
    (u, y): (&[f64], &[f64]),
    fit_fraction: f64,
    d: &Diagnosis,
    decimate: usize,
) {
    let n_fit = fit_len(u.len().min(y.len()), fit_fraction);
    let last = d.steps().last().map_or(&d.base_sim.y, |c| &c.output);
    let check =
        crate::diagnose::fit::baseline::check((u, y), n_fit, (last, d.after_rmse()), decimate);
    if let Some(c) = check.as_ref().filter(|c| c.final_behind)
        && let Some(w) = out["warnings"].as_array_mut()
    {
        w.push(json!(c.reason));
    }
    out["linear_baseline"] = json!(check);
}

/// Adds the rate to a command's JSON: `decimate` (the factor the record was worked at) and `rate` (how it
/// was chosen and why).
pub fn with_rate(out: &mut Value, rate: &Rate) {
    out["decimate"] = json!(rate.decimate);
    out["rate"] = json!(rate);
}

/// The record's input and output at the rate chosen by [`choose_rate`] (`user`: the factor asked for), with
/// the rate.
pub fn at_rate(
    u: &[f64],
    y: &[f64],
    user: Option<usize>,
    fit_fraction: f64,
) -> Result<(Rate, [Vec<f64>; 2]), ApiError> {
    let [u, y] = decimated(u, y, user.unwrap_or(1))?;
    let rate = choose_rate(&u, &y, user, fit_fraction)?;
    let out = match rate.chosen_by {
        "data" => decimated(&u, &y, rate.decimate)?,
        _ => [u, y],
    };
    Ok((rate, out))
}

/// The record's input and output after decimation by `decimate` (block means), checked.
pub fn decimated(u: &[f64], y: &[f64], decimate: usize) -> Result<[Vec<f64>; 2], ApiError> {
    check_record(&[("u", u), ("y", y)], 0)?;
    RecordOptions {
        decimate,
        ..RecordOptions::default()
    }
    .check()?;
    let mut d = crate::stats::block_means(&[u, y], decimate).into_iter();
    Ok([d.next().unwrap_or_default(), d.next().unwrap_or_default()])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_are_refused_with_the_array_and_sample_named() {
        let u = [1.0, 2.0, f64::NAN];
        let y = [1.0, 2.0];
        let e = check_record(&[("u", &u), ("y", &y)], 0).unwrap_err();
        assert_eq!(
            e.to_string(),
            "u has 3 samples and y 2: they must be the same length"
        );
        let e = check_record(&[("u", &u), ("y", &u)], 0).unwrap_err();
        assert_eq!(
            e.to_string(),
            "u[2] is NaN: every sample must be a finite number"
        );
        let e = check_record(&[("u", &y)], 3).unwrap_err();
        assert_eq!(
            e.to_string(),
            "2 samples are too few: at least 3 are needed"
        );
        assert_eq!(check_record(&[("u", &y), ("y", &y)], 2), Ok(2));
    }
}
