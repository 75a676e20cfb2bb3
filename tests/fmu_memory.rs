//! Memory of the FMUs is constant in run length: a plant + estimator co-simulation through the exported FMI
//! functions (the crate is also an rlib, so these are the functions the .so exports), with a counting global
//! allocator, performs no heap allocation at all per step once running, and frees everything it allocated
//! when the instances are freed.
//!
//! Per step k, as a master does it (and as tests/python/cosim.py pairs the samples): plant
//! `fmi2GetReal(y, x, w)` (the output y(k) at t_k), `fmi2SetReal(u)`; estimator `fmi2SetReal(u, y)`; both
//! `fmi2DoStep`; estimator `fmi2GetReal(a1, a2, b0, m2, c1, c2, y_hat, e)` and `fmi2GetBoolean(updating)`.
//!
//! Found with it: the FMI layer allocated twice per get/set call (the index and value vectors), 11 times per
//! pair step; it now works on stack arrays (src/fmi/instance.rs, `STACK_VRS`, `get_with`, `set_with`).
//!
//! Run length: `FMU_MEMORY_STEPS`, default 10 million in release builds (the pair costs a few hundred ns per
//! step, so about 2-4 s; `cargo test --release` is how CI runs the suite) and 1 million in debug builds
//! (unoptimised code is ~30x slower). Counting is per thread, so the test harness's own threads do not
//! disturb it. Logging is off, as in a production run (a logged call formats its message, which allocates).
#![allow(
    clippy::undocumented_unsafe_blocks,
    clippy::multiple_unsafe_ops_per_block,
    reason = "the tests call the exported FMI functions directly, many with hostile arguments on purpose: \
              what each call passes and why is the test itself"
)]

use backlash::fmi2::exports::*;
use backlash::fmi2::ffi::*;
use backlash::fmus::{backlash_plant, mrgia_estimator};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::ffi::CString;
use std::ptr::null_mut;

struct Counting;

#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Counts {
    allocs: u64,
    frees: u64,
    /// Bytes allocated minus bytes freed (reallocations count their size change).
    net: i64,
}

thread_local! {
    static COUNTS: Cell<Counts> = const { Cell::new(Counts { allocs: 0, frees: 0, net: 0 }) };
}

fn record(f: impl FnOnce(&mut Counts)) {
    // try_with: the allocator can run during thread teardown, after the slot is gone.
    let _ = COUNTS.try_with(|c| {
        let mut v = c.get();
        f(&mut v);
        c.set(v);
    });
}

// SAFETY: every call is forwarded to the system allocator unchanged; the counters are thread-local cells.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        record(|c| {
            c.allocs += 1;
            c.net += layout.size() as i64;
        });
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        record(|c| {
            c.allocs += 1;
            c.net += layout.size() as i64;
        });
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        record(|c| {
            c.frees += 1;
            c.net -= layout.size() as i64;
        });
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        record(|c| {
            c.allocs += 1;
            c.frees += 1;
            c.net += new_size as i64 - layout.size() as i64;
        });
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOC: Counting = Counting;

fn counts() -> Counts {
    COUNTS.with(|c| c.get())
}

fn steps() -> u64 {
    std::env::var("FMU_MEMORY_STEPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(if cfg!(debug_assertions) {
            1_000_000
        } else {
            10_000_000
        })
}

const OK: u32 = Fmi2Status::Ok as u32;

fn vr(vars: &[backlash::fmi::vars::VarInfo], name: &str) -> u32 {
    vars.iter()
        .find(|v| v.name == name)
        .unwrap_or_else(|| panic!("no variable {name}"))
        .vr
}

fn instantiate(name: &str, guid: &str) -> Fmi2Component {
    let cb = Fmi2CallbackFunctions {
        logger: None,
        allocate_memory: None,
        free_memory: None,
        step_finished: None,
        component_environment: null_mut(),
    };
    let (name, guid) = (CString::new(name).unwrap(), CString::new(guid).unwrap());
    // SAFETY: valid strings and callbacks for the duration of the call (the instance copies them).
    let c = unsafe {
        fmi2Instantiate(
            name.as_ptr(),
            FMI2_CO_SIMULATION,
            guid.as_ptr(),
            c"file:///nonexistent/resources".as_ptr(),
            &cb,
            FMI2_FALSE,
            FMI2_FALSE,
        )
    };
    assert!(!c.is_null(), "fmi2Instantiate returned NULL");
    // SAFETY: c is a live instance.
    unsafe {
        assert_eq!(
            fmi2SetupExperiment(c, FMI2_FALSE, 0.0, 0.0, FMI2_FALSE, 0.0),
            OK
        );
    }
    c
}

fn initialise(c: Fmi2Component) {
    // SAFETY: c is a live instance.
    unsafe {
        assert_eq!(fmi2EnterInitializationMode(c), OK);
        assert_eq!(fmi2ExitInitializationMode(c), OK);
    }
}

/// A xorshift generator for the input: uniform on [-A, A], A = sqrt(3 * 1.93) (the paper's input variance),
/// without allocating (a pre-computed 10-million-sample input would be 80 MB).
struct Input(u64);

impl Input {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        let r = (self.0 >> 11) as f64 / (1u64 << 53) as f64;
        (3.0f64 * 1.93).sqrt() * (2.0 * r - 1.0)
    }
}

#[test]
fn pair_steps_allocate_nothing_and_free_everything() {
    pair_run(false, steps());
}

/// The same with the estimator's `refine` setting (its start, an output-error fit of the first 500 samples,
/// allocates once, within the first 1000 steps): a fifth of the steps, as a refine step costs several plain
/// ones.
#[test]
fn refine_pair_steps_allocate_nothing_and_free_everything() {
    pair_run(true, steps() / 5);
}

/// The value references a pair step uses.
struct PairVrs {
    /// Plant: input u, outputs y, x, w.
    pu: u32,
    py: u32,
    px: u32,
    pw: u32,
    /// Estimator: inputs u, y, the six estimates, y_hat, e and six standard errors, `updating`.
    eu: u32,
    ey: u32,
    real_outs: Vec<u32>,
    updating: u32,
}

impl PairVrs {
    fn new() -> PairVrs {
        let pv = &backlash_plant::VARIABLES;
        let ev = &mrgia_estimator::VARIABLES;
        PairVrs {
            pu: vr(pv, "u"),
            py: vr(pv, "y"),
            px: vr(pv, "x"),
            pw: vr(pv, "w"),
            eu: vr(ev, "u"),
            ey: vr(ev, "y"),
            real_outs: [
                "a1", "a2", "b0", "m2", "c1", "c2", "y_hat", "e", "a1_se", "a2_se", "b0_se",
                "m2_se", "c1_se", "c2_se",
            ]
            .iter()
            .map(|name| vr(ev, name))
            .collect(),
            updating: vr(ev, "updating"),
        }
    }
}

/// What a pair run counted.
struct PairRun {
    /// The counts after the warm-up steps and at the end of the run (before freeing).
    at_warm_up: Counts,
    at_end: Counts,
    /// The steps in which the estimator updated.
    updates: u64,
    /// The estimator's Real outputs after the last step (`PairVrs::real_outs`).
    est_out: [f64; 14],
}

fn pair_run(refine: bool, n: u64) {
    let warm_up = 1000;
    let vrs = PairVrs::new();
    let before = counts();
    let (plant, est) = start_pair(refine);
    let run = step_pair(plant, est, &vrs, n, warm_up);
    // SAFETY: live instances, freed once.
    unsafe {
        assert_eq!(fmi2Terminate(plant), OK);
        assert_eq!(fmi2Terminate(est), OK);
        fmi2FreeInstance(plant);
        fmi2FreeInstance(est);
    }
    let after = counts();
    let (at_warm_up, at_end) = (run.at_warm_up, run.at_end);
    println!(
        "{n} pair steps: {} allocations ({} bytes net) while instantiating and the first {warm_up} steps, \
         {} allocations and {} frees in the remaining {} steps; {} bytes net after freeing; {} \
         estimator updates; estimate {:?}",
        at_warm_up.allocs - before.allocs,
        at_warm_up.net - before.net,
        at_end.allocs - at_warm_up.allocs,
        at_end.frees - at_warm_up.frees,
        n - warm_up,
        after.net - before.net,
        run.updates,
        &run.est_out[..6],
    );
    check_estimates(&run, refine, n);
    // Constant memory: nothing allocated (or freed) per step after the warm-up, and all given back at the end.
    assert_eq!(at_end.allocs, at_warm_up.allocs, "allocations per step");
    assert_eq!(at_end.frees, at_warm_up.frees, "frees per step");
    assert_eq!(at_end.net, at_warm_up.net, "heap growth over the run");
    assert_eq!(after.net, before.net, "bytes not freed by fmi2FreeInstance");
}

/// The plant (noise on) and the estimator (`refine` as given), instantiated and initialised.
fn start_pair(refine: bool) -> (Fmi2Component, Fmi2Component) {
    let pv = &backlash_plant::VARIABLES;
    let ev = &mrgia_estimator::VARIABLES;
    let (noise_std, noise_seed) = (vr(pv, "noise_std"), vr(pv, "noise_seed"));
    let plant = instantiate("plant", backlash_plant::GUID);
    let est = instantiate("estimator", mrgia_estimator::GUID);
    // SAFETY: live instances; the value arrays match the reference arrays in length.
    unsafe {
        // Noise on: the plant's random generator runs every step too.
        assert_eq!(fmi2SetReal(plant, &noise_std, 1, &0.01), OK);
        assert_eq!(fmi2SetInteger(plant, &noise_seed, 1, &3), OK);
        let on = if refine { FMI2_TRUE } else { FMI2_FALSE };
        assert_eq!(fmi2SetBoolean(est, &vr(ev, "refine"), 1, &on), OK);
    }
    initialise(plant);
    initialise(est);
    (plant, est)
}

/// `n` pair steps, the allocator's counts taken after `warm_up` of them and at the end.
fn step_pair(
    plant: Fmi2Component,
    est: Fmi2Component,
    v: &PairVrs,
    n: u64,
    warm_up: u64,
) -> PairRun {
    let mut input = Input(0x9E37_79B9_7F4A_7C15);
    let mut plant_out = [0.0; 3];
    let mut est_out = [0.0; 14];
    let mut updating: Fmi2Boolean = FMI2_FALSE;
    let mut updates = 0u64;
    let mut at_warm_up = Counts::default();
    let mut t = 0.0;
    for k in 0..n {
        if k == warm_up {
            at_warm_up = counts();
        }
        let u = input.next();
        // SAFETY: live instances; every array has the length passed with it.
        unsafe {
            // y(k) before the plant steps over sample k (as tests/python/cosim.py pairs them).
            assert_eq!(
                fmi2GetReal(
                    plant,
                    [v.py, v.px, v.pw].as_ptr(),
                    3,
                    plant_out.as_mut_ptr()
                ),
                OK
            );
            assert_eq!(fmi2SetReal(plant, &v.pu, 1, &u), OK);
            assert_eq!(
                fmi2SetReal(est, [v.eu, v.ey].as_ptr(), 2, [u, plant_out[0]].as_ptr()),
                OK
            );
            assert_eq!(fmi2DoStep(plant, t, 1.0, FMI2_TRUE), OK);
            assert_eq!(fmi2DoStep(est, t, 1.0, FMI2_TRUE), OK);
            assert_eq!(
                fmi2GetReal(est, v.real_outs.as_ptr(), 14, est_out.as_mut_ptr()),
                OK
            );
            assert_eq!(fmi2GetBoolean(est, &v.updating, 1, &mut updating), OK);
        }
        updates += u64::from(updating != FMI2_FALSE);
        t += 1.0;
    }
    PairRun {
        at_warm_up,
        at_end: counts(),
        updates,
        est_out,
    }
}

/// The estimator really ran its update path (the plant drove it), and converged near the paper's truth;
/// its standard errors are known (positive) with refine, 0 without.
fn check_estimates(run: &PairRun, refine: bool, n: u64) {
    let (updates, est_out) = (run.updates, &run.est_out);
    assert!(updates > n / 2, "only {updates} of {n} steps updated");
    let truth = [0.45, 0.55, 0.8, 1.5, 0.5, 1.0];
    for (got, want) in est_out[..6].iter().zip(truth) {
        assert!((got - want).abs() < 0.05, "estimate {est_out:?}");
    }
    // Standard errors: known (positive) with refine, 0 without.
    assert!(
        est_out[8..]
            .iter()
            .all(|&s| if refine { s > 0.0 } else { s == 0.0 }),
        "standard errors {:?}",
        &est_out[8..]
    );
}
