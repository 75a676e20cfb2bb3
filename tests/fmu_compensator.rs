//! BacklashCompensator through the exported FMI 2.0 functions, in-process: v depends directly on the inputs,
//! the step commits the direction memory, degenerate estimates answer fmi2Warning with a log line and a finite
//! v, and bad calls (setting the output, a parameter out of range or after initialisation, a non-finite input,
//! an unknown value reference, no instance) answer fmi2Error with a reason. The state-machine tables of
//! tests/fmi_state_machine.rs run on the protocol layer this FMU shares with the other two.
//!
//! Gated to x86_64 Linux for the logger (tests/common says why).
#![allow(
    clippy::undocumented_unsafe_blocks,
    clippy::multiple_unsafe_ops_per_block,
    reason = "the tests call the exported FMI functions directly, some with hostile arguments on purpose: \
              what each call passes and why is the test itself"
)]
#![cfg(all(target_arch = "x86_64", target_os = "linux"))]

use crate::common::{Entry, Sink, callbacks};
use backlash::fmi2::exports::*;
use backlash::fmi2::ffi::*;
use backlash::fmus::backlash_compensator::{GUID, VARIABLES};
use std::ffi::CString;
use std::ptr::null_mut;

const OK: u32 = Fmi2Status::Ok as u32;
const WARNING: u32 = Fmi2Status::Warning as u32;
const ERROR: u32 = Fmi2Status::Error as u32;

fn vr(name: &str) -> u32 {
    VARIABLES.iter().find(|v| v.name == name).unwrap().vr
}

struct Comp {
    c: Fmi2Component,
    sink: Box<Sink>,
}

impl Comp {
    /// An instance with logging on, set up at time 0, in initialization mode.
    fn new() -> Comp {
        let sink: Box<Sink> = Box::default();
        let cb = callbacks(&sink);
        let guid = CString::new(GUID).unwrap();
        let c = unsafe {
            fmi2Instantiate(
                c"comp".as_ptr(),
                FMI2_CO_SIMULATION,
                guid.as_ptr(),
                c"file:///nonexistent/resources".as_ptr(),
                &cb,
                FMI2_FALSE,
                FMI2_TRUE,
            )
        };
        assert!(!c.is_null());
        let f = Comp { c, sink };
        assert_eq!(
            unsafe { fmi2SetupExperiment(c, FMI2_FALSE, 0.0, 0.0, FMI2_FALSE, 0.0) },
            OK
        );
        assert_eq!(unsafe { fmi2EnterInitializationMode(c) }, OK);
        f
    }

    fn init(&self) {
        assert_eq!(unsafe { fmi2ExitInitializationMode(self.c) }, OK);
    }

    fn set(&self, name: &str, x: f64) -> u32 {
        unsafe { fmi2SetReal(self.c, &vr(name), 1, &x) }
    }

    fn get(&self, name: &str) -> (u32, f64) {
        let mut x = f64::NAN;
        let s = unsafe { fmi2GetReal(self.c, &vr(name), 1, &mut x) };
        (s, x)
    }

    fn step(&self, t: f64) -> u32 {
        unsafe { fmi2DoStep(self.c, t, 1.0, FMI2_TRUE) }
    }

    fn log(&self) -> Vec<Entry> {
        self.sink.lock().unwrap().clone()
    }

    fn logged(&self, category: &str, text: &str) -> bool {
        self.log()
            .iter()
            .any(|e| e.category == category && e.message.contains(text))
    }
}

impl Drop for Comp {
    fn drop(&mut self) {
        unsafe { fmi2FreeInstance(self.c) };
        self.c = null_mut();
    }
}

/// The paper's backlash (m1 1, m2 1.5, c1 0.5, c2 1): up border v = r + 0.5, down border v = r/1.5 - 1.
fn paper() -> Comp {
    let f = Comp::new();
    f.init();
    for (n, x) in [("m2", 1.5), ("c1", 0.5), ("c2", 1.0)] {
        assert_eq!(f.set(n, x), OK);
    }
    f
}

#[test]
fn v_follows_the_inputs_directly_and_the_step_commits() {
    let f = paper();
    assert_eq!(f.set("r", 1.0), OK);
    assert_eq!(f.get("v"), (OK, 1.5));
    // Not committed yet: another r at the same instant is answered from the same memory.
    assert_eq!(f.set("r", 0.5), OK);
    assert_eq!(f.get("v"), (OK, 1.0));
    assert_eq!(f.set("r", 1.0), OK);
    assert_eq!(f.step(0.0), OK);
    assert_eq!(f.get("w"), (OK, 1.0));
    // Held reference: v holds; a reversal drives the lower border.
    assert_eq!(f.get("v"), (OK, 1.5));
    assert_eq!(f.set("r", 0.3), OK);
    let (s, v) = f.get("v");
    assert_eq!(s, OK);
    assert!((v - (0.3 / 1.5 - 1.0)).abs() < 1e-12, "{v}");
}

#[test]
fn a_degenerate_estimate_answers_warning_with_a_log_line_and_a_finite_v() {
    let f = paper();
    assert_eq!(f.set("r", 1.0), OK);
    assert_eq!(f.step(0.0), OK);
    for (name, x, text) in [
        ("m2", -1.0, "m2 = -1 is not a positive number"),
        ("m2", 0.0, "m2 = 0 is not a positive number"),
        ("c1", -0.2, "gap c1 = -0.2 is negative"),
    ] {
        let keep = f.get(name).1;
        assert_eq!(f.set(name, x), OK);
        let (s, v) = f.get("v");
        assert_eq!(s, WARNING, "{name} = {x}");
        assert!(v.is_finite());
        assert!(f.logged("logStatusWarning", text), "{:?}", f.log());
        assert_eq!(f.set(name, keep), OK);
    }
    // Crossing borders: m2 = 3 and gaps of 0.01 cross below w = -0.03. Down to w = -3 is fine (from w = 1);
    // from there the lower border's input for -3.3 (-1.11) lies above the upper border's start (-2.99).
    for (n, x) in [("m2", 3.0), ("c1", 0.01), ("c2", 0.01), ("r", -3.0)] {
        assert_eq!(f.set(n, x), OK);
    }
    assert_eq!(f.get("v").0, OK);
    // The step commits w = -3 and answers for the inputs as they stand against it: holding -3 is already
    // impossible there (the zone of -3 is empty).
    assert_eq!(f.step(1.0), WARNING);
    assert_eq!(f.get("w").0, WARNING);
    assert_eq!(f.set("r", -3.3), OK);
    assert_eq!(f.get("v").0, WARNING);
    assert_eq!(f.step(2.0), WARNING);
    assert!(f.logged("logStatusWarning", "fmi2DoStep: the borders cross"));
}

#[test]
fn bad_calls_answer_error_with_a_reason() {
    let f = Comp::new();
    assert_eq!(f.set("smoothing", -0.1), ERROR);
    assert!(f.logged("logStatusError", "smoothing"), "{:?}", f.log());
    let f = Comp::new();
    assert_eq!(f.set("v", 1.0), ERROR);
    assert!(f.logged("logStatusError", "'v' is an output and cannot be set"));
    let f = Comp::new();
    f.init();
    assert_eq!(f.set("smoothing", 0.1), ERROR);
    assert!(f.logged("logStatusError", "parameter 'smoothing' is fixed"));
    let f = Comp::new();
    f.init();
    assert_eq!(f.set("r", f64::NAN), ERROR);
    let f = Comp::new();
    let x = 0.0;
    assert_eq!(unsafe { fmi2SetReal(f.c, &999, 1, &x) }, ERROR);
    assert!(f.logged("logStatusError", "unknown value reference 999"));
    assert_eq!(unsafe { fmi2SetReal(null_mut(), &vr("r"), 1, &x) }, ERROR);
}
