//! The exported FMI 3.0 functions of a co-simulation FMU: the C boundary.
//!
//! Every function of the standard's fmi3Functions.h is exported (FMPy, for one, loads them all whatever the
//! interface). Each checks its pointers,
//! runs under `catch_unwind` (in `with_instance`, shared with the FMI 2.0 layer), checks the call against
//! the state machine ([`super::state`]) and turns every refusal into fmi3Error with a logged reason. What
//! these FMUs do not provide (other types, clocks, event and configuration mode, derivatives, dependencies,
//! the model-exchange and scheduled-execution functions) answers fmi3Error with a log line saying so; model
//! exchange and scheduled execution are refused at instantiation.
//!
//! Safety, for every export: the importer keeps the standard's promises (an instance is NULL or a live
//! instance called by one thread at a time; arrays hold the elements their counts say; strings are
//! NUL-terminated; output arguments point to writable variables). Within those, every argument is checked,
//! and each pointer is read or written in one small helper of the core's
//! [`boundary`](crate::fmi::boundary). The one unsafe call of this layer's own is that of the importer's
//! logger (`Fmi3Logger`).
#![allow(
    non_snake_case,
    reason = "the exported functions carry the names the FMI standard gives them"
)]
#![allow(
    clippy::missing_safety_doc,
    reason = "the exports share one safety contract, stated in the module documentation"
)]

use super::TIME_VR;
use super::ffi::*;
use super::state::Call;
use crate::fmi::boundary::{
    c_str, check_counts, deserialize, do_step, free_fmu_state, free_instance, get_fmu_state,
    get_values, instance, new_instance, serialize, serialized_size, set_debug_logging,
    set_fmu_state, set_values, slice, slice_mut, with_instance, write_out,
};
use crate::fmi::log::{Logger, cstring};
use crate::fmi::status::Status;
use crate::fmi::vars::{Value, VarType};
use std::ffi::{CStr, c_char};
use std::panic::catch_unwind;

/// The importer's logger and its environment (fmi3LogMessageCallback; NULL means no logging).
#[derive(Clone, Copy)]
struct Fmi3Logger {
    environment: Fmi3InstanceEnvironment,
    callback: Fmi3LogMessageCallback,
}

impl Logger for Fmi3Logger {
    fn log(&self, _instance: &CStr, status: Status, category: &str, text: &str) {
        if let Some(callback) = self.callback {
            let (category, message) = (cstring(category), cstring(text));
            // SAFETY: the importer's C function with its own environment; both strings are NUL-terminated
            // and outlive the call (FMI 3.0 messages are plain text, not printf formats).
            unsafe {
                callback(
                    self.environment,
                    Fmi3Status::from(status) as Fmi3StatusC,
                    category.as_ptr(),
                    message.as_ptr(),
                )
            };
        }
    }
}

#[unsafe(no_mangle)]
pub extern "C" fn fmi3GetVersion() -> *const c_char {
    c"3.0".as_ptr()
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SetDebugLogging(
    c: Fmi3Instance,
    logging_on: Fmi3Boolean,
    n_categories: usize,
    categories: *const Fmi3String,
) -> Fmi3StatusC {
    // SAFETY: the arguments as the standard requires of the importer (see `set_debug_logging`).
    unsafe {
        set_debug_logging(
            c,
            Call::SetDebugLogging,
            logging_on != FMI3_FALSE,
            n_categories,
            categories,
        )
    }
}

/// Log why an instantiation is refused (if the importer gave a logger) and return NULL.
fn refuse(logger: Fmi3Logger, call: Call, reason: &str) -> Fmi3Instance {
    logger.log(
        c"",
        Status::Error,
        "logStatusError",
        &format!("{}: {reason}", call.name()),
    );
    std::ptr::null_mut()
}

#[unsafe(no_mangle)]
#[allow(
    clippy::too_many_arguments,
    reason = "the signature the FMI 3.0 standard gives fmi3InstantiateCoSimulation"
)]
pub unsafe extern "C" fn fmi3InstantiateCoSimulation(
    instance_name: Fmi3String,
    instantiation_token: Fmi3String,
    _resource_path: Fmi3String,
    _visible: Fmi3Boolean,
    logging_on: Fmi3Boolean,
    event_mode_used: Fmi3Boolean,
    _early_return_allowed: Fmi3Boolean,
    _required_intermediate_variables: *const Fmi3ValueReference,
    _n_required_intermediate_variables: usize,
    instance_environment: Fmi3InstanceEnvironment,
    log_message: Fmi3LogMessageCallback,
    _intermediate_update: Fmi3IntermediateUpdateCallback,
) -> Fmi3Instance {
    let logger = Fmi3Logger {
        environment: instance_environment,
        callback: log_message,
    };
    let call = Call::InstantiateCoSimulation;
    let result = catch_unwind(|| {
        // SAFETY: the importer passes NULL or a NUL-terminated string.
        let name = match unsafe { c_str(instance_name, "instanceName") } {
            Ok(n) if !n.is_empty() => n,
            Ok(_) => return refuse(logger, call, "instanceName is empty"),
            Err(e) => return refuse(logger, call, &e),
        };
        if event_mode_used != FMI3_FALSE {
            return refuse(
                logger,
                call,
                "eventModeUsed is true, but this FMU has no event mode (hasEventMode=\"false\")",
            );
        }
        // SAFETY: the importer passes NULL or a NUL-terminated string.
        let token = match unsafe { c_str(instantiation_token, "instantiationToken") } {
            Ok(t) => t,
            Err(e) => return refuse(logger, call, &e),
        };
        let made = new_instance(
            call,
            name,
            ("instantiationToken", token),
            logger,
            logging_on != FMI3_FALSE,
        );
        made.unwrap_or_else(|e| refuse(logger, call, &e))
    });
    result.unwrap_or(std::ptr::null_mut())
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3InstantiateModelExchange(
    _instance_name: Fmi3String,
    _instantiation_token: Fmi3String,
    _resource_path: Fmi3String,
    _visible: Fmi3Boolean,
    _logging_on: Fmi3Boolean,
    instance_environment: Fmi3InstanceEnvironment,
    log_message: Fmi3LogMessageCallback,
) -> Fmi3Instance {
    let logger = Fmi3Logger {
        environment: instance_environment,
        callback: log_message,
    };
    catch_unwind(|| {
        refuse(
            logger,
            Call::InstantiateModelExchange,
            "this FMU implements co-simulation only: call fmi3InstantiateCoSimulation",
        )
    })
    .unwrap_or(std::ptr::null_mut())
}

#[unsafe(no_mangle)]
#[allow(
    clippy::too_many_arguments,
    reason = "the signature the FMI 3.0 standard gives fmi3InstantiateScheduledExecution"
)]
pub unsafe extern "C" fn fmi3InstantiateScheduledExecution(
    _instance_name: Fmi3String,
    _instantiation_token: Fmi3String,
    _resource_path: Fmi3String,
    _visible: Fmi3Boolean,
    _logging_on: Fmi3Boolean,
    instance_environment: Fmi3InstanceEnvironment,
    log_message: Fmi3LogMessageCallback,
    _clock_update: Fmi3ClockUpdateCallback,
    _lock_preemption: Fmi3PreemptionCallback,
    _unlock_preemption: Fmi3PreemptionCallback,
) -> Fmi3Instance {
    let logger = Fmi3Logger {
        environment: instance_environment,
        callback: log_message,
    };
    catch_unwind(|| {
        refuse(
            logger,
            Call::InstantiateScheduledExecution,
            "this FMU implements co-simulation only: call fmi3InstantiateCoSimulation",
        )
    })
    .unwrap_or(std::ptr::null_mut())
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3FreeInstance(c: Fmi3Instance) {
    // SAFETY: `c` is NULL or a live instance, freed once (the importer's side of the standard).
    unsafe { free_instance(c, Call::FreeInstance) }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3EnterInitializationMode(
    c: Fmi3Instance,
    tolerance_defined: Fmi3Boolean,
    tolerance: Fmi3Float64,
    start_time: Fmi3Float64,
    stop_time_defined: Fmi3Boolean,
    stop_time: Fmi3Float64,
) -> Fmi3StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::EnterInitializationMode, |inst| {
        inst.log_call(Call::EnterInitializationMode, || {
            format!("tolerance={tolerance}, startTime={start_time}, stopTime={stop_time}")
        });
        inst.setup_experiment(
            tolerance_defined != FMI3_FALSE,
            tolerance,
            start_time,
            stop_time_defined != FMI3_FALSE,
            stop_time,
        )?;
        // The independent variable reads the start time during initialization.
        inst.layer.time = start_time;
        inst.enter_initialization()?;
        Ok(Status::Ok)
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3ExitInitializationMode(c: Fmi3Instance) -> Fmi3StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::ExitInitializationMode, |inst| {
        inst.log_call(Call::ExitInitializationMode, String::new);
        // Without event mode the instance goes straight to step mode.
        inst.exit_initialization()?;
        Ok(Status::Ok)
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3Terminate(c: Fmi3Instance) -> Fmi3StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::Terminate, |inst| {
        inst.log_call(Call::Terminate, String::new);
        inst.terminate()?;
        Ok(Status::Ok)
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3Reset(c: Fmi3Instance) -> Fmi3StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::Reset, |inst| {
        inst.log_call(Call::Reset, String::new);
        inst.reset()?;
        Ok(Status::Ok)
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetFloat64(
    c: Fmi3Instance,
    value_references: *const Fmi3ValueReference,
    n_value_references: usize,
    values: *mut Fmi3Float64,
    n_values: usize,
) -> Fmi3StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::GetFloat64, |inst| {
        check_counts(n_value_references, n_values)?;
        // SAFETY: both arrays hold `n_value_references` elements, as the standard requires.
        let vrs = unsafe { slice(value_references, n_value_references, "valueReferences") }?;
        // SAFETY: as above.
        let out = unsafe { slice_mut(values, n_value_references, "values") }?;
        if vrs.contains(&TIME_VR) {
            // The independent variable is the layer's clock, not a model variable: one by one.
            for (k, &vr) in vrs.iter().enumerate() {
                if vr == TIME_VR {
                    out[k] = inst.time();
                } else {
                    inst.get_with(VarType::Real, &vrs[k..=k], |_, v| out[k] = v.as_real())?;
                }
            }
        } else {
            // No allocation: the values go straight to the caller's array.
            inst.get_with(VarType::Real, vrs, |k, v| out[k] = v.as_real())?;
        }
        Ok(inst.model_status(Call::GetFloat64))
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetInt32(
    c: Fmi3Instance,
    value_references: *const Fmi3ValueReference,
    n_value_references: usize,
    values: *mut Fmi3Int32,
    n_values: usize,
) -> Fmi3StatusC {
    // SAFETY: the arguments as the standard requires of the importer (see `get_values`).
    unsafe {
        get_values(
            c,
            Call::GetInt32,
            VarType::Integer,
            value_references,
            n_value_references,
            values,
            n_values,
            Value::as_integer,
        )
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetBoolean(
    c: Fmi3Instance,
    value_references: *const Fmi3ValueReference,
    n_value_references: usize,
    values: *mut Fmi3Boolean,
    n_values: usize,
) -> Fmi3StatusC {
    // SAFETY: the arguments as the standard requires of the importer (see `get_values`).
    unsafe {
        get_values(
            c,
            Call::GetBoolean,
            VarType::Boolean,
            value_references,
            n_value_references,
            values,
            n_values,
            |v| if v.as_bool() { FMI3_TRUE } else { FMI3_FALSE },
        )
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SetFloat64(
    c: Fmi3Instance,
    value_references: *const Fmi3ValueReference,
    n_value_references: usize,
    values: *const Fmi3Float64,
    n_values: usize,
) -> Fmi3StatusC {
    // SAFETY: the arguments as the standard requires of the importer (see `set_values`).
    unsafe {
        set_values(
            c,
            Call::SetFloat64,
            VarType::Real,
            value_references,
            n_value_references,
            values,
            n_values,
            |v| Ok(Value::Real(v)),
        )
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SetInt32(
    c: Fmi3Instance,
    value_references: *const Fmi3ValueReference,
    n_value_references: usize,
    values: *const Fmi3Int32,
    n_values: usize,
) -> Fmi3StatusC {
    // SAFETY: the arguments as the standard requires of the importer (see `set_values`).
    unsafe {
        set_values(
            c,
            Call::SetInt32,
            VarType::Integer,
            value_references,
            n_value_references,
            values,
            n_values,
            |v| Ok(Value::Integer(v)),
        )
    }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SetBoolean(
    c: Fmi3Instance,
    value_references: *const Fmi3ValueReference,
    n_value_references: usize,
    values: *const Fmi3Boolean,
    n_values: usize,
) -> Fmi3StatusC {
    // SAFETY: the arguments as the standard requires of the importer (see `set_values`).
    unsafe {
        set_values(
            c,
            Call::SetBoolean,
            VarType::Boolean,
            value_references,
            n_value_references,
            values,
            n_values,
            |v| Ok(Value::Boolean(v != FMI3_FALSE)),
        )
    }
}

/// A getter or setter of a type no variable of these FMUs has: fine for no reference at all, fmi3Error
/// naming the type otherwise.
///
/// # Safety
/// `c` is NULL or a live instance, as the standard requires of the importer.
unsafe fn absent_type(c: Fmi3Instance, call: Call, type_name: &str, n: usize) -> Fmi3StatusC {
    // SAFETY: `c` as this function's caller promises.
    let inst = unsafe { instance(c) };
    with_instance(inst, call, |_| {
        if n == 0 {
            Ok(Status::Ok)
        } else {
            Err(format!(
                "this FMU has no {type_name} variable: its variables are Float64, Int32 and Boolean scalars"
            ))
        }
    })
}

macro_rules! absent_types {
    ($($name:ident, $call:ident, $ty:literal, ($($arg:ident: $argty:ty),*);)*) => {$(
        #[unsafe(no_mangle)]
        pub unsafe extern "C" fn $name(
            c: Fmi3Instance,
            _value_references: *const Fmi3ValueReference,
            n_value_references: usize,
            $($arg: $argty),*
        ) -> Fmi3StatusC {
            // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
            unsafe { absent_type(c, Call::$call, $ty, n_value_references) }
        }
    )*};
}

absent_types! {
    fmi3GetFloat32, GetFloat32, "Float32", (_values: *mut f32, _n_values: usize);
    fmi3GetInt8, GetInt8, "Int8", (_values: *mut i8, _n_values: usize);
    fmi3GetUInt8, GetUInt8, "UInt8", (_values: *mut u8, _n_values: usize);
    fmi3GetInt16, GetInt16, "Int16", (_values: *mut i16, _n_values: usize);
    fmi3GetUInt16, GetUInt16, "UInt16", (_values: *mut u16, _n_values: usize);
    fmi3GetUInt32, GetUInt32, "UInt32", (_values: *mut u32, _n_values: usize);
    fmi3GetInt64, GetInt64, "Int64", (_values: *mut i64, _n_values: usize);
    fmi3GetUInt64, GetUInt64, "UInt64", (_values: *mut u64, _n_values: usize);
    fmi3GetString, GetString, "String", (_values: *mut Fmi3String, _n_values: usize);
    fmi3GetBinary, GetBinary, "Binary",
        (_value_sizes: *mut usize, _values: *mut *const Fmi3Byte, _n_values: usize);
    fmi3GetClock, GetClock, "Clock", (_values: *mut Fmi3Boolean);
    fmi3SetFloat32, SetFloat32, "Float32", (_values: *const f32, _n_values: usize);
    fmi3SetInt8, SetInt8, "Int8", (_values: *const i8, _n_values: usize);
    fmi3SetUInt8, SetUInt8, "UInt8", (_values: *const u8, _n_values: usize);
    fmi3SetInt16, SetInt16, "Int16", (_values: *const i16, _n_values: usize);
    fmi3SetUInt16, SetUInt16, "UInt16", (_values: *const u16, _n_values: usize);
    fmi3SetUInt32, SetUInt32, "UInt32", (_values: *const u32, _n_values: usize);
    fmi3SetInt64, SetInt64, "Int64", (_values: *const i64, _n_values: usize);
    fmi3SetUInt64, SetUInt64, "UInt64", (_values: *const u64, _n_values: usize);
    fmi3SetString, SetString, "String", (_values: *const Fmi3String, _n_values: usize);
    fmi3SetBinary, SetBinary, "Binary",
        (_value_sizes: *const usize, _values: *const *const Fmi3Byte, _n_values: usize);
    fmi3SetClock, SetClock, "Clock", (_values: *const Fmi3Boolean);
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetFMUState(c: Fmi3Instance, state: *mut Fmi3FmuState) -> Fmi3StatusC {
    // SAFETY: the arguments as the standard requires of the importer (see `get_fmu_state`).
    unsafe { get_fmu_state(c, Call::GetFmuState, state) }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SetFMUState(c: Fmi3Instance, state: Fmi3FmuState) -> Fmi3StatusC {
    // SAFETY: the arguments as the standard requires of the importer (see `set_fmu_state`).
    unsafe { set_fmu_state(c, Call::SetFmuState, state) }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3FreeFMUState(
    c: Fmi3Instance,
    state: *mut Fmi3FmuState,
) -> Fmi3StatusC {
    // SAFETY: the arguments as the standard requires of the importer (see `free_fmu_state`).
    unsafe { free_fmu_state(c, Call::FreeFmuState, state) }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SerializedFMUStateSize(
    c: Fmi3Instance,
    state: Fmi3FmuState,
    size: *mut usize,
) -> Fmi3StatusC {
    // SAFETY: the arguments as the standard requires of the importer (see `serialized_size`).
    unsafe { serialized_size(c, Call::SerializedFmuStateSize, state, size) }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SerializeFMUState(
    c: Fmi3Instance,
    state: Fmi3FmuState,
    serialized_state: *mut Fmi3Byte,
    size: usize,
) -> Fmi3StatusC {
    // SAFETY: the arguments as the standard requires of the importer (see `serialize`).
    unsafe { serialize(c, Call::SerializeFmuState, state, serialized_state, size) }
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3DeserializeFMUState(
    c: Fmi3Instance,
    serialized_state: *const Fmi3Byte,
    size: usize,
    state: *mut Fmi3FmuState,
) -> Fmi3StatusC {
    // SAFETY: the arguments as the standard requires of the importer (see `deserialize`).
    unsafe { deserialize(c, Call::DeserializeFmuState, serialized_state, size, state) }
}

#[unsafe(no_mangle)]
#[allow(
    clippy::too_many_arguments,
    reason = "the signature the FMI 3.0 standard gives fmi3DoStep"
)]
pub unsafe extern "C" fn fmi3DoStep(
    c: Fmi3Instance,
    current_communication_point: Fmi3Float64,
    communication_step_size: Fmi3Float64,
    _no_set_fmu_state_prior_to_current_point: Fmi3Boolean,
    event_handling_needed: *mut Fmi3Boolean,
    terminate_simulation: *mut Fmi3Boolean,
    early_return: *mut Fmi3Boolean,
    last_successful_time: *mut Fmi3Float64,
) -> Fmi3StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::DoStep, |inst| {
        if event_handling_needed.is_null()
            || terminate_simulation.is_null()
            || early_return.is_null()
            || last_successful_time.is_null()
        {
            return Err(
                "eventHandlingNeeded, terminateSimulation, earlyReturn and lastSuccessfulTime must be \
                 addresses of the importer's variables, not NULL"
                    .into(),
            );
        }
        let status = do_step(
            inst,
            Call::DoStep,
            current_communication_point,
            communication_step_size,
        )?;
        // No events, no request to stop, never an early return; the clock is the last successful time
        // (the step's end, or the instant a cut step stopped at).
        // SAFETY: not NULL, and the importer's writable variables (the standard).
        unsafe { write_out(event_handling_needed, FMI3_FALSE, "eventHandlingNeeded") }?;
        // SAFETY: as above.
        unsafe { write_out(terminate_simulation, FMI3_FALSE, "terminateSimulation") }?;
        // SAFETY: as above.
        unsafe { write_out(early_return, FMI3_FALSE, "earlyReturn") }?;
        // SAFETY: as above.
        unsafe { write_out(last_successful_time, inst.time(), "lastSuccessfulTime") }?;
        Ok(status)
    })
}

macro_rules! not_provided {
    ($($name:ident, $call:ident, $why:literal, ($($arg:ident: $argty:ty),*);)*) => {$(
        #[unsafe(no_mangle)]
        pub unsafe extern "C" fn $name(c: Fmi3Instance, $($arg: $argty),*) -> Fmi3StatusC {
            // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
            let inst = unsafe { instance(c) };
            with_instance(inst, Call::$call, |_| Err($why.into()))
        }
    )*};
}

not_provided! {
    fmi3EnterEventMode, EnterEventMode,
        "not provided (hasEventMode=\"false\"): after fmi3ExitInitializationMode the instance is in step mode",
        ();
    fmi3GetNumberOfVariableDependencies, GetNumberOfVariableDependencies,
        "not provided (providesPerElementDependencies=\"false\"): the ModelStructure lists the dependencies",
        (_value_reference: Fmi3ValueReference, _n_dependencies: *mut usize);
    fmi3GetVariableDependencies, GetVariableDependencies,
        "not provided (providesPerElementDependencies=\"false\"): the ModelStructure lists the dependencies",
        (_dependent: Fmi3ValueReference, _element_indices_of_dependent: *mut usize,
         _independents: *mut Fmi3ValueReference, _element_indices_of_independents: *mut usize,
         _dependency_kinds: *mut Fmi3EnumC, _n_dependencies: usize);
    fmi3GetDirectionalDerivative, GetDirectionalDerivative,
        "not provided (providesDirectionalDerivatives=\"false\")",
        (_unknowns: *const Fmi3ValueReference, _n_unknowns: usize, _knowns: *const Fmi3ValueReference,
         _n_knowns: usize, _seed: *const Fmi3Float64, _n_seed: usize, _sensitivity: *mut Fmi3Float64,
         _n_sensitivity: usize);
    fmi3GetAdjointDerivative, GetAdjointDerivative,
        "not provided (providesAdjointDerivatives=\"false\")",
        (_unknowns: *const Fmi3ValueReference, _n_unknowns: usize, _knowns: *const Fmi3ValueReference,
         _n_knowns: usize, _seed: *const Fmi3Float64, _n_seed: usize, _sensitivity: *mut Fmi3Float64,
         _n_sensitivity: usize);
    fmi3EnterConfigurationMode, EnterConfigurationMode,
        "not provided: this FMU has no structural parameters", ();
    fmi3ExitConfigurationMode, ExitConfigurationMode,
        "not provided: this FMU has no structural parameters", ();
    fmi3GetIntervalDecimal, GetIntervalDecimal, "not provided: this FMU has no clocks",
        (_value_references: *const Fmi3ValueReference, _n_value_references: usize,
         _intervals: *mut Fmi3Float64, _qualifiers: *mut Fmi3EnumC);
    fmi3GetIntervalFraction, GetIntervalFraction, "not provided: this FMU has no clocks",
        (_value_references: *const Fmi3ValueReference, _n_value_references: usize,
         _counters: *mut u64, _resolutions: *mut u64, _qualifiers: *mut Fmi3EnumC);
    fmi3GetShiftDecimal, GetShiftDecimal, "not provided: this FMU has no clocks",
        (_value_references: *const Fmi3ValueReference, _n_value_references: usize,
         _shifts: *mut Fmi3Float64);
    fmi3GetShiftFraction, GetShiftFraction, "not provided: this FMU has no clocks",
        (_value_references: *const Fmi3ValueReference, _n_value_references: usize,
         _counters: *mut u64, _resolutions: *mut u64);
    fmi3SetIntervalDecimal, SetIntervalDecimal, "not provided: this FMU has no clocks",
        (_value_references: *const Fmi3ValueReference, _n_value_references: usize,
         _intervals: *const Fmi3Float64);
    fmi3SetIntervalFraction, SetIntervalFraction, "not provided: this FMU has no clocks",
        (_value_references: *const Fmi3ValueReference, _n_value_references: usize,
         _counters: *const u64, _resolutions: *const u64);
    fmi3SetShiftDecimal, SetShiftDecimal, "not provided: this FMU has no clocks",
        (_value_references: *const Fmi3ValueReference, _n_value_references: usize,
         _shifts: *const Fmi3Float64);
    fmi3SetShiftFraction, SetShiftFraction, "not provided: this FMU has no clocks",
        (_value_references: *const Fmi3ValueReference, _n_value_references: usize,
         _counters: *const u64, _resolutions: *const u64);
    fmi3EvaluateDiscreteStates, EvaluateDiscreteStates,
        "not provided: this FMU has no clocks and no event mode", ();
    fmi3UpdateDiscreteStates, UpdateDiscreteStates,
        "not provided (hasEventMode=\"false\"): discrete states change only in fmi3DoStep",
        (_discrete_states_need_update: *mut Fmi3Boolean, _terminate_simulation: *mut Fmi3Boolean,
         _nominals_changed: *mut Fmi3Boolean, _values_changed: *mut Fmi3Boolean,
         _next_event_time_defined: *mut Fmi3Boolean, _next_event_time: *mut Fmi3Float64);
    fmi3EnterStepMode, EnterStepMode,
        "not provided (hasEventMode=\"false\"): the instance is in step mode after fmi3ExitInitializationMode",
        ();
    fmi3GetOutputDerivatives, GetOutputDerivatives,
        "not provided (maxOutputDerivativeOrder=\"0\"): outputs are sampled, held over a step",
        (_value_references: *const Fmi3ValueReference, _n_value_references: usize,
         _orders: *const Fmi3Int32, _values: *mut Fmi3Float64, _n_values: usize);
    fmi3EnterContinuousTimeMode, EnterContinuousTimeMode, "not provided: this FMU is co-simulation only", ();
    fmi3CompletedIntegratorStep, CompletedIntegratorStep, "not provided: this FMU is co-simulation only",
        (_no_set_fmu_state_prior_to_current_point: Fmi3Boolean, _enter_event_mode: *mut Fmi3Boolean,
         _terminate_simulation: *mut Fmi3Boolean);
    fmi3SetTime, SetTime, "not provided: this FMU is co-simulation only (fmi3DoStep advances time)",
        (_time: Fmi3Float64);
    fmi3SetContinuousStates, SetContinuousStates, "not provided: this FMU is co-simulation only",
        (_continuous_states: *const Fmi3Float64, _n_continuous_states: usize);
    fmi3GetContinuousStateDerivatives, GetContinuousStateDerivatives,
        "not provided: this FMU is co-simulation only",
        (_derivatives: *mut Fmi3Float64, _n_continuous_states: usize);
    fmi3GetEventIndicators, GetEventIndicators, "not provided: this FMU is co-simulation only",
        (_event_indicators: *mut Fmi3Float64, _n_event_indicators: usize);
    fmi3GetContinuousStates, GetContinuousStates, "not provided: this FMU is co-simulation only",
        (_continuous_states: *mut Fmi3Float64, _n_continuous_states: usize);
    fmi3GetNominalsOfContinuousStates, GetNominalsOfContinuousStates,
        "not provided: this FMU is co-simulation only",
        (_nominals: *mut Fmi3Float64, _n_continuous_states: usize);
    fmi3GetNumberOfEventIndicators, GetNumberOfEventIndicators,
        "not provided: this FMU is co-simulation only", (_n_event_indicators: *mut usize);
    fmi3GetNumberOfContinuousStates, GetNumberOfContinuousStates,
        "not provided: this FMU is co-simulation only", (_n_continuous_states: *mut usize);
    fmi3ActivateModelPartition, ActivateModelPartition,
        "not provided: this FMU is co-simulation only (no scheduled execution)",
        (_clock_reference: Fmi3ValueReference, _activation_time: Fmi3Float64);
}
