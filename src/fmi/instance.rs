//! An FMU instance: the state machine, argument checks, logging and FMU state, for any [`Model`].
//!
//! The importer's pointers and the panic guard are handled in `exports`. The unsafe code here is confined to
//! what the instance itself owns across the C boundary: the FMU states it hands out as raw pointers (a
//! registry of live Boxes; a pointer is compared against it before it is read through or freed), the call
//! of the importer's logger, and `Send`. Each unsafe block states why it holds.
//!
//! Every refused call returns `Err(reason)`; the caller logs the reason under `logStatusError`, returns
//! fmi2Error and, as the standard prescribes for fmi2Error, puts the instance in the `error` state, from which
//! only getters, fmi2Reset, fmi2SetFMUstate and fmi2FreeInstance lead on.

use super::Model;
use super::ffi::{Fmi2CallbackFunctions, Fmi2Status};
use super::state::State;
use super::vars::{Causality, Start, Value, VarInfo, VarType, Variability};
use serde::{Deserialize, Serialize};
use std::ffi::{CStr, CString};

/// The one time tolerance, relative to the time it is applied at (an instant t_j, or the instance's clock):
/// 1e-7, above the relative rounding of a float32 (2^-24 = 6e-8), so that a master whose step is a float32
/// (h = float32(0.1) = 0.1000000015) or whose clock is a float32 or float64 sum lands on the instants it
/// means to; for instants it is never more than a quarter of the step nor a quarter of Ts (see
/// [`instant_tolerance`]), so that steps far shorter than the relative tolerance stay exact late in long runs.
pub const TIME_TOLERANCE: f64 = 1e-7;

/// Tolerance for comparing a time with `at` (the master's clock arithmetic): relative to `at`, with `ts` as
/// the floor of the scale so that times near 0 are not compared exactly.
pub fn time_tolerance(at: f64, ts: f64) -> f64 {
    TIME_TOLERANCE * at.abs().max(ts)
}

/// Tolerance for "a step ending at `end` reaches the instant `at`": [`time_tolerance`], at most a quarter of
/// the step `h` and of the sample period `ts` (so that instants never merge and sub-steps stay distinct).
pub fn instant_tolerance(at: f64, ts: f64, h: f64) -> f64 {
    time_tolerance(at, ts).min(0.25 * h.min(ts))
}

/// Tag at the start of every saved or serialised FMU state.
const STATE_FORMAT: &str = "backlash-fmu-state/2";

/// What the layer itself keeps besides the model (saved with it in an FMU state).
///
/// Timing (sampled data): the sample instants are t_j = start_time + j Ts. `samples` = k means the instants
/// t_1 .. t_k have been reached, so the outputs are sample k's. `time` is the instance's clock, the end of
/// the last step exactly as the master computed it (never snapped to an instant). `latched` holds the inputs
/// current at t_k once a step has started from t_k: they are sample k's inputs, used when t_{k+1} is reached,
/// whatever the master sets in between. `latched` is false while the clock stands at t_k.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LayerState {
    pub state: State,
    pub start_time: f64,
    pub stop_time: Option<f64>,
    pub time: f64,
    /// Samples advanced since fmi2ExitInitializationMode.
    pub samples: u64,
    pub latched: bool,
    /// The inputs (in the order of the variable table) latched at t_k, as numbers (meaningful when
    /// `latched`; always one per input, so that stepping does not allocate).
    pub latched_inputs: Vec<f64>,
}

impl LayerState {
    fn new(inputs: usize) -> Self {
        Self {
            state: State::Instantiated,
            start_time: 0.0,
            stop_time: None,
            time: 0.0,
            samples: 0,
            latched: false,
            latched_inputs: vec![0.0; inputs],
        }
    }
}

/// What one fmi2DoStep did: every instant it reached was sampled, or the model's limit cut it short at the
/// returned time (fmi2Discard, the last successful time).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StepOutcome {
    Complete,
    Cut { at: f64, reached: u64, limit: u64 },
}

/// The object-safe face of a model, so that one instance type serves every FMU.
pub trait Slave: Send {
    fn identifier(&self) -> &'static str;
    fn guid(&self) -> &'static str;
    fn log_categories(&self) -> &'static [&'static str];
    fn variables(&self) -> &'static [VarInfo];
    /// Most samples one communication step may advance; a step reaching more instants is cut there.
    fn max_samples_per_step(&self) -> u64;
    fn get(&self, index: usize) -> Value;
    fn set(&mut self, index: usize, value: Value);
    fn exit_initialization(&mut self) -> Result<(), String>;
    fn sample_period(&self) -> f64;
    fn step(&mut self, n: u64) -> Result<(), String>;
    /// A fresh model at its start values.
    fn reset(&mut self);
    fn save(&self, layer: &LayerState) -> Result<Vec<u8>, String>;
    fn restore(&mut self, bytes: &[u8]) -> Result<LayerState, String>;
    /// Check that `bytes` is a state of this model without applying it.
    fn check_state(&self, bytes: &[u8]) -> Result<(), String>;
}

/// The generic adapter from [`Model`] to [`Slave`].
pub struct Adapter<M: Model>(pub M);

#[derive(Serialize)]
struct EnvelopeRef<'a, M> {
    format: &'a str,
    guid: &'a str,
    layer: &'a LayerState,
    model: &'a M,
}

#[derive(Deserialize)]
struct Envelope<M> {
    format: String,
    guid: String,
    layer: LayerState,
    model: M,
}

#[derive(Deserialize)]
struct Header {
    format: String,
    guid: String,
}

/// The layer states an FMU state may carry: those a sequence of legal calls can leave an instance in.
fn check_layer(l: &LayerState, inputs: usize) -> Result<(), String> {
    if !matches!(
        l.state,
        State::Instantiated
            | State::InitializationMode
            | State::StepComplete
            | State::StepFailed
            | State::Terminated
            | State::Error
    ) {
        return Err(format!(
            "the FMU state claims the instance state '{}', which no sequence of calls produces",
            l.state.name()
        ));
    }
    if !l.start_time.is_finite()
        || l.stop_time
            .is_some_and(|s| !(s.is_finite() && s >= l.start_time))
    {
        return Err("the FMU state's start or stop time is invalid".into());
    }
    if !l.time.is_finite() || l.time < l.start_time {
        return Err("the FMU state's time is not finite or lies before its start time".into());
    }
    let v = &l.latched_inputs;
    if v.len() != inputs || v.iter().any(|x| !x.is_finite()) {
        return Err(format!(
            "the FMU state's latched inputs are not {inputs} finite numbers"
        ));
    }
    Ok(())
}

fn check_header(bytes: &[u8], guid: &str, model: &str) -> Result<(), String> {
    let h: Header = serde_json::from_slice(bytes)
        .map_err(|e| format!("the FMU state is truncated or corrupted ({e})"))?;
    if h.format != STATE_FORMAT {
        return Err(format!(
            "the FMU state has format '{}', expected '{STATE_FORMAT}'",
            h.format
        ));
    }
    if h.guid != guid {
        return Err(format!(
            "the FMU state belongs to another FMU (GUID {}), not to {model} (GUID {guid})",
            h.guid
        ));
    }
    Ok(())
}

/// Parse and check an FMU state: header, JSON, layer state, and the model's own consistency.
fn parse_state<M: Model>(bytes: &[u8]) -> Result<Envelope<M>, String> {
    check_header(bytes, M::GUID, M::MODEL_IDENTIFIER)?;
    let env: Envelope<M> = serde_json::from_slice(bytes)
        .map_err(|e| format!("the FMU state is truncated or corrupted ({e})"))?;
    debug_assert!(env.format == STATE_FORMAT && env.guid == M::GUID);
    check_layer(&env.layer, input_indices(M::VARIABLES).len())?;
    env.model
        .check_restored()
        .map_err(|e| format!("the FMU state is inconsistent: {e}"))?;
    check_clock(&env.layer, env.model.sample_period())?;
    for (i, v) in M::VARIABLES.iter().enumerate() {
        if v.causality != Causality::Output {
            check_value(v, &env.model.get(M::var(i)))
                .map_err(|e| format!("the FMU state is inconsistent: {e}"))?;
        }
    }
    Ok(env)
}

/// A value the variable `v` may take: a finite Real or Integer within the XML's min and max.
fn check_value(v: &VarInfo, value: &Value) -> Result<(), String> {
    if let Value::Real(x) = value
        && !x.is_finite()
    {
        return Err(format!("'{}' = {x} is not a finite number", v.name));
    }
    let x = value.as_real();
    if matches!(value, Value::Real(_) | Value::Integer(_)) {
        if let Some(lo) = v.min
            && x < lo
        {
            return Err(format!("'{}' = {x} is below its minimum {lo}", v.name));
        }
        if let Some(hi) = v.max
            && x > hi
        {
            return Err(format!("'{}' = {x} is above its maximum {hi}", v.name));
        }
    }
    Ok(())
}

/// The clock and the sample count of a layer state must agree as [`Instance::do_step`] leaves them: the
/// clock stands at or after instant t_k (within the time tolerance) and before t_{k+1}, which any step
/// ending there would have reached.
fn check_clock(l: &LayerState, ts: f64) -> Result<(), String> {
    let since = l.time - l.start_time;
    let (k, next) = (
        l.samples as f64 * ts,
        l.samples.saturating_add(1) as f64 * ts,
    );
    if since < k - time_tolerance(l.start_time + k, ts) || since >= next {
        return Err(format!(
            "the FMU state is inconsistent: its clock {} is not between sample instant {} and the next one \
             (start time {}, Ts = {ts})",
            l.time, l.samples, l.start_time
        ));
    }
    Ok(())
}

/// Indices of the input variables, in the order of the variable table.
fn input_indices(vars: &[VarInfo]) -> Vec<usize> {
    vars.iter()
        .enumerate()
        .filter(|(_, v)| v.causality == Causality::Input)
        .map(|(i, _)| i)
        .collect()
}

/// A model at its XML start values.
fn fresh<M: Model>() -> M {
    let mut m = M::new();
    for (i, v) in M::VARIABLES.iter().enumerate() {
        let value = match v.start {
            Start::None => continue,
            Start::Real(x) => Value::Real(x),
            Start::Integer(x) => Value::Integer(x),
            Start::Boolean(x) => Value::Boolean(x),
            Start::String(x) => Value::String(x.to_string()),
        };
        m.set(M::var(i), value);
    }
    m
}

impl<M: Model> Adapter<M> {
    pub fn new() -> Self {
        Self(fresh::<M>())
    }
}

impl<M: Model> Default for Adapter<M> {
    fn default() -> Self {
        Self::new()
    }
}

impl<M: Model> Slave for Adapter<M> {
    fn identifier(&self) -> &'static str {
        M::MODEL_IDENTIFIER
    }
    fn guid(&self) -> &'static str {
        M::GUID
    }
    fn log_categories(&self) -> &'static [&'static str] {
        M::LOG_CATEGORIES
    }
    fn variables(&self) -> &'static [VarInfo] {
        M::VARIABLES
    }
    fn max_samples_per_step(&self) -> u64 {
        M::MAX_SAMPLES_PER_STEP
    }
    fn get(&self, index: usize) -> Value {
        self.0.get(M::var(index))
    }
    fn set(&mut self, index: usize, value: Value) {
        self.0.set(M::var(index), value)
    }
    fn exit_initialization(&mut self) -> Result<(), String> {
        self.0.exit_initialization()
    }
    fn sample_period(&self) -> f64 {
        self.0.sample_period()
    }
    fn step(&mut self, n: u64) -> Result<(), String> {
        self.0.step(n)
    }
    fn reset(&mut self) {
        self.0 = fresh::<M>();
    }
    fn save(&self, layer: &LayerState) -> Result<Vec<u8>, String> {
        let bytes = serde_json::to_vec(&EnvelopeRef {
            format: STATE_FORMAT,
            guid: M::GUID,
            layer,
            model: &self.0,
        })
        .map_err(|e| format!("cannot save the FMU state: {e}"))?;
        // Hand out only states that can be restored (JSON has no NaN or infinity, for one).
        self.check_state(&bytes)
            .map_err(|e| format!("cannot save the FMU state: it would not restore: {e}"))?;
        Ok(bytes)
    }
    fn restore(&mut self, bytes: &[u8]) -> Result<LayerState, String> {
        let env = parse_state::<M>(bytes)?;
        self.0 = env.model;
        Ok(env.layer)
    }
    fn check_state(&self, bytes: &[u8]) -> Result<(), String> {
        parse_state::<M>(bytes).map(|_| ())
    }
}

/// A saved FMU state: a deep, pointer-free copy (the serialised bytes themselves).
pub struct SavedState {
    pub bytes: Vec<u8>,
}

/// A function of a protocol's API, as the instance's state machine sees it (FMI 2.0's `state::Call`, FMI
/// 3.0's `crate::fmi3::state::Call`): its C name and whether the protocol's table allows it in a state.
pub trait Api: Copy + std::panic::UnwindSafe + std::panic::RefUnwindSafe {
    fn name(self) -> &'static str;
    fn allowed_in(self, state: State) -> bool;
}

/// Where an instance's messages go: the logger the importer gave at instantiation, in the form of the
/// protocol it instantiated with. The status is the protocol's numeric status (the values of fmi2Status and
/// fmi3Status agree from OK to Fatal).
pub trait Logger {
    fn log(&self, instance: &CStr, status: Fmi2Status, category: &str, text: &str);
}

impl Logger for Fmi2CallbackFunctions {
    fn log(&self, instance: &CStr, status: Fmi2Status, category: &str, text: &str) {
        emit_raw(self, instance, status, category, text);
    }
}

/// Log categories the instance can switch on.
#[derive(Debug, Clone, Copy, Default)]
pub struct LogSwitches {
    pub errors: bool,
    pub discards: bool,
    pub warnings: bool,
    pub calls: bool,
}

/// One FMU instance.
pub struct Instance {
    pub name: CString,
    logger: Box<dyn Logger>,
    pub logging_on: bool,
    pub log: LogSwitches,
    pub layer: LayerState,
    pub slave: Box<dyn Slave>,
    /// Strings handed out by fmi2GetString stay valid until the next call.
    string_buffer: Vec<CString>,
    /// Value reference -> variable index, per type (see [`VrTable`]).
    vr_table: VrTable,
    /// Indices of the Real outputs (checked after every step).
    real_outputs: Vec<usize>,
    /// Indices of the inputs (latched at each sample instant).
    inputs: Vec<usize>,
    /// The inputs' current values while a sample runs on the latched ones (allocated once).
    held_inputs: Vec<f64>,
    /// The FMU states this instance issued and has not freed: the only pointers the state functions accept.
    issued: Vec<*mut SavedState>,
}

// SAFETY: the raw pointers are the importer's callbacks and environment (in `logger`), and the FMU states this instance
// owns; the standard lets the importer call an instance from any thread as long as calls are not concurrent,
// so the instance may move between threads.
unsafe impl Send for Instance {}

/// `text` as a C string (an interior NUL becomes a space).
pub fn cstring(text: &str) -> CString {
    CString::new(text.replace('\0', " ")).unwrap_or_default()
}

impl Instance {
    pub fn new(
        name: &str,
        logger: impl Logger + 'static,
        logging_on: bool,
        slave: Box<dyn Slave>,
    ) -> Self {
        Self {
            name: cstring(name),
            logger: Box::new(logger),
            logging_on,
            log: LogSwitches {
                errors: true,
                discards: true,
                warnings: true,
                calls: false,
            },
            layer: LayerState::new(
                slave
                    .variables()
                    .iter()
                    .filter(|v| v.causality == Causality::Input)
                    .count(),
            ),
            vr_table: VrTable::new(slave.variables()),
            real_outputs: slave
                .variables()
                .iter()
                .enumerate()
                .filter(|(_, v)| v.causality == Causality::Output && v.ty == VarType::Real)
                .map(|(i, _)| i)
                .collect(),
            inputs: input_indices(slave.variables()),
            held_inputs: Vec::new(),
            issued: Vec::new(),
            slave,
            string_buffer: Vec::new(),
        }
    }

    /// Send one message to the importer's logger (see [`Logger`]).
    pub fn emit(&self, status: Fmi2Status, category: &str, text: &str) {
        self.logger.log(&self.name, status, category, text);
    }

    /// Log a refused call under logStatusError (always on: the importer needs the reason).
    pub fn log_error(&self, call: impl Api, reason: &str) {
        if self.log.errors {
            self.emit(
                Fmi2Status::Error,
                "logStatusError",
                &format!("{}: {reason}", call.name()),
            );
        }
    }

    pub fn log_call(&self, call: impl Api, args: impl FnOnce() -> String) {
        if self.logging_on && self.log.calls {
            self.emit(
                Fmi2Status::Ok,
                "logCalls",
                &format!("{}({})", call.name(), args()),
            );
        }
    }

    /// Refuse a call the state machine does not allow, with a reason that names the call and the state.
    pub fn check_state(&self, call: impl Api) -> Result<(), String> {
        if call.allowed_in(self.layer.state) {
            return Ok(());
        }
        // After fmi2Error the standard allows only the getters, the FMU-state functions, fmi2Reset and
        // fmi2FreeInstance (state.rs), so fmi2Terminate after an error is refused too.
        Err(format!(
            "illegal call in state '{}' of instance '{}'",
            self.layer.state.name(),
            self.name.to_string_lossy()
        ))
    }

    /// The instance's clock: the start time, then the end of the last step (see [`LayerState`]).
    pub fn time(&self) -> f64 {
        self.layer.time
    }

    /// Sample instant t_j.
    fn instant(&self, j: u64) -> f64 {
        self.layer.start_time + self.offset(j)
    }

    pub fn set_debug_logging(&mut self, on: bool, categories: &[String]) -> Result<(), String> {
        let known = self.slave.log_categories();
        for c in categories {
            if !known.contains(&c.as_str()) {
                return Err(format!(
                    "unknown log category '{c}' (declared: {})",
                    known.join(", ")
                ));
            }
        }
        self.logging_on = on;
        let all = categories.is_empty() || categories.iter().any(|c| c == "logAll");
        let has = |n: &str| all || categories.iter().any(|c| c == n);
        // logStatusError stays on whatever is asked: refusals always carry their reason.
        self.log = LogSwitches {
            errors: true,
            discards: !on || has("logStatusDiscard"),
            warnings: !on || has("logStatusWarning"),
            calls: on && has("logCalls"),
        };
        Ok(())
    }

    pub fn setup_experiment(
        &mut self,
        tolerance_defined: bool,
        tolerance: f64,
        start: f64,
        stop_defined: bool,
        stop: f64,
    ) -> Result<(), String> {
        if !start.is_finite() {
            return Err(format!("startTime {start} is not finite"));
        }
        if tolerance_defined && !(tolerance.is_finite() && tolerance > 0.0) {
            return Err(format!("tolerance {tolerance} must be positive and finite"));
        }
        if stop_defined && !(stop.is_finite() && stop >= start) {
            return Err(format!(
                "stopTime {stop} must be finite and >= startTime {start}"
            ));
        }
        self.layer.start_time = start;
        self.layer.stop_time = stop_defined.then_some(stop);
        Ok(())
    }

    pub fn enter_initialization(&mut self) -> Result<(), String> {
        self.layer.state = State::InitializationMode;
        Ok(())
    }

    pub fn exit_initialization(&mut self) -> Result<(), String> {
        let ts = self.slave.sample_period();
        if !(ts.is_finite() && ts > 0.0) {
            return Err(format!("parameter Ts = {ts} must be positive and finite"));
        }
        self.slave.exit_initialization()?;
        self.check_outputs("at the start")?;
        self.layer.time = self.layer.start_time;
        self.layer.samples = 0;
        self.layer.latched = false;
        self.layer.state = State::StepComplete;
        Ok(())
    }

    pub fn terminate(&mut self) -> Result<(), String> {
        self.layer.state = State::Terminated;
        Ok(())
    }

    pub fn reset(&mut self) -> Result<(), String> {
        self.slave.reset();
        self.layer = LayerState::new(self.inputs.len());
        self.string_buffer.clear();
        Ok(())
    }

    /// Index of the variable with value reference `vr` and type `ty`.
    fn lookup(&self, ty: VarType, vr: u32) -> Result<usize, String> {
        self.vr_table
            .get(self.slave.variables(), ty, vr)
            .ok_or_else(|| {
                format!(
                    "unknown value reference {vr} for type {} in {}",
                    ty.name(),
                    self.slave.identifier()
                )
            })
    }

    /// The variable indices of `vrs`, all or nothing, in `stack` when they fit (every get/set a master makes
    /// per step), else in `heap`, so that a step's get/set calls do not allocate.
    fn lookup_all<'b>(
        &self,
        ty: VarType,
        vrs: &[u32],
        stack: &'b mut [usize; STACK_VRS],
        heap: &'b mut Vec<usize>,
    ) -> Result<&'b [usize], String> {
        let idx: &mut [usize] = if vrs.len() <= STACK_VRS {
            &mut stack[..vrs.len()]
        } else {
            heap.resize(vrs.len(), 0);
            heap
        };
        for (slot, &vr) in idx.iter_mut().zip(vrs) {
            *slot = self.lookup(ty, vr)?;
        }
        Ok(idx)
    }

    /// Values of the variables `vrs` of type `ty`, all or nothing: `out(k, value)` is called for every `k` in
    /// order only once all references are known and all values are valid. No allocation for up to
    /// `STACK_VRS` references and non-string types.
    pub fn get_with(
        &mut self,
        ty: VarType,
        vrs: &[u32],
        mut out: impl FnMut(usize, &Value),
    ) -> Result<(), String> {
        let (mut stack, mut heap) = ([0; STACK_VRS], Vec::new());
        let idx = self.lookup_all(ty, vrs, &mut stack, &mut heap)?;
        if ty != VarType::Real || idx.len() > STACK_VRS {
            if ty == VarType::Real {
                self.check_finite(idx)?;
            }
            for (k, &i) in idx.iter().enumerate() {
                out(k, &self.slave.get(i));
            }
            return Ok(());
        }
        // Reals: read once into a stack buffer, check, then hand out.
        let mut vals = [0.0; STACK_VRS];
        for (x, &i) in vals.iter_mut().zip(idx) {
            *x = self.slave.get(i).as_real();
        }
        if let Some(k) = vals[..idx.len()].iter().position(|x| !x.is_finite()) {
            return Err(format!(
                "'{}' is not finite ({}): the model diverged",
                self.slave.variables()[idx[k]].name,
                vals[k]
            ));
        }
        for (k, &x) in vals[..idx.len()].iter().enumerate() {
            out(k, &Value::Real(x));
        }
        Ok(())
    }

    /// A diverged model (refused at its step, see check_outputs) must not hand out NaN or infinity as fmi2OK.
    fn check_finite(&self, idx: &[usize]) -> Result<(), String> {
        for &i in idx {
            if let Value::Real(x) = self.slave.get(i)
                && !x.is_finite()
            {
                return Err(format!(
                    "'{}' is not finite ({x}): the model diverged",
                    self.slave.variables()[i].name
                ));
            }
        }
        Ok(())
    }

    /// Values of the variables `vrs` of type `ty`, all or nothing (see [`Instance::get_with`]).
    pub fn get(&mut self, ty: VarType, vrs: &[u32]) -> Result<Vec<Value>, String> {
        let mut values = Vec::with_capacity(vrs.len());
        self.get_with(ty, vrs, |_, v| values.push(v.clone()))?;
        Ok(values)
    }

    /// Hand out C strings that live until the next fmi2GetString.
    pub fn keep_strings(&mut self, values: &[Value]) -> &[CString] {
        self.string_buffer = values
            .iter()
            .map(|v| match v {
                Value::String(s) => cstring(s),
                _ => CString::default(),
            })
            .collect();
        &self.string_buffer
    }

    /// Set variables: every value is checked before any is applied.
    pub fn set(&mut self, ty: VarType, vrs: &[u32], values: Vec<Value>) -> Result<(), String> {
        debug_assert_eq!(vrs.len(), values.len());
        self.set_with(ty, vrs, |k| Ok(values[k].clone()))
    }

    /// Set variables, the `k`-th to `value(k)`: every value is converted and checked before any is applied
    /// (`value` is called twice per variable: to check, then to apply). No allocation for up to
    /// `STACK_VRS` references and non-string types.
    pub fn set_with(
        &mut self,
        ty: VarType,
        vrs: &[u32],
        value: impl Fn(usize) -> Result<Value, String>,
    ) -> Result<(), String> {
        let (mut stack, mut heap) = ([0; STACK_VRS], Vec::new());
        let idx = self.lookup_all(ty, vrs, &mut stack, &mut heap)?;
        let state = self.layer.state;
        for (k, &i) in idx.iter().enumerate() {
            let value = &value(k)?;
            let v = &self.slave.variables()[i];
            match v.causality {
                Causality::Output => {
                    return Err(format!("'{}' is an output and cannot be set", v.name));
                }
                Causality::Parameter
                    if v.variability == Variability::Fixed
                        && !matches!(state, State::Instantiated | State::InitializationMode) =>
                {
                    return Err(format!(
                        "parameter '{}' is fixed: set it before fmi2ExitInitializationMode",
                        v.name
                    ));
                }
                _ => {}
            }
            check_value(v, value)?;
        }
        for (k, &i) in idx.iter().enumerate() {
            self.slave.set(i, value(k)?);
        }
        Ok(())
    }

    /// Advance the clock from `t` to `t + h`, sampling at every instant t_j the step reaches (sampled data,
    /// see [`LayerState`]): the first instant takes the inputs latched at the previous one, later instants
    /// inside the step take the inputs held over it. A step reaching more instants than the model allows is
    /// cut at the last allowed one ([`StepOutcome::Cut`], the clock then stands there).
    pub fn do_step(&mut self, t: f64, h: f64) -> Result<StepOutcome, String> {
        let ts = self.slave.sample_period();
        let now = self.layer.time;
        if !t.is_finite() || !h.is_finite() {
            return Err(format!(
                "currentCommunicationPoint {t} and communicationStepSize {h} must be finite"
            ));
        }
        if h <= 0.0 {
            return Err(format!("communicationStepSize {h} must be positive"));
        }
        if (t - now).abs() > time_tolerance(now, ts) {
            return Err(format!(
                "currentCommunicationPoint {t} is not the instance's time {now} (the end of the previous step; \
                 relative tolerance {TIME_TOLERANCE})"
            ));
        }
        let end = t + h;
        if !end.is_finite() {
            return Err(format!("the step would end at {end}, which is not finite"));
        }
        if end <= t {
            return Err(format!(
                "communicationStepSize {h} is below the resolution of the time {t} (t + h = t)"
            ));
        }
        if let Some(stop) = self.layer.stop_time
            && end > stop + time_tolerance(stop, ts)
        {
            return Err(format!(
                "the step would end at {end}, after the stopTime {stop} set in fmi2SetupExperiment"
            ));
        }
        let reached = self.instants_reached(end, h);
        let limit = self.slave.max_samples_per_step();
        if !self.layer.latched {
            // The step starts at t_k: what is set now is sample k's input.
            self.latch_inputs();
        }
        let n = reached.min(limit);
        if n > 0 {
            self.sample_latched()?;
            if n > 1 {
                self.slave.step(n - 1)?;
            }
            self.layer.samples += n;
            self.layer.latched = false;
        }
        let outcome = if reached > limit {
            let at = self.instant(self.layer.samples);
            self.layer.time = at;
            StepOutcome::Cut { at, reached, limit }
        } else {
            self.layer.time = end;
            let (last, since) = (
                self.instant(self.layer.samples),
                (end - self.layer.start_time) - self.offset(self.layer.samples),
            );
            // A step ending past its last instant has held the inputs there: they are that sample's.
            if n > 0 && since > instant_tolerance(last, ts, h) {
                self.latch_inputs();
            }
            StepOutcome::Complete
        };
        self.check_outputs("after the step")?;
        Ok(outcome)
    }

    /// How many instants after t_k a step of size `h` ending at `end` reaches (an instant within
    /// [`instant_tolerance`] of the end counts as reached). Offsets from the start time are compared, so that
    /// a start time far larger than Ts does not swallow the instants.
    fn instants_reached(&self, end: f64, h: f64) -> u64 {
        let (ts, k) = (self.slave.sample_period(), self.layer.samples);
        let since_start = end - self.layer.start_time;
        let reaches = |j: u64| {
            let at = self.instant(j);
            self.offset(j) - instant_tolerance(at, ts, h) <= since_start
        };
        // The estimate is within one or two of the answer (the tolerance is below Ts / 4), unless the sample
        // count is beyond what a float resolves (2^53), where a few adjustments are as good as any; `as`
        // saturates.
        let mut j = ((since_start / ts).floor().max(0.0) as u64).max(k);
        for _ in 0..4 {
            if j < u64::MAX && reaches(j + 1) {
                j += 1;
            } else if j > k && !reaches(j) {
                j -= 1;
            } else {
                break;
            }
        }
        j - k
    }

    /// Time from the start to instant t_j.
    fn offset(&self, j: u64) -> f64 {
        j as f64 * self.slave.sample_period()
    }

    /// Latch the inputs' current values as those of the instant the clock stands at.
    fn latch_inputs(&mut self) {
        let mut buf = std::mem::take(&mut self.layer.latched_inputs);
        self.read_inputs(&mut buf);
        self.layer.latched_inputs = buf;
        self.layer.latched = true;
    }

    /// The inputs' current values, as numbers, into `buf` (no allocation once `buf` has its size).
    fn read_inputs(&self, buf: &mut Vec<f64>) {
        buf.clear();
        buf.extend(self.inputs.iter().map(|&i| self.slave.get(i).as_real()));
    }

    /// Advance one sample with the latched inputs, then put the current inputs back.
    fn sample_latched(&mut self) -> Result<(), String> {
        let mut held = std::mem::take(&mut self.held_inputs);
        self.read_inputs(&mut held);
        let latched = std::mem::take(&mut self.layer.latched_inputs);
        self.apply_inputs(&latched);
        let result = self.slave.step(1);
        self.apply_inputs(&held);
        self.layer.latched_inputs = latched;
        self.held_inputs = held;
        result
    }

    fn apply_inputs(&mut self, values: &[f64]) {
        for (&i, &x) in self.inputs.iter().zip(values) {
            let value = match self.slave.variables()[i].ty {
                VarType::Real => Value::Real(x),
                VarType::Integer => Value::Integer(x as i32),
                VarType::Boolean => Value::Boolean(x != 0.0),
                // String inputs cannot be latched as numbers; no model of this crate has one.
                VarType::String => continue,
            };
            self.slave.set(i, value);
        }
    }

    /// A model that diverged (an unstable linear block, absurd inputs or parameters) must not be reported as
    /// fine: every Real output must be finite.
    fn check_outputs(&self, when: &str) -> Result<(), String> {
        for &i in &self.real_outputs {
            if !self.slave.get(i).as_real().is_finite() {
                let v = &self.slave.variables()[i];
                return Err(format!(
                    "the model diverged: output '{}' is not finite {when} (is the linear block stable, \
                     are the input and the parameters of a sensible size?)",
                    v.name
                ));
            }
        }
        Ok(())
    }

    pub fn save_state(&self) -> Result<SavedState, String> {
        Ok(SavedState {
            bytes: self.slave.save(&self.layer)?,
        })
    }

    pub fn restore_state(&mut self, saved: &SavedState) -> Result<(), String> {
        let layer = self.slave.restore(&saved.bytes)?;
        self.layer = layer;
        Ok(())
    }

    /// Store `saved` where the importer's `*FMUstate` points: in the state it names if that is one this
    /// instance issued (the standard's "overwrite a previous state"), else in a new one. Returns the pointer
    /// to hand out. A non-NULL pointer this instance did not issue is refused, never dereferenced.
    pub fn issue_state(
        &mut self,
        existing: *mut SavedState,
        saved: SavedState,
    ) -> Result<*mut SavedState, String> {
        if existing.is_null() {
            let p = Box::into_raw(Box::new(saved));
            self.issued.push(p);
            return Ok(p);
        }
        let q = self.find_issued(existing)?;
        // SAFETY: `q` comes from the registry: a live Box this instance made and has not freed.
        unsafe { *q = saved };
        Ok(q)
    }

    /// The state behind `p` if this instance issued it and has not freed it.
    pub fn issued_state(&self, p: *const SavedState) -> Result<&SavedState, String> {
        let q = self.find_issued(p)?;
        // SAFETY: `q` comes from the registry: a live Box this instance made; it lives while `self` holds it.
        Ok(unsafe { &*q })
    }

    /// Restore the state behind `p` if this instance issued it and has not freed it.
    pub fn restore_issued_state(&mut self, p: *const SavedState) -> Result<(), String> {
        let q = self.find_issued(p)?;
        // SAFETY: `q` comes from the registry: a live Box this instance made. Restoring reads it and leaves
        // the registry alone, so it stays alive and unaliased by any `&mut` meanwhile.
        let saved = unsafe { &*q };
        self.restore_state(saved)
    }

    /// Free a state this instance issued.
    pub fn free_state(&mut self, p: *mut SavedState) -> Result<(), String> {
        let q = self.find_issued(p)?;
        self.issued.retain(|&r| r != q);
        // SAFETY: `q` was in the registry (a live Box from `issue_state`) and is now out of it: freed once.
        drop(unsafe { Box::from_raw(q) });
        Ok(())
    }

    /// The registry's entry equal to `p`: pointers are compared, never read through.
    fn find_issued(&self, p: *const SavedState) -> Result<*mut SavedState, String> {
        if let Some(&q) = self.issued.iter().find(|&&q| std::ptr::eq(q, p)) {
            Ok(q)
        } else {
            Err(format!(
                "FMUstate {p:p} is not a state this instance issued (or it was freed): pass the fmi2FMUstate \
                 that fmi2GetFMUstate or fmi2DeSerializeFMUstate returned (for fmi2FreeFMUstate, its address)"
            ))
        }
    }
}

impl Instance {
    pub fn check_state_bytes(&self, bytes: &[u8]) -> Result<(), String> {
        self.slave.check_state(bytes)
    }
}

impl Drop for Instance {
    /// States the importer did not free belong to the instance and go with it.
    fn drop(&mut self) {
        for p in self.issued.drain(..) {
            // SAFETY: every registered pointer is a live Box from `issue_state`, freed nowhere else.
            drop(unsafe { Box::from_raw(p) });
        }
    }
}

/// Log through the importer's logger, if it gave one. The text is the format itself, with every '%' doubled
/// and no further argument: printf-style loggers (FMPy's, the FMI Library's) print it unchanged, and loggers
/// that do not format show it as it is, apart from the doubled '%' (the standard's logger is a printf format).
pub fn emit_raw(
    callbacks: &Fmi2CallbackFunctions,
    instance: &CStr,
    status: Fmi2Status,
    category: &str,
    text: &str,
) {
    if let Some(logger) = callbacks.logger {
        let category = cstring(category);
        let format = cstring(&text.replace('%', "%%"));
        // SAFETY: the logger is the importer's C function; all strings are NUL-terminated and outlive the
        // call; the format has no conversion (every '%' is doubled), so no variadic argument is read.
        unsafe {
            logger(
                callbacks.component_environment,
                instance.as_ptr(),
                status as super::ffi::Fmi2StatusC,
                category.as_ptr(),
                format.as_ptr(),
            );
        }
    }
}

/// Value references of one get/set call whose indices are looked up on the stack (more use the heap).
const STACK_VRS: usize = 32;

/// Value reference -> variable index for each of the four types: a dense table when the largest value
/// reference is small (it is: the model descriptions number their variables below 100), so that a lookup is one
/// load instead of a scan of the variable list; a scan otherwise.
struct VrTable {
    /// `dense[type][vr]` = index + 1, 0 for none. Empty when the references are too sparse.
    dense: [Vec<u16>; 4],
}

impl VrTable {
    /// Largest value reference put in the dense table.
    const DENSE_MAX: u32 = 4096;

    fn slot(ty: VarType) -> usize {
        match ty {
            VarType::Real => 0,
            VarType::Integer => 1,
            VarType::Boolean => 2,
            VarType::String => 3,
        }
    }

    fn new(vars: &[VarInfo]) -> Self {
        let mut dense: [Vec<u16>; 4] = Default::default();
        let fits =
            vars.len() < usize::from(u16::MAX) && vars.iter().all(|v| v.vr <= Self::DENSE_MAX);
        if fits {
            // The first variable with a given (type, vr) wins, as the scan it replaces.
            for (i, v) in vars.iter().enumerate().rev() {
                let t = &mut dense[Self::slot(v.ty)];
                let at = v.vr as usize;
                if t.len() <= at {
                    t.resize(at + 1, 0);
                }
                t[at] = (i + 1) as u16;
            }
        }
        Self { dense }
    }

    fn get(&self, vars: &[VarInfo], ty: VarType, vr: u32) -> Option<usize> {
        if self.dense.iter().all(Vec::is_empty) {
            return vars.iter().position(|v| v.vr == vr && v.ty == ty);
        }
        match self.dense[Self::slot(ty)].get(vr as usize) {
            Some(&i) if i > 0 => Some(usize::from(i) - 1),
            _ => None,
        }
    }
}
