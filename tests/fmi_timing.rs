//! Sampled-data timing of both FMUs under the step patterns FMI masters use, through the exported C functions
//! (in process), and the FMU-state registry and the logger's format.
//!
//! The contract (docs/INTERFACE.md, "What masters can expect"): samples happen at the instants
//! t_k = start + k Ts that the steps reach; between instants the outputs hold sample k's values; u(k) is the
//! value of u current at t_k. Stepping by Ts, by Ts/m or by n Ts gives the same values at the instants (bit for
//! bit); float32 and float64 sums of steps are never refused. The estimator takes at most one instant per step
//! and cuts a longer step at the first one with fmi2Discard.
//!
//! The logger is variadic C; see tests/common/mod.rs for why a five-argument non-variadic function receives
//! the layer's calls correctly on x86_64 Linux, to which this file is gated.
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
use common::{Kind, Sink, callbacks};
use std::ffi::CString;
use std::ptr::null_mut;

const OK: u32 = Fmi2Status::Ok as u32;
const DISCARD: u32 = Fmi2Status::Discard as u32;
const ERROR: u32 = Fmi2Status::Error as u32;

/// An initialised instance (Ts as given, start time 0) with a recording logger.
struct Fmu {
    c: Fmi2Component,
    kind: Kind,
    sink: Box<Sink>,
}

impl Fmu {
    fn new(kind: Kind, name: &str, ts: f64) -> Fmu {
        Self::with_stop(kind, name, ts, None)
    }

    fn with_stop(kind: Kind, name: &str, ts: f64, stop: Option<f64>) -> Fmu {
        let sink: Box<Sink> = Box::default();
        let cb = callbacks(&sink);
        let (name, guid) = (CString::new(name).unwrap(), kind.guid());
        // SAFETY: valid strings and callbacks for the call; the instance copies the callbacks.
        let c = unsafe {
            fmi2Instantiate(
                name.as_ptr(),
                FMI2_CO_SIMULATION,
                guid.as_ptr(),
                std::ptr::null(),
                &cb,
                FMI2_FALSE,
                FMI2_FALSE,
            )
        };
        assert!(!c.is_null());
        let f = Fmu { c, kind, sink };
        unsafe {
            let (defined, stop) = (i32::from(stop.is_some()), stop.unwrap_or(0.0));
            assert_eq!(
                fmi2SetupExperiment(c, FMI2_FALSE, 0.0, 0.0, defined, stop),
                OK
            );
            assert_eq!(fmi2EnterInitializationMode(c), OK);
        }
        f.set(&["Ts"], &[ts]);
        assert_eq!(unsafe { fmi2ExitInitializationMode(c) }, OK);
        f
    }

    fn set(&self, names: &[&str], values: &[f64]) {
        let vrs: Vec<u32> = names.iter().map(|n| self.kind.vr(n)).collect();
        let s = unsafe { fmi2SetReal(self.c, vrs.as_ptr(), vrs.len(), values.as_ptr()) };
        assert_eq!(s, OK, "set {names:?}");
    }

    fn get(&self, names: &[&str]) -> Vec<f64> {
        let vrs: Vec<u32> = names.iter().map(|n| self.kind.vr(n)).collect();
        let mut out = vec![f64::NAN; vrs.len()];
        let s = unsafe { fmi2GetReal(self.c, vrs.as_ptr(), vrs.len(), out.as_mut_ptr()) };
        assert_eq!(s, OK, "get {names:?}");
        out
    }

    fn step(&self, t: f64, h: f64) -> u32 {
        unsafe { fmi2DoStep(self.c, t, h, FMI2_TRUE) }
    }

    fn last_successful_time(&self) -> f64 {
        let mut t = f64::NAN;
        assert_eq!(
            unsafe { fmi2GetRealStatus(self.c, FMI2_LAST_SUCCESSFUL_TIME, &mut t) },
            OK
        );
        t
    }

    fn log(&self) -> Vec<common::Entry> {
        self.sink.lock().unwrap().clone()
    }
}

impl Drop for Fmu {
    fn drop(&mut self) {
        unsafe { fmi2FreeInstance(self.c) };
    }
}

/// A deterministic input with both signs (the backlash engages up and down).
fn input(k: u64) -> f64 {
    let x = (k as f64 * 0.7391).sin() * 2.0 + (k as f64 * 0.1234).cos();
    if k % 7 == 3 { -x } else { x }
}

const PLANT_OUT: [&str; 4] = ["y", "w", "x", "f"];
const EST_OUT: [&str; 8] = ["a1", "a2", "b0", "m2", "c1", "c2", "y_hat", "e"];

/// The plant stepped by exactly Ts: outputs at t_0 .. t_n.
fn plant_reference(ts: f64, n: u64, u: impl Fn(u64) -> f64) -> Vec<Vec<f64>> {
    let p = Fmu::new(Kind::Plant, "reference", ts);
    let mut out = vec![p.get(&PLANT_OUT)];
    for k in 0..n {
        p.set(&["u"], &[u(k)]);
        assert_eq!(p.step(k as f64 * ts, ts), OK);
        out.push(p.get(&PLANT_OUT));
    }
    out
}

/// Step the plant by `m` equal sub-steps per sample (the master's clock a float64 sum), setting u(k) at each
/// instant and another value at the points in between, which the plant must ignore.
fn plant_substeps(ts: f64, n: u64, m: u64, h: f64) -> Vec<Vec<f64>> {
    let p = Fmu::new(Kind::Plant, "substeps", ts);
    let mut out = vec![p.get(&PLANT_OUT)];
    let mut t = 0.0;
    for k in 0..n {
        for i in 0..m {
            p.set(&["u"], &[if i == 0 { input(k) } else { 1e3 + i as f64 }]);
            assert_eq!(p.step(t, h), OK, "sample {k}, sub-step {i}, t = {t}");
            t += h;
            if i + 1 < m {
                // Between instants the outputs hold sample k's.
                assert_eq!(
                    p.get(&PLANT_OUT),
                    out[k as usize],
                    "held at sample {k}, sub-step {i}"
                );
            }
        }
        out.push(p.get(&PLANT_OUT));
    }
    out
}

#[test]
fn plant_sub_steps_give_the_ts_values_at_the_instants_bit_for_bit() {
    let n = 300;
    for (ts, m, h) in [
        (1.0, 4, 0.25),
        (1.0, 50, 0.02),
        (0.1, 3, 0.1 / 3.0),
        (1.0, 1000, 1e-3),
    ] {
        let want = plant_reference(ts, n.min(60), input);
        let got = plant_substeps(ts, n.min(60), m, h);
        assert_eq!(got, want, "Ts = {ts}, {m} sub-steps of {h}");
    }
}

#[test]
fn plant_stepped_by_n_ts_holds_the_input_over_the_step() {
    let (ts, n_per) = (0.5, 3u64);
    // The master holds u over each step of n Ts: the samples inside take the held value.
    let held = |k: u64| input(k / n_per * n_per);
    let want = plant_reference(ts, 90, held);
    let p = Fmu::new(Kind::Plant, "n-ts", ts);
    for j in 0..30u64 {
        p.set(&["u"], &[held(j * n_per)]);
        assert_eq!(p.step(j as f64 * n_per as f64 * ts, n_per as f64 * ts), OK);
        assert_eq!(
            p.get(&PLANT_OUT),
            want[((j + 1) * n_per) as usize],
            "after step {j}"
        );
    }
}

/// A step that reaches an instant and goes on past it has held u there: u(1) is the value set before the
/// step from 0 to 1.5 Ts, not the one the master sets at 1.5 Ts, between the instants, before its next step.
#[test]
fn plant_stepped_past_an_instant_keeps_the_input_held_there() {
    let ts = 1.0;
    let u = |k: u64| if k <= 1 { 2.0 } else { -2.0 };
    let want = plant_reference(ts, 4, u);
    let p = Fmu::new(Kind::Plant, "past", ts);
    p.set(&["u"], &[u(0)]);
    assert_eq!(p.step(0.0, 1.5), OK);
    assert_eq!(p.get(&PLANT_OUT), want[1]);
    p.set(&["u"], &[u(2)]);
    assert_eq!(p.step(1.5, 2.5), OK);
    assert_eq!(p.get(&PLANT_OUT), want[4]);
}

/// The estimator fed by the reference plant's y, stepped so that each sample takes `m` sub-steps of `h`.
fn estimator_run(ts: f64, n: u64, m: u64, h: f64, y: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let e = Fmu::new(Kind::Estimator, "estimator", ts);
    let mut out = Vec::new();
    let mut t = 0.0;
    for k in 0..n {
        for i in 0..m {
            let (u, yk) = if i == 0 {
                (input(k), y[k as usize][0])
            } else {
                (-5.0, 7.0)
            };
            e.set(&["u", "y"], &[u, yk]);
            assert_eq!(e.step(t, h), OK, "sample {k}, sub-step {i}");
            t += h;
        }
        out.push(e.get(&EST_OUT));
    }
    out
}

#[test]
fn estimator_sub_steps_give_the_ts_estimates_bit_for_bit() {
    let n = 400;
    let y = plant_reference(1.0, n, input);
    let want = estimator_run(1.0, n, 1, 1.0, &y);
    assert_eq!(estimator_run(1.0, n, 4, 0.25, &y), want, "Ts/4");
    assert_eq!(estimator_run(1.0, 40, 1000, 1e-3, &y), want[..40], "1e-3");
}

/// Steps of h = float32(Ts) (0.1000000015 for Ts = 0.1: 1e7 steps; 0.6999999881 for 0.7, shorter than Ts:
/// 1e6), the clock a float64 sum: never refused, one sample per step, the same values as stepping by Ts.
#[test]
fn ten_million_float32_steps_are_never_refused_and_match_ts_stepping() {
    for (ts, steps) in [(0.1, 10_000_000u64), (0.7, 1_000_000)] {
        let h = f64::from(ts as f32);
        assert_ne!(h, ts);
        let (p, q) = (
            Fmu::new(Kind::Plant, "f32", ts),
            Fmu::new(Kind::Plant, "ts", ts),
        );
        let e = Fmu::new(Kind::Estimator, "f32-est", ts);
        let mut t = 0.0;
        for k in 0..steps {
            let u = input(k % 1000);
            let y = q.get(&["y"])[0];
            p.set(&["u"], &[u]);
            q.set(&["u"], &[u]);
            e.set(&["u", "y"], &[u, y]);
            assert_eq!(p.step(t, h), OK, "plant, step {k} at t = {t}");
            assert_eq!(e.step(t, h), OK, "estimator, step {k} at t = {t}");
            assert_eq!(q.step(k as f64 * ts, ts), OK);
            t += h;
            if k % 9973 == 0 || k + 1 == steps {
                assert_eq!(p.get(&PLANT_OUT), q.get(&PLANT_OUT), "Ts = {ts}, step {k}");
            }
        }
    }
}

/// A float64 sum of 1e6 steps of 0.1 ends at 100000.00000133288, past the stop time 1e5 by 1.3e-11 of it:
/// within the relative tolerance, so the last step is taken; a step beyond the stop time is refused.
#[test]
fn float64_sums_of_steps_reach_the_stop_time() {
    let ts = 0.1;
    let e = Fmu::with_stop(Kind::Estimator, "sum", ts, Some(1e5));
    let mut t = 0.0;
    for k in 0..1_000_000u64 {
        e.set(&["u", "y"], &[input(k % 100), 0.1]);
        assert_eq!(e.step(t, ts), OK, "step {k} at t = {t}");
        t += ts;
    }
    assert_ne!(t, 1e5);
    assert_eq!(e.last_successful_time(), t);
    assert_eq!(e.step(t, ts), ERROR, "beyond the stop time");
}

#[test]
fn estimator_step_over_two_instants_is_cut_at_the_first_with_discard() {
    let e = Fmu::new(Kind::Estimator, "long", 0.5);
    e.set(&["u", "y"], &[1.0, 0.0]);
    assert_eq!(e.step(0.0, 0.5), OK);
    let mut saved: Fmi2FmuState = null_mut();
    assert_eq!(unsafe { fmi2GetFMUstate(e.c, &mut saved) }, OK);
    let before = e.get(&EST_OUT);
    e.set(&["u", "y"], &[0.5, 0.8]);
    assert_eq!(e.step(0.5, 1.0), DISCARD);
    assert_eq!(
        e.last_successful_time(),
        1.0,
        "the first instant the step reached"
    );
    let log = e.log();
    let last = log.last().unwrap();
    assert_eq!(
        (last.status, last.category.as_str()),
        (DISCARD, "logStatusDiscard")
    );
    assert!(last.message.contains("at most 1"), "{last:?}");
    // Step failed: outputs readable, no further step, terminate allowed.
    let cut = e.get(&EST_OUT);
    assert_eq!(e.step(1.0, 0.5), ERROR);
    // Retry from the saved state with steps of Ts: the first gives the same estimate as the cut step.
    assert_eq!(unsafe { fmi2SetFMUstate(e.c, saved) }, OK);
    assert_eq!(e.get(&EST_OUT), before);
    e.set(&["u", "y"], &[0.5, 0.8]);
    assert_eq!(e.step(0.5, 0.5), OK);
    assert_eq!(e.get(&EST_OUT), cut);
    assert_eq!(e.step(1.0, 0.5), OK);
    assert_eq!(unsafe { fmi2Terminate(e.c) }, OK);
    assert_eq!(unsafe { fmi2FreeFMUstate(e.c, &mut saved) }, OK);
}

#[test]
fn a_discarded_step_leaves_step_failed_where_terminate_is_allowed() {
    let e = Fmu::new(Kind::Estimator, "terminate", 1.0);
    assert_eq!(e.step(0.0, 6.0), DISCARD);
    assert_eq!(e.last_successful_time(), 1.0);
    assert_eq!(unsafe { fmi2Terminate(e.c) }, OK);
    assert_eq!(unsafe { fmi2Reset(e.c) }, OK);
}

#[test]
fn foreign_state_pointers_are_refused_and_never_read_through() {
    let (a, b) = (
        Fmu::new(Kind::Plant, "a", 1.0),
        Fmu::new(Kind::Plant, "b", 1.0),
    );
    let mut sa: Fmi2FmuState = null_mut();
    assert_eq!(unsafe { fmi2GetFMUstate(a.c, &mut sa) }, OK);
    unsafe {
        // Another instance's state.
        assert_eq!(fmi2SetFMUstate(b.c, sa), ERROR);
        assert_eq!(fmi2Reset(b.c), OK);
        // The state itself where its address is expected (as fmusim 0.0.39 passes it).
        assert_eq!(fmi2FreeFMUstate(a.c, sa as *mut Fmi2FmuState), ERROR);
        let why = a.log().last().unwrap().message.clone();
        assert!(why.contains("not the address"), "{why}");
        assert_eq!(fmi2Reset(a.c), OK);
        // Pointers nobody issued, including ones that would fault if read.
        for p in [8usize, 0xdead_beef, usize::MAX - 7] {
            assert_eq!(fmi2SetFMUstate(a.c, p as Fmi2FmuState), ERROR);
            assert_eq!(fmi2Reset(a.c), OK);
            let mut size = 0;
            assert_eq!(
                fmi2SerializedFMUstateSize(a.c, p as Fmi2FmuState, &mut size),
                ERROR
            );
            assert_eq!(fmi2Reset(a.c), OK);
            let mut q = p as Fmi2FmuState;
            assert_eq!(fmi2FreeFMUstate(a.c, &mut q), ERROR);
            assert_eq!(q as usize, p);
            assert_eq!(fmi2Reset(a.c), OK);
        }
        // The real one still works, by its address.
        assert_eq!(fmi2FreeFMUstate(a.c, &mut sa), OK);
        assert!(sa.is_null());
    }
}

#[test]
fn messages_with_percent_signs_arrive_intact() {
    let name = "plant %s %n 100% %%d";
    let p = Fmu::new(Kind::Plant, name, 1.0);
    assert_eq!(p.step(5.0, 1.0), ERROR);
    let e = p.log().last().unwrap().clone();
    assert!(
        e.message.contains(&format!("'{name}'")) || e.message.contains("5"),
        "{e:?}"
    );
    assert!(!e.message.starts_with("<format"), "{e:?}");
    assert_eq!(unsafe { fmi2Reset(p.c) }, OK);
    // The illegal-call message names the instance, percent signs and all.
    assert_eq!(unsafe { fmi2ExitInitializationMode(p.c) }, ERROR);
    let e = p.log().last().unwrap().clone();
    assert!(e.message.contains(&format!("'{name}'")), "{e:?}");
}
