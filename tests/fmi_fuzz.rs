//! Call-sequence fuzzing of the 34 exported FMI 2.0 functions, in-process, over both FMUs at once.
//!
//! A seeded ChaCha8 generator drives a few instance slots of both FMUs through random sequences of calls
//! with random arguments: NULL pointers, nvr = 0, nvr huge with NULL arrays, unknown value references and
//! value references of the wrong type, NaN, infinities, huge and subnormal numbers, negative, zero and
//! fractional step sizes, wrong communication points, FMU states got, set, overwritten, freed, serialised
//! with right and wrong sizes and deserialised from intact, truncated, corrupted, foreign (the other FMU's)
//! random bytes and valid JSON with one number changed, reset, terminate, free and re-instantiate with good and
//! bad arguments. Episodes of 5,000 calls differ in how wild they are (3 % to 60 % of the calls drawn from all
//! 34 functions; the rest follow the happy path of the current state, mostly with valid arguments), so that
//! the instances get deep into runs (about 1 call in 8 is a successful fmi2DoStep).
//!
//! Invariants, checked after every call:
//! - no crash, no panic escaping (a panic caught inside the layer shows as an "internal error" log line:
//!   counted and reported; a failure in the strict run);
//! - a status is one of fmi2OK, fmi2Warning, fmi2Discard, fmi2Error (never fmi2Fatal or fmi2Pending);
//! - a call the state machine forbids returns fmi2Error (`Call::allowed_in`); fmi2Error leaves the instance
//!   in the error state; the API never enters start/end, step in progress/failed/canceled or fatal;
//! - every fmi2Error on an instance logs its reason under logStatusError, "<fmi2Name>: ..."; the logger
//!   always gets a format without conversions ('%' doubled), a declared category and the instance's name;
//! - no get/set returns fmi2OK when a value reference is unknown (for the FMU and the type);
//! - after fmi2OK from fmi2GetReal every value is finite; from fmi2GetBoolean 0 or 1; from fmi2GetString
//!   valid UTF-8 C strings;
//! - an FMU state of the other FMU, a strict prefix of a serialised state and an empty byte string are
//!   refused; what fmi2SerializeFMUstate wrote deserialises again on the same FMU.
//!
//! Three known FMI-layer bugs break invariants now and then (non-finite outputs answered fmi2OK, an FMU's own
//! state refused, a panic caught inside the layer after a forged plant state): the default run counts and
//! prints them; `random_call_sequences_strict` and the small deterministic tests at the end (all ignored until
//! the bugs are fixed) fail on them.
//!
//! Out of scope: a dangling or foreign component pointer, and arrays shorter than nvr, are undefined
//! behaviour by the standard's contract (the importer's side), so they are never passed.
//!
//! Budget: `FMI_FUZZ_CALLS` calls per FMU (default 120,000 in release, 15,000 in a debug build),
//! `FMI_FUZZ_SEED` the first seed. The seed and the last calls are printed on failure.
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

use backlash::fmi::fmu_state::SavedState;
use backlash::fmi::instance::Instance;
use backlash::fmi::state::State;
use backlash::fmi::vars::{Causality, VarType};
use backlash::fmi2::exports::*;
use backlash::fmi2::ffi::*;
use backlash::fmi2::state::Call;
use rand_chacha::ChaCha8Rng;
use rand_core::{Rng, SeedableRng};
use std::collections::VecDeque;
use std::ffi::{CStr, c_char};
use std::ptr::{null, null_mut};
use std::time::Instant;

// ------------------------------------------------------------------------------------------------ logger

use common::{Entry, Kind, Sink, callbacks};

// ------------------------------------------------------------------------------------------------- model

struct Slot {
    c: Fmi2Component,
    kind: Kind,
    /// None: instantiated without a logger.
    sink: Option<Box<Sink>>,
    name: String,
}

impl Slot {
    fn inst(&self) -> &Instance {
        // SAFETY: c is a live instance made by this library.
        unsafe { &*(self.c as *const Instance) }
    }
    fn state(&self) -> State {
        self.inst().layer.state
    }
    fn log_len(&self) -> usize {
        self.sink.as_ref().map_or(0, |s| s.lock().unwrap().len())
    }
    fn log_since(&self, n: usize) -> Vec<Entry> {
        self.sink
            .as_ref()
            .map_or(Vec::new(), |s| s.lock().unwrap()[n..].to_vec())
    }
    fn trim_log(&self) {
        if let Some(s) = &self.sink {
            s.lock().unwrap().clear();
        }
    }
}

/// A saved FMU state, the FMU it came from and the instance that issued it (the only one that accepts it).
struct Saved {
    ptr: Fmi2FmuState,
    kind: Kind,
    owner: Fmi2Component,
}

/// Serialised bytes and the FMU they came from.
struct Blob {
    bytes: Vec<u8>,
    kind: Kind,
}

/// What one call did, for the checks after it.
struct CallDid<'a> {
    call: Call,
    status: Option<u32>,
    pre: State,
    post: State,
    /// The log lines the call wrote.
    new_log: &'a [Entry],
    /// The instance has a logger (else it logs nothing).
    has_sink: bool,
}

/// What bytes handed to fmi2DeSerializeFMUstate are, and so what must happen to them.
#[derive(Debug, PartialEq)]
enum What {
    Intact(Kind),
    Truncated,
    Corrupted,
    /// Still valid JSON: one number replaced by another (the checks beyond the syntax).
    Perturbed,
    Random,
    Empty,
    NullHuge,
}

/// Why `inst` refuses the state `bytes`, and where each offending value sits (serde_json writes NaN and
/// infinities as null).
fn refusal_reason(inst: &Instance, bytes: &[u8]) -> String {
    let mut reason = inst.check_state_bytes(bytes).err().unwrap_or_default();
    let text = String::from_utf8_lossy(bytes).into_owned();
    for (at, _) in text
        .match_indices("null")
        .filter(|(at, _)| !text[..*at].ends_with("\"stop_time\":"))
    {
        reason.push_str(&format!(
            " | ...{}",
            &text[at.saturating_sub(90)..(at + 4).min(text.len())]
        ));
    }
    reason
}

#[derive(Default, Debug)]
struct Stats {
    calls: [u64; 2],
    ok: u64,
    error: u64,
    discard: u64,
    steps_ok: u64,
    instantiations: u64,
    states_restored: u64,
    deserialized: u64,
    internal_errors: u64,
    max_time: f64,
    /// Known FMI-layer bugs hit (counted unless strict): fmi2OK from fmi2GetReal with a non-finite value,
    /// and an FMU state this FMU serialised refused by it; per FMU (plant, estimator).
    nonfinite_get: [u64; 2],
    own_state_refused: [u64; 2],
    first_known_bug: Option<String>,
    first_panic: Option<String>,
}

struct Fuzzer {
    rng: ChaCha8Rng,
    slots: Vec<Option<Slot>>,
    states: Vec<Saved>,
    blobs: Vec<Blob>,
    stats: Stats,
    trace: VecDeque<String>,
    seed: u64,
    step: u64,
    /// Probability that a call is drawn from all 34 rather than from the happy path of the state.
    chaos: f64,
    /// This call's arguments are to be valid (most happy-path calls).
    valid: bool,
    /// Known bugs fail the run (else they are counted).
    strict: bool,
}

const SLOTS: usize = 4;
const STATUS_NAMES: [&str; 6] = ["OK", "Warning", "Discard", "Error", "Fatal", "Pending"];
const OK: u32 = 0;
const ERROR: u32 = 3;
const DISCARD: u32 = 2;

impl Fuzzer {
    fn new(seed: u64) -> Self {
        Fuzzer {
            rng: ChaCha8Rng::seed_from_u64(seed),
            slots: (0..SLOTS).map(|_| None).collect(),
            states: Vec::new(),
            blobs: Vec::new(),
            stats: Stats::default(),
            trace: VecDeque::new(),
            seed,
            step: 0,
            // Episodes differ in how wild they are: mostly-valid runs get deep into a simulation, wild ones
            // hit the refusals.
            chaos: [0.03, 0.1, 0.3, 0.6][(seed % 4) as usize],
            valid: false,
            strict: false,
        }
    }

    // -------------------------------------------------------------------------------- random helpers
    fn below(&mut self, n: u64) -> u64 {
        self.rng.next_u64() % n.max(1)
    }
    fn chance(&mut self, p: f64) -> bool {
        self.unit() < p
    }
    fn unit(&mut self) -> f64 {
        (self.rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn pick<T: Copy>(&mut self, xs: &[T]) -> T {
        xs[self.below(xs.len() as u64) as usize]
    }
    fn real(&mut self) -> f64 {
        match self.below(20) {
            0 => f64::NAN,
            1 => f64::INFINITY,
            2 => f64::NEG_INFINITY,
            3 => f64::MAX,
            4 => -f64::MAX,
            5 => 1e300,
            6 => -1e300,
            7 => 5e-324,
            8 => 1e-300,
            9 => -0.0,
            10 => 0.0,
            11 => 1.0,
            12 => -1.0,
            13 => 1e-9,
            14 => (self.unit() - 0.5) * 2e6,
            15 => f64::from_bits(self.rng.next_u64()),
            _ => (self.unit() - 0.5) * 6.0,
        }
    }
    /// An input value for the happy path: moderate, now and then huge (finite, so valid).
    fn input(&mut self) -> f64 {
        if self.chance(0.01) {
            self.pick(&[1e300, -1e300, f64::MAX, -f64::MAX, 1e154])
        } else {
            (self.unit() - 0.5) * 5.0
        }
    }
    fn integer(&mut self) -> i32 {
        match self.below(10) {
            0 => i32::MIN,
            1 => i32::MAX,
            2 => -1,
            3 => 65,
            4 => self.rng.next_u32() as i32,
            _ => self.below(6) as i32,
        }
    }
    fn vrs(&mut self, kind: Kind, ty: VarType) -> Vec<u32> {
        let same: Vec<u32> = kind
            .variables()
            .iter()
            .filter(|v| v.ty == ty)
            .map(|v| v.vr)
            .collect();
        if self.valid {
            let len = if same.is_empty() {
                0
            } else {
                1 + self.below(3) as usize
            };
            return (0..len).map(|_| self.pick(&same)).collect();
        }
        let len = self.pick(&[0usize, 1, 1, 1, 2, 3, 5, 8]);
        let all: Vec<u32> = kind.variables().iter().map(|v| v.vr).collect();
        (0..len)
            .map(|_| match self.below(10) {
                0 => self.pick(&all),
                1 => self.pick(&[0u32, 6, 7, 99, 1000, 62, 14]),
                2 => {
                    let r = self.rng.next_u32();
                    self.pick(&[u32::MAX, r])
                }
                _ if !same.is_empty() => self.pick(&same),
                _ => self.rng.next_u32() % 128,
            })
            .collect()
    }
    /// (nvr, vr NULL?, values NULL?). A huge nvr goes with a NULL vr array only: longer arrays than
    /// given are the importer's undefined behaviour.
    fn shape(&mut self, len: usize) -> (usize, bool, bool) {
        if self.valid {
            return (len, false, false);
        }
        match self.below(20) {
            0 => (0, true, true),
            1 => (len, true, false),
            2 => (len, false, true),
            3 => (
                self.pick(&[usize::MAX, isize::MAX as usize, 1 << 40, (1 << 33) + 1]),
                true,
                self.chance(0.5),
            ),
            4 => (0, false, false),
            _ => (len, false, false),
        }
    }

    fn note(&mut self, s: String) {
        if self.trace.len() == 60 {
            self.trace.pop_front();
        }
        self.trace.push_back(format!("#{} {s}", self.step));
    }

    /// A known FMI-layer bug (see the report in `random_call_sequences_strict`): fail when strict.
    fn known_bug(&mut self, what: &str) {
        if self.strict {
            self.fail(what);
        }
        if self.stats.first_known_bug.is_none() {
            self.stats.first_known_bug =
                Some(format!("seed {}, call {}: {what}", self.seed, self.step));
        }
    }

    fn fail(&self, what: &str) -> ! {
        let trace: Vec<&String> = self.trace.iter().collect();
        panic!(
            "fuzz invariant broken (seed {}, call {}): {what}\nlast calls:\n{}\nstats: {:?}",
            self.seed,
            self.step,
            trace
                .iter()
                .map(|s| s.as_str())
                .collect::<Vec<_>>()
                .join("\n"),
            self.stats
        );
    }

    // ------------------------------------------------------------------------------------ instances
    fn instantiate(&mut self, i: usize) {
        let kind = if self.chance(0.5) {
            Kind::Plant
        } else {
            Kind::Estimator
        };
        let (good_guid, guid) = self.draw_guid(kind);
        let ty = if self.chance(0.95) {
            FMI2_CO_SIMULATION
        } else {
            self.pick(&[FMI2_MODEL_EXCHANGE, 2, u32::MAX])
        };
        let (name_ptr, name_ok) = self.draw_name();
        let cb_mode = self.below(20); // 0: NULL callbacks, 1: no logger, else the recorder
        let sink: Box<Sink> = Box::default();
        let mut cb = callbacks(&sink);
        if cb_mode == 1 {
            cb.logger = None;
        }
        let cbp: *const Fmi2CallbackFunctions = if cb_mode == 0 { null() } else { &cb };
        let c = unsafe {
            fmi2Instantiate(
                name_ptr,
                ty,
                guid,
                null(),
                cbp,
                self.below(2) as i32,
                self.below(2) as i32,
            )
        };
        self.stats.calls[kind.idx()] += 1;
        self.note(format!(
            "fmi2Instantiate(kind {kind:?}, guid ok {good_guid}, type {ty}, name ok {name_ok}, callbacks {cb_mode}) -> {c:?}"
        ));
        let should = good_guid && ty == FMI2_CO_SIMULATION && name_ok && cb_mode != 0;
        if c.is_null() == should {
            self.fail(&format!(
                "fmi2Instantiate returned {c:?}, expected success {should}"
            ));
        }
        if !c.is_null() {
            self.stats.instantiations += 1;
            let name = unsafe { CStr::from_ptr(name_ptr) }
                .to_string_lossy()
                .into_owned();
            let slot = Slot {
                c,
                kind,
                sink: if cb_mode == 1 { None } else { Some(sink) },
                name,
            };
            if slot.state() != State::Instantiated {
                self.fail("a new instance is not in 'instantiated'");
            }
            self.slots[i] = Some(slot);
        } else if cb_mode >= 2 && !sink.lock().unwrap().iter().any(|e| e.status == ERROR) {
            self.fail("a refused fmi2Instantiate logged no reason");
        }
    }

    /// (whether it is `kind`'s, the GUID to instantiate with): mostly `kind`'s, else NULL, empty or wrong.
    fn draw_guid(&mut self, kind: Kind) -> (bool, *const c_char) {
        let good_guid = self.chance(0.93);
        let guid: *const c_char = if good_guid {
            kind.guid().as_ptr()
        } else {
            self.pick(&[
                null(),
                c"".as_ptr(),
                c"{aec9594e-c19e-4bf7-b4ce-9d1bba6d029}".as_ptr(),
                c"BacklashPlant".as_ptr(),
            ])
        };
        (good_guid, guid)
    }

    /// (the instance name to instantiate with, whether it is acceptable): now and then NULL or not UTF-8.
    fn draw_name(&mut self) -> (*const c_char, bool) {
        let names: [&CStr; 5] = [c"a", c"plant-1", c"estimator \u{e9}", c"", c"x"];
        let name_i = self.below(names.len() as u64) as usize;
        let null_name = self.chance(0.03);
        let name_ptr = if null_name {
            null()
        } else if self.chance(0.02) {
            c"\xff\xfe".as_ptr()
        } else {
            names[name_i].as_ptr()
        };
        let name_ok = !null_name
            && unsafe { CStr::from_ptr(name_ptr) }.to_str().is_ok()
            && !unsafe { CStr::from_ptr(name_ptr) }.is_empty();
        (name_ptr, name_ok)
    }

    // ------------------------------------------------------------------------------------ the calls

    /// One random call on slot `i` (or instantiation into it when empty).
    fn one(&mut self) {
        self.step += 1;
        let i = self.below(SLOTS as u64) as usize;
        if self.slots[i].is_none() {
            self.fill(i);
            return;
        }
        let (c, kind, pre) = {
            let s = self.slots[i].as_ref().unwrap();
            (s.c, s.kind, s.state())
        };
        let log0 = self.slots[i].as_ref().unwrap().log_len();
        let call = self.draw_call(kind, pre);
        self.stats.calls[kind.idx()] += 1;
        let (status, desc) = self.perform(i, c, kind, pre, call);
        self.note(format!(
            "[{i} {kind:?} {}] {desc} -> {}",
            pre.name(),
            status.map_or("-".to_string(), |s| STATUS_NAMES
                .get(s as usize)
                .map_or(s.to_string(), |n| n.to_string()))
        ));
        let Some(slot) = self.slots[i].as_ref() else {
            return; // freed
        };
        let post = slot.state();
        let new_log = slot.log_since(log0);
        let has_sink = slot.sink.is_some();
        let logs_discards = slot.inst().log.discards;
        let name = slot.name.clone();
        self.check_log(kind, &name, &new_log);
        let did = CallDid {
            call,
            status,
            pre,
            post,
            new_log: &new_log,
            has_sink,
        };
        if let Some(s) = status {
            self.check_status(&did, s);
        }
        self.check_transition(&did, logs_discards);
        let slot = self.slots[i].as_ref().unwrap();
        if post == State::StepComplete || post == State::Terminated {
            let t = slot.inst().time();
            if t.is_finite() && t > self.stats.max_time {
                self.stats.max_time = t;
            }
        }
        if slot.log_len() > 4096 {
            slot.trim_log();
        }
    }

    /// An empty slot: now and then the component-less functions (and freeing NULL), else an instantiation.
    fn fill(&mut self, i: usize) {
        if self.chance(0.02) {
            unsafe {
                assert_eq!(CStr::from_ptr(fmi2GetTypesPlatform()), c"default");
                assert_eq!(CStr::from_ptr(fmi2GetVersion()), c"2.0");
                fmi2FreeInstance(null_mut());
            }
            return;
        }
        self.instantiate(i);
    }

    /// The next call on an instance of `kind` in `state`: mostly the happy path, `chaos` of the time any of
    /// the 34; sets whether its arguments are to be valid.
    fn draw_call(&mut self, kind: Kind, state: State) -> Call {
        let happy = !self.chance(self.chaos);
        self.valid = happy && !self.chance(0.1);
        let call = if happy {
            self.happy(kind, state)
        } else {
            self.pick(&Call::ALL)
        };
        let call = match call {
            // Not instance functions: keep the draw on the instance.
            Call::GetTypesPlatform | Call::GetVersion | Call::Instantiate => Call::GetRealStatus,
            c => c,
        };
        // Keep the pool of saved states bounded.
        if self.states.len() > 24 && self.chance(0.5) {
            Call::FreeFmuState
        } else {
            call
        }
    }

    /// The log lines a call wrote: formats without conversions, declared categories, the instance's name;
    /// a panic caught inside the layer is counted (and fails the strict run).
    fn check_log(&mut self, kind: Kind, name: &str, new_log: &[Entry]) {
        for e in new_log {
            if e.message.starts_with("<format") {
                self.fail(&format!("logger format: {e:?}"));
            }
            if !kind.categories().contains(&e.category.as_str()) {
                self.fail(&format!("undeclared log category: {e:?}"));
            }
            if e.instance != name {
                self.fail(&format!(
                    "log names instance {:?}, not {name:?}",
                    e.instance
                ));
            }
            if e.message.contains("internal error") {
                self.stats.internal_errors += 1;
                if self.stats.first_panic.is_none() {
                    self.stats.first_panic = Some(format!(
                        "seed {}, call {}: {}",
                        self.seed, self.step, e.message
                    ));
                }
                if self.strict {
                    self.fail(&format!("a panic was caught inside the layer: {e:?}"));
                }
            }
        }
    }

    /// The status `s` of a call: a valid one, fmi2Error for an illegal call, and fmi2Error leaves the
    /// instance in the error state with its reason logged.
    fn check_status(&mut self, did: &CallDid, s: u32) {
        let (call, pre, post) = (did.call, did.pre, did.post);
        match s {
            0 => self.stats.ok += 1,
            2 => self.stats.discard += 1,
            3 => self.stats.error += 1,
            1 => {}
            _ => self.fail(&format!("status {s} from {}", call.name())),
        }
        if !call.allowed_in(pre) && s != ERROR {
            self.fail(&format!(
                "{} is illegal in '{}' but returned {s}",
                call.name(),
                pre.name()
            ));
        }
        if s == ERROR {
            if post != State::Error {
                self.fail(&format!("fmi2Error left the instance in '{}'", post.name()));
            }
            if did.has_sink
                && !did.new_log.iter().any(|e| {
                    e.status == ERROR
                        && e.category == "logStatusError"
                        && e.message.starts_with(&format!("{}: ", call.name()))
                })
            {
                self.fail(&format!(
                    "fmi2Error from {} without a reason: {:?}",
                    call.name(),
                    did.new_log
                ));
            }
        }
    }

    /// The state a call left: step failed only after a step cut short (with its reason logged) or by
    /// restoring a state saved there, and never a state the API does not enter.
    fn check_transition(&self, did: &CallDid, logs_discards: bool) {
        let (call, status, pre, post) = (did.call, did.status, did.pre, did.post);
        // Into step failed only by a step cut short (fmi2Discard), or by restoring a state saved there.
        let entered_failed = post == State::StepFailed && pre != State::StepFailed;
        if (call == Call::DoStep && (status == Some(DISCARD)) != (post == State::StepFailed))
            || (call != Call::DoStep && call != Call::SetFmuState && entered_failed)
        {
            self.fail(&format!(
                "{} returned {status:?} and left the instance in '{}'",
                call.name(),
                post.name()
            ));
        }
        if status == Some(DISCARD)
            && call == Call::DoStep
            && did.has_sink
            && !did.new_log.iter().any(|e| e.category == "logStatusDiscard")
            && logs_discards
        {
            self.fail("fmi2DoStep returned fmi2Discard without a reason");
        }
        if !matches!(
            post,
            State::Instantiated
                | State::InitializationMode
                | State::StepComplete
                | State::StepFailed
                | State::Terminated
                | State::Error
        ) {
            self.fail(&format!("the instance entered '{}'", post.name()));
        }
    }

    /// The call that moves the instance on from `state`.
    fn happy(&mut self, _kind: Kind, state: State) -> Call {
        match state {
            State::Instantiated => self.pick(&[
                Call::SetupExperiment,
                Call::EnterInitializationMode,
                Call::SetReal,
                Call::SetInteger,
            ]),
            State::InitializationMode => self.pick(&[
                Call::ExitInitializationMode,
                Call::ExitInitializationMode,
                Call::SetReal,
                Call::GetReal,
            ]),
            State::StepComplete => match self.below(200) {
                0..=79 => Call::DoStep,
                80..=139 => Call::SetReal,
                140..=164 => Call::GetReal,
                165..=169 => Call::GetBoolean,
                170..=176 => Call::GetFmuState,
                177..=183 => Call::SerializeFmuState,
                184..=190 => Call::SetFmuState,
                191..=194 => Call::DeSerializeFmuState,
                195..=197 => Call::GetRealStatus,
                _ => Call::Terminate,
            },
            State::Terminated => self.pick(&[Call::Reset, Call::GetReal, Call::FreeInstance]),
            _ => self.pick(&[
                Call::Reset,
                Call::SetFmuState,
                Call::SetFmuState,
                Call::SetFmuState,
                Call::DeSerializeFmuState,
                Call::GetReal,
                Call::FreeInstance,
            ]),
        }
    }

    /// Perform `call` with random arguments; returns the status (None for void functions) and a text.
    fn perform(
        &mut self,
        i: usize,
        c: Fmi2Component,
        kind: Kind,
        state: State,
        call: Call,
    ) -> (Option<u32>, String) {
        unsafe {
            match call {
                Call::FreeInstance => self.free_instance(i, c),
                Call::SetDebugLogging => self.set_debug_logging(c),
                Call::SetupExperiment => self.setup_experiment(c),
                Call::EnterInitializationMode => (
                    Some(fmi2EnterInitializationMode(c)),
                    "fmi2EnterInitializationMode".into(),
                ),
                Call::ExitInitializationMode => (
                    Some(fmi2ExitInitializationMode(c)),
                    "fmi2ExitInitializationMode".into(),
                ),
                Call::Terminate => (Some(fmi2Terminate(c)), "fmi2Terminate".into()),
                Call::Reset => (Some(fmi2Reset(c)), "fmi2Reset".into()),
                Call::CancelStep => (Some(fmi2CancelStep(c)), "fmi2CancelStep".into()),
                Call::GetReal | Call::GetInteger | Call::GetBoolean | Call::GetString => {
                    self.get(c, kind, call)
                }
                Call::SetReal | Call::SetInteger | Call::SetBoolean | Call::SetString => {
                    self.set(c, kind, state, call)
                }
                Call::DoStep => self.do_step(c, kind),
                Call::GetStatus => self.get_status(c),
                Call::GetRealStatus => self.get_real_status(c),
                Call::GetIntegerStatus => self.get_integer_status(c),
                Call::GetBooleanStatus => self.get_boolean_status(c),
                Call::GetStringStatus => self.get_string_status(c),
                Call::GetDirectionalDerivative => self.get_directional_derivative(c, kind),
                Call::SetRealInputDerivatives => self.set_real_input_derivatives(c, kind),
                Call::GetRealOutputDerivatives => self.get_real_output_derivatives(c, kind),
                Call::GetFmuState => self.get_state(c, kind),
                Call::SetFmuState => self.set_state(c, kind),
                Call::FreeFmuState => self.free_state(c),
                Call::SerializedFmuStateSize => self.serialized_size(c),
                Call::SerializeFmuState => self.serialize(c),
                Call::DeSerializeFmuState => self.deserialize(c, kind, state),
                Call::GetTypesPlatform | Call::GetVersion | Call::Instantiate => unreachable!(),
            }
        }
    }

    /// fmi2FreeInstance on slot `i`; the states the instance issued go with it.
    unsafe fn free_instance(&mut self, i: usize, c: Fmi2Component) -> (Option<u32>, String) {
        unsafe { fmi2FreeInstance(c) };
        // The instance's FMU states went with it.
        self.states.retain(|s| s.owner != c);
        self.slots[i] = None;
        (None, "fmi2FreeInstance".into())
    }

    /// fmi2SetDebugLogging with declared, undeclared, NULL and non-UTF-8 categories, or a NULL array.
    unsafe fn set_debug_logging(&mut self, c: Fmi2Component) -> (Option<u32>, String) {
        let pool: [*const c_char; 7] = [
            c"logAll".as_ptr(),
            c"logCalls".as_ptr(),
            c"logStatusError".as_ptr(),
            c"logStatusWarning".as_ptr(),
            c"bogus".as_ptr(),
            null(),
            c"\xff".as_ptr(),
        ];
        let n = self.below(4) as usize;
        let cats: Vec<*const c_char> = (0..n).map(|_| self.pick(&pool)).collect();
        let on = self.below(3) as i32;
        let (nc, p) = match self.below(10) {
            0 => (3usize, null()),
            1 => (usize::MAX, null()),
            _ => (cats.len(), cats.as_ptr()),
        };
        let s = unsafe { fmi2SetDebugLogging(c, on, nc, p) };
        (Some(s), format!("fmi2SetDebugLogging(on {on}, n {nc})"))
    }

    /// fmi2SetupExperiment: the happy defaults, or random (often non-finite) times and tolerance.
    unsafe fn setup_experiment(&mut self, c: Fmi2Component) -> (Option<u32>, String) {
        let happy = self.valid || self.chance(0.3);
        let (td, tol, start, sd, stop) = if happy {
            (FMI2_FALSE, 0.0, 0.0, FMI2_FALSE, 0.0)
        } else {
            let start = self.pick(&[0.0, 1.5, -10.0, 0.0]);
            let start = if self.chance(0.2) { self.real() } else { start };
            let stop = if self.chance(0.5) {
                start + self.below(50) as f64
            } else {
                self.real()
            };
            let tol = self.real();
            (self.below(2) as i32, tol, start, self.below(2) as i32, stop)
        };
        let s = unsafe { fmi2SetupExperiment(c, td, tol, start, sd, stop) };
        (
            Some(s),
            format!("fmi2SetupExperiment({td}, {tol:e}, {start:e}, {sd}, {stop:e})"),
        )
    }

    /// fmi2DoStep, mostly at the current time with a step size relative to Ts, else at a wrong time or
    /// with a step size the layer must refuse; then the clock and the samples reached are checked.
    unsafe fn do_step(&mut self, c: Fmi2Component, kind: Kind) -> (Option<u32>, String) {
        let inst = unsafe { &*(c as *const Instance) };
        let ts = inst.slave.sample_period();
        let now = inst.time();
        let t = if self.valid || self.chance(0.85) {
            now
        } else {
            let r = self.real();
            self.pick(&[now + ts, now - ts, f64::NAN, 0.0, now + 0.5 * ts, r])
        };
        let h = self.step_size(kind, ts);
        let samples = inst.layer.samples;
        let s = unsafe { fmi2DoStep(c, t, h, self.below(2) as i32) };
        let inst = unsafe { &*(c as *const Instance) };
        let advanced = inst.layer.samples - samples;
        if s == OK {
            self.stats.steps_ok += 1;
            self.check_step_done(inst, kind, t, h, ts, advanced);
        }
        if s == DISCARD {
            self.check_step_cut(inst, h, ts, advanced);
        }
        (
            Some(s),
            format!("fmi2DoStep(t {t:e} (now {now:e}), h {h:e}, Ts {ts:e})"),
        )
    }

    /// A step size relative to the sample period `ts` (or one the layer refuses): a random h with a tiny Ts
    /// would be billions of samples, which the plant cuts after 1e8 (seconds of work).
    fn step_size(&mut self, kind: Kind, ts: f64) -> f64 {
        match self.below(24) {
            n if self.valid && kind == Kind::Estimator => ts / (1 + n % 4) as f64,
            n if self.valid => ts * [1.0, 2.0, 3.0, 0.5, 0.25][n as usize % 5],
            0 => 0.0,
            1 => -ts,
            2 => f64::NAN,
            3 => f64::INFINITY,
            4 => f64::NEG_INFINITY,
            5 => 0.5 * ts,
            6 => ts * 1e13,
            7 => 5e-324,
            8 => ts * (1.0 + 1e-3),
            9 => ts * (1.0 + 1e-9),
            10 => 2.0 * ts,
            11 => 3.0 * ts,
            12 => ts / 3.0,
            13 => f64::from(ts as f32),
            _ => ts,
        }
    }

    /// After fmi2OK from fmi2DoStep(t, h) with the sample period ts: the clock at t + h, and no more
    /// samples reached than h spans.
    fn check_step_done(&self, inst: &Instance, kind: Kind, t: f64, h: f64, ts: f64, advanced: u64) {
        // The clock follows the master's arithmetic; the samples are the instants reached.
        if inst.time() != t + h {
            self.fail(&format!(
                "fmi2DoStep({t:e}, {h:e}) left the clock at {:e}",
                inst.time()
            ));
        }
        let max = (h / ts).ceil() as u64 + 1;
        if advanced > max || (kind == Kind::Estimator && advanced > 1) {
            self.fail(&format!(
                "fmi2DoStep(h = {h:e}, Ts = {ts:e}) advanced {advanced} samples"
            ));
        }
    }

    /// After fmi2Discard from fmi2DoStep(_, h) with the sample period ts: cut at the model's limit of
    /// samples per step, the clock at the last instant sampled.
    fn check_step_cut(&self, inst: &Instance, h: f64, ts: f64, advanced: u64) {
        let limit = inst.slave.max_samples_per_step();
        let at = inst.layer.start_time + inst.layer.samples as f64 * ts;
        if advanced != limit || inst.time() != at || (h / ts) < limit as f64 * (1.0 - 1e-6) {
            self.fail(&format!(
                "fmi2DoStep(h = {h:e}, Ts = {ts:e}) discarded after {advanced} samples at {:e}",
                inst.time()
            ));
        }
    }

    unsafe fn get_status(&mut self, c: Fmi2Component) -> (Option<u32>, String) {
        let mut v: Fmi2StatusC = 77;
        let kind_ = self.pick(&[0u32, 1, 2, 3, 4, u32::MAX]);
        let p: *mut Fmi2StatusC = if self.chance(0.1) { null_mut() } else { &mut v };
        let s = unsafe { fmi2GetStatus(c, kind_, p) };
        (
            Some(s),
            format!("fmi2GetStatus({kind_}, null {})", p.is_null()),
        )
    }

    unsafe fn get_real_status(&mut self, c: Fmi2Component) -> (Option<u32>, String) {
        let mut v = f64::NAN;
        let kind_ = self.pick(&[2u32, 2, 0, 1, 3, 9]);
        let p: *mut f64 = if self.chance(0.1) { null_mut() } else { &mut v };
        let s = unsafe { fmi2GetRealStatus(c, kind_, p) };
        (Some(s), format!("fmi2GetRealStatus({kind_}) = {v:e}"))
    }

    unsafe fn get_integer_status(&mut self, c: Fmi2Component) -> (Option<u32>, String) {
        let mut v = 0;
        let p: *mut i32 = if self.chance(0.2) { null_mut() } else { &mut v };
        let kind_ = self.pick(&[0u32, 1, 2, 3, 77]);
        (
            Some(unsafe { fmi2GetIntegerStatus(c, kind_, p) }),
            format!("fmi2GetIntegerStatus({kind_})"),
        )
    }

    /// fmi2GetBooleanStatus; a value it answers with fmi2OK is fmi2True or fmi2False.
    unsafe fn get_boolean_status(&mut self, c: Fmi2Component) -> (Option<u32>, String) {
        let mut v = 5;
        let p: *mut i32 = if self.chance(0.1) { null_mut() } else { &mut v };
        let kind_ = self.pick(&[3u32, 3, 0, 1, 2, 8]);
        let s = unsafe { fmi2GetBooleanStatus(c, kind_, p) };
        if s == OK && v != FMI2_FALSE && v != FMI2_TRUE {
            self.fail(&format!("fmi2GetBooleanStatus gave {v}"));
        }
        (Some(s), format!("fmi2GetBooleanStatus({kind_})"))
    }

    unsafe fn get_string_status(&mut self, c: Fmi2Component) -> (Option<u32>, String) {
        let mut v: Fmi2String = null();
        let p: *mut Fmi2String = if self.chance(0.2) { null_mut() } else { &mut v };
        let kind_ = self.pick(&[1u32, 0, 2, 3]);
        (
            Some(unsafe { fmi2GetStringStatus(c, kind_, p) }),
            format!("fmi2GetStringStatus({kind_})"),
        )
    }

    /// The result of a call the FMUs refuse whatever the arguments (`why`: "not provided", "not supported"):
    /// the test fails unless the status is fmi2Error.
    fn must_refuse(&self, s: u32, name: &str, why: &str) -> (Option<u32>, String) {
        if s != ERROR {
            self.fail(&format!("{name} is {why} but did not fail"));
        }
        (Some(s), name.into())
    }

    /// fmi2GetDirectionalDerivative (not provided): fmi2Error whatever the arguments.
    unsafe fn get_directional_derivative(
        &mut self,
        c: Fmi2Component,
        kind: Kind,
    ) -> (Option<u32>, String) {
        let vu = self.vrs(kind, VarType::Real);
        let vk = self.vrs(kind, VarType::Real);
        let dk = vec![1.0; vk.len()];
        let mut du = vec![0.0; vu.len()];
        let s = unsafe {
            fmi2GetDirectionalDerivative(
                c,
                vu.as_ptr(),
                vu.len(),
                vk.as_ptr(),
                vk.len(),
                dk.as_ptr(),
                du.as_mut_ptr(),
            )
        };
        self.must_refuse(s, "fmi2GetDirectionalDerivative", "not provided")
    }

    /// fmi2SetRealInputDerivatives (not supported): fmi2Error whatever the arguments.
    unsafe fn set_real_input_derivatives(
        &mut self,
        c: Fmi2Component,
        kind: Kind,
    ) -> (Option<u32>, String) {
        let v = self.vrs(kind, VarType::Real);
        let order = vec![1; v.len()];
        let val = vec![self.real(); v.len()];
        let s = unsafe {
            fmi2SetRealInputDerivatives(c, v.as_ptr(), v.len(), order.as_ptr(), val.as_ptr())
        };
        self.must_refuse(s, "fmi2SetRealInputDerivatives", "not supported")
    }

    /// fmi2GetRealOutputDerivatives (not supported): fmi2Error whatever the arguments.
    unsafe fn get_real_output_derivatives(
        &mut self,
        c: Fmi2Component,
        kind: Kind,
    ) -> (Option<u32>, String) {
        let v = self.vrs(kind, VarType::Real);
        let order = vec![1; v.len()];
        let mut val = vec![0.0; v.len()];
        let s = unsafe {
            fmi2GetRealOutputDerivatives(c, v.as_ptr(), v.len(), order.as_ptr(), val.as_mut_ptr())
        };
        self.must_refuse(s, "fmi2GetRealOutputDerivatives", "not supported")
    }

    /// fmi2SerializedFMUstateSize of a saved state (or NULL, or into NULL); the size is the state's.
    unsafe fn serialized_size(&mut self, c: Fmi2Component) -> (Option<u32>, String) {
        let mut size = 0usize;
        let st = self.some_state();
        let sp: *mut usize = if self.chance(0.1) {
            null_mut()
        } else {
            &mut size
        };
        let s = unsafe { fmi2SerializedFMUstateSize(c, st, sp) };
        self.check_owner(s, st, c, "fmi2SerializedFMUstateSize");
        if s == OK && size != unsafe { (*(st as *const SavedState)).bytes.len() } {
            self.fail("fmi2SerializedFMUstateSize is wrong");
        }
        (
            Some(s),
            format!("fmi2SerializedFMUstateSize(null state {})", st.is_null()),
        )
    }

    unsafe fn get(&mut self, c: Fmi2Component, kind: Kind, call: Call) -> (Option<u32>, String) {
        let ty = match call {
            Call::GetReal => VarType::Real,
            Call::GetInteger => VarType::Integer,
            Call::GetBoolean => VarType::Boolean,
            _ => VarType::String,
        };
        let vrs = self.vrs(kind, ty);
        let (nvr, vnull, onull) = self.shape(vrs.len());
        let vp = if vnull { null() } else { vrs.as_ptr() };
        let mut r = vec![f64::NAN; vrs.len()];
        let mut n = vec![-77i32; vrs.len()];
        let mut s: Vec<Fmi2String> = vec![null(); vrs.len()];
        let st = unsafe {
            match ty {
                VarType::Real => {
                    fmi2GetReal(c, vp, nvr, if onull { null_mut() } else { r.as_mut_ptr() })
                }
                VarType::Integer => {
                    fmi2GetInteger(c, vp, nvr, if onull { null_mut() } else { n.as_mut_ptr() })
                }
                VarType::Boolean => {
                    fmi2GetBoolean(c, vp, nvr, if onull { null_mut() } else { n.as_mut_ptr() })
                }
                VarType::String => {
                    fmi2GetString(c, vp, nvr, if onull { null_mut() } else { s.as_mut_ptr() })
                }
            }
        };
        let desc = format!(
            "{}(vr {vrs:?}, nvr {nvr}, vr NULL {vnull}, values NULL {onull})",
            call.name()
        );
        if st == OK && nvr > 0 {
            if let Some(&bad) = vrs.iter().find(|&&v| !kind.known(ty, v)) {
                self.fail(&format!(
                    "{desc} returned fmi2OK with the unknown value reference {bad}"
                ));
            }
            match ty {
                VarType::Real => {
                    if let Some(x) = r.iter().find(|x| !x.is_finite()) {
                        let names: Vec<&str> = vrs
                            .iter()
                            .map(|v| {
                                kind.variables()
                                    .iter()
                                    .find(|x| x.vr == *v && x.ty == ty)
                                    .unwrap()
                                    .name
                            })
                            .collect();
                        let what = format!(
                            "{desc} returned fmi2OK with the non-finite value {x} ({names:?} = {r:?})"
                        );
                        self.stats.nonfinite_get[kind.idx()] += 1;
                        self.known_bug(&what);
                    }
                }
                VarType::Boolean => {
                    if n.iter().any(|&b| b != FMI2_TRUE && b != FMI2_FALSE) {
                        self.fail(&format!("{desc}: Boolean values {n:?}"));
                    }
                }
                VarType::String => {
                    for p in &s {
                        if p.is_null() || unsafe { CStr::from_ptr(*p) }.to_str().is_err() {
                            self.fail(&format!("{desc}: bad string"));
                        }
                    }
                }
                VarType::Integer => {}
            }
        }
        (Some(st), desc)
    }

    unsafe fn set(
        &mut self,
        c: Fmi2Component,
        kind: Kind,
        state: State,
        call: Call,
    ) -> (Option<u32>, String) {
        if self.valid && matches!(state, State::Instantiated | State::InitializationMode) {
            return unsafe { self.set_valid_parameter(c, call) };
        }
        // The happy path: a moderate input in step complete.
        if call == Call::SetReal && state == State::StepComplete && (self.valid || self.chance(0.3))
        {
            let u = kind.vr("u");
            let mut vrs = vec![u];
            let mut vals = vec![self.input()];
            if kind == Kind::Estimator {
                vrs.push(kind.vr("y"));
                vals.push(self.input());
            }
            let st = unsafe { fmi2SetReal(c, vrs.as_ptr(), vrs.len(), vals.as_ptr()) };
            return (Some(st), format!("fmi2SetReal(inputs {vals:?})"));
        }
        let ty = match call {
            Call::SetReal => VarType::Real,
            Call::SetInteger => VarType::Integer,
            Call::SetBoolean => VarType::Boolean,
            _ => VarType::String,
        };
        let vrs = self.vrs(kind, ty);
        let (nvr, vnull, onull) = self.shape(vrs.len());
        let vp = if vnull { null() } else { vrs.as_ptr() };
        let reals: Vec<f64> = (0..vrs.len()).map(|_| self.real()).collect();
        let ints: Vec<i32> = (0..vrs.len()).map(|_| self.integer()).collect();
        let bools: Vec<i32> = (0..vrs.len())
            .map(|_| self.pick(&[0, 1, 1, 2, -1]))
            .collect();
        let strs: Vec<Fmi2String> = (0..vrs.len())
            .map(|_| self.pick(&[c"abc".as_ptr(), null(), c"".as_ptr(), c"\xff".as_ptr()]))
            .collect();
        let st = unsafe {
            match ty {
                VarType::Real => {
                    fmi2SetReal(c, vp, nvr, if onull { null() } else { reals.as_ptr() })
                }
                VarType::Integer => {
                    fmi2SetInteger(c, vp, nvr, if onull { null() } else { ints.as_ptr() })
                }
                VarType::Boolean => {
                    fmi2SetBoolean(c, vp, nvr, if onull { null() } else { bools.as_ptr() })
                }
                VarType::String => {
                    fmi2SetString(c, vp, nvr, if onull { null() } else { strs.as_ptr() })
                }
            }
        };
        let vals = match ty {
            VarType::Real => format!("{reals:?}"),
            VarType::Integer => format!("{ints:?}"),
            VarType::Boolean => format!("{bools:?}"),
            VarType::String => "strings".into(),
        };
        let desc = format!(
            "{}(vr {vrs:?}, {vals}, nvr {nvr}, vr NULL {vnull}, values NULL {onull})",
            call.name()
        );
        if st == OK && nvr > 0 {
            if let Some(&bad) = vrs.iter().find(|&&v| !kind.known(ty, v)) {
                self.fail(&format!(
                    "{desc} returned fmi2OK with the unknown value reference {bad}"
                ));
            }
            if ty == VarType::Real && reals.iter().any(|x| !x.is_finite()) {
                self.fail(&format!("{desc} accepted a non-finite value"));
            }
        }
        (Some(st), desc)
    }

    /// Set one input or parameter of type `call` to a valid value: its current value, a Real nudged by up to
    /// 10 % (the white box tells the current value; every range in the descriptions is closed under that).
    unsafe fn set_valid_parameter(
        &mut self,
        c: Fmi2Component,
        call: Call,
    ) -> (Option<u32>, String) {
        let inst = unsafe { &*(c as *const Instance) };
        let ty = match call {
            Call::SetReal => VarType::Real,
            Call::SetInteger => VarType::Integer,
            Call::SetBoolean => VarType::Boolean,
            _ => VarType::String,
        };
        let vars = inst.slave.variables();
        let idx: Vec<usize> = (0..vars.len())
            .filter(|&i| vars[i].ty == ty && vars[i].causality != Causality::Output)
            .collect();
        if idx.is_empty() {
            let st = unsafe { fmi2SetString(c, null(), 0, null()) };
            return (Some(st), format!("{}(nvr 0) as fmi2SetString", call.name()));
        }
        let i = self.pick(&idx);
        let v = &vars[i];
        let cur = inst.slave.get(i);
        let st = unsafe {
            match ty {
                VarType::Real => {
                    let x = if self.chance(0.03) {
                        // Valid, if unwise: an unstable linear block, a steep border, a huge gap.
                        self.pick(&[-2.0, 3.0, 1e6, 1e300])
                    } else {
                        cur.as_real() * (1.0 + 0.2 * (self.unit() - 0.5))
                    };
                    let x = if x.is_finite() { x } else { cur.as_real() };
                    let x = match (v.min, v.max) {
                        (Some(lo), _) if x < lo => lo,
                        (_, Some(hi)) if x > hi => hi,
                        _ => x,
                    };
                    fmi2SetReal(c, &v.vr, 1, &x)
                }
                VarType::Integer => fmi2SetInteger(c, &v.vr, 1, &cur.as_integer()),
                VarType::Boolean => {
                    let b = if self.chance(0.5) {
                        FMI2_TRUE
                    } else {
                        FMI2_FALSE
                    };
                    fmi2SetBoolean(c, &v.vr, 1, &b)
                }
                VarType::String => fmi2SetString(c, null(), 0, null()),
            }
        };
        if st != OK {
            self.fail(&format!(
                "a valid {}('{}') was refused",
                call.name(),
                v.name
            ));
        }
        (Some(st), format!("{}('{}', valid)", call.name(), v.name))
    }

    /// A state function may succeed only on a state the instance `c` issued.
    fn check_owner(&mut self, status: u32, p: Fmi2FmuState, c: Fmi2Component, what: &str) {
        let owner = self.states.iter().find(|s| s.ptr == p).map(|s| s.owner);
        if status == OK && owner != Some(c) {
            self.fail(&format!("{what} accepted a state another instance issued"));
        }
    }

    fn some_state(&mut self) -> Fmi2FmuState {
        if self.states.is_empty() || self.chance(0.05) {
            null_mut()
        } else {
            let j = self.below(self.states.len() as u64) as usize;
            self.states[j].ptr
        }
    }

    unsafe fn get_state(&mut self, c: Fmi2Component, kind: Kind) -> (Option<u32>, String) {
        match self.below(10) {
            0 => {
                let s = unsafe { fmi2GetFMUstate(c, null_mut()) };
                (Some(s), "fmi2GetFMUstate(NULL)".into())
            }
            1 | 2 if !self.states.is_empty() => {
                // Overwrite a state this library returned.
                let j = self.below(self.states.len() as u64) as usize;
                let mut p = self.states[j].ptr;
                let s = unsafe { fmi2GetFMUstate(c, &mut p) };
                if p != self.states[j].ptr {
                    self.fail("fmi2GetFMUstate moved an existing state");
                }
                self.check_owner(s, p, c, "fmi2GetFMUstate (overwrite)");
                if s == OK {
                    self.states[j].kind = kind;
                }
                (Some(s), format!("fmi2GetFMUstate(overwrite #{j})"))
            }
            _ => {
                let mut p: Fmi2FmuState = null_mut();
                let s = unsafe { fmi2GetFMUstate(c, &mut p) };
                if (s == OK) == p.is_null() {
                    self.fail("fmi2GetFMUstate: status and pointer disagree");
                }
                if !p.is_null() {
                    self.states.push(Saved {
                        ptr: p,
                        kind,
                        owner: c,
                    });
                }
                (Some(s), "fmi2GetFMUstate(new)".into())
            }
        }
    }

    unsafe fn set_state(&mut self, c: Fmi2Component, kind: Kind) -> (Option<u32>, String) {
        // Prefer a state of this FMU, for depth.
        let same: Vec<usize> = (0..self.states.len())
            .filter(|&j| self.states[j].kind == kind)
            .collect();
        let (p, from) = if !same.is_empty() && self.chance(0.8) {
            let j = self.pick(&same);
            (self.states[j].ptr, Some(self.states[j].kind))
        } else if !self.states.is_empty() && self.chance(0.9) {
            let j = self.below(self.states.len() as u64) as usize;
            (self.states[j].ptr, Some(self.states[j].kind))
        } else {
            (null_mut(), None)
        };
        let s = unsafe { fmi2SetFMUstate(c, p) };
        self.check_owner(s, p, c, "fmi2SetFMUstate");
        if s == OK {
            self.stats.states_restored += 1;
            if from != Some(kind) {
                self.fail(&format!(
                    "fmi2SetFMUstate accepted a state of {from:?} on {kind:?}"
                ));
            }
        }
        (Some(s), format!("fmi2SetFMUstate(from {from:?})"))
    }

    unsafe fn free_state(&mut self, c: Fmi2Component) -> (Option<u32>, String) {
        match self.below(10) {
            0 => (
                Some(unsafe { fmi2FreeFMUstate(c, null_mut()) }),
                "fmi2FreeFMUstate(NULL)".into(),
            ),
            1 => {
                let mut p: Fmi2FmuState = null_mut();
                (
                    Some(unsafe { fmi2FreeFMUstate(c, &mut p) }),
                    "fmi2FreeFMUstate(&NULL)".into(),
                )
            }
            _ if !self.states.is_empty() => {
                let j = self.below(self.states.len() as u64) as usize;
                let mut p = self.states[j].ptr;
                let s = unsafe { fmi2FreeFMUstate(c, &mut p) };
                self.check_owner(s, self.states[j].ptr, c, "fmi2FreeFMUstate");
                if p.is_null() {
                    self.states.swap_remove(j);
                    if s != OK {
                        self.fail("fmi2FreeFMUstate freed but did not return fmi2OK");
                    }
                } else if s == OK {
                    self.fail("fmi2FreeFMUstate returned fmi2OK but kept the state");
                }
                (Some(s), format!("fmi2FreeFMUstate(#{j})"))
            }
            _ => (
                Some(unsafe { fmi2FreeFMUstate(c, null_mut()) }),
                "fmi2FreeFMUstate(NULL)".into(),
            ),
        }
    }

    unsafe fn serialize(&mut self, c: Fmi2Component) -> (Option<u32>, String) {
        let (st, kind) = if self.states.is_empty() || self.chance(0.05) {
            (null_mut(), None)
        } else {
            let j = self.below(self.states.len() as u64) as usize;
            (self.states[j].ptr, Some(self.states[j].kind))
        };
        let len = if st.is_null() {
            0
        } else {
            unsafe { (*(st as *const SavedState)).bytes.len() }
        };
        let size = match self.below(10) {
            _ if self.valid => len,
            0 => len + 1,
            1 => len.saturating_sub(1),
            2 => 0,
            3 => usize::MAX,
            _ => len,
        };
        // A buffer of exactly `size` bytes, or NULL (never a buffer shorter than size).
        let mut buf = if size <= len + 1 {
            vec![0u8; size]
        } else {
            Vec::new()
        };
        let bp: *mut c_char = if buf.len() == size && (self.valid || !self.chance(0.05)) {
            buf.as_mut_ptr() as *mut c_char
        } else {
            null_mut()
        };
        let s = unsafe { fmi2SerializeFMUstate(c, st, bp, size) };
        self.check_owner(s, st, c, "fmi2SerializeFMUstate");
        if s == OK {
            if size != len {
                self.fail("fmi2SerializeFMUstate accepted a wrong size");
            }
            let bytes = unsafe { &(*(st as *const SavedState)).bytes };
            if size > 0 && buf != *bytes {
                self.fail("fmi2SerializeFMUstate wrote other bytes than the state");
            }
            if self.blobs.len() > 16 {
                self.blobs.swap_remove(0);
            }
            self.blobs.push(Blob {
                bytes: buf,
                kind: kind.unwrap(),
            });
        }
        (
            Some(s),
            format!(
                "fmi2SerializeFMUstate(len {len}, size {size}, buffer NULL {})",
                bp.is_null()
            ),
        )
    }

    unsafe fn deserialize(
        &mut self,
        c: Fmi2Component,
        kind: Kind,
        state: State,
    ) -> (Option<u32>, String) {
        let (bytes, what) = self.draw_bytes(kind);
        let (ptr, size) = match what {
            What::NullHuge => (null(), self.pick(&[1usize, 1 << 40, usize::MAX])),
            What::Empty if self.chance(0.5) => (null(), 0),
            _ => (bytes.as_ptr() as *const c_char, bytes.len()),
        };
        let mut target: Fmi2FmuState = null_mut();
        let (tp, overwrite): (*mut Fmi2FmuState, Option<usize>) = match self.below(10) {
            _ if self.valid => (&mut target, None),
            0 => (null_mut(), None),
            1 | 2 if !self.states.is_empty() => {
                let j = self.below(self.states.len() as u64) as usize;
                target = self.states[j].ptr;
                (&mut target, Some(j))
            }
            _ => (&mut target, None),
        };
        let s = unsafe { fmi2DeSerializeFMUstate(c, ptr, size, tp) };
        let desc = format!("fmi2DeSerializeFMUstate({what:?}, size {size}, into {overwrite:?})");
        if let Some(j) = overwrite {
            self.check_owner(
                s,
                self.states[j].ptr,
                c,
                "fmi2DeSerializeFMUstate (overwrite)",
            );
        }
        if s == OK {
            self.deserialized(c, kind, &what, overwrite, target, &desc);
        } else {
            // (Overwriting a state another instance issued is refused, whatever the bytes.)
            if what == What::Intact(kind)
                && !tp.is_null()
                && Call::DeSerializeFmuState.allowed_in(state)
                && overwrite.is_none_or(|j| self.states[j].owner == c)
            {
                // A state this FMU serialised deserialises again wherever the call is legal.
                self.stats.own_state_refused[kind.idx()] += 1;
                let inst = unsafe { &*(c as *const Instance) };
                let reason = refusal_reason(inst, &bytes);
                self.known_bug(&format!(
                    "{desc}: refused a state this FMU serialised: {reason}"
                ));
            }
            if overwrite.is_none() && !target.is_null() {
                self.fail("fmi2DeSerializeFMUstate failed but returned a state");
            }
        }
        (Some(s), desc)
    }

    /// The bytes to deserialise on an instance of `kind`, and what they are.
    fn draw_bytes(&mut self, kind: Kind) -> (Vec<u8>, What) {
        let own: Vec<usize> = (0..self.blobs.len())
            .filter(|&j| self.blobs[j].kind == kind)
            .collect();
        match self.below(12) {
            _ if self.valid && !own.is_empty() => {
                let j = self.pick(&own);
                (self.blobs[j].bytes.clone(), What::Intact(kind))
            }
            0..=2 if !self.blobs.is_empty() => {
                let j = self.below(self.blobs.len() as u64) as usize;
                (
                    self.blobs[j].bytes.clone(),
                    What::Intact(self.blobs[j].kind),
                )
            }
            5 | 6 if !self.blobs.is_empty() => {
                let j = self.below(self.blobs.len() as u64) as usize;
                let cut = self.below(self.blobs[j].bytes.len() as u64) as usize;
                (self.blobs[j].bytes[..cut].to_vec(), What::Truncated)
            }
            7 | 8 if !self.blobs.is_empty() => (self.corrupted_blob(), What::Corrupted),
            3 | 4 if !self.blobs.is_empty() => (self.perturbed_blob(), What::Perturbed),
            9 => {
                let n = self.below(200) as usize;
                let mut b = vec![0u8; n];
                self.rng.fill_bytes(&mut b);
                (b, What::Random)
            }
            10 => (Vec::new(), What::NullHuge),
            _ => (Vec::new(), What::Empty),
        }
    }

    /// A serialised state with one to three random bytes overwritten (`blobs` is not empty).
    fn corrupted_blob(&mut self) -> Vec<u8> {
        let j = self.below(self.blobs.len() as u64) as usize;
        let mut b = self.blobs[j].bytes.clone();
        for _ in 0..=self.below(3) {
            let k = self.below(b.len() as u64) as usize;
            b[k] = self.rng.next_u32() as u8;
        }
        b
    }

    /// A serialised state with one digit replaced by a number: still valid JSON (`blobs` is not empty).
    fn perturbed_blob(&mut self) -> Vec<u8> {
        let j = self.below(self.blobs.len() as u64) as usize;
        let mut text = String::from_utf8_lossy(&self.blobs[j].bytes).into_owned();
        let digits: Vec<usize> = text
            .char_indices()
            .filter(|(_, c)| c.is_ascii_digit())
            .map(|(i, _)| i)
            .collect();
        if !digits.is_empty() {
            let at = self.pick(&digits);
            let with = self.pick(&[
                "0",
                "1",
                "2",
                "7",
                "99",
                "999",
                "65536",
                "4294967296",
                "1e300",
                "-3",
            ]);
            text.replace_range(at..at + 1, with);
        }
        text.into_bytes()
    }

    /// After fmi2OK from fmi2DeSerializeFMUstate of `what` on an instance of `kind`: the bytes were to be
    /// accepted, and the state landed in place (`overwrite`) or is new.
    fn deserialized(
        &mut self,
        c: Fmi2Component,
        kind: Kind,
        what: &What,
        overwrite: Option<usize>,
        target: Fmi2FmuState,
        desc: &str,
    ) {
        self.stats.deserialized += 1;
        match *what {
            What::Intact(k) if k != kind => {
                self.fail(&format!("{desc}: accepted a state of {k:?} on {kind:?}"))
            }
            What::Truncated | What::Empty | What::NullHuge => {
                self.fail(&format!("{desc}: accepted"))
            }
            _ => {}
        }
        match overwrite {
            Some(j) => {
                if target != self.states[j].ptr {
                    self.fail("fmi2DeSerializeFMUstate moved an existing state");
                }
                self.states[j].kind = kind;
            }
            None => self.states.push(Saved {
                ptr: target,
                kind,
                owner: c,
            }),
        }
    }

    fn teardown(&mut self) {
        // A fresh instance refuses every state (none is its own), then each instance is freed with the states
        // it still holds.
        let sink: Box<Sink> = Box::default();
        let cb = callbacks(&sink);
        unsafe {
            let c = fmi2Instantiate(
                c"sweeper".as_ptr(),
                FMI2_CO_SIMULATION,
                Kind::Plant.guid().as_ptr(),
                null(),
                &cb,
                0,
                0,
            );
            assert!(!c.is_null());
            for mut s in self.states.drain(..) {
                let p = s.ptr;
                assert_eq!(fmi2FreeFMUstate(c, &mut s.ptr), ERROR);
                assert_eq!(
                    s.ptr, p,
                    "a refused fmi2FreeFMUstate must leave the pointer"
                );
            }
            fmi2FreeInstance(c);
            for s in self.slots.iter_mut() {
                if let Some(slot) = s.take() {
                    fmi2FreeInstance(slot.c);
                }
            }
        }
    }
}

fn budget() -> u64 {
    std::env::var("FMI_FUZZ_CALLS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(if cfg!(debug_assertions) {
            15_000
        } else {
            120_000
        })
}

/// Run episodes until both FMUs had `per_fmu` calls; returns the summed statistics.
fn fuzz(per_fmu: u64, first_seed: u64, strict: bool) -> Stats {
    let start = Instant::now();
    let mut total = Stats::default();
    let mut episodes = 0u64;
    // Episodes of a few thousand calls, each with its own seed, until both FMUs had their budget.
    while total.calls[0] < per_fmu || total.calls[1] < per_fmu {
        let seed = first_seed + episodes;
        let mut fz = Fuzzer::new(seed);
        fz.strict = strict;
        for _ in 0..5_000 {
            fz.one();
        }
        fz.teardown();
        let s = fz.stats;
        for k in 0..2 {
            total.calls[k] += s.calls[k];
            total.nonfinite_get[k] += s.nonfinite_get[k];
            total.own_state_refused[k] += s.own_state_refused[k];
        }
        total.ok += s.ok;
        total.error += s.error;
        total.discard += s.discard;
        total.steps_ok += s.steps_ok;
        total.instantiations += s.instantiations;
        total.states_restored += s.states_restored;
        total.deserialized += s.deserialized;
        total.internal_errors += s.internal_errors;
        total.max_time = total.max_time.max(s.max_time);
        if total.first_known_bug.is_none() {
            total.first_known_bug = s.first_known_bug;
        }
        if total.first_panic.is_none() {
            total.first_panic = s.first_panic;
        }
        episodes += 1;
    }
    let secs = start.elapsed().as_secs_f64();
    println!(
        "fuzz: {} episodes, seeds {first_seed}..{}, {} calls on BacklashPlant, {} on MrgiaEstimator in {secs:.2} s; \
         {} fmi2OK ({} steps, {} states restored, {} deserialised), {} fmi2Discard, {} fmi2Error, \
         {} instantiations, {} panics caught inside the layer, latest time reached {:e}",
        episodes,
        first_seed + episodes - 1,
        total.calls[0],
        total.calls[1],
        total.ok,
        total.steps_ok,
        total.states_restored,
        total.deserialized,
        total.discard,
        total.error,
        total.instantiations,
        total.internal_errors,
        total.max_time
    );
    println!(
        "known FMI-layer bugs hit (plant, estimator): fmi2OK with non-finite fmi2GetReal values {:?}, own \
         serialised state refused {:?}; first: {}",
        total.nonfinite_get,
        total.own_state_refused,
        total.first_known_bug.as_deref().unwrap_or("none")
    );
    println!(
        "panics caught inside the layer: {}; first: {}",
        total.internal_errors,
        total.first_panic.as_deref().unwrap_or("none")
    );
    assert!(total.calls[0] >= per_fmu && total.calls[1] >= per_fmu);
    // The sequences went deep: many successful steps and restores, not only refusals.
    assert!(
        total.steps_ok * 20 > total.calls[0] + total.calls[1],
        "fewer than 5 % of the calls were successful steps: {total:?}"
    );
    assert!(total.states_restored > 100, "{total:?}");
    total
}

fn first_seed() -> u64 {
    std::env::var("FMI_FUZZ_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0x5eed)
}

/// Every invariant, strictly: the layer bugs this fuzzer found (non-finite outputs answered with fmi2OK, an
/// FMU's own state refused after NaN/inf crept in, inconsistent plant states accepted and panicking on the
/// next step) are fixed and stay fixed; the small deterministic tests below pin each of them.
#[test]
fn random_call_sequences_over_both_fmus() {
    fuzz(budget(), first_seed(), true);
}

/// The same with a budget of at least 1,000,000 calls per FMU (scripts/compliance.sh runs it).
#[test]
#[ignore = "long: 1,000,000 calls per FMU, run by scripts/compliance.sh"]
fn random_call_sequences_strict() {
    let per_fmu = if cfg!(debug_assertions) {
        budget()
    } else {
        budget().max(1_000_000)
    };
    fuzz(per_fmu, first_seed(), true);
}

/// The known bug in a few lines (see `random_call_sequences_strict`): an unstable but accepted linear block.
#[test]
fn overflowing_plant_is_not_reported_ok() {
    let sink: Box<Sink> = Box::default();
    let cb = callbacks(&sink);
    let k = Kind::Plant;
    unsafe {
        let c = fmi2Instantiate(
            c"p".as_ptr(),
            FMI2_CO_SIMULATION,
            k.guid().as_ptr(),
            null(),
            &cb,
            0,
            0,
        );
        assert_eq!(fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0), OK);
        // x(k) = 2 x(k-1) + 0.8 u(k-1): unstable, and accepted (a1, a2 have no range in the description).
        let (a1, a2, u) = (k.vr("a1"), k.vr("a2"), k.vr("u"));
        assert_eq!(
            fmi2SetReal(c, [a1, a2].as_ptr(), 2, [-2.0, 0.0].as_ptr()),
            OK
        );
        assert_eq!(fmi2EnterInitializationMode(c), OK);
        assert_eq!(fmi2ExitInitializationMode(c), OK);
        let mut last = OK;
        for step in 0..1100 {
            assert_eq!(fmi2SetReal(c, &u, 1, &1.0), OK);
            last = fmi2DoStep(c, step as f64, 1.0, FMI2_TRUE);
            if last != OK {
                break;
            }
        }
        let outs = [k.vr("x"), k.vr("w"), k.vr("y")];
        let mut v = [0.0; 3];
        let got = fmi2GetReal(c, outs.as_ptr(), 3, v.as_mut_ptr());
        let mut st: Fmi2FmuState = null_mut();
        let saved = fmi2GetFMUstate(c, &mut st);
        let restored = if saved == OK {
            fmi2SetFMUstate(c, st)
        } else {
            ERROR
        };
        if !st.is_null() {
            fmi2FreeFMUstate(c, &mut st);
        }
        fmi2FreeInstance(c);
        // Either a step refuses to produce non-finite outputs, or the outputs are finite; and a state the FMU
        // saved with fmi2OK is one it restores.
        assert!(
            last != OK || (got == OK && v.iter().all(|x| x.is_finite())),
            "1100 steps answered fmi2OK and fmi2GetReal gives x, w, y = {v:?}"
        );
        assert!(
            saved != OK || restored == OK,
            "fmi2SetFMUstate refused the state fmi2GetFMUstate just saved"
        );
    }
}

/// An instance of `kind` in step complete, with a recording logger.
unsafe fn running(kind: Kind, sink: &Sink) -> Fmi2Component {
    let cb = callbacks(sink);
    unsafe {
        let c = fmi2Instantiate(
            c"r".as_ptr(),
            FMI2_CO_SIMULATION,
            kind.guid().as_ptr(),
            null(),
            &cb,
            0,
            0,
        );
        assert!(!c.is_null());
        assert_eq!(fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0), OK);
        assert_eq!(fmi2EnterInitializationMode(c), OK);
        assert_eq!(fmi2ExitInitializationMode(c), OK);
        c
    }
}

/// MrgiaEstimator: four valid samples, one with the input at f64::MAX; the outputs stay finite, but the
/// auxiliary model's history x^ becomes inf (b0 * u overflows; the clamp X_CLAMP * (1 + u_max + y_max) is
/// itself inf), so the state fmi2GetFMUstate saves with fmi2OK is refused by fmi2SetFMUstate.
#[test]
fn estimator_state_after_a_huge_input_is_restorable() {
    let k = Kind::Estimator;
    let sink = Sink::default();
    unsafe {
        let c = running(k, &sink);
        let vrs = [k.vr("u"), k.vr("y")];
        let samples = [(0.59, 0.0), (0.0, 2.095), (f64::MAX, 0.0), (0.0, 0.0)];
        for (step, (u, y)) in samples.iter().enumerate() {
            assert_eq!(fmi2SetReal(c, vrs.as_ptr(), 2, [*u, *y].as_ptr()), OK);
            assert_eq!(fmi2DoStep(c, step as f64, 1.0, FMI2_TRUE), OK);
        }
        let mut st: Fmi2FmuState = null_mut();
        assert_eq!(fmi2GetFMUstate(c, &mut st), OK);
        let restored = fmi2SetFMUstate(c, st);
        let log = sink.lock().unwrap().last().map(|e| e.message.clone());
        fmi2FreeFMUstate(c, &mut st);
        fmi2FreeInstance(c);
        assert_eq!(restored, OK, "its own state refused: {log:?}");
    }
}

/// BacklashPlant: a deserialised state is not validated beyond its syntax (the estimator's is, by
/// `TryFrom<MrgiaState>`), so valid JSON with an out-of-range history index is accepted, and the next
/// fmi2DoStep panics inside the layer (caught: fmi2Error "internal error: index out of bounds", with the
/// panic message and backtrace on the importer's stderr).
#[test]
fn forged_plant_state_is_refused_at_deserialisation() {
    let k = Kind::Plant;
    let sink = Sink::default();
    unsafe {
        let c = running(k, &sink);
        assert_eq!(fmi2DoStep(c, 0.0, 1.0, FMI2_TRUE), OK);
        let mut st: Fmi2FmuState = null_mut();
        assert_eq!(fmi2GetFMUstate(c, &mut st), OK);
        let mut size = 0usize;
        assert_eq!(fmi2SerializedFMUstateSize(c, st, &mut size), OK);
        let mut bytes = vec![0u8; size];
        assert_eq!(
            fmi2SerializeFMUstate(c, st, bytes.as_mut_ptr() as *mut c_char, size),
            OK
        );
        fmi2FreeFMUstate(c, &mut st);
        let text = String::from_utf8(bytes).unwrap();
        let at = text
            .find("\"head\":")
            .expect("a history in the plant state");
        let end = at
            + 7
            + text[at + 7..]
                .find(|ch: char| !ch.is_ascii_digit())
                .unwrap();
        let forged = format!("{}\"head\":999{}", &text[..at], &text[end..]);
        let mut st2: Fmi2FmuState = null_mut();
        let r =
            fmi2DeSerializeFMUstate(c, forged.as_ptr() as *const c_char, forged.len(), &mut st2);
        let mut stepped = None;
        if r == OK {
            assert_eq!(fmi2SetFMUstate(c, st2), OK);
            fmi2FreeFMUstate(c, &mut st2);
            let s = fmi2DoStep(c, 1.0, 1.0, FMI2_TRUE);
            stepped = Some((s, sink.lock().unwrap().last().map(|e| e.message.clone())));
        }
        fmi2FreeInstance(c);
        assert_eq!(
            r, ERROR,
            "a plant state with history head 999 was accepted; then fmi2DoStep: {stepped:?}"
        );
    }
}
