//! The 34 exported FMI 2.0 co-simulation functions: the C boundary.
//!
//! Each function checks its pointers, runs under `catch_unwind` so that no panic crosses into the importer,
//! checks the call against the state machine, and turns every refusal into fmi2Error with a logged reason.
//! Model exchange functions are not exported: the descriptions declare co-simulation only.
//!
//! Safety, for every export: the importer keeps the standard's promises (a component is NULL or a live
//! instance called by one thread at a time; arrays hold the elements their counts say; strings are
//! NUL-terminated). Within those, every argument is checked, and each pointer is read or written in one
//! small helper here (`instance`, `slice`, `slice_mut`, `c_str`, `write_out`, `read_state_slot`).
#![allow(
    non_snake_case,
    reason = "the exported functions carry the names the FMI standard gives them"
)]
#![allow(
    clippy::missing_safety_doc,
    reason = "the exports share one safety contract, stated in the module documentation"
)]

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

/// The instance behind the component pointer `c`, or `None` for NULL.
///
/// # Safety
/// `c` is NULL or a pointer that `fmi2Instantiate` returned and `fmi2FreeInstance` has not freed, and no
/// other call on the same instance runs meanwhile: the importer's side of the standard.
unsafe fn instance<'a>(c: Fmi2Component) -> Option<&'a mut Instance> {
    // SAFETY: the caller's promise above; `as_mut` turns NULL into `None`.
    unsafe { c.cast::<Instance>().as_mut() }
}

/// Run `f` on the instance (refusing a NULL component): state check, panic guard, error logging.
fn with_instance(
    inst: Option<&mut Instance>,
    call: Call,
    f: impl FnOnce(&mut Instance) -> Res,
) -> Fmi2StatusC {
    let Some(inst) = inst else {
        return Fmi2Status::Error as Fmi2StatusC;
    };
    let result = catch_unwind(AssertUnwindSafe(|| {
        inst.check_state(call)?;
        f(&mut *inst)
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
            inst.log_error(call, &format!("internal error: {text}"));
            inst.layer.state = State::Error;
            Fmi2Status::Error
        }
    };
    status as Fmi2StatusC
}

/// The largest element count a slice of `T` may have.
fn max_len<T>() -> usize {
    (isize::MAX as usize) / std::mem::size_of::<T>().max(1)
}

/// A slice from a C array, refusing NULL when `n > 0`.
///
/// # Safety
/// `ptr` is NULL or points to `n` initialised elements that nothing writes while the slice lives.
unsafe fn slice<'a, T>(ptr: *const T, n: usize, what: &str) -> Result<&'a [T], String> {
    if n == 0 {
        Ok(&[])
    } else if ptr.is_null() {
        Err(format!("{what} is NULL but nvr = {n}"))
    } else if n > max_len::<T>() {
        Err(format!("nvr = {n} is too large"))
    } else {
        // SAFETY: not NULL, `n` elements within the size limit of a slice; readable by the caller's promise.
        Ok(unsafe { std::slice::from_raw_parts(ptr, n) })
    }
}

/// A mutable slice from a C array, refusing NULL when `n > 0`.
///
/// # Safety
/// `ptr` is NULL or points to `n` initialised elements that nothing else reads or writes while the slice
/// lives.
unsafe fn slice_mut<'a, T>(ptr: *mut T, n: usize, what: &str) -> Result<&'a mut [T], String> {
    if n == 0 {
        Ok(&mut [])
    } else if ptr.is_null() {
        Err(format!("{what} is NULL but nvr = {n}"))
    } else if n > max_len::<T>() {
        Err(format!("nvr = {n} is too large"))
    } else {
        // SAFETY: not NULL, `n` elements within the size limit of a slice; writable by the caller's promise.
        Ok(unsafe { std::slice::from_raw_parts_mut(ptr, n) })
    }
}

/// A C string as UTF-8, refusing NULL.
///
/// # Safety
/// `p` is NULL or points to a NUL-terminated string that outlives the result.
unsafe fn c_str<'a>(p: Fmi2String, what: &str) -> Result<&'a str, String> {
    if p.is_null() {
        return Err(format!("{what} is NULL"));
    }
    // SAFETY: not NULL, and NUL-terminated by the caller's promise.
    unsafe { CStr::from_ptr(p) }
        .to_str()
        .map_err(|_| format!("{what} is not valid UTF-8"))
}

/// Store `value` in the importer's output variable at `p`, refusing NULL.
///
/// # Safety
/// `p` is NULL or valid for a write of one `T` (it need not be initialised: the old value is not read).
unsafe fn write_out<T: Copy>(p: *mut T, value: T, what: &str) -> Result<(), String> {
    if p.is_null() {
        return Err(format!("{what} is NULL"));
    }
    // SAFETY: not NULL, and writable by the caller's promise; `T: Copy` has nothing to drop.
    unsafe { p.write(value) };
    Ok(())
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
            // SAFETY: not NULL, and the importer passes the address of its callback struct.
            Some(unsafe { *functions })
        };
        let name = if instance_name.is_null() {
            None
        } else {
            // SAFETY: not NULL, and the importer passes NUL-terminated strings.
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
        // SAFETY: the importer passes NULL or a NUL-terminated string.
        let guid = match unsafe { c_str(fmu_guid, "fmuGUID") } {
            Ok(g) => g,
            Err(e) => return refuse(&e),
        };
        let slave = match crate::fmus::instantiate(guid) {
            Ok(s) => s,
            Err(e) => return refuse(&e),
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
        // SAFETY: the Box that fmi2Instantiate leaked, freed here once; `inst` is not used after this.
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
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::SetDebugLogging, |inst| {
        // SAFETY: the importer passes `n_categories` category strings at `categories`.
        let cats = unsafe { slice(categories, n_categories, "categories") }?;
        let cats = cats
            .iter()
            // SAFETY: each category is NULL or a NUL-terminated string (the importer's promise).
            .map(|&p| unsafe { c_str(p, "a category") }.map(str::to_string))
            .collect::<Result<Vec<_>, _>>()?;
        inst.set_debug_logging(logging_on != FMI2_FALSE, &cats)?;
        Ok(Fmi2Status::Ok)
    })
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
        Ok(Fmi2Status::Ok)
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2EnterInitializationMode(c: Fmi2Component) -> Fmi2StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::EnterInitializationMode, |inst| {
        inst.log_call(Call::EnterInitializationMode, String::new);
        inst.enter_initialization()?;
        Ok(Fmi2Status::Ok)
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2ExitInitializationMode(c: Fmi2Component) -> Fmi2StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::ExitInitializationMode, |inst| {
        inst.log_call(Call::ExitInitializationMode, String::new);
        inst.exit_initialization()?;
        Ok(Fmi2Status::Ok)
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2Terminate(c: Fmi2Component) -> Fmi2StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::Terminate, |inst| {
        inst.log_call(Call::Terminate, String::new);
        inst.terminate()?;
        Ok(Fmi2Status::Ok)
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2Reset(c: Fmi2Component) -> Fmi2StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::Reset, |inst| {
        inst.log_call(Call::Reset, String::new);
        inst.reset()?;
        Ok(Fmi2Status::Ok)
    })
}

/// A getter's body: `value[k]` = `convert` of the variable `vr[k]`.
///
/// # Safety
/// `c` as for [`instance`]; `vr` and `value` are NULL or hold `nvr` elements, as the standard requires.
unsafe fn get_values<T>(
    c: Fmi2Component,
    call: Call,
    ty: VarType,
    vr: *const Fmi2ValueReference,
    nvr: usize,
    value: *mut T,
    convert: impl Fn(&Value) -> T,
) -> Fmi2StatusC {
    // SAFETY: `c` as this function's caller promises.
    let inst = unsafe { instance(c) };
    with_instance(inst, call, |inst| {
        // SAFETY: `vr` and `value` hold `nvr` elements, as this function's caller promises.
        let vrs = unsafe { slice(vr, nvr, "vr") }?;
        // SAFETY: as above.
        let out = unsafe { slice_mut(value, nvr, "value") }?;
        // No allocation: the values go straight to the caller's array.
        inst.get_with(ty, vrs, |k, v| out[k] = convert(v))?;
        Ok(Fmi2Status::Ok)
    })
}

/// A setter's body: the variable `vr[k]` = `convert(value[k])`.
///
/// # Safety
/// `c` as for [`instance`]; `vr` and `value` are NULL or hold `nvr` elements, as the standard requires.
unsafe fn set_values<T: Copy>(
    c: Fmi2Component,
    call: Call,
    ty: VarType,
    vr: *const Fmi2ValueReference,
    nvr: usize,
    value: *const T,
    convert: impl Fn(T) -> Result<Value, String>,
) -> Fmi2StatusC {
    // SAFETY: `c` as this function's caller promises.
    let inst = unsafe { instance(c) };
    with_instance(inst, call, |inst| {
        // SAFETY: `vr` and `value` hold `nvr` elements, as this function's caller promises.
        let vrs = unsafe { slice(vr, nvr, "vr") }?;
        // SAFETY: as above.
        let vals = unsafe { slice(value, nvr, "value") }?;
        // No allocation: each value is converted where it is checked and again where it is applied.
        inst.set_with(ty, vrs, |k| convert(vals[k]))?;
        Ok(Fmi2Status::Ok)
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
        Ok(Fmi2Status::Ok)
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
    // SAFETY: the arguments as the standard requires of the importer (see `set_values`).
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
    // SAFETY: the arguments as the standard requires of the importer (see `set_values`).
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
    let convert = |p: Fmi2String| {
        // SAFETY: each value is NULL or a NUL-terminated string (the importer's promise).
        unsafe { c_str(p, "a string value") }.map(|s| Value::String(s.to_string()))
    };
    // SAFETY: the arguments as the standard requires of the importer (see `set_values`).
    unsafe { set_values(c, Call::SetString, VarType::String, vr, nvr, value, convert) }
}

/// Read the importer's `*FMUstate` from the address `state`, after making sure `state` is not itself one of
/// the instance's states (an importer passing the state where its address is expected, as some do with
/// fmi2FreeFMUstate): that pointer is refused without being read through.
///
/// # Safety
/// `state` is NULL, one of the instance's states, or valid for reading an `fmi2FMUstate`.
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
    // SAFETY: neither NULL nor one of our states, so by the caller's promise the importer's variable.
    Ok(unsafe { state.read() } as *mut SavedState)
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetFMUstate(
    c: Fmi2Component,
    state: *mut Fmi2FmuState,
) -> Fmi2StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::GetFmuState, |inst| {
        // SAFETY: `state` is NULL or the address of the importer's fmi2FMUstate variable (the standard).
        let existing = unsafe { read_state_slot(inst, state) }?;
        let saved = inst.save_state()?;
        let issued = inst.issue_state(existing, saved)? as Fmi2FmuState;
        // SAFETY: the same variable, writable too.
        unsafe { write_out(state, issued, "FMUstate") }?;
        Ok(Fmi2Status::Ok)
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetFMUstate(c: Fmi2Component, state: Fmi2FmuState) -> Fmi2StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::SetFmuState, |inst| {
        if state.is_null() {
            return Err("FMUstate is NULL".into());
        }
        inst.restore_issued_state(state as *const SavedState)?;
        Ok(Fmi2Status::Ok)
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2FreeFMUstate(
    c: Fmi2Component,
    state: *mut Fmi2FmuState,
) -> Fmi2StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::FreeFmuState, |inst| {
        // SAFETY: `state` is NULL or the address of the importer's fmi2FMUstate variable (the standard).
        let s = unsafe { read_state_slot(inst, state) }?;
        if !s.is_null() {
            inst.free_state(s)?;
            // SAFETY: the same variable, writable too.
            unsafe { write_out(state, std::ptr::null_mut(), "FMUstate") }?;
        }
        Ok(Fmi2Status::Ok)
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SerializedFMUstateSize(
    c: Fmi2Component,
    state: Fmi2FmuState,
    size: *mut usize,
) -> Fmi2StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::SerializedFmuStateSize, |inst| {
        if state.is_null() || size.is_null() {
            return Err("FMUstate or size is NULL".into());
        }
        let n = inst.issued_state(state as *const SavedState)?.bytes.len();
        // SAFETY: `size` is the address of the importer's variable (the standard).
        unsafe { write_out(size, n, "size") }?;
        Ok(Fmi2Status::Ok)
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SerializeFMUstate(
    c: Fmi2Component,
    state: Fmi2FmuState,
    bytes: *mut Fmi2Byte,
    size: usize,
) -> Fmi2StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::SerializeFmuState, |inst| {
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
        // SAFETY: the importer passes a buffer of `size` bytes (the standard).
        let out = unsafe { slice_mut(bytes as *mut u8, size, "serializedState") }?;
        out.copy_from_slice(&saved.bytes);
        Ok(Fmi2Status::Ok)
    })
}

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
    c: Fmi2Component,
    bytes: *const Fmi2Byte,
    size: usize,
    state: *mut Fmi2FmuState,
) -> Fmi2StatusC {
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::DeSerializeFmuState, |inst| {
        // SAFETY: `state` is NULL or the address of the importer's fmi2FMUstate variable (the standard).
        let existing = unsafe { read_state_slot(inst, state) }?;
        // SAFETY: the importer passes `size` bytes (the standard).
        let data = unsafe { slice(bytes as *const u8, size, "serializedState") }?;
        inst.check_state_bytes(data)?;
        let saved = SavedState {
            bytes: data.to_vec(),
        };
        let issued = inst.issue_state(existing, saved)? as Fmi2FmuState;
        // SAFETY: the same variable, writable too.
        unsafe { write_out(state, issued, "FMUstate") }?;
        Ok(Fmi2Status::Ok)
    })
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

#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2CancelStep(c: Fmi2Component) -> Fmi2StatusC {
    // Steps are synchronous, so no step is ever in progress: the state machine refuses this call.
    // SAFETY: `c` is NULL or a live instance, as the standard requires of the importer.
    let inst = unsafe { instance(c) };
    with_instance(inst, Call::CancelStep, |_| Ok(Fmi2Status::Ok))
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
            Ok(Fmi2Status::Ok)
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
            Ok(Fmi2Status::Ok)
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
            Ok(Fmi2Status::Ok)
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
