//! What the in-process FMI tests share: which FMU a test drives ([`Kind`]), and a logger that records what
//! the FMI 2.0 layer logs.
//!
//! The FMI logger is variadic C, and Rust cannot define variadic functions on stable. The layer calls it with
//! the message as the format, every '%' doubled, and no variadic argument; on x86_64 SysV (the platform the
//! tests that use this module are gated to) a variadic call without variadic arguments passes the named ones
//! exactly like a non-variadic call, so a five-argument `extern "C"` function transmuted to the logger type
//! receives them. The recorder prints the format as printf would (`%%` -> `%`) and records a marker if the
//! format holds a conversion, which would read an argument that is not there.
#![allow(dead_code, reason = "each test crate uses only some of these helpers")]

pub mod forge;
mod kind;

pub use kind::Kind;

use backlash::fmi2::ffi::*;
use std::ffi::{CStr, c_char, c_void};
use std::sync::Mutex;

#[derive(Debug, Clone, PartialEq)]
pub struct Entry {
    pub instance: String,
    pub status: u32,
    pub category: String,
    pub message: String,
}

pub type Sink = Mutex<Vec<Entry>>;

type FixedLogger =
    unsafe extern "C" fn(Fmi2ComponentEnvironment, Fmi2String, Fmi2StatusC, Fmi2String, Fmi2String);

/// What printf prints for `format` with no argument, or `None` if it holds a conversion (a '%' not doubled).
pub fn printf_without_arguments(format: &str) -> Option<String> {
    let mut out = String::with_capacity(format.len());
    let mut chars = format.chars();
    while let Some(c) = chars.next() {
        if c == '%' && chars.next() != Some('%') {
            return None;
        }
        out.push(c);
    }
    Some(out)
}

/// The logger as the layer calls it (see the module documentation). Never panics (a panic cannot unwind out
/// of an `extern "C"` function).
pub unsafe extern "C" fn record(
    env: Fmi2ComponentEnvironment,
    instance: Fmi2String,
    status: Fmi2StatusC,
    category: Fmi2String,
    format: Fmi2String,
) {
    let s = |p: *const c_char| {
        if p.is_null() {
            "<NULL>".to_string()
        } else {
            // SAFETY: the layer passes NUL-terminated strings that outlive the call.
            unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
        }
    };
    let format = s(format);
    let message = printf_without_arguments(&format)
        .unwrap_or_else(|| format!("<format {format:?} has a conversion without its argument>"));
    if env.is_null() {
        return;
    }
    // SAFETY: env is the `Sink` the test put in the callbacks; it outlives the instance.
    let sink = unsafe { &*(env as *const Sink) };
    if let Ok(mut v) = sink.lock() {
        v.push(Entry {
            instance: s(instance),
            status,
            category: s(category),
            message,
        });
    }
}

pub fn logger() -> Fmi2CallbackLogger {
    // SAFETY: on x86_64 SysV a call through the variadic type with no vararg
    // is ABI-identical to a call of this five-argument function.
    let variadic = unsafe {
        std::mem::transmute::<
            FixedLogger,
            unsafe extern "C" fn(
                Fmi2ComponentEnvironment,
                Fmi2String,
                Fmi2StatusC,
                Fmi2String,
                Fmi2String,
                ...
            ),
        >(record)
    };
    Some(variadic)
}

/// Callbacks whose logger records into `sink` (which must outlive the instance).
pub fn callbacks(sink: &Sink) -> Fmi2CallbackFunctions {
    Fmi2CallbackFunctions {
        logger: logger(),
        allocate_memory: None,
        free_memory: None,
        step_finished: None,
        component_environment: sink as *const Sink as *mut c_void,
    }
}
