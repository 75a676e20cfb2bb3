//! `backlash_fmu._backlash`: the library on NumPy arrays, and the `backlash` command.
//!
//! Each function checks its arguments in the library (`backlash::api`), runs with the GIL released, and
//! returns what the command line prints with `--json` (as its text: `backlash_fmu` parses it, so the dicts
//! equal the program's JSON number for number). A bad argument raises `ValueError` with the library's message;
//! a panic (a bug) is caught here and raised as `RuntimeError`, never unwound into Python.

use std::panic::{AssertUnwindSafe, catch_unwind};

use std::sync::Mutex;

use backlash::api::{self, ApiError, CrbNoise, LIST_NAMES, MrgiaSettings, OeOptions, PlantSpec};
use backlash::diagnose::engine::DiagnoseConfig;
use backlash::diagnose::structure::Structure;
use backlash::identify::frequency::analysis::AnalysisOptions;
use backlash::progress::StageCount;
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// The program (src/bin/backlash): `backlash_fmu`'s console script runs [`cli::run`].
#[allow(
    dead_code,
    reason = "the program's fn main is not called here: the extension calls cli::run"
)]
#[path = "../../src/bin/backlash/main.rs"]
mod cli;

/// Runs `f` with the GIL released; a library error becomes `ValueError`, a panic `RuntimeError`.
fn compute<T: Send>(py: Python<'_>, f: impl FnOnce() -> Result<T, ApiError> + Send) -> PyResult<T> {
    match py.detach(|| catch_unwind(AssertUnwindSafe(f))) {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(e)) => Err(PyValueError::new_err(e.to_string())),
        Err(panic) => {
            let msg = panic
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| panic.downcast_ref::<&str>().copied())
                .unwrap_or("no message");
            Err(PyRuntimeError::new_err(format!(
                "backlash: internal error (please report it): {msg}"
            )))
        }
    }
}

/// The structure given by all three of na, nb and delay, or none of them.
fn structure(
    na: Option<usize>,
    nb: Option<usize>,
    delay: Option<usize>,
) -> PyResult<Option<Structure>> {
    match (na, nb, delay) {
        (Some(na), Some(nb), Some(delay)) => Ok(Some(Structure { na, nb, delay })),
        (None, None, None) => Ok(None),
        _ => Err(PyValueError::new_err(
            "give all three of na, nb and delay, or none of them (then the structure is chosen from the data)",
        )),
    }
}

/// A progress report to a Python callable `progress(done, total)`, made with the GIL taken back; the first
/// exception it raises is kept (and later reports are skipped) until the computation returns.
struct Progress {
    callback: Option<Py<PyAny>>,
    error: Option<PyErr>,
}

impl Progress {
    fn new(callback: Option<Py<PyAny>>) -> Self {
        Self {
            callback,
            error: None,
        }
    }

    fn report(&mut self, done: usize, total: usize) {
        if self.error.is_some() {
            return;
        }
        if let Some(cb) = &self.callback {
            Python::attach(|py| {
                if let Err(e) = cb.call1(py, (done, total)) {
                    self.error = Some(e);
                }
            });
        }
    }

    fn finish<T>(self, result: PyResult<T>) -> PyResult<T> {
        match self.error {
            Some(e) => Err(e),
            None => result,
        }
    }
}

/// Stage reports (sentences) as calls `progress(done, total)` of a Python callable, counted by
/// [`StageCount`] (a stage one, a stage of n parts n; the total grows as parts are announced), from any
/// thread, with the GIL taken back; the first exception it raises is kept (and later reports skipped) until
/// the computation returns. A computation that succeeds ends with `progress(total, total)`.
struct Stages {
    callback: Option<Py<PyAny>>,
    count: StageCount,
    error: Mutex<Option<PyErr>>,
}

impl Stages {
    /// For a computation of at least `expected` stages.
    fn new(callback: Option<Py<PyAny>>, expected: usize) -> Self {
        Self {
            callback,
            count: StageCount::new(expected),
            error: Mutex::new(None),
        }
    }

    fn report(&self, stage: &str) {
        if self.callback.is_some() {
            self.call(self.count.stage(stage));
        }
    }

    fn call(&self, (done, total): (usize, usize)) {
        let Some(cb) = &self.callback else {
            return;
        };
        let mut error = self.error.lock().unwrap_or_else(|e| e.into_inner());
        if error.is_none() {
            Python::attach(|py| {
                if let Err(e) = cb.call1(py, (done, total)) {
                    *error = Some(e);
                }
            });
        }
    }

    fn finish<T>(self, result: PyResult<T>) -> PyResult<T> {
        if result.is_ok() {
            self.call(self.count.finish());
        }
        match self.error.into_inner().unwrap_or_else(|e| e.into_inner()) {
            Some(e) => Err(e),
            None => result,
        }
    }
}

fn json_text(v: &serde_json::Value) -> String {
    v.to_string()
}

/// A NumPy array made here.
type Array<'py> = Bound<'py, PyArray1<f64>>;

/// The plant parameters of a dict (the plant FMU's names; lists for `a` and `b`), refused by name when
/// unknown.
fn plant_spec(params: &Bound<'_, PyDict>) -> PyResult<PlantSpec> {
    let mut spec = PlantSpec::default();
    let err = |e: ApiError| PyValueError::new_err(e.to_string());
    for (k, v) in params.iter() {
        let name: String = k.extract()?;
        if LIST_NAMES.contains(&name.as_str()) {
            let list: Vec<f64> = v.extract().map_err(|_| {
                PyValueError::new_err(format!("{name} must be a list of numbers, not {v}"))
            })?;
            spec.set_list(&name, &list).map_err(err)?;
        } else {
            let x: f64 = v
                .extract()
                .map_err(|_| PyValueError::new_err(format!("{name} must be a number, not {v}")))?;
            spec.set(&name, x).map_err(err)?;
        }
    }
    Ok(spec)
}

/// plant_parameters() -> the names `simulate` takes: `a`, `b` (lists), then the plant FMU's parameters.
#[pyfunction]
fn plant_parameters() -> Vec<&'static str> {
    PlantSpec::names()
}

/// simulate(u, params) -> (x, w, y): the plant of `backlash simulate`; `params` a dict of the plant FMU's
/// parameters by name (`a`, `b` lists; unknown names are refused).
#[pyfunction]
fn simulate<'py>(
    py: Python<'py>,
    u: PyReadonlyArray1<'py, f64>,
    params: &Bound<'py, PyDict>,
) -> PyResult<(Array<'py>, Array<'py>, Array<'py>)> {
    let spec = plant_spec(params)?;
    let u = u.as_slice()?;
    let out = compute(py, || api::simulate(&spec, u))?;
    let col =
        |f: fn(&backlash::plant::PlantOutput) -> f64| -> Vec<f64> { out.iter().map(f).collect() };
    Ok((
        PyArray1::from_vec(py, col(|o| o.x)),
        PyArray1::from_vec(py, col(|o| o.w)),
        PyArray1::from_vec(py, col(|o| o.y)),
    ))
}

/// identify_mrgia(u, y, na, nb, delay, recommended, refine, p0, rho_exp, rho_min, eps, sigma0, c_init, progress)
/// -> the JSON text of `identify mrgia`.
#[pyfunction]
#[pyo3(signature = (u, y, na, nb, delay, recommended=false, refine=false, p0=None, rho_exp=None, rho_min=None, eps=None,
    sigma0=None, c_init=None, progress=None, decimate=1))]
#[expect(
    clippy::too_many_arguments,
    reason = "the Python signature: keyword arguments with defaults"
)]
fn identify_mrgia(
    py: Python<'_>,
    u: PyReadonlyArray1<'_, f64>,
    y: PyReadonlyArray1<'_, f64>,
    na: usize,
    nb: usize,
    delay: usize,
    recommended: bool,
    refine: bool,
    p0: Option<f64>,
    rho_exp: Option<f64>,
    rho_min: Option<f64>,
    eps: Option<f64>,
    sigma0: Option<f64>,
    c_init: Option<f64>,
    progress: Option<Py<PyAny>>,
    decimate: usize,
) -> PyResult<String> {
    let settings = MrgiaSettings {
        recommended,
        refine,
        p0,
        rho_exp,
        rho_min,
        eps,
        sigma0,
        c_init,
    };
    let (u, y) = (u.as_slice()?, y.as_slice()?);
    let mut bar = Progress::new(progress);
    let r = compute(py, || {
        let [u, y] = api::decimated(u, y, decimate)?;
        api::identify_mrgia(&u, &y, na, nb, delay, &settings, &mut |d, t| {
            bar.report(d, t)
        })
        .map(|v| json_text(&v))
    });
    bar.finish(r)
}

/// identify_oe(u, y, na, nb, delay, max_delay, single_start, max_iter, crb_noise_std, target_rel)
/// -> the JSON text of `identify oe`.
#[pyfunction]
#[pyo3(signature = (u, y, na=None, nb=None, delay=None, max_delay=10, single_start=false, max_iter=None,
    crb_noise_std=None, target_rel=None, progress=None, decimate=None))]
#[expect(
    clippy::too_many_arguments,
    reason = "the Python signature: keyword arguments with defaults"
)]
fn identify_oe(
    py: Python<'_>,
    u: PyReadonlyArray1<'_, f64>,
    y: PyReadonlyArray1<'_, f64>,
    na: Option<usize>,
    nb: Option<usize>,
    delay: Option<usize>,
    max_delay: usize,
    single_start: bool,
    max_iter: Option<usize>,
    crb_noise_std: Option<f64>,
    target_rel: Option<f64>,
    progress: Option<Py<PyAny>>,
    decimate: Option<usize>,
) -> PyResult<String> {
    let opts = OeOptions {
        structure: structure(na, nb, delay)?,
        max_delay,
        single_start,
        max_iter,
        crb_noise_std,
    };
    let (u, y) = (u.as_slice()?, y.as_slice()?);
    // The fit, and the choice of the structure when it is not declared.
    let stages = Stages::new(progress, 1 + usize::from(opts.structure.is_none()));
    let r = compute(py, || {
        let fit_fraction = DiagnoseConfig::auto().fit_fraction;
        let (rate, [u, y]) = api::at_rate(u, y, decimate, fit_fraction)?;
        let mut out = api::identify_oe_with_progress(&u, &y, &opts, &|s| stages.report(s))?
            .json(target_rel)?;
        api::with_rate(&mut out, &rate);
        Ok(json_text(&out))
    });
    stages.finish(r)
}

/// identify_frequency(time, u, y, omega, amplitude, degree, start, end, transient) -> the JSON text of
/// `identify frequency`.
#[pyfunction]
#[pyo3(signature = (time, u, y, omega=None, amplitude=None, degree=None, start=None, end=None,
    transient=None))]
#[expect(
    clippy::too_many_arguments,
    reason = "the Python signature: keyword arguments with defaults"
)]
fn identify_frequency(
    py: Python<'_>,
    time: PyReadonlyArray1<'_, f64>,
    u: Option<PyReadonlyArray1<'_, f64>>,
    y: PyReadonlyArray1<'_, f64>,
    omega: Option<f64>,
    amplitude: Option<f64>,
    degree: Option<usize>,
    start: Option<f64>,
    end: Option<f64>,
    transient: Option<f64>,
) -> PyResult<String> {
    let opts = AnalysisOptions {
        omega,
        amplitude,
        degree,
        start,
        end,
        transient,
    };
    let (time, y) = (time.as_slice()?, y.as_slice()?);
    let u = u.as_ref().map(|u| u.as_slice()).transpose()?;
    compute(py, || {
        api::identify_frequency(time, u, y, &opts).map(|a| json_text(&api::frequency_json(&a)))
    })
}

/// crb(u, truth, noise_std, snr, target_rel, input) -> the JSON text of `backlash crb`; `truth` a dict of
/// the model's parameters by name.
#[pyfunction]
#[pyo3(signature = (u, truth, noise_std=None, snr=None, target_rel=None, input="array"))]
fn crb(
    py: Python<'_>,
    u: PyReadonlyArray1<'_, f64>,
    truth: &Bound<'_, PyDict>,
    noise_std: Option<f64>,
    snr: Option<f64>,
    target_rel: Option<f64>,
    input: &str,
) -> PyResult<String> {
    let spec = plant_spec(truth)?;
    let noise = match (noise_std, snr) {
        (Some(s), None) => CrbNoise::Std(s),
        (None, Some(r)) => CrbNoise::Snr(r),
        _ => {
            return Err(PyValueError::new_err(
                "give one of noise_std and snr (the noise of the bound)",
            ));
        }
    };
    let u = u.as_slice()?;
    compute(py, || {
        api::crb(u, &spec, noise)?
            .json(input, target_rel)
            .map(|v| json_text(&v))
    })
}

/// diagnose(u, y, na, nb, delay, ts, max_delay, fit_fraction, seed, max_effects, time_budget, decimate,
/// progress) -> the JSON text of `backlash diagnose` (without what belongs to a file).
#[pyfunction]
#[pyo3(signature = (u, y, na=None, nb=None, delay=None, ts=None, max_delay=10, fit_fraction=0.7, seed=0,
    max_effects=3, time_budget=300.0, decimate=None, progress=None))]
#[expect(
    clippy::too_many_arguments,
    reason = "the Python signature: keyword arguments with defaults"
)]
fn diagnose(
    py: Python<'_>,
    u: PyReadonlyArray1<'_, f64>,
    y: PyReadonlyArray1<'_, f64>,
    na: Option<usize>,
    nb: Option<usize>,
    delay: Option<usize>,
    ts: Option<f64>,
    max_delay: usize,
    fit_fraction: f64,
    seed: u64,
    max_effects: usize,
    time_budget: f64,
    decimate: Option<usize>,
    progress: Option<Py<PyAny>>,
) -> PyResult<String> {
    if let Some(t) = ts
        && !(t.is_finite() && t > 0.0)
    {
        return Err(PyValueError::new_err(format!(
            "the sample period ts = {t} must be a positive finite number of seconds"
        )));
    }
    let structure = structure(na, nb, delay)?;
    let (u, y) = (u.as_slice()?, y.as_slice()?);
    // The initial state, the linear and the backlash fits, the choice of the structure when it is not
    // declared; then the rounds, counted as their candidates are announced.
    let stages = Stages::new(progress, 3 + usize::from(structure.is_none()));
    let r = compute(py, || {
        let cfg = DiagnoseConfig {
            structure,
            max_delay,
            fit_fraction,
            seed,
            max_effects,
            time_budget: api::time_budget(time_budget)?,
            ..DiagnoseConfig::auto()
        };
        let (rate, [u_w, y_w]) = api::at_rate(u, y, decimate, fit_fraction)?;
        let d = api::diagnose_with_progress(&u_w, &y_w, &cfg, &|s| stages.report(s))?;
        let ts = ts.map(|t| t * rate.decimate as f64);
        let mut out = api::diagnosis_json(&d, &u_w, ts, rate.decimate);
        api::with_rate(&mut out, &rate);
        // The linear baseline at the rate the rate stage saw (the user's decimation, if any).
        let [u_g, y_g] = api::decimated(u, y, decimate.unwrap_or(1))?;
        let factor = if rate.chosen_by == "data" {
            rate.decimate
        } else {
            1
        };
        api::with_linear_baseline(&mut out, (&u_g, &y_g), fit_fraction, &d, factor);
        Ok(json_text(&out))
    });
    stages.finish(r)
}

/// monitor(u, y, na, nb, delay, wear_ratio, alarm_period, learn, reference_play, ts, recommended)
/// -> the JSON text of `backlash monitor` (times are k ts).
#[pyfunction]
#[pyo3(signature = (u, y, na, nb, delay, wear_ratio=0.1, alarm_period=1e6, learn=2000, reference_play=None,
    ts=1.0, recommended=false))]
#[expect(
    clippy::too_many_arguments,
    reason = "the Python signature: keyword arguments with defaults"
)]
fn monitor(
    py: Python<'_>,
    u: PyReadonlyArray1<'_, f64>,
    y: PyReadonlyArray1<'_, f64>,
    na: usize,
    nb: usize,
    delay: usize,
    wear_ratio: f64,
    alarm_period: f64,
    learn: u64,
    reference_play: Option<f64>,
    ts: f64,
    recommended: bool,
) -> PyResult<String> {
    use backlash::identify::mrgia::MrgiaConfig;
    use backlash::identify::oe::online::monitor::{MonitorConfig, Session};
    if !(ts.is_finite() && ts > 0.0) {
        return Err(PyValueError::new_err(format!(
            "the sample period ts = {ts} must be a positive finite number of seconds"
        )));
    }
    let cfg = MonitorConfig {
        wear_ratio,
        alarm_period,
        learn,
        reference_play,
        follow: true,
    };
    let (u, y) = (u.as_slice()?, y.as_slice()?);
    compute(py, || {
        api::check_record(&[("u", u), ("y", y)], 1)?;
        let est = if recommended {
            MrgiaConfig::recommended(na, nb, delay)
        } else {
            MrgiaConfig::paper(na, nb, delay)
        };
        let mut session = Session::new(est, cfg).map_err(|e| ApiError::Setting(e.to_string()))?;
        for (k, (&uk, &yk)) in u.iter().zip(y).enumerate() {
            session.push(k as f64 * ts, uk, yk);
        }
        Ok(api::monitor_json(&session, &api::InputCheck::of(u))?.to_string())
    })
}

/// compensate(r, noise_std, noise_seed, wear, wear_ratio, memory, smoothing, modes) -> the JSON text of
/// `backlash compensate` (wear "none", "ramp" or "step"; memory 0: no forgetting; modes: names, empty: all).
#[pyfunction]
#[pyo3(signature = (r, noise_std=0.0, noise_seed=0, wear="none", wear_ratio=0.5, memory=500.0, smoothing=0.0,
    modes=Vec::new(), estimate_lag=0))]
#[expect(
    clippy::too_many_arguments,
    reason = "the Python signature: keyword arguments with defaults"
)]
fn compensate(
    py: Python<'_>,
    r: PyReadonlyArray1<'_, f64>,
    noise_std: f64,
    noise_seed: u64,
    wear: &str,
    wear_ratio: f64,
    memory: f64,
    smoothing: f64,
    modes: Vec<String>,
    estimate_lag: usize,
) -> PyResult<String> {
    use backlash::compensate::adaptive::Wear;
    let wear = match wear {
        "none" => Wear::None,
        "ramp" => Wear::Ramp { ratio: wear_ratio },
        "step" => Wear::Step { ratio: wear_ratio },
        other => {
            return Err(PyValueError::new_err(format!(
                "wear '{other}' is unknown: one of none, ramp, step"
            )));
        }
    };
    let r = r.as_slice()?;
    compute(py, || {
        let mut o = api::CompensateOptions {
            noise_std,
            noise_seed,
            wear,
            memory: (memory != 0.0).then_some(memory),
            smoothing,
            estimate_lag,
            ..api::CompensateOptions::default()
        };
        if !modes.is_empty() {
            o.modes = modes
                .iter()
                .map(|m| api::mode_named(m))
                .collect::<Result<_, _>>()?;
        }
        Ok(api::compensate(r, &o)?.1.to_string())
    })
}

/// run_cli(argv) -> exit status: the `backlash` program on a command line (its name first), with the GIL
/// released (a long `backlash study` does not hold up other threads).
#[pyfunction]
fn run_cli(py: Python<'_>, argv: Vec<String>) -> PyResult<i32> {
    compute(py, || Ok(cli::run(argv)))
}

#[pymodule]
fn _backlash(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(plant_parameters, m)?)?;
    m.add_function(wrap_pyfunction!(identify_mrgia, m)?)?;
    m.add_function(wrap_pyfunction!(identify_oe, m)?)?;
    m.add_function(wrap_pyfunction!(identify_frequency, m)?)?;
    m.add_function(wrap_pyfunction!(crb, m)?)?;
    m.add_function(wrap_pyfunction!(diagnose, m)?)?;
    m.add_function(wrap_pyfunction!(monitor, m)?)?;
    m.add_function(wrap_pyfunction!(compensate, m)?)?;
    m.add_function(wrap_pyfunction!(run_cli, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
