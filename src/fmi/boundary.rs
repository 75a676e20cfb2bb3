//! The C boundary both protocol layers share: every access to the importer's memory (each in one small
//! helper, with its safety contract), making and freeing instances, the panic guard and the state check
//! around every call on an instance, and the bodies the two protocols' functions have in common.
//!
//! FMI 2.0 and FMI 3.0 agree on what these need: a component is NULL or a live instance called by one
//! thread at a time; arrays hold the elements their counts say; strings are NUL-terminated. Each function
//! that answers a call returns the protocol's own C status: the core's [`Status`] coded by the call's
//! [`Api::code`], the layer's edge.

use super::fmu_state::SavedState;
use super::instance::Instance;
use super::log::Logger;
use super::registry;
use super::state::{Api, State};
use super::status::{Outcome, Status};
use super::timing::StepOutcome;
use super::vars::{Value, VarType};
use std::ffi::{CStr, c_char, c_void};
use std::panic::{AssertUnwindSafe, catch_unwind};

pub fn panic_text(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into())
}

/// The instance behind the component pointer `c`, or `None` for NULL.
///
/// # Safety
/// `c` is NULL or a pointer that the layer's instantiate function returned and its free function has not
/// freed, and no other call on the same instance runs meanwhile: the importer's side of the standard.
pub unsafe fn instance<'a>(c: *mut c_void) -> Option<&'a mut Instance> {
    // SAFETY: the caller's promise above; `as_mut` turns NULL into `None`.
    unsafe { c.cast::<Instance>().as_mut() }
}

/// A new instance of the FMU whose GUID (FMI 2.0) or instantiation token (FMI 3.0, `what` names which) is
/// `guid`, among those the binary registered ([`registry::registry`]), as the pointer the instantiate
/// function hands out; [`free_instance`] takes it back.
pub fn new_instance(
    call: impl Api,
    name: &str,
    (what, guid): (&str, &str),
    logger: impl Logger + 'static,
    logging_on: bool,
) -> Result<*mut c_void, String> {
    let slave = registry::registry().instantiate(guid, what)?;
    let inst = Box::new(Instance::new(name, logger, logging_on, slave));
    inst.log_call(call, || format!("instanceName={name}, {what}={guid}"));
    Ok(Box::into_raw(inst).cast())
}

/// Run `f` on the instance (refusing a NULL component): state check, panic guard, error logging; the
/// answer in the protocol's C status.
pub fn with_instance<C: Api>(
    inst: Option<&mut Instance>,
    call: C,
    f: impl FnOnce(&mut Instance) -> Outcome,
) -> C::Code {
    let Some(inst) = inst else {
        return C::code(Status::Error);
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
            Status::Error
        }
        Err(p) => {
            // A panic is a bug in this library; the instance may be inconsistent, so it goes to the error
            // state, from which a reset rebuilds it.
            let text = panic_text(p.as_ref());
            inst.log_error(call, &format!("internal error: {text}"));
            inst.layer.state = State::Error;
            Status::Error
        }
    };
    C::code(status)
}

/// The largest element count a slice of `T` may have.
fn max_len<T>() -> usize {
    (isize::MAX as usize) / std::mem::size_of::<T>().max(1)
}

/// A slice from a C array, refusing NULL when `n > 0`.
///
/// # Safety
/// `ptr` is NULL or points to `n` initialised elements that nothing writes while the slice lives.
pub unsafe fn slice<'a, T>(ptr: *const T, n: usize, what: &str) -> Result<&'a [T], String> {
    if n == 0 {
        Ok(&[])
    } else if ptr.is_null() {
        Err(format!("{what} is NULL but its length is {n}"))
    } else if n > max_len::<T>() {
        Err(format!("the length {n} of {what} is too large"))
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
pub unsafe fn slice_mut<'a, T>(ptr: *mut T, n: usize, what: &str) -> Result<&'a mut [T], String> {
    if n == 0 {
        Ok(&mut [])
    } else if ptr.is_null() {
        Err(format!("{what} is NULL but its length is {n}"))
    } else if n > max_len::<T>() {
        Err(format!("the length {n} of {what} is too large"))
    } else {
        // SAFETY: not NULL, `n` elements within the size limit of a slice; writable by the caller's promise.
        Ok(unsafe { std::slice::from_raw_parts_mut(ptr, n) })
    }
}

/// A C string as UTF-8, refusing NULL.
///
/// # Safety
/// `p` is NULL or points to a NUL-terminated string that outlives the result.
pub unsafe fn c_str<'a>(p: *const c_char, what: &str) -> Result<&'a str, String> {
    if p.is_null() {
        return Err(format!("{what} is NULL"));
    }
    // SAFETY: not NULL, and NUL-terminated by the caller's promise.
    unsafe { CStr::from_ptr(p) }
        .to_str()
        .map_err(|_| format!("{what} is not valid UTF-8"))
}

/// A copy of the importer's value at `p` (a struct it passes by address), or `None` for NULL.
///
/// # Safety
/// `p` is NULL or points to an initialised `T`.
pub unsafe fn read_in<T: Copy>(p: *const T) -> Option<T> {
    // SAFETY: NULL becomes `None`; otherwise readable by the caller's promise; `T: Copy` is copied out.
    unsafe { p.as_ref() }.copied()
}

/// Store `value` in the importer's output variable at `p`, refusing NULL.
///
/// # Safety
/// `p` is NULL or valid for a write of one `T` (it need not be initialised: the old value is not read).
pub unsafe fn write_out<T: Copy>(p: *mut T, value: T, what: &str) -> Result<(), String> {
    if p.is_null() {
        return Err(format!("{what} is NULL"));
    }
    // SAFETY: not NULL, and writable by the caller's promise; `T: Copy` has nothing to drop.
    unsafe { p.write(value) };
    Ok(())
}

/// Read the importer's `*FMUstate` from the address `state`, after making sure `state` is not itself one of
/// the instance's states (an importer passing the state where its address is expected, as some do with
/// fmi2FreeFMUstate): that pointer is refused without being read through.
///
/// # Safety
/// `state` is NULL, one of the instance's states, or valid for reading an `fmi2FMUstate`.
pub unsafe fn read_state_slot(
    inst: &Instance,
    state: *mut *mut c_void,
) -> Result<*mut SavedState, String> {
    if state.is_null() {
        return Err(
            "FMUstate is NULL (expected the address of the variable holding an FMU state)".into(),
        );
    }
    if inst.issued_state(state as *const SavedState).is_ok() {
        return Err(
            "the argument is an FMU state itself, not the address of a variable holding it \
             (pass &state)"
                .into(),
        );
    }
    // SAFETY: neither NULL nor one of our states, so by the caller's promise the importer's variable.
    Ok(unsafe { state.read() } as *mut SavedState)
}

/// A getter's body: `value[k]` = `convert` of the variable `vr[k]`, after checking that the importer's
/// value array has one element per reference (`n_values`: FMI 3.0 passes it, FMI 2.0 passes `nvr`).
///
/// # Safety
/// `c` as for [`instance`]; `vr` holds `nvr` elements and `value` `n_values`, or is NULL, as the standards
/// require.
#[allow(
    clippy::too_many_arguments,
    reason = "the C signature's arguments, passed on unchanged"
)]
pub unsafe fn get_values<C: Api, T>(
    c: *mut c_void,
    call: C,
    ty: VarType,
    vr: *const u32,
    nvr: usize,
    value: *mut T,
    n_values: usize,
    convert: impl Fn(&Value) -> T,
) -> C::Code {
    // SAFETY: `c` as this function's caller promises.
    let inst = unsafe { instance(c) };
    with_instance(inst, call, |inst| {
        check_counts(nvr, n_values)?;
        // SAFETY: `vr` and `value` hold `nvr` elements, as this function's caller promises.
        let vrs = unsafe { slice(vr, nvr, "the value references") }?;
        // SAFETY: as above.
        let out = unsafe { slice_mut(value, nvr, "the values") }?;
        // No allocation: the values go straight to the caller's array.
        inst.get_with(ty, vrs, |k, v| out[k] = convert(v))?;
        Ok(inst.model_status(call))
    })
}

/// A setter's body: the variable `vr[k]` = `convert(value[k])` (see [`get_values`] for `n_values`).
///
/// # Safety
/// `c` as for [`instance`]; `vr` holds `nvr` elements and `value` `n_values`, or is NULL, as the standards
/// require.
#[allow(
    clippy::too_many_arguments,
    reason = "the C signature's arguments, passed on unchanged"
)]
pub unsafe fn set_values<C: Api, T: Copy>(
    c: *mut c_void,
    call: C,
    ty: VarType,
    vr: *const u32,
    nvr: usize,
    value: *const T,
    n_values: usize,
    convert: impl Fn(T) -> Result<Value, String>,
) -> C::Code {
    // SAFETY: `c` as this function's caller promises.
    let inst = unsafe { instance(c) };
    with_instance(inst, call, |inst| {
        check_counts(nvr, n_values)?;
        // SAFETY: `vr` and `value` hold `nvr` elements, as this function's caller promises.
        let vrs = unsafe { slice(vr, nvr, "the value references") }?;
        // SAFETY: as above.
        let vals = unsafe { slice(value, nvr, "the values") }?;
        // No allocation: each value is converted where it is checked and again where it is applied.
        inst.set_with(ty, vrs, |k| convert(vals[k]))?;
        Ok(Status::Ok)
    })
}

/// Every variable of these FMUs is a scalar: one value per value reference.
pub fn check_counts(nvr: usize, n_values: usize) -> Result<(), String> {
    if nvr == n_values {
        Ok(())
    } else {
        Err(format!(
            "nValues = {n_values} but nValueReferences = {nvr}: every variable of this FMU is a scalar, \
             so both must be equal"
        ))
    }
}

/// Get an FMU state (fmi2GetFMUstate, fmi3GetFMUState): a new one, or the importer's previous one
/// overwritten.
///
/// # Safety
/// `c` as for [`instance`]; `state` is NULL or the address of the importer's FMU state variable.
pub unsafe fn get_fmu_state<C: Api>(c: *mut c_void, call: C, state: *mut *mut c_void) -> C::Code {
    // SAFETY: `c` as this function's caller promises.
    let inst = unsafe { instance(c) };
    with_instance(inst, call, |inst| {
        // SAFETY: `state` is NULL or the address of the importer's FMU state variable (the caller).
        let existing = unsafe { read_state_slot(inst, state) }?;
        let saved = inst.save_state()?;
        let issued = inst.issue_state(existing, saved)?.cast::<c_void>();
        // SAFETY: the same variable, writable too.
        unsafe { write_out(state, issued, "FMUstate") }?;
        Ok(Status::Ok)
    })
}

/// Restore an FMU state this instance issued (fmi2SetFMUstate, fmi3SetFMUState).
///
/// # Safety
/// `c` as for [`instance`]. `state` is compared with the instance's states, never read through otherwise.
pub unsafe fn set_fmu_state<C: Api>(c: *mut c_void, call: C, state: *mut c_void) -> C::Code {
    // SAFETY: `c` as this function's caller promises.
    let inst = unsafe { instance(c) };
    with_instance(inst, call, |inst| {
        if state.is_null() {
            return Err("FMUstate is NULL".into());
        }
        inst.restore_issued_state(state as *const SavedState)?;
        Ok(Status::Ok)
    })
}

/// Free an FMU state this instance issued and set the importer's variable to NULL (fmi2FreeFMUstate,
/// fmi3FreeFMUState); a variable holding NULL is fine.
///
/// # Safety
/// `c` as for [`instance`]; `state` is NULL or the address of the importer's FMU state variable.
pub unsafe fn free_fmu_state<C: Api>(c: *mut c_void, call: C, state: *mut *mut c_void) -> C::Code {
    // SAFETY: `c` as this function's caller promises.
    let inst = unsafe { instance(c) };
    with_instance(inst, call, |inst| {
        // SAFETY: `state` is NULL or the address of the importer's FMU state variable (the caller).
        let s = unsafe { read_state_slot(inst, state) }?;
        if !s.is_null() {
            inst.free_state(s)?;
            // SAFETY: the same variable, writable too.
            unsafe { write_out(state, std::ptr::null_mut(), "FMUstate") }?;
        }
        Ok(Status::Ok)
    })
}

/// The size of an issued FMU state, serialised.
///
/// # Safety
/// `c` as for [`instance`]; `size` is NULL or the address of the importer's variable.
pub unsafe fn serialized_size<C: Api>(
    c: *mut c_void,
    call: C,
    state: *mut c_void,
    size: *mut usize,
) -> C::Code {
    // SAFETY: `c` as this function's caller promises.
    let inst = unsafe { instance(c) };
    with_instance(inst, call, |inst| {
        if state.is_null() || size.is_null() {
            return Err("FMUstate or size is NULL".into());
        }
        let n = inst.issued_state(state as *const SavedState)?.bytes.len();
        // SAFETY: `size` is the address of the importer's variable (the caller).
        unsafe { write_out(size, n, "size") }?;
        Ok(Status::Ok)
    })
}

/// Copy an issued FMU state, serialised, into the importer's buffer of exactly its size.
///
/// # Safety
/// `c` as for [`instance`]; `bytes` is NULL or a buffer of `size` bytes.
pub unsafe fn serialize<C: Api>(
    c: *mut c_void,
    call: C,
    state: *mut c_void,
    bytes: *mut u8,
    size: usize,
) -> C::Code {
    // SAFETY: `c` as this function's caller promises.
    let inst = unsafe { instance(c) };
    with_instance(inst, call, |inst| {
        if state.is_null() {
            return Err("FMUstate is NULL".into());
        }
        let saved = inst.issued_state(state as *const SavedState)?;
        if size != saved.bytes.len() {
            return Err(format!(
                "size {size} differs from the serialised size {} of the FMU state",
                saved.bytes.len()
            ));
        }
        // SAFETY: the importer passes a buffer of `size` bytes (the caller).
        let out = unsafe { slice_mut(bytes, size, "serializedState") }?;
        out.copy_from_slice(&saved.bytes);
        Ok(Status::Ok)
    })
}

/// Make an FMU state from serialised bytes (checked first) and hand it out as [`get_fmu_state`] does.
///
/// # Safety
/// `c` as for [`instance`]; `bytes` is NULL or `size` bytes; `state` is NULL or the address of the
/// importer's FMU state variable.
pub unsafe fn deserialize<C: Api>(
    c: *mut c_void,
    call: C,
    bytes: *const u8,
    size: usize,
    state: *mut *mut c_void,
) -> C::Code {
    // SAFETY: `c` as this function's caller promises.
    let inst = unsafe { instance(c) };
    with_instance(inst, call, |inst| {
        // SAFETY: `state` is NULL or the address of the importer's FMU state variable (the caller).
        let existing = unsafe { read_state_slot(inst, state) }?;
        // SAFETY: the importer passes `size` bytes (the caller).
        let data = unsafe { slice(bytes, size, "serializedState") }?;
        inst.check_state_bytes(data)?;
        let saved = SavedState {
            bytes: data.to_vec(),
        };
        let issued = inst.issue_state(existing, saved)?.cast::<c_void>();
        // SAFETY: the same variable, writable too.
        unsafe { write_out(state, issued, "FMUstate") }?;
        Ok(Status::Ok)
    })
}

/// One communication step on the instance, with the sampled-data timing of [`Instance::do_step`]. A step
/// the model's limit cuts short answers Discard: the instance goes to the step-failed state, from which the
/// master reads the last successful time, then terminates or restores an FMU state and retries shorter.
pub fn do_step(inst: &mut Instance, call: impl Api, t: f64, h: f64) -> Outcome {
    inst.log_call(call, || {
        format!("currentCommunicationPoint={t}, communicationStepSize={h}")
    });
    match inst.do_step(t, h)? {
        StepOutcome::Complete => Ok(inst.model_status(call)),
        StepOutcome::Cut { at, reached, limit } => {
            inst.layer.state = State::StepFailed;
            if inst.log.discards {
                inst.emit(
                    Status::Discard,
                    "logStatusDiscard",
                    &format!(
                        "{}: the step from {t} by {h} reaches {reached} sample instants; {} takes at most \
                         {limit} per step, so it stopped at t = {at} (the last successful time). Step by \
                         at most Ts = {}",
                        call.name(),
                        inst.slave.identifier(),
                        inst.slave.sample_period()
                    ),
                );
            }
            Ok(Status::Discard)
        }
    }
}

/// Free an instance (fmi2FreeInstance, fmi3FreeInstance): NULL is ignored; a call the state machine
/// refuses is logged, and the memory is released anyway, as an importer freeing an instance will not call
/// it again.
///
/// # Safety
/// `c` is NULL or a live instance, not used after this call.
pub unsafe fn free_instance(c: *mut c_void, call: impl Api) {
    if c.is_null() {
        return;
    }
    let _ = catch_unwind(|| {
        // SAFETY: c came from the instantiate function and is freed once (the importer's side).
        let inst = unsafe { &*(c as *mut Instance) };
        if let Err(reason) = inst.check_state(call) {
            inst.log_error(call, &reason);
        }
        inst.log_call(call, String::new);
        // SAFETY: the Box that the instantiate function leaked, freed here once; `inst` is not used after.
        drop(unsafe { Box::from_raw(c as *mut Instance) });
    });
}

/// Switch logging and its categories (fmi2SetDebugLogging, fmi3SetDebugLogging).
///
/// # Safety
/// `c` as for [`instance`]; `categories` is NULL or holds `n_categories` strings, each NULL or
/// NUL-terminated.
pub unsafe fn set_debug_logging<C: Api>(
    c: *mut c_void,
    call: C,
    logging_on: bool,
    n_categories: usize,
    categories: *const *const c_char,
) -> C::Code {
    // SAFETY: `c` as this function's caller promises.
    let inst = unsafe { instance(c) };
    with_instance(inst, call, |inst| {
        // SAFETY: the importer passes `n_categories` category strings at `categories`.
        let cats = unsafe { slice(categories, n_categories, "categories") }?;
        let cats = cats
            .iter()
            // SAFETY: each category is NULL or a NUL-terminated string (the importer's promise).
            .map(|&p| unsafe { c_str(p, "a category") }.map(str::to_string))
            .collect::<Result<Vec<_>, _>>()?;
        inst.set_debug_logging(logging_on, &cats)?;
        Ok(Status::Ok)
    })
}
