//! Several instances in one process, and instances in parallel threads, through the exported FMI functions.
//!
//! - Instances are independent: eight instances of both FMUs (different parameters, noise seeds and inputs)
//!   stepped round-robin in one thread give bit-for-bit what each gives stepped alone.
//! - Instances stepped in parallel threads (std::thread::scope, one instance per thread, as the standard
//!   allows: calls on one instance are never concurrent) give bit-for-bit what each gives alone, while another
//!   thread keeps instantiating, failing and freeing instances of both FMUs.
//! - `leak_cycles` (ignored; scripts/leak_check.sh runs it under valgrind memcheck): thousands of
//!   instantiate / initialise / step / get-set FMU state / serialise / refuse / reset / free cycles on both
//!   FMUs, for "definitely lost: 0 bytes".
//!
//! The logger is variadic C; see tests/common/mod.rs for why a five-argument non-variadic function receives
//! the layer's calls (no variadic argument) correctly on x86_64 Linux, to which this file is gated.
#![allow(
    clippy::undocumented_unsafe_blocks,
    clippy::multiple_unsafe_ops_per_block,
    reason = "the tests call the exported FMI functions directly, many with hostile arguments on purpose: \
              what each call passes and why is the test itself"
)]
#![cfg(all(target_arch = "x86_64", target_os = "linux"))]

use crate::common;

use backlash::fmi2::exports::*;
use backlash::fmi2::ffi::*;
use backlash::plant::{Plant, PlantParams};
use std::ffi::{CString, c_char};
use std::ptr::{null, null_mut};

use common::{Kind, Sink, callbacks};

const OK: u32 = Fmi2Status::Ok as u32;
const ERROR: u32 = Fmi2Status::Error as u32;

fn outputs(kind: Kind) -> Vec<u32> {
    match kind {
        Kind::Plant => ["y", "w", "x"].iter().map(|n| kind.vr(n)).collect(),
        Kind::Estimator => ["a1", "a2", "b0", "m2", "c1", "c2", "y_hat", "e"]
            .iter()
            .map(|n| kind.vr(n))
            .collect(),
    }
}

/// An instance with a logger writing to `sink`.
struct Fmu {
    c: Fmi2Component,
}

unsafe impl Send for Fmu {}

impl Fmu {
    fn new(kind: Kind, name: &str, sink: &Sink) -> Fmu {
        let cb = callbacks(sink);
        let guid = kind.guid();
        let name = CString::new(name).unwrap();
        let c = unsafe {
            fmi2Instantiate(
                name.as_ptr(),
                FMI2_CO_SIMULATION,
                guid.as_ptr(),
                null(),
                &cb,
                FMI2_FALSE,
                FMI2_FALSE,
            )
        };
        assert!(!c.is_null());
        Fmu { c }
    }
}

impl Drop for Fmu {
    fn drop(&mut self) {
        unsafe { fmi2FreeInstance(self.c) }
    }
}

fn ok(s: u32, what: &str) {
    assert_eq!(s, OK, "{what}");
}

/// One run: its FMU, parameters and input sequence.
#[derive(Clone)]
struct Job {
    kind: Kind,
    name: String,
    /// (value reference, value) set before initialisation.
    reals: Vec<(u32, f64)>,
    ints: Vec<(u32, i32)>,
    /// Inputs per step: u, or (u, y) for the estimator.
    inputs: Vec<(f64, f64)>,
}

fn jobs(steps: usize) -> Vec<Job> {
    let mut out = Vec::new();
    for j in 0..4u32 {
        let u: Vec<f64> = (0..steps)
            .map(|k| 2.4 * ((k as f64 * (0.5 + 0.1 * j as f64)).sin()))
            .collect();
        let mut params = PlantParams::PAPER;
        params.noise_std = 0.02 * (j + 1) as f64;
        params.noise_seed = u64::from(j) + 7;
        let y: Vec<f64> = Plant::simulate(params, &u)
            .unwrap()
            .iter()
            .map(|o| o.y)
            .collect();
        out.push(Job {
            kind: Kind::Plant,
            name: format!("plant{j}"),
            reals: vec![
                (Kind::Plant.vr("noise_std"), params.noise_std),
                (Kind::Plant.vr("c1"), 0.5 + 0.1 * j as f64),
            ],
            ints: vec![(Kind::Plant.vr("noise_seed"), 7 + j as i32)],
            inputs: u.iter().map(|&u| (u, 0.0)).collect(),
        });
        out.push(Job {
            kind: Kind::Estimator,
            name: format!("estimator{j}"),
            reals: vec![(Kind::Estimator.vr("rho_min"), 0.001 * j as f64)],
            ints: vec![],
            inputs: u.iter().copied().zip(y).collect(),
        });
    }
    out
}

/// A job's instance, initialised.
fn start(job: &Job, sink: &Sink) -> Fmu {
    let f = Fmu::new(job.kind, &job.name, sink);
    unsafe {
        ok(
            fmi2SetupExperiment(f.c, FMI2_FALSE, 0.0, 0.0, FMI2_FALSE, 0.0),
            "setup",
        );
        for &(v, x) in &job.reals {
            ok(fmi2SetReal(f.c, &v, 1, &x), "set real parameter");
        }
        for &(v, x) in &job.ints {
            ok(fmi2SetInteger(f.c, &v, 1, &x), "set integer parameter");
        }
        ok(fmi2EnterInitializationMode(f.c), "enter");
        ok(fmi2ExitInitializationMode(f.c), "exit");
    }
    f
}

/// Step `k` of a job; the outputs' bits are appended to `out`.
fn step(job: &Job, f: &Fmu, k: usize, out: &mut Vec<u64>) {
    let (u, y) = job.inputs[k];
    unsafe {
        match job.kind {
            Kind::Plant => {
                let v = job.kind.vr("u");
                ok(fmi2SetReal(f.c, &v, 1, &u), "set u");
            }
            Kind::Estimator => {
                let v = [job.kind.vr("u"), job.kind.vr("y")];
                ok(fmi2SetReal(f.c, v.as_ptr(), 2, [u, y].as_ptr()), "set u, y");
            }
        }
        ok(fmi2DoStep(f.c, k as f64, 1.0, FMI2_TRUE), "step");
        let vrs = outputs(job.kind);
        let mut vals = vec![0.0; vrs.len()];
        ok(
            fmi2GetReal(f.c, vrs.as_ptr(), vrs.len(), vals.as_mut_ptr()),
            "get",
        );
        out.extend(vals.iter().map(|v| v.to_bits()));
    }
}

fn alone(job: &Job) -> Vec<u64> {
    let sink = Sink::default();
    let f = start(job, &sink);
    let mut out = Vec::new();
    for k in 0..job.inputs.len() {
        step(job, &f, k, &mut out);
    }
    drop(f);
    assert!(sink.lock().unwrap().iter().all(|e| e.status < ERROR));
    out
}

#[test]
fn instances_interleaved_in_one_thread_are_independent() {
    let jobs = jobs(600);
    let want: Vec<Vec<u64>> = jobs.iter().map(alone).collect();
    let sink = Sink::default();
    let fmus: Vec<Fmu> = jobs.iter().map(|j| start(j, &sink)).collect();
    let mut got: Vec<Vec<u64>> = vec![Vec::new(); jobs.len()];
    for k in 0..600 {
        // A different order at every step.
        for i in 0..jobs.len() {
            let i = (i * 3 + k) % jobs.len();
            step(&jobs[i], &fmus[i], k, &mut got[i]);
        }
        if k == 300 {
            // Saving and restoring one instance's state leaves the others alone.
            let mut s: Fmi2FmuState = null_mut();
            unsafe {
                ok(fmi2GetFMUstate(fmus[1].c, &mut s), "get state");
                ok(fmi2SetFMUstate(fmus[1].c, s), "set state");
                ok(fmi2FreeFMUstate(fmus[1].c, &mut s), "free state");
            }
        }
    }
    for (i, job) in jobs.iter().enumerate() {
        assert!(got[i] == want[i], "{} differs when interleaved", job.name);
    }
    // An error in one instance does not touch the others.
    unsafe {
        assert_eq!(fmi2DoStep(fmus[0].c, 0.0, 1.0, FMI2_TRUE), ERROR);
        ok(
            fmi2DoStep(fmus[2].c, 600.0, 1.0, FMI2_TRUE),
            "another instance steps on",
        );
    }
    let log = sink.lock().unwrap();
    assert!(
        log.iter().filter(|e| e.status == ERROR).count() == 1,
        "{log:?}"
    );
    assert_eq!(log.last().unwrap().instance, "plant0");
}

#[test]
fn instances_stepped_in_parallel_threads_match_stepped_alone() {
    let steps = if cfg!(debug_assertions) { 1_500 } else { 6_000 };
    let jobs = jobs(steps);
    let want: Vec<Vec<u64>> = jobs.iter().map(alone).collect();
    // One logger sink shared by every thread: the logger is called concurrently from several instances.
    let sink = Sink::default();
    let stop = std::sync::atomic::AtomicBool::new(false);
    let got: Vec<Vec<u64>> = std::thread::scope(|scope| {
        // Churn: instances of both FMUs created, refused, failed and freed meanwhile.
        let churn = scope.spawn(|| {
            let mut n = 0u64;
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                let kind = if n & 1 == 0 {
                    Kind::Plant
                } else {
                    Kind::Estimator
                };
                let f = Fmu::new(kind, "churn", &sink);
                unsafe {
                    assert_eq!(fmi2DoStep(f.c, 0.0, 1.0, FMI2_TRUE), ERROR);
                    assert_eq!(fmi2Reset(f.c), OK);
                    let mut s: Fmi2FmuState = null_mut();
                    assert_eq!(fmi2GetFMUstate(f.c, &mut s), OK);
                    assert_eq!(fmi2FreeFMUstate(f.c, &mut s), OK);
                }
                drop(f);
                n += 1;
            }
            n
        });
        let handles: Vec<_> = jobs
            .iter()
            .map(|job| {
                let sink = &sink;
                scope.spawn(move || {
                    let f = start(job, sink);
                    let mut out = Vec::new();
                    for k in 0..job.inputs.len() {
                        step(job, &f, k, &mut out);
                        if k % 1000 == 500 {
                            std::thread::yield_now();
                        }
                    }
                    out
                })
            })
            .collect();
        let got: Vec<Vec<u64>> = handles.into_iter().map(|h| h.join().unwrap()).collect();
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
        let churned = churn.join().unwrap();
        assert!(churned > 0);
        got
    });
    for (i, job) in jobs.iter().enumerate() {
        assert_eq!(got[i].len(), want[i].len());
        assert!(got[i] == want[i], "{} differs in a thread", job.name);
    }
    let log = sink.lock().unwrap();
    assert!(log.iter().all(|e| e.message != "<bad format>"));
    assert!(
        log.iter()
            .filter(|e| e.status == ERROR)
            .all(|e| e.instance == "churn"),
        "only the churn instances failed"
    );
}

/// For valgrind (scripts/leak_check.sh): every allocation path of the layer, thousands of times.
/// `FMI_LEAK_CYCLES` cycles per FMU (default 2000).
#[test]
#[ignore = "run under valgrind by scripts/leak_check.sh"]
fn leak_cycles() {
    let cycles: usize = std::env::var("FMI_LEAK_CYCLES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(2000);
    let sink = Sink::default();
    let mut jobs = jobs(8);
    jobs.truncate(2); // one of each FMU
    for cycle in 0..cycles {
        for job in &jobs {
            leak_cycle(job, &sink);
        }
        if cycle % 64 == 0 {
            sink.lock().unwrap().clear();
        }
    }
}

/// One cycle of `leak_cycles` on `job`'s FMU: refused instantiations, then an instance through logging,
/// steps, strings, FMU states, refusals and resets to its end.
fn leak_cycle(job: &Job, sink: &Sink) {
    refused_instantiations(sink);
    let f = start(job, sink);
    let cats = [c"logAll".as_ptr()];
    ok(
        unsafe { fmi2SetDebugLogging(f.c, FMI2_TRUE, 1, cats.as_ptr()) },
        "logging",
    );
    let mut out = Vec::new();
    for k in 0..4 {
        step(job, &f, k, &mut out);
    }
    // Strings: the buffer kept until the next call.
    let mut sv: [Fmi2String; 0] = [];
    ok(
        unsafe { fmi2GetString(f.c, null(), 0, sv.as_mut_ptr()) },
        "get string",
    );
    let bytes = fmu_state_cycle(job, &f, &mut out);
    refusals_and_resets(job, &f, &bytes, &mut out);
    ok(unsafe { fmi2Terminate(f.c) }, "terminate");
    drop(f); // fmi2FreeInstance
}

/// A refused instantiation (wrong type) and a NULL-callback one.
fn refused_instantiations(sink: &Sink) {
    let cb = callbacks(sink);
    let guid = Kind::Plant.guid();
    unsafe {
        assert!(
            fmi2Instantiate(
                c"x".as_ptr(),
                FMI2_MODEL_EXCHANGE,
                guid.as_ptr(),
                null(),
                &cb,
                0,
                0
            )
            .is_null()
        );
        assert!(
            fmi2Instantiate(
                c"x".as_ptr(),
                FMI2_CO_SIMULATION,
                guid.as_ptr(),
                null(),
                null(),
                0,
                0
            )
            .is_null()
        );
    }
}

/// FMU states: new, overwritten, serialised, deserialised (new and in place), set, freed; returns the
/// serialised bytes.
fn fmu_state_cycle(job: &Job, f: &Fmu, out: &mut Vec<u64>) -> Vec<u8> {
    unsafe {
        let mut s1: Fmi2FmuState = null_mut();
        ok(fmi2GetFMUstate(f.c, &mut s1), "get state");
        step(job, f, 4, out);
        ok(fmi2GetFMUstate(f.c, &mut s1), "overwrite state");
        let mut size = 0usize;
        ok(fmi2SerializedFMUstateSize(f.c, s1, &mut size), "size");
        let mut bytes = vec![0u8; size];
        ok(
            fmi2SerializeFMUstate(f.c, s1, bytes.as_mut_ptr() as *mut c_char, size),
            "serialise",
        );
        let mut s2: Fmi2FmuState = null_mut();
        ok(
            fmi2DeSerializeFMUstate(f.c, bytes.as_ptr() as *const c_char, size, &mut s2),
            "deserialise",
        );
        ok(
            fmi2DeSerializeFMUstate(f.c, bytes.as_ptr() as *const c_char, size, &mut s2),
            "deserialise in place",
        );
        ok(fmi2SetFMUstate(f.c, s2), "set state");
        step(job, f, 5, out);
        ok(fmi2FreeFMUstate(f.c, &mut s1), "free state 1");
        ok(fmi2FreeFMUstate(f.c, &mut s2), "free state 2");
        bytes
    }
}

/// Refusals: a truncated state of `bytes`, an unknown value reference (error state), then reset; and the
/// instance initialised again and stepped.
fn refusals_and_resets(job: &Job, f: &Fmu, bytes: &[u8], out: &mut Vec<u64>) {
    let size = bytes.len();
    unsafe {
        let mut s3: Fmi2FmuState = null_mut();
        assert_eq!(
            fmi2DeSerializeFMUstate(f.c, bytes.as_ptr() as *const c_char, size / 2, &mut s3),
            ERROR
        );
        assert!(s3.is_null());
        ok(fmi2Reset(f.c), "reset");
        let bad = 99_999u32;
        let mut x = 0.0;
        ok(fmi2SetupExperiment(f.c, 0, 0.0, 0.0, 0, 0.0), "setup");
        ok(fmi2EnterInitializationMode(f.c), "enter");
        assert_eq!(fmi2GetReal(f.c, &bad, 1, &mut x), ERROR);
        ok(fmi2Reset(f.c), "reset");
        ok(fmi2SetupExperiment(f.c, 0, 0.0, 0.0, 0, 0.0), "setup");
        ok(fmi2EnterInitializationMode(f.c), "enter");
        ok(fmi2ExitInitializationMode(f.c), "exit");
        step(job, f, 0, out);
    }
}
