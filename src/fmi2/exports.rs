//! The 34 exported FMI 2.0 co-simulation functions: the C boundary.
//!
//! Each function checks its pointers, runs under `catch_unwind` so that no panic crosses into the importer,
//! checks the call against the state machine, and turns every refusal into fmi2Error with a logged reason.
//! Model exchange functions are not exported: the descriptions declare co-simulation only.
#![allow(non_snake_case, clippy::missing_safety_doc)]

use super::ffi::*;
use super::instance::{Instance, SavedState, StepOutcome, emit_raw};
use super::state::{Call, State};
use super::vars::{Value, VarType};
use std::ffi::{CStr, c_char};
use std::panic::{AssertUnwindSafe, catch_unwind};

type Res = Result<Fmi2Status, String>;

fn panic_text(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into())
}

/// Run `f` on the instance behind `c`: null check, state check, panic guard, error logging.
unsafe fn with_instance(
    c: Fmi2Component,
    call: Call,
    f: impl FnOnce(&mut Instance) -> Res,
) -> Fmi2StatusC {
    if c.is_null() {
        return Fmi2Status::Error as Fmi2StatusC;
    }
    // SAFETY: a non-null component is a pointer this library returned from fmi2Instantiate and that has not
    // been freed (the importer's side of the contract); calls on one instance are not concurrent.
    let inst = unsafe { &mut *(c as *mut Instance) };
    let result = catch_unwind(AssertUnwindSafe(|| {
        inst.check_state(call)?;
        f(inst)
    }));
    let status = match result {
        Ok(Ok(status)) => status,
        Ok(Err(reason)) => {
            inst.log_error(call, &reason);
            if inst.layer.state != State::Fatal {
                inst.layer.state = State::Error;
            }
            Fmi2Status::Error
        }
        Err(p) => {
            // A panic is a bug in this library; the instance may be inconsistent, so it goes to the error
            // state, from which fmi2Reset rebuilds it.
            let text = panic_text(p.as_ref());
            let inst = unsafe { &mut *(c as *mut Instance) };
            inst.log_error(call, &format!("internal error: {text}"));
            inst.layer.state = State::Error;
            Fmi2Status::Error
        }
    };
    status as Fmi2StatusC
}

/// A slice from a C array, refusing NULL when `n > 0`.
unsafe fn slice<'a, T>(ptr: *const T, n: usize, what: &str) -> Result<&'a [T], String> {
    if n == 0 {
        Ok(&[])
    } else if ptr.is_null() {
        Err(format!("{what} is NULL but nvr = {n}"))
    } else if n > (isize::MAX as usize) / std::mem::size_of::<T>().max(1) {
        Err(format!("nvr = {n} is too large"))
    } else {
        // SAFETY: the importer promises `n` readable elements at `ptr`.
        Ok(unsafe { std::slice::from_raw_parts(ptr, n) })
    }
}

unsafe fn slice_mut<'a, T>(ptr: *mut T, n: usize, what: &str) -> Result<&'a mut [T], String> {
    if n == 0 {
        Ok(&mut [])
    } else if ptr.is_null() {
        Err(format!("{what} is NULL but nvr = {n}"))
    } else if n > (isize::MAX as usize) / std::mem::size_of::<T>().max(1) {
        Err(format!("nvr = {n} is too large"))
    } else {
        // SAFETY: the importer promises `n` writable elements at `ptr`.
        Ok(unsafe { std::slice::from_raw_parts_mut(ptr, n) })
    }
}

unsafe fn c_str<'a>(p: Fmi2String, what: &str) -> Result<&'a str, String> {
    if p.is_null() {
        return Err(format!("{what} is NULL"));
    }
    // SAFETY: the importer passes NUL-terminated strings.
    unsafe { CStr::from_ptr(p) }
        .to_str()
        .map_err(|_| format!("{what} is not valid UTF-8"))
}

#[unsafe(no_mangle)]
pub extern "C" fn fmi2GetTypesPlatform() -> *const c_char {
    c"default".as_ptr()
}

#[unsafe(no_mangle)]
pub extern "C" fn fmi2GetVersion() -> *const c_char {
    c"2.0".as_ptr()
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2Instantiate(
    instance_name: Fmi2String,
    fmu_type: Fmi2Type,
    fmu_guid: Fmi2String,
    _fmu_resource_location: Fmi2String,
    functions: *const Fmi2CallbackFunctions,
    _visible: Fmi2Boolean,
    logging_on: Fmi2Boolean,
) -> Fmi2Component {
    let result = catch_unwind(|| {
        let callbacks = if functions.is_null() {
            None
        } else {
            // SAFETY: non-null, points to the importer's callback struct.
            Some(unsafe { *functions })
        };
        let name = if instance_name.is_null() {
            None
        } else {
            unsafe { CStr::from_ptr(instance_name) }.to_str().ok()
        };
        let refuse = |reason: &str| {
            if let Some(cb) = &callbacks {
                let n = std::ffi::CString::new(name.unwrap_or("?")).unwrap_or_default();
                emit_raw(
                    cb,
                    &n,
                    Fmi2Status::Error,
                    "logStatusError",
                    &format!("fmi2Instantiate: {reason}"),
                );
            }
            std::ptr::null_mut()
        };
        let Some(callbacks) = callbacks else {
            return std::ptr::null_mut();
        };
        let Some(name) = name else {
            return refuse("instanceName is NULL or not UTF-8");
        };
        if name.is_empty() {
            return refuse("instanceName is empty");
        }
        if fmu_type != FMI2_CO_SIMULATION {
            return refuse(&format!(
                "fmuType {fmu_type} is not supported: this FMU implements co-simulation (fmi2CoSimulation = 1) only"
            ));
        }
        let guid = match unsafe { c_str(fmu_guid, "fmuGUID") } {
            Ok(g) => g,
            Err(e) => return refuse(&e),
        };
        let Some(slave) = crate::fmus::instantiate(guid) else {
            return refuse(&format!(
                "fmuGUID {guid} matches neither {} nor {}: the modelDescription.xml and the binary do not belong together",
                crate::fmus::backlash_plant::GUID,
                crate::fmus::mrgia_estimator::GUID
            ));
        };
        let inst = Box::new(Instance::new(
            name,
            callbacks,
            logging_on != FMI2_FALSE,
            slave,
        ));
        inst.log_call(Call::Instantiate, || {
            format!("instanceName={name}, fmuGUID={guid}")
        });
        Box::into_raw(inst) as Fmi2Component
    });
    result.unwrap_or(std::ptr::null_mut())
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2FreeInstance(c: Fmi2Component) {
    if c.is_null() {
        return;
    }
    let _ = catch_unwind(|| {
        // SAFETY: c came from fmi2Instantiate and is freed once (the importer's side of the contract).
        let inst = unsafe { &*(c as *mut Instance) };
        if let Err(reason) = inst.check_state(Call::FreeInstance) {
            // Freeing is allowed everywhere except during an asynchronous step or after fatal; the memory is
            // released anyway, as an importer freeing an instance will not call it again.
            inst.log_error(Call::FreeInstance, &reason);
        }
        inst.log_call(Call::FreeInstance, String::new);
        drop(unsafe { Box::from_raw(c as *mut Instance) });
    });
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetDebugLogging(
    c: Fmi2Component,
    logging_on: Fmi2Boolean,
    n_categories: usize,
    categories: *const Fmi2String,
) -> Fmi2StatusC {
    unsafe {
        with_instance(c, Call::SetDebugLogging, |inst| {
            let cats = slice(categories, n_categories, "categories")?;
            let cats = cats
                .iter()
                .map(|&p| c_str(p, "a category").map(str::to_string))
                .collect::<Result<Vec<_>, _>>()?;
            inst.set_debug_logging(logging_on != FMI2_FALSE, &cats)?;
            Ok(Fmi2Status::Ok)
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetupExperiment(
    c: Fmi2Component,
    tolerance_defined: Fmi2Boolean,
    tolerance: Fmi2Real,
    start_time: Fmi2Real,
    stop_time_defined: Fmi2Boolean,
    stop_time: Fmi2Real,
) -> Fmi2StatusC {
    unsafe {
        with_instance(c, Call::SetupExperiment, |inst| {
            inst.log_call(Call::SetupExperiment, || {
                format!("tolerance={tolerance}, startTime={start_time}, stopTime={stop_time}")
            });
            inst.setup_experiment(
                tolerance_defined != FMI2_FALSE,
                tolerance,
                start_time,
                stop_time_defined != FMI2_FALSE,
                stop_time,
            )?;
            Ok(Fmi2Status::Ok)
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2EnterInitializationMode(c: Fmi2Component) -> Fmi2StatusC {
    unsafe {
        with_instance(c, Call::EnterInitializationMode, |inst| {
            inst.log_call(Call::EnterInitializationMode, String::new);
            inst.enter_initialization()?;
            Ok(Fmi2Status::Ok)
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2ExitInitializationMode(c: Fmi2Component) -> Fmi2StatusC {
    unsafe {
        with_instance(c, Call::ExitInitializationMode, |inst| {
            inst.log_call(Call::ExitInitializationMode, String::new);
            inst.exit_initialization()?;
            Ok(Fmi2Status::Ok)
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2Terminate(c: Fmi2Component) -> Fmi2StatusC {
    unsafe {
        with_instance(c, Call::Terminate, |inst| {
            inst.log_call(Call::Terminate, String::new);
            inst.terminate()?;
            Ok(Fmi2Status::Ok)
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2Reset(c: Fmi2Component) -> Fmi2StatusC {
    unsafe {
        with_instance(c, Call::Reset, |inst| {
            inst.log_call(Call::Reset, String::new);
            inst.reset()?;
            Ok(Fmi2Status::Ok)
        })
    }
}

unsafe fn get_values<T>(
    c: Fmi2Component,
    call: Call,
    ty: VarType,
    vr: *const Fmi2ValueReference,
    nvr: usize,
    value: *mut T,
    convert: impl Fn(&Value) -> T,
) -> Fmi2StatusC {
    unsafe {
        with_instance(c, call, |inst| {
            let vrs = slice(vr, nvr, "vr")?;
            let out = slice_mut(value, nvr, "value")?;
            // No allocation: the values go straight to the caller's array.
            inst.get_with(ty, vrs, |k, v| out[k] = convert(v))?;
            Ok(Fmi2Status::Ok)
        })
    }
}

unsafe fn set_values<T: Copy>(
    c: Fmi2Component,
    call: Call,
    ty: VarType,
    vr: *const Fmi2ValueReference,
    nvr: usize,
    value: *const T,
    convert: impl Fn(T) -> Result<Value, String>,
) -> Fmi2StatusC {
    unsafe {
        with_instance(c, call, |inst| {
            let vrs = slice(vr, nvr, "vr")?;
            let vals = slice(value, nvr, "value")?;
            // No allocation: each value is converted where it is checked and again where it is applied.
            inst.set_with(ty, vrs, |k| convert(vals[k]))?;
            Ok(Fmi2Status::Ok)
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetReal(
    c: Fmi2Component,
    vr: *const Fmi2ValueReference,
    nvr: usize,
    value: *mut Fmi2Real,
) -> Fmi2StatusC {
    unsafe {
        get_values(
            c,
            Call::GetReal,
            VarType::Real,
            vr,
            nvr,
            value,
            Value::as_real,
        )
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetInteger(
    c: Fmi2Component,
    vr: *const Fmi2ValueReference,
    nvr: usize,
    value: *mut Fmi2Integer,
) -> Fmi2StatusC {
    unsafe {
        get_values(
            c,
            Call::GetInteger,
            VarType::Integer,
            vr,
            nvr,
            value,
            Value::as_integer,
        )
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetBoolean(
    c: Fmi2Component,
    vr: *const Fmi2ValueReference,
    nvr: usize,
    value: *mut Fmi2Boolean,
) -> Fmi2StatusC {
    unsafe {
        get_values(c, Call::GetBoolean, VarType::Boolean, vr, nvr, value, |v| {
            if v.as_bool() { FMI2_TRUE } else { FMI2_FALSE }
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetString(
    c: Fmi2Component,
    vr: *const Fmi2ValueReference,
    nvr: usize,
    value: *mut Fmi2String,
) -> Fmi2StatusC {
    unsafe {
        with_instance(c, Call::GetString, |inst| {
            let vrs = slice(vr, nvr, "vr")?;
            let out = slice_mut(value, nvr, "value")?;
            let values = inst.get(VarType::String, vrs)?;
            let kept = inst.keep_strings(&values);
            for (o, s) in out.iter_mut().zip(kept) {
                *o = s.as_ptr();
            }
            Ok(Fmi2Status::Ok)
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetReal(
    c: Fmi2Component,
    vr: *const Fmi2ValueReference,
    nvr: usize,
    value: *const Fmi2Real,
) -> Fmi2StatusC {
    unsafe {
        set_values(c, Call::SetReal, VarType::Real, vr, nvr, value, |v| {
            Ok(Value::Real(v))
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetInteger(
    c: Fmi2Component,
    vr: *const Fmi2ValueReference,
    nvr: usize,
    value: *const Fmi2Integer,
) -> Fmi2StatusC {
    unsafe {
        set_values(c, Call::SetInteger, VarType::Integer, vr, nvr, value, |v| {
            Ok(Value::Integer(v))
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetBoolean(
    c: Fmi2Component,
    vr: *const Fmi2ValueReference,
    nvr: usize,
    value: *const Fmi2Boolean,
) -> Fmi2StatusC {
    unsafe {
        set_values(c, Call::SetBoolean, VarType::Boolean, vr, nvr, value, |v| {
            Ok(Value::Boolean(v != FMI2_FALSE))
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetString(
    c: Fmi2Component,
    vr: *const Fmi2ValueReference,
    nvr: usize,
    value: *const Fmi2String,
) -> Fmi2StatusC {
    unsafe {
        set_values(c, Call::SetString, VarType::String, vr, nvr, value, |p| {
            c_str(p, "a string value").map(|s| Value::String(s.to_string()))
        })
    }
}

/// Read the importer's `*FMUstate` from the address `state`, after making sure `state` is not itself one of
/// the instance's states (an importer passing the state where its address is expected, as some do with
/// fmi2FreeFMUstate): that pointer is refused without being read through.
unsafe fn read_state_slot(
    inst: &Instance,
    state: *mut Fmi2FmuState,
) -> Result<*mut SavedState, String> {
    if state.is_null() {
        return Err("FMUstate is NULL (expected the address of an fmi2FMUstate variable)".into());
    }
    if inst.issued_state(state as *const SavedState).is_ok() {
        return Err(
            "the argument is an fmi2FMUstate itself, not the address of a variable holding it \
             (pass &state)"
                .into(),
        );
    }
    // SAFETY: a non-NULL pointer that is not one of our states is the importer's fmi2FMUstate variable.
    Ok(unsafe { *state } as *mut SavedState)
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetFMUstate(
    c: Fmi2Component,
    state: *mut Fmi2FmuState,
) -> Fmi2StatusC {
    unsafe {
        with_instance(c, Call::GetFmuState, |inst| {
            let existing = read_state_slot(inst, state)?;
            let saved = inst.save_state()?;
            *state = inst.issue_state(existing, saved)? as Fmi2FmuState;
            Ok(Fmi2Status::Ok)
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetFMUstate(c: Fmi2Component, state: Fmi2FmuState) -> Fmi2StatusC {
    unsafe {
        with_instance(c, Call::SetFmuState, |inst| {
            if state.is_null() {
                return Err("FMUstate is NULL".into());
            }
            let p = state as *const SavedState;
            inst.issued_state(p)?;
            // SAFETY: checked against the registry just above: a live state of this instance.
            inst.restore_state(&*p)?;
            Ok(Fmi2Status::Ok)
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2FreeFMUstate(
    c: Fmi2Component,
    state: *mut Fmi2FmuState,
) -> Fmi2StatusC {
    unsafe {
        with_instance(c, Call::FreeFmuState, |inst| {
            let s = read_state_slot(inst, state)?;
            if !s.is_null() {
                inst.free_state(s)?;
                *state = std::ptr::null_mut();
            }
            Ok(Fmi2Status::Ok)
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SerializedFMUstateSize(
    c: Fmi2Component,
    state: Fmi2FmuState,
    size: *mut usize,
) -> Fmi2StatusC {
    unsafe {
        with_instance(c, Call::SerializedFmuStateSize, |inst| {
            if state.is_null() || size.is_null() {
                return Err("FMUstate or size is NULL".into());
            }
            *size = inst.issued_state(state as *const SavedState)?.bytes.len();
            Ok(Fmi2Status::Ok)
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SerializeFMUstate(
    c: Fmi2Component,
    state: Fmi2FmuState,
    bytes: *mut Fmi2Byte,
    size: usize,
) -> Fmi2StatusC {
    unsafe {
        with_instance(c, Call::SerializeFmuState, |inst| {
            if state.is_null() {
                return Err("FMUstate is NULL".into());
            }
            let saved = inst.issued_state(state as *const SavedState)?;
            if size != saved.bytes.len() {
                return Err(format!(
                    "size {size} differs from fmi2SerializedFMUstateSize {}",
                    saved.bytes.len()
                ));
            }
            let out = slice_mut(bytes as *mut u8, size, "serializedState")?;
            out.copy_from_slice(&saved.bytes);
            Ok(Fmi2Status::Ok)
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
    c: Fmi2Component,
    bytes: *const Fmi2Byte,
    size: usize,
    state: *mut Fmi2FmuState,
) -> Fmi2StatusC {
    unsafe {
        with_instance(c, Call::DeSerializeFmuState, |inst| {
            let existing = read_state_slot(inst, state)?;
            let data = slice(bytes as *const u8, size, "serializedState")?;
            inst.check_state_bytes(data)?;
            let saved = SavedState {
                bytes: data.to_vec(),
            };
            *state = inst.issue_state(existing, saved)? as Fmi2FmuState;
            Ok(Fmi2Status::Ok)
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetDirectionalDerivative(
    c: Fmi2Component,
    _v_unknown: *const Fmi2ValueReference,
    _n_unknown: usize,
    _v_known: *const Fmi2ValueReference,
    _n_known: usize,
    _dv_known: *const Fmi2Real,
    _dv_unknown: *mut Fmi2Real,
) -> Fmi2StatusC {
    unsafe {
        with_instance(c, Call::GetDirectionalDerivative, |_| {
            Err("not provided (providesDirectionalDerivative=\"false\")".into())
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetRealInputDerivatives(
    c: Fmi2Component,
    _vr: *const Fmi2ValueReference,
    _nvr: usize,
    _order: *const Fmi2Integer,
    _value: *const Fmi2Real,
) -> Fmi2StatusC {
    unsafe {
        with_instance(c, Call::SetRealInputDerivatives, |_| {
            Err("not supported (canInterpolateInputs=\"false\"): inputs are sampled, held over a step".into())
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetRealOutputDerivatives(
    c: Fmi2Component,
    _vr: *const Fmi2ValueReference,
    _nvr: usize,
    _order: *const Fmi2Integer,
    _value: *mut Fmi2Real,
) -> Fmi2StatusC {
    unsafe {
        with_instance(c, Call::GetRealOutputDerivatives, |_| {
            Err("not supported (maxOutputDerivativeOrder=\"0\")".into())
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2DoStep(
    c: Fmi2Component,
    current_communication_point: Fmi2Real,
    communication_step_size: Fmi2Real,
    _no_set_fmu_state_prior: Fmi2Boolean,
) -> Fmi2StatusC {
    unsafe {
        with_instance(c, Call::DoStep, |inst| {
            inst.log_call(Call::DoStep, || {
                format!("currentCommunicationPoint={current_communication_point}, communicationStepSize={communication_step_size}")
            });
            match inst.do_step(current_communication_point, communication_step_size)? {
                StepOutcome::Complete => Ok(Fmi2Status::Ok),
                StepOutcome::Cut { at, reached, limit } => {
                    // fmi2Discard: only part of the step was computed; the standard's step failed state
                    // follows, from which the master reads fmi2LastSuccessfulTime, then terminates or
                    // restores an FMU state and retries with a shorter step.
                    inst.layer.state = State::StepFailed;
                    if inst.log.discards {
                        inst.emit(
                            Fmi2Status::Discard,
                            "logStatusDiscard",
                            &format!(
                                "fmi2DoStep: the step from {current_communication_point} by \
                                 {communication_step_size} reaches {reached} sample instants; {} takes at most \
                                 {limit} per step, so it stopped at t = {at} (fmi2LastSuccessfulTime). Step by \
                                 at most Ts = {}",
                                inst.slave.identifier(),
                                inst.slave.sample_period()
                            ),
                        );
                    }
                    Ok(Fmi2Status::Discard)
                }
            }
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2CancelStep(c: Fmi2Component) -> Fmi2StatusC {
    // Steps are synchronous, so no step is ever in progress: the state machine refuses this call.
    unsafe { with_instance(c, Call::CancelStep, |_| Ok(Fmi2Status::Ok)) }
}

/// A status kind this slave cannot report: fmi2Discard, as the standard prescribes, with a warning.
fn unavailable(inst: &Instance, call: &str, kind: Fmi2StatusKind) -> Fmi2Status {
    if inst.log.warnings {
        inst.emit(
            Fmi2Status::Discard,
            "logStatusWarning",
            &format!("{call}: status kind {kind} is not available (steps are synchronous)"),
        );
    }
    Fmi2Status::Discard
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetStatus(
    c: Fmi2Component,
    s: Fmi2StatusKind,
    value: *mut Fmi2StatusC,
) -> Fmi2StatusC {
    unsafe {
        with_instance(c, Call::GetStatus, |inst| {
            if value.is_null() {
                return Err("value is NULL".into());
            }
            if s == FMI2_DO_STEP_STATUS {
                // Steps complete before fmi2DoStep returns; there is no asynchronous status to report.
                *value = Fmi2Status::Ok as Fmi2StatusC;
                Ok(Fmi2Status::Ok)
            } else {
                Ok(unavailable(inst, "fmi2GetStatus", s))
            }
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetRealStatus(
    c: Fmi2Component,
    s: Fmi2StatusKind,
    value: *mut Fmi2Real,
) -> Fmi2StatusC {
    unsafe {
        with_instance(c, Call::GetRealStatus, |inst| {
            if value.is_null() {
                return Err("value is NULL".into());
            }
            if s == FMI2_LAST_SUCCESSFUL_TIME {
                *value = inst.time();
                Ok(Fmi2Status::Ok)
            } else {
                Ok(unavailable(inst, "fmi2GetRealStatus", s))
            }
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetIntegerStatus(
    c: Fmi2Component,
    s: Fmi2StatusKind,
    _value: *mut Fmi2Integer,
) -> Fmi2StatusC {
    unsafe {
        with_instance(c, Call::GetIntegerStatus, |inst| {
            Ok(unavailable(inst, "fmi2GetIntegerStatus", s))
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetBooleanStatus(
    c: Fmi2Component,
    s: Fmi2StatusKind,
    value: *mut Fmi2Boolean,
) -> Fmi2StatusC {
    unsafe {
        with_instance(c, Call::GetBooleanStatus, |inst| {
            if value.is_null() {
                return Err("value is NULL".into());
            }
            if s == FMI2_TERMINATED {
                // The slave never asks to end the simulation.
                *value = FMI2_FALSE;
                Ok(Fmi2Status::Ok)
            } else {
                Ok(unavailable(inst, "fmi2GetBooleanStatus", s))
            }
        })
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetStringStatus(
    c: Fmi2Component,
    s: Fmi2StatusKind,
    _value: *mut Fmi2String,
) -> Fmi2StatusC {
    unsafe {
        with_instance(c, Call::GetStringStatus, |inst| {
            Ok(unavailable(inst, "fmi2GetStringStatus", s))
        })
    }
}
