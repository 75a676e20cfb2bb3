//! An FMU instance: the state machine, argument checks, sampled-data stepping, logging and FMU states, for
//! any model behind a [`Slave`].
//!
//! The importer's pointers and the panic guard are handled in [`boundary`](super::boundary); the FMU states
//! handed out as raw pointers in [`fmu_state`](super::fmu_state). Every refused call returns `Err(reason)`; the
//! boundary logs the reason under `logStatusError`, answers Error and, as both standards prescribe for an
//! error, puts the instance in the `error` state, from which only getters, reset, restoring an FMU state and
//! freeing the instance lead on.

use super::adapter::Slave;
use super::fmu_state::{Issued, SavedState};
use super::log::{LogSwitches, Logger, cstring};
use super::state::{Api, State};
use super::status::Status;
use super::timing::{LayerState, StepOutcome};
use super::vars::{Causality, Value, VarType, Variability, VrTable, check_value, input_indices};
use std::ffi::CString;

/// Value references of one get/set call whose indices are looked up on the stack (more use the heap).
const STACK_VRS: usize = 32;

/// One FMU instance.
pub struct Instance {
    pub name: CString,
    logger: Box<dyn Logger>,
    pub logging_on: bool,
    pub log: LogSwitches,
    pub layer: LayerState,
    pub slave: Box<dyn Slave>,
    /// Strings handed out by the string getter stay valid until the next call.
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
    states: Issued,
}

// SAFETY: the raw pointers are the importer's callbacks and environment (in `logger`), and the FMU states this
// instance owns (in `states`); the standards let the importer call an instance from any thread as long as
// calls are not concurrent, so the instance may move between threads.
unsafe impl Send for Instance {}

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
            log: LogSwitches::default(),
            layer: LayerState::new(input_indices(slave.variables()).len()),
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
            states: Issued::default(),
            slave,
            string_buffer: Vec::new(),
        }
    }

    /// Send one message to the importer's logger (see [`Logger`]).
    pub fn emit(&self, status: Status, category: &str, text: &str) {
        self.logger.log(&self.name, status, category, text);
    }

    /// Log a refused call under logStatusError (always on: the importer needs the reason).
    pub fn log_error(&self, call: impl Api, reason: &str) {
        if self.log.errors {
            self.emit(
                Status::Error,
                "logStatusError",
                &format!("{}: {reason}", call.name()),
            );
        }
    }

    pub fn log_call(&self, call: impl Api, args: impl FnOnce() -> String) {
        if self.logging_on && self.log.calls {
            self.emit(
                Status::Ok,
                "logCalls",
                &format!("{}({})", call.name(), args()),
            );
        }
    }

    /// The status of a successful get or step: Warning, logged under logStatusWarning, when the model
    /// reports a fallback for the inputs as set ([`Model::warning`](super::Model::warning)), else OK.
    pub fn model_status(&self, call: impl Api) -> Status {
        let Some(text) = self.slave.warning() else {
            return Status::Ok;
        };
        if self.log.warnings {
            self.emit(
                Status::Warning,
                "logStatusWarning",
                &format!("{}: {text}", call.name()),
            );
        }
        Status::Warning
    }

    /// Refuse a call the state machine does not allow, with a reason that names the call and the state.
    pub fn check_state(&self, call: impl Api) -> Result<(), String> {
        if call.allowed_in(self.layer.state) {
            return Ok(());
        }
        // After an error the standards allow only the getters, the FMU-state functions, reset and freeing the
        // instance (the layers' tables), so terminating after an error is refused too.
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

    /// Switch logging and its categories (see [`LogSwitches::requested`]).
    pub fn set_debug_logging(&mut self, on: bool, categories: &[String]) -> Result<(), String> {
        self.log = LogSwitches::requested(on, categories, self.slave.log_categories())?;
        self.logging_on = on;
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

    /// A diverged model (refused at its step, see check_outputs) must not hand out NaN or infinity as OK.
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

    /// Hand out C strings that live until the next call of the string getter.
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
                        "parameter '{}' is fixed: set it before initialization mode is left",
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
        let end = self.layer.step_end(ts, t, h)?;
        let reached = self.layer.instants_reached(ts, end, h);
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
            let at = self.layer.instant(ts, self.layer.samples);
            self.layer.time = at;
            StepOutcome::Cut { at, reached, limit }
        } else {
            self.layer.time = end;
            // A step ending past its last instant has held the inputs there: they are that sample's.
            if n > 0 && self.layer.past_last_instant(ts, end, h) {
                self.latch_inputs();
            }
            StepOutcome::Complete
        };
        self.check_outputs("after the step")?;
        Ok(outcome)
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

    /// Store `saved` where the importer's `*FMUstate` points (see [`Issued::issue`]); the pointer to hand out.
    pub fn issue_state(
        &mut self,
        existing: *mut SavedState,
        saved: SavedState,
    ) -> Result<*mut SavedState, String> {
        self.states.issue(existing, saved)
    }

    /// The state behind `p` if this instance issued it and has not freed it.
    pub fn issued_state(&self, p: *const SavedState) -> Result<&SavedState, String> {
        self.states.get(p)
    }

    /// Restore the state behind `p` if this instance issued it and has not freed it.
    pub fn restore_issued_state(&mut self, p: *const SavedState) -> Result<(), String> {
        let saved = self.states.get(p)?;
        self.layer = self.slave.restore(&saved.bytes)?;
        Ok(())
    }

    /// Free a state this instance issued.
    pub fn free_state(&mut self, p: *mut SavedState) -> Result<(), String> {
        self.states.free(p)
    }

    /// Check that `bytes` is an FMU state of this instance's model, without applying it.
    pub fn check_state_bytes(&self, bytes: &[u8]) -> Result<(), String> {
        self.slave.check_state(bytes)
    }
}
