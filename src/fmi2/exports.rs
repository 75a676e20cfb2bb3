//! The 34 exported FMI 2.0 co-simulation functions: the C boundary.
//!
//! Each function checks its pointers, runs under `catch_unwind` so that no panic crosses into the importer,
//! checks the call against the state machine, and turns every refusal into fmi2Error with a logged reason.
//! Model exchange functions are not exported: the descriptions declare co-simulation only.
//!
//! Safety, for every export: the importer keeps the standard's promises (a component is NULL or a live
//! instance called by one thread at a time; arrays hold the elements their counts say; strings are
//! NUL-terminated). Within those, every argument is checked, and each pointer is read or written in one
//! small helper of the core's [`boundary`](crate::fmi::boundary) (`instance`, `slice`, `slice_mut`, `c_str`,
//! `read_in`, `write_out`, `read_state_slot`), which the FMI 3.0 layer shares. The one unsafe call of this
//! layer's own is that of the importer's logger ([`emit_raw`]).
#![allow(
    non_snake_case,
    reason = "the exported functions carry the names the FMI standard gives them"
)]
#![allow(
    clippy::missing_safety_doc,
    reason = "the exports share one safety contract, stated in the module documentation"
)]

use super::ffi::*;
use super::state::Call;
use crate::fmi::boundary::{
    c_str, deserialize, do_step, free_fmu_state, free_instance, get_fmu_state, get_values,
    instance, new_instance, read_in, serialize, serialized_size, set_debug_logging, set_fmu_state,
    set_values, slice, slice_mut, with_instance, write_out,
};
use crate::fmi::instance::Instance;
use crate::fmi::log::{Logger, cstring};
use crate::fmi::status::Status;
use crate::fmi::vars::{Value, VarType};
use std::ffi::{CStr, c_char};
use std::panic::catch_unwind;

/// Log through the importer's logger, if it gave one. The text is the format itself, with every '%' doubled
/// and no further argument: printf-style loggers (FMPy's, the FMI Library's) print it unchanged, and loggers
/// that do not format show it as it is, apart from the doubled '%' (the standard's logger is a printf format).
pub fn emit_raw(
    callbacks: &Fmi2CallbackFunctions,
    instance: &CStr,
    status: Status,
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
                Fmi2Status::from(status) as Fmi2StatusC,
                category.as_ptr(),
                format.as_ptr(),
            );
        }
    }
}

impl Logger for Fmi2CallbackFunctions {
    fn log(&self, instance: &CStr, status: Status, category: &str, text: &str) {
        emit_raw(self, instance, status, category, text);
    }
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
        // SAFETY: the importer passes NULL or the address of its callback struct.
        let callbacks = unsafe { read_in(functions) };
        // SAFETY: the importer passes NULL or a NUL-terminated string.
        let name = unsafe { c_str(instance_name, "instanceName") }.ok();
        let refuse = |reason: &str| {
            if let Some(cb) = &callbacks {
                let n = std::ffi::CString::new(name.unwrap_or("?")).unwrap_or_default();
                emit_raw(
                    cb,
                    &n,
                    Status::Error,
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
        // SAFETY: the importer passes NULL or a NUL-terminated string.
        let guid = match unsafe { c_str(fmu_guid, "fmuGUID") } {
            Ok(g) => g,
            Err(e) => return refuse(&e),
        };
        let made = new_instance(
            Call::Instantiate,
            name,
            ("fmuGUID", guid),
            callbacks,
            logging_on != FMI2_FALSE,
        );
        made.unwrap_or_else(|e| refuse(&e))
    });
    result.unwrap_or(std::ptr::null_mut())
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2FreeInstance(c: Fmi2Component) {
    // SAFETY: `c` is NULL or a live instance, freed once (the importer's side of the standard).
    unsafe { free_instance(c, Call::FreeInstance) }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetDebugLogging(
    c: Fmi2Component,
    logging_on: Fmi2Boolean,
    n_categories: usize,
    categories: *const Fmi2String,
) -> Fmi2StatusC {
    // SAFETY: the arguments as the standard requires of the importer (see `set_debug_logging`).
    unsafe {
        set_debug_logging(
            c,
            Call::SetDebugLogging,
            logging_on != FMI2_FALSE,
            n_categories,
            categories,
        )
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
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::SetupExperiment, |inst| {
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
        Ok(Status::Ok)
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2EnterInitializationMode(c: Fmi2Component) -> Fmi2StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::EnterInitializationMode, |inst| {
        inst.log_call(Call::EnterInitializationMode, String::new);
        inst.enter_initialization()?;
        Ok(Status::Ok)
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2ExitInitializationMode(c: Fmi2Component) -> Fmi2StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::ExitInitializationMode, |inst| {
        inst.log_call(Call::ExitInitializationMode, String::new);
        inst.exit_initialization()?;
        Ok(Status::Ok)
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2Terminate(c: Fmi2Component) -> Fmi2StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::Terminate, |inst| {
        inst.log_call(Call::Terminate, String::new);
        inst.terminate()?;
        Ok(Status::Ok)
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2Reset(c: Fmi2Component) -> Fmi2StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::Reset, |inst| {
        inst.log_call(Call::Reset, String::new);
        inst.reset()?;
        Ok(Status::Ok)
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetReal(
    c: Fmi2Component,
    vr: *const Fmi2ValueReference,
    nvr: usize,
    value: *mut Fmi2Real,
) -> Fmi2StatusC {
    // SAFETY: the arguments as the standard requires of the importer (see `get_values`).
    unsafe {
        get_values(
            c,
            Call::GetReal,
            VarType::Real,
            vr,
            nvr,
            value,
            nvr,
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
    // SAFETY: the arguments as the standard requires of the importer (see `get_values`).
    unsafe {
        get_values(
            c,
            Call::GetInteger,
            VarType::Integer,
            vr,
            nvr,
            value,
            nvr,
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
    // SAFETY: the arguments as the standard requires of the importer (see `get_values`).
    unsafe {
        get_values(
            c,
            Call::GetBoolean,
            VarType::Boolean,
            vr,
            nvr,
            value,
            nvr,
            |v| {
                if v.as_bool() { FMI2_TRUE } else { FMI2_FALSE }
            },
        )
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetString(
    c: Fmi2Component,
    vr: *const Fmi2ValueReference,
    nvr: usize,
    value: *mut Fmi2String,
) -> Fmi2StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::GetString, |inst| {
        // SAFETY: `vr` and `value` hold `nvr` elements, as the standard requires of the importer.
        let vrs = unsafe { slice(vr, nvr, "vr") }?;
        // SAFETY: as above.
        let out = unsafe { slice_mut(value, nvr, "value") }?;
        let values = inst.get(VarType::String, vrs)?;
        let kept = inst.keep_strings(&values);
        for (o, s) in out.iter_mut().zip(kept) {
            *o = s.as_ptr();
        }
        Ok(Status::Ok)
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetReal(
    c: Fmi2Component,
    vr: *const Fmi2ValueReference,
    nvr: usize,
    value: *const Fmi2Real,
) -> Fmi2StatusC {
    // SAFETY: the arguments as the standard requires of the importer (see `set_values`).
    unsafe {
        set_values(c, Call::SetReal, VarType::Real, vr, nvr, value, nvr, |v| {
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
    // SAFETY: the arguments as the standard requires of the importer (see `set_values`).
    unsafe {
        set_values(
            c,
            Call::SetInteger,
            VarType::Integer,
            vr,
            nvr,
            value,
            nvr,
            |v| Ok(Value::Integer(v)),
        )
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetBoolean(
    c: Fmi2Component,
    vr: *const Fmi2ValueReference,
    nvr: usize,
    value: *const Fmi2Boolean,
) -> Fmi2StatusC {
    // SAFETY: the arguments as the standard requires of the importer (see `set_values`).
    unsafe {
        set_values(
            c,
            Call::SetBoolean,
            VarType::Boolean,
            vr,
            nvr,
            value,
            nvr,
            |v| Ok(Value::Boolean(v != FMI2_FALSE)),
        )
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetString(
    c: Fmi2Component,
    vr: *const Fmi2ValueReference,
    nvr: usize,
    value: *const Fmi2String,
) -> Fmi2StatusC {
    let convert = |p: Fmi2String| {
        // SAFETY: each value is NULL or a NUL-terminated string (the importer's promise).
        unsafe { c_str(p, "a string value") }.map(|s| Value::String(s.to_string()))
    };
    // SAFETY: the arguments as the standard requires of the importer (see `set_values`).
    unsafe {
        set_values(
            c,
            Call::SetString,
            VarType::String,
            vr,
            nvr,
            value,
            nvr,
            convert,
        )
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetFMUstate(
    c: Fmi2Component,
    state: *mut Fmi2FmuState,
) -> Fmi2StatusC {
    // SAFETY: the arguments as the standard requires of the importer (see `get_fmu_state`).
    unsafe { get_fmu_state(c, Call::GetFmuState, state) }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetFMUstate(c: Fmi2Component, state: Fmi2FmuState) -> Fmi2StatusC {
    // SAFETY: the arguments as the standard requires of the importer (see `set_fmu_state`).
    unsafe { set_fmu_state(c, Call::SetFmuState, state) }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2FreeFMUstate(
    c: Fmi2Component,
    state: *mut Fmi2FmuState,
) -> Fmi2StatusC {
    // SAFETY: the arguments as the standard requires of the importer (see `free_fmu_state`).
    unsafe { free_fmu_state(c, Call::FreeFmuState, state) }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SerializedFMUstateSize(
    c: Fmi2Component,
    state: Fmi2FmuState,
    size: *mut usize,
) -> Fmi2StatusC {
    // SAFETY: the arguments as the standard requires of the importer (see `serialized_size`).
    unsafe { serialized_size(c, Call::SerializedFmuStateSize, state, size) }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SerializeFMUstate(
    c: Fmi2Component,
    state: Fmi2FmuState,
    bytes: *mut Fmi2Byte,
    size: usize,
) -> Fmi2StatusC {
    // SAFETY: the arguments as the standard requires of the importer (see `serialize`).
    unsafe { serialize(c, Call::SerializeFmuState, state, bytes.cast::<u8>(), size) }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
    c: Fmi2Component,
    bytes: *const Fmi2Byte,
    size: usize,
    state: *mut Fmi2FmuState,
) -> Fmi2StatusC {
    // SAFETY: the arguments as the standard requires of the importer (see `deserialize`).
    unsafe {
        deserialize(
            c,
            Call::DeSerializeFmuState,
            bytes.cast::<u8>(),
            size,
            state,
        )
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
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::GetDirectionalDerivative, |_| {
        Err("not provided (providesDirectionalDerivative=\"false\")".into())
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetRealInputDerivatives(
    c: Fmi2Component,
    _vr: *const Fmi2ValueReference,
    _nvr: usize,
    _order: *const Fmi2Integer,
    _value: *const Fmi2Real,
) -> Fmi2StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::SetRealInputDerivatives, |_| {
        Err(
            "not supported (canInterpolateInputs=\"false\"): inputs are sampled, held over a step"
                .into(),
        )
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetRealOutputDerivatives(
    c: Fmi2Component,
    _vr: *const Fmi2ValueReference,
    _nvr: usize,
    _order: *const Fmi2Integer,
    _value: *mut Fmi2Real,
) -> Fmi2StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::GetRealOutputDerivatives, |_| {
        Err("not supported (maxOutputDerivativeOrder=\"0\")".into())
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2DoStep(
    c: Fmi2Component,
    current_communication_point: Fmi2Real,
    communication_step_size: Fmi2Real,
    _no_set_fmu_state_prior: Fmi2Boolean,
) -> Fmi2StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::DoStep, |inst| {
        do_step(
            inst,
            Call::DoStep,
            current_communication_point,
            communication_step_size,
        )
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2CancelStep(c: Fmi2Component) -> Fmi2StatusC {
    // Steps are synchronous, so no step is ever in progress: the state machine refuses this call.
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::CancelStep, |_| Ok(Status::Ok))
}

/// A status kind this slave cannot report: fmi2Discard, as the standard prescribes, with a warning.
fn unavailable(inst: &Instance, call: &str, kind: Fmi2StatusKind) -> Status {
    if inst.log.warnings {
        inst.emit(
            Status::Discard,
            "logStatusWarning",
            &format!("{call}: status kind {kind} is not available (steps are synchronous)"),
        );
    }
    Status::Discard
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetStatus(
    c: Fmi2Component,
    s: Fmi2StatusKind,
    value: *mut Fmi2StatusC,
) -> Fmi2StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::GetStatus, |inst| {
        if value.is_null() {
            return Err("value is NULL".into());
        }
        if s == FMI2_DO_STEP_STATUS {
            // Steps complete before fmi2DoStep returns; there is no asynchronous status to report.
            // SAFETY: `value` is the address of the importer's variable (the standard).
            unsafe { write_out(value, Fmi2Status::Ok as Fmi2StatusC, "value") }?;
            Ok(Status::Ok)
        } else {
            Ok(unavailable(inst, "fmi2GetStatus", s))
        }
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetRealStatus(
    c: Fmi2Component,
    s: Fmi2StatusKind,
    value: *mut Fmi2Real,
) -> Fmi2StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::GetRealStatus, |inst| {
        if value.is_null() {
            return Err("value is NULL".into());
        }
        if s == FMI2_LAST_SUCCESSFUL_TIME {
            // SAFETY: `value` is the address of the importer's variable (the standard).
            unsafe { write_out(value, inst.time(), "value") }?;
            Ok(Status::Ok)
        } else {
            Ok(unavailable(inst, "fmi2GetRealStatus", s))
        }
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetIntegerStatus(
    c: Fmi2Component,
    s: Fmi2StatusKind,
    _value: *mut Fmi2Integer,
) -> Fmi2StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::GetIntegerStatus, |inst| {
        Ok(unavailable(inst, "fmi2GetIntegerStatus", s))
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetBooleanStatus(
    c: Fmi2Component,
    s: Fmi2StatusKind,
    value: *mut Fmi2Boolean,
) -> Fmi2StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::GetBooleanStatus, |inst| {
        if value.is_null() {
            return Err("value is NULL".into());
        }
        if s == FMI2_TERMINATED {
            // The slave never asks to end the simulation.
            // SAFETY: `value` is the address of the importer's variable (the standard).
            unsafe { write_out(value, FMI2_FALSE, "value") }?;
            Ok(Status::Ok)
        } else {
            Ok(unavailable(inst, "fmi2GetBooleanStatus", s))
        }
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetStringStatus(
    c: Fmi2Component,
    s: Fmi2StatusKind,
    _value: *mut Fmi2String,
) -> Fmi2StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::GetStringStatus, |inst| {
        Ok(unavailable(inst, "fmi2GetStringStatus", s))
    })
}
