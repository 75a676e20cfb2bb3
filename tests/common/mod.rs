//! What the in-process FMI tests share: a logger that records what the layer logs.
//!
//! The FMI logger is variadic C, and Rust cannot define variadic functions on stable. The layer always calls
//! it with the format "%s" and the text as the one variadic argument; on x86_64 SysV (the platform the tests
//! that use this module are gated to) a variadic call with one pointer argument passes it exactly like a
//! sixth named argument, so a six-argument `extern "C"` function transmuted to the logger type receives it.
#![allow(dead_code)]

use backlash::fmi2::ffi::*;
use std::ffi::{CStr, c_char};
use std::sync::Mutex;

#[derive(Debug, Clone, PartialEq)]
pub struct Entry {
    pub instance: String,
    pub status: u32,
    pub category: String,
    pub message: String,
}

pub type Sink = Mutex<Vec<Entry>>;

type FixedLogger = unsafe extern "C" fn(
    Fmi2ComponentEnvironment,
    Fmi2String,
    Fmi2StatusC,
    Fmi2String,
    Fmi2String,
    Fmi2String,
);

/// The logger as the layer calls it: "%s" and the text (see the module documentation). Never panics (a
/// panic cannot unwind out of an `extern "C"` function).
pub unsafe extern "C" fn record(
    env: Fmi2ComponentEnvironment,
    instance: Fmi2String,
    status: Fmi2StatusC,
    category: Fmi2String,
    format: Fmi2String,
    text: Fmi2String,
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
    let message = if format == "%s" {
        s(text)
    } else {
        format!("<format is {format:?}, not \"%s\">")
    };
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
    // SAFETY: on x86_64 SysV a call through the variadic type with one vararg
    // is ABI-identical to a call of this six-argument function.
    Some(unsafe {
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
    })
}
