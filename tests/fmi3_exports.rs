//! The FMI 3.0 co-simulation exports, called in-process (the crate is also an rlib), on both FMUs.
//!
//! 1. The state table: for every exported function that works on an instance and every state an instance
//!    can be in (instantiated, initialization mode, step mode, step failed — forced, white box, as in
//!    tests/fmi_state_machine.rs —, terminated, error), a fresh instance is driven into the state and the
//!    function is called with valid arguments. An illegal call is fmi3Error with exactly
//!    "<fmi3Name>: illegal call in state '<state>' of instance '<name>'" under logStatusError and leaves the
//!    error state; a function the FMUs do not provide is fmi3Error everywhere with its own reason; a legal
//!    call is fmi3OK and moves the instance where the standard says.
//! 2. Random call sequences with hostile arguments (NULL pointers, counts that disagree, unknown value
//!    references, non-finite times, FMU states the instance did not issue): every status is one of
//!    fmi3OK .. fmi3Error, every fmi3Error logs its reason under the call's name, and no call panics.
//!    `FMI3_FUZZ_CALLS` sets the calls per FMU (scripts/leak_check.sh runs it under valgrind).
//! 3. The same step sequence through the FMI 2.0 and the FMI 3.0 exports gives bit-identical outputs.
//!
//! The FMI 3.0 logger is not variadic, so the recorder here is an ordinary `extern "C"` function.
#![allow(
    clippy::undocumented_unsafe_blocks,
    clippy::multiple_unsafe_ops_per_block,
    reason = "the tests call the exported FMI functions directly, many with hostile arguments on purpose: \
              what each call passes and why is the test itself"
)]

use crate::common;

use backlash::fmi::instance::Instance;
use backlash::fmi::state::{Api, State};
use backlash::fmi::vars::VarType;
use backlash::fmi3::exports::*;
use backlash::fmi3::ffi::*;
use backlash::fmi3::state::Call;
use common::Kind;
use common::forge::{StateApi, forged_states_are_refused};
use std::ffi::{CStr, CString, c_char, c_void};
use std::ptr::{null, null_mut};
use std::sync::Mutex;

type Sink = Mutex<Vec<(u32, String, String)>>;

unsafe extern "C" fn record(
    env: Fmi3InstanceEnvironment,
    status: Fmi3StatusC,
    category: Fmi3String,
    message: Fmi3String,
) {
    let s = |p: *const c_char| {
        if p.is_null() {
            "<NULL>".to_string()
        } else {
            unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
        }
    };
    if env.is_null() {
        return;
    }
    let sink = unsafe { &*(env as *const Sink) };
    if let Ok(mut v) = sink.lock() {
        v.push((status, s(category), s(message)));
    }
}

struct Fmu {
    c: Fmi3Instance,
    sink: Box<Sink>,
    name: String,
}

impl Fmu {
    fn new(kind: Kind, name: &str) -> Fmu {
        let sink: Box<Sink> = Box::default();
        let cname = CString::new(name).unwrap();
        let token = kind.guid();
        let c = unsafe {
            fmi3InstantiateCoSimulation(
                cname.as_ptr(),
                token.as_ptr(),
                null(),
                FMI3_FALSE,
                FMI3_FALSE,
                FMI3_FALSE,
                FMI3_FALSE,
                null(),
                0,
                &*sink as *const Sink as *mut c_void,
                Some(record),
                None,
            )
        };
        assert!(
            !c.is_null(),
            "fmi3InstantiateCoSimulation({kind:?}) returned NULL"
        );
        Fmu {
            c,
            sink,
            name: name.to_string(),
        }
    }
    fn state(&self) -> State {
        unsafe { (*(self.c as *const Instance)).layer.state }
    }
    fn force(&self, s: State) {
        unsafe { (*(self.c as *mut Instance)).layer.state = s }
    }
    fn log_len(&self) -> usize {
        self.sink.lock().unwrap().len()
    }
    fn last_log(&self) -> Option<(u32, String, String)> {
        self.sink.lock().unwrap().last().cloned()
    }
    fn enter(&self) -> u32 {
        unsafe { fmi3EnterInitializationMode(self.c, FMI3_FALSE, 0.0, 0.0, FMI3_FALSE, 0.0) }
    }
    fn exit(&self) -> u32 {
        unsafe { fmi3ExitInitializationMode(self.c) }
    }
    /// Drive a fresh instance into `s` (StepFailed and the states the API cannot reach are forced).
    fn drive(&self, s: State) {
        match s {
            State::Instantiated => {}
            State::InitializationMode => assert_eq!(self.enter(), 0),
            State::StepComplete => {
                assert_eq!(self.enter(), 0);
                assert_eq!(self.exit(), 0);
            }
            State::Terminated => {
                self.drive(State::StepComplete);
                assert_eq!(unsafe { fmi3Terminate(self.c) }, 0);
            }
            State::Error => {
                // An unsupported call is fmi3Error, which the standard's error state follows.
                assert_eq!(unsafe { fmi3EnterEventMode(self.c) }, 3);
            }
            other => {
                self.drive(State::StepComplete);
                self.force(other);
            }
        }
        assert_eq!(self.state(), s);
    }
    /// The instance's clock (white box, so that reading it never counts as a call).
    fn time(&self) -> f64 {
        unsafe { (*(self.c as *const Instance)).layer.time }
    }
}

impl Drop for Fmu {
    fn drop(&mut self) {
        if !self.c.is_null() {
            unsafe { fmi3FreeInstance(self.c) };
        }
    }
}

/// The functions answered "not provided" wherever they are called.
fn not_provided(call: Call) -> bool {
    use Call::*;
    matches!(
        call,
        EnterEventMode
            | GetNumberOfVariableDependencies
            | GetVariableDependencies
            | GetDirectionalDerivative
            | GetAdjointDerivative
            | EnterConfigurationMode
            | ExitConfigurationMode
            | GetIntervalDecimal
            | GetIntervalFraction
            | GetShiftDecimal
            | GetShiftFraction
            | SetIntervalDecimal
            | SetIntervalFraction
            | SetShiftDecimal
            | SetShiftFraction
            | EvaluateDiscreteStates
            | UpdateDiscreteStates
            | EnterStepMode
            | GetOutputDerivatives
            | EnterContinuousTimeMode
            | CompletedIntegratorStep
            | SetTime
            | SetContinuousStates
            | GetContinuousStateDerivatives
            | GetEventIndicators
            | GetContinuousStates
            | GetNominalsOfContinuousStates
            | GetNumberOfEventIndicators
            | GetNumberOfContinuousStates
            | ActivateModelPartition
    )
}

/// Call `call` on `f` with valid arguments; FMU states it needs are taken from `f` itself just before.
fn call_valid(f: &mut Fmu, kind: Kind, call: Call) -> u32 {
    match call {
        Call::GetVersion
        | Call::InstantiateCoSimulation
        | Call::InstantiateModelExchange
        | Call::InstantiateScheduledExecution => unreachable!("not a call on an instance"),
        c if not_provided(c) => call_not_provided(f.c, c),
        Call::SetDebugLogging
        | Call::FreeInstance
        | Call::EnterInitializationMode
        | Call::ExitInitializationMode
        | Call::Terminate
        | Call::Reset
        | Call::DoStep => call_lifecycle(f, call),
        Call::GetFmuState => get_and_free_fmu_state(f.c),
        Call::SetFmuState
        | Call::FreeFmuState
        | Call::SerializedFmuStateSize
        | Call::SerializeFmuState
        | Call::DeserializeFmuState => call_on_own_fmu_state(f, call),
        _ => call_get_set(f.c, kind, call),
    }
}

/// The calls that move an instance through its life (and fmi3SetDebugLogging), with valid arguments.
fn call_lifecycle(f: &mut Fmu, call: Call) -> u32 {
    let c = f.c;
    let (mut b1, mut b2, mut b3, mut t) = (0u8, 0u8, 0u8, 0.0f64);
    unsafe {
        match call {
            Call::SetDebugLogging => fmi3SetDebugLogging(c, FMI3_TRUE, 0, null()),
            Call::FreeInstance => {
                fmi3FreeInstance(c);
                f.c = null_mut();
                0
            }
            Call::EnterInitializationMode => f.enter(),
            Call::ExitInitializationMode => f.exit(),
            Call::Terminate => fmi3Terminate(c),
            Call::Reset => fmi3Reset(c),
            Call::DoStep => {
                let now = f.time();
                fmi3DoStep(c, now, 1.0, FMI3_TRUE, &mut b1, &mut b2, &mut b3, &mut t)
            }
            other => unreachable!("{} is not a lifecycle call", other.name()),
        }
    }
}

/// A getter or setter with valid arguments: one variable of the types the FMUs have (if the FMU has one; an
/// input for fmi3SetFloat64), no variable for the other types.
fn call_get_set(c: Fmi3Instance, kind: Kind, call: Call) -> u32 {
    let (mut x, mut i, mut b) = (0.0f64, 0i32, 0u8);
    let one = |vr: Option<u32>| (vr.unwrap_or(0), usize::from(vr.is_some()));
    unsafe {
        match call {
            Call::GetFloat64 => {
                let (vr, n) = one(kind.any(VarType::Real));
                fmi3GetFloat64(c, &vr, n, &mut x, n)
            }
            Call::GetInt32 => {
                let (vr, n) = one(kind.any(VarType::Integer));
                fmi3GetInt32(c, &vr, n, &mut i, n)
            }
            Call::GetBoolean => {
                let (vr, n) = one(kind.any(VarType::Boolean));
                fmi3GetBoolean(c, &vr, n, &mut b, n)
            }
            Call::SetFloat64 => fmi3SetFloat64(c, &kind.input(), 1, &0.25, 1),
            Call::SetInt32 => fmi3SetInt32(c, null(), 0, null(), 0),
            Call::SetBoolean => fmi3SetBoolean(c, null(), 0, null(), 0),
            other => call_get_set_empty(c, other),
        }
    }
}

/// A getter or setter of a type the FMUs have no variable of: the valid call is the empty one.
fn call_get_set_empty(c: Fmi3Instance, call: Call) -> u32 {
    unsafe {
        match call {
            Call::GetFloat32 => fmi3GetFloat32(c, null(), 0, null_mut(), 0),
            Call::GetInt8 => fmi3GetInt8(c, null(), 0, null_mut(), 0),
            Call::GetUInt8 => fmi3GetUInt8(c, null(), 0, null_mut(), 0),
            Call::GetInt16 => fmi3GetInt16(c, null(), 0, null_mut(), 0),
            Call::GetUInt16 => fmi3GetUInt16(c, null(), 0, null_mut(), 0),
            Call::GetUInt32 => fmi3GetUInt32(c, null(), 0, null_mut(), 0),
            Call::GetInt64 => fmi3GetInt64(c, null(), 0, null_mut(), 0),
            Call::GetUInt64 => fmi3GetUInt64(c, null(), 0, null_mut(), 0),
            Call::GetString => fmi3GetString(c, null(), 0, null_mut(), 0),
            Call::GetBinary => fmi3GetBinary(c, null(), 0, null_mut(), null_mut(), 0),
            Call::GetClock => fmi3GetClock(c, null(), 0, null_mut()),
            Call::SetFloat32 => fmi3SetFloat32(c, null(), 0, null(), 0),
            Call::SetInt8 => fmi3SetInt8(c, null(), 0, null(), 0),
            Call::SetUInt8 => fmi3SetUInt8(c, null(), 0, null(), 0),
            Call::SetInt16 => fmi3SetInt16(c, null(), 0, null(), 0),
            Call::SetUInt16 => fmi3SetUInt16(c, null(), 0, null(), 0),
            Call::SetUInt32 => fmi3SetUInt32(c, null(), 0, null(), 0),
            Call::SetInt64 => fmi3SetInt64(c, null(), 0, null(), 0),
            Call::SetUInt64 => fmi3SetUInt64(c, null(), 0, null(), 0),
            Call::SetString => fmi3SetString(c, null(), 0, null(), 0),
            Call::SetBinary => fmi3SetBinary(c, null(), 0, null(), null(), 0),
            Call::SetClock => fmi3SetClock(c, null(), 0, null()),
            other => unreachable!("{} has no valid call in this table", other.name()),
        }
    }
}

/// fmi3GetFMUState, and the state freed again if it was taken.
fn get_and_free_fmu_state(c: Fmi3Instance) -> u32 {
    unsafe {
        let mut s = null_mut();
        let st = fmi3GetFMUState(c, &mut s);
        if st == 0 {
            assert_eq!(fmi3FreeFMUState(c, &mut s), 0);
        }
        st
    }
}

/// A call on an FMU state `f` issued just before (set, free, size, serialise, deserialise); where the
/// instance cannot issue one, fmi3SetFMUState(NULL) in the state it was in.
fn call_on_own_fmu_state(f: &Fmu, call: Call) -> u32 {
    let c = f.c;
    unsafe {
        let before = f.state();
        let mut s = null_mut();
        // Taking a state is legal in every state these tests reach except the forced ones.
        if fmi3GetFMUState(c, &mut s) != 0 {
            f.force(before);
            return fmi3SetFMUState(c, null_mut());
        }
        let mut size = 0usize;
        let st = match call {
            Call::SetFmuState => fmi3SetFMUState(c, s),
            Call::FreeFmuState => fmi3FreeFMUState(c, &mut s),
            Call::SerializedFmuStateSize => fmi3SerializedFMUStateSize(c, s, &mut size),
            Call::SerializeFmuState => {
                assert_eq!(fmi3SerializedFMUStateSize(c, s, &mut size), 0);
                let mut buf = vec![0u8; size];
                fmi3SerializeFMUState(c, s, buf.as_mut_ptr(), size)
            }
            _ => deserialize_and_free(c, s),
        };
        if !s.is_null() {
            fmi3FreeFMUState(c, &mut s);
        }
        st
    }
}

/// fmi3DeserializeFMUState of what `s` serialises to; the new state is freed again.
fn deserialize_and_free(c: Fmi3Instance, s: Fmi3FmuState) -> u32 {
    unsafe {
        let mut size = 0usize;
        assert_eq!(fmi3SerializedFMUStateSize(c, s, &mut size), 0);
        let mut buf = vec![0u8; size];
        assert_eq!(fmi3SerializeFMUState(c, s, buf.as_mut_ptr(), size), 0);
        let mut other = null_mut();
        let st = fmi3DeserializeFMUState(c, buf.as_ptr(), size, &mut other);
        if st == 0 {
            fmi3FreeFMUState(c, &mut other);
        }
        st
    }
}

/// A function the FMUs do not provide (`not_provided`), with arguments as valid as its signature allows.
fn call_not_provided(c: Fmi3Instance, call: Call) -> u32 {
    let (mut b, mut b1, mut b2, mut b3, mut t) = (0u8, 0u8, 0u8, 0u8, 0.0f64);
    let mut n = 0usize;
    unsafe {
        match call {
            Call::EnterEventMode => fmi3EnterEventMode(c),
            Call::GetNumberOfVariableDependencies => {
                fmi3GetNumberOfVariableDependencies(c, 1, &mut n)
            }
            Call::GetVariableDependencies => {
                fmi3GetVariableDependencies(c, 1, null_mut(), null_mut(), null_mut(), null_mut(), 0)
            }
            Call::GetDirectionalDerivative => {
                fmi3GetDirectionalDerivative(c, null(), 0, null(), 0, null(), 0, null_mut(), 0)
            }
            Call::GetAdjointDerivative => {
                fmi3GetAdjointDerivative(c, null(), 0, null(), 0, null(), 0, null_mut(), 0)
            }
            Call::EnterConfigurationMode => fmi3EnterConfigurationMode(c),
            Call::ExitConfigurationMode => fmi3ExitConfigurationMode(c),
            Call::EvaluateDiscreteStates => fmi3EvaluateDiscreteStates(c),
            Call::UpdateDiscreteStates => {
                fmi3UpdateDiscreteStates(c, &mut b1, &mut b2, &mut b3, &mut b, &mut b, &mut t)
            }
            Call::EnterStepMode => fmi3EnterStepMode(c),
            Call::GetOutputDerivatives => {
                fmi3GetOutputDerivatives(c, null(), 0, null(), null_mut(), 0)
            }
            Call::ActivateModelPartition => fmi3ActivateModelPartition(c, 1, 0.0),
            other => call_clock_or_model_exchange(c, other),
        }
    }
}

/// A clock or model-exchange function (none provided), with arguments as valid as its signature allows.
fn call_clock_or_model_exchange(c: Fmi3Instance, call: Call) -> u32 {
    let (mut b1, mut b2) = (0u8, 0u8);
    let mut n = 0usize;
    unsafe {
        match call {
            Call::GetIntervalDecimal => {
                fmi3GetIntervalDecimal(c, null(), 0, null_mut(), null_mut())
            }
            Call::GetIntervalFraction => {
                fmi3GetIntervalFraction(c, null(), 0, null_mut(), null_mut(), null_mut())
            }
            Call::GetShiftDecimal => fmi3GetShiftDecimal(c, null(), 0, null_mut()),
            Call::GetShiftFraction => fmi3GetShiftFraction(c, null(), 0, null_mut(), null_mut()),
            Call::SetIntervalDecimal => fmi3SetIntervalDecimal(c, null(), 0, null()),
            Call::SetIntervalFraction => fmi3SetIntervalFraction(c, null(), 0, null(), null()),
            Call::SetShiftDecimal => fmi3SetShiftDecimal(c, null(), 0, null()),
            Call::SetShiftFraction => fmi3SetShiftFraction(c, null(), 0, null(), null()),
            Call::EnterContinuousTimeMode => fmi3EnterContinuousTimeMode(c),
            Call::CompletedIntegratorStep => fmi3CompletedIntegratorStep(c, 1, &mut b1, &mut b2),
            Call::SetTime => fmi3SetTime(c, 1.0),
            Call::SetContinuousStates => fmi3SetContinuousStates(c, null(), 0),
            Call::GetContinuousStateDerivatives => {
                fmi3GetContinuousStateDerivatives(c, null_mut(), 0)
            }
            Call::GetEventIndicators => fmi3GetEventIndicators(c, null_mut(), 0),
            Call::GetContinuousStates => fmi3GetContinuousStates(c, null_mut(), 0),
            Call::GetNominalsOfContinuousStates => {
                fmi3GetNominalsOfContinuousStates(c, null_mut(), 0)
            }
            Call::GetNumberOfEventIndicators => fmi3GetNumberOfEventIndicators(c, &mut n),
            Call::GetNumberOfContinuousStates => fmi3GetNumberOfContinuousStates(c, &mut n),
            other => unreachable!("{} is provided", other.name()),
        }
    }
}

/// Where a legal call leaves an instance that was in `s`.
fn after(call: Call, s: State) -> Option<State> {
    Some(match call {
        Call::FreeInstance => return None,
        Call::EnterInitializationMode => State::InitializationMode,
        Call::ExitInitializationMode | Call::DoStep => State::StepComplete,
        Call::Terminate => State::Terminated,
        Call::Reset => State::Instantiated,
        _ => s,
    })
}

const STATES: [State; 6] = [
    State::Instantiated,
    State::InitializationMode,
    State::StepComplete,
    State::StepFailed,
    State::Terminated,
    State::Error,
];

#[test]
fn every_call_in_every_state_follows_the_table() {
    let mut failures = Vec::new();
    let mut checked = 0;
    for kind in Kind::ALL {
        for &call in Call::ALL {
            if matches!(
                call,
                Call::GetVersion
                    | Call::InstantiateCoSimulation
                    | Call::InstantiateModelExchange
                    | Call::InstantiateScheduledExecution
            ) {
                continue;
            }
            for s in STATES {
                let mut f = Fmu::new(kind, "table");
                f.drive(s);
                let logged = f.log_len();
                let status = call_valid(&mut f, kind, call);
                checked += 1;
                let ctx = format!("{kind:?} {} in '{}'", call.name(), s.name());
                let legal = call.allowed_in(s);
                if !legal {
                    let want = format!(
                        "{}: illegal call in state '{}' of instance '{}'",
                        call.name(),
                        s.name(),
                        f.name
                    );
                    let last = f.last_log();
                    if status != 3
                        || f.state() != State::Error
                        || last.as_ref().map(|l| (&l.1[..], &l.2[..]))
                            != Some(("logStatusError", &want[..]))
                    {
                        failures.push(format!(
                            "{ctx}: status {status}, state {:?}, log {last:?}",
                            f.state()
                        ));
                    }
                } else if not_provided(call) {
                    let last = f.last_log();
                    if status != 3
                        || f.state() != State::Error
                        || !last.as_ref().is_some_and(|l| {
                            l.2.starts_with(&format!("{}: not provided", call.name()))
                        })
                    {
                        failures.push(format!("{ctx}: status {status}, log {last:?}"));
                    }
                } else {
                    let want = after(call, s);
                    let now = (!f.c.is_null()).then(|| f.state());
                    if status != 0 || now != want || f.log_len() != logged {
                        failures.push(format!(
                            "{ctx}: status {status}, state {now:?} (expected {want:?}), log {:?}",
                            f.last_log()
                        ));
                    }
                }
            }
        }
    }
    assert!(checked > 700, "{checked} calls checked");
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

#[test]
fn instantiation_refusals_log_their_reason_and_return_null() {
    let sink: Sink = Mutex::default();
    co_simulation_refusals_log_their_reason(&sink);
    model_exchange_is_refused_with_its_reason(&sink);
    // No logger at all is allowed in FMI 3.0: the instance works, silently.
    instance_without_a_logger_works();
    assert_eq!(unsafe { CStr::from_ptr(fmi3GetVersion()) }, c"3.0");
}

/// fmi3InstantiateCoSimulation with a foreign token, an empty name, a NULL token and event mode requested:
/// NULL, and the reason logged into `sink`.
fn co_simulation_refusals_log_their_reason(sink: &Sink) {
    let env = sink as *const Sink as *mut c_void;
    let token = Kind::Plant.guid();
    let cases: [(&CStr, *const c_char, u8, &str); 4] = [
        (
            c"p",
            c"{00000000-0000-0000-0000-000000000000}".as_ptr(),
            0,
            "matches none of this binary's FMUs",
        ),
        (c"", token.as_ptr(), 0, "instanceName is empty"),
        (c"p", null(), 0, "instantiationToken is NULL"),
        (c"p", token.as_ptr(), 1, "eventModeUsed is true"),
    ];
    for (name, tok, event_mode, reason) in cases {
        let c = unsafe {
            fmi3InstantiateCoSimulation(
                name.as_ptr(),
                tok,
                null(),
                0,
                0,
                event_mode,
                0,
                null(),
                0,
                env,
                Some(record),
                None,
            )
        };
        assert!(c.is_null(), "{reason}");
        let last = sink.lock().unwrap().last().cloned().unwrap();
        assert!(
            last.2.starts_with("fmi3InstantiateCoSimulation: ") && last.2.contains(reason),
            "{last:?}"
        );
    }
}

/// fmi3InstantiateModelExchange: NULL, "co-simulation only" logged into `sink`.
fn model_exchange_is_refused_with_its_reason(sink: &Sink) {
    let env = sink as *const Sink as *mut c_void;
    let token = Kind::Plant.guid();
    let me = unsafe {
        fmi3InstantiateModelExchange(
            c"p".as_ptr(),
            token.as_ptr(),
            null(),
            0,
            0,
            env,
            Some(record),
        )
    };
    assert!(me.is_null());
    assert!(
        sink.lock()
            .unwrap()
            .last()
            .unwrap()
            .2
            .contains("co-simulation only")
    );
}

/// An instance without a logger (and without an environment) is made and answers calls.
fn instance_without_a_logger_works() {
    let token = Kind::Plant.guid();
    let c = unsafe {
        fmi3InstantiateCoSimulation(
            c"quiet".as_ptr(),
            token.as_ptr(),
            null(),
            0,
            0,
            0,
            0,
            null(),
            0,
            null_mut(),
            None,
            None,
        )
    };
    assert!(!c.is_null());
    assert_eq!(unsafe { fmi3EnterEventMode(c) }, 3);
    unsafe { fmi3FreeInstance(c) };
}

/// Every variable is a scalar: fmi3SetFloat64 and fmi3GetFloat64 with nValues other than nValueReferences
/// are fmi3Error, logged under the call's name with both counts (each on a fresh instance in
/// initialization mode, where both calls are legal).
#[test]
fn value_counts_must_equal_the_references() {
    for kind in Kind::ALL {
        let u = kind.input();
        let (vals, mut out) = ([0.25, 0.75], [0.0; 2]);
        for name in ["fmi3SetFloat64", "fmi3GetFloat64"] {
            let f = Fmu::new(kind, "counts");
            f.drive(State::InitializationMode);
            let code = unsafe {
                if name == "fmi3SetFloat64" {
                    fmi3SetFloat64(f.c, &u, 1, vals.as_ptr(), 2)
                } else {
                    fmi3GetFloat64(f.c, &u, 1, out.as_mut_ptr(), 2)
                }
            };
            assert_eq!(code, 3, "{kind:?} {name}");
            let (status, _, message) = f.last_log().expect("a log line");
            assert_eq!(status, 3, "{message}");
            assert!(
                message.contains(name) && message.contains("nValues = 2 but nValueReferences = 1"),
                "{kind:?}: {message}"
            );
        }
    }
}

/// The FMI 2.0 exports on the same model and inputs, for the bit-for-bit comparison.
fn fmi2_outputs(
    kind: Kind,
    inputs: &[f64],
    h: f64,
    steps_per_sample: usize,
    out: &[u32],
) -> Vec<f64> {
    use backlash::fmi2::exports::*;
    use backlash::fmi2::ffi::*;
    let cb = Fmi2CallbackFunctions {
        logger: None,
        allocate_memory: None,
        free_memory: None,
        step_finished: None,
        component_environment: null_mut(),
    };
    let token = kind.guid();
    let mut values = Vec::new();
    unsafe {
        let c = fmi2Instantiate(
            c"two".as_ptr(),
            FMI2_CO_SIMULATION,
            token.as_ptr(),
            null(),
            &cb,
            0,
            0,
        );
        assert!(!c.is_null());
        assert_eq!(fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0), 0);
        assert_eq!(fmi2EnterInitializationMode(c), 0);
        assert_eq!(fmi2ExitInitializationMode(c), 0);
        let (mut t, u) = (0.0, kind.input());
        for &x in inputs {
            let mut y = vec![0.0; out.len()];
            assert_eq!(fmi2GetReal(c, out.as_ptr(), out.len(), y.as_mut_ptr()), 0);
            values.extend(y);
            assert_eq!(fmi2SetReal(c, &u, 1, &x), 0);
            for _ in 0..steps_per_sample {
                assert_eq!(fmi2DoStep(c, t, h, 1), 0);
                t += h;
            }
        }
        fmi2FreeInstance(c);
    }
    values
}

#[test]
fn fmi3_and_fmi2_exports_give_the_same_bits() {
    for (kind, out) in [
        (Kind::Plant, vec![3u32, 4, 5, 6]),
        (Kind::Estimator, vec![10, 11, 20, 31, 32, 33, 40, 41]),
    ] {
        for steps in [1usize, 3] {
            let h = 1.0 / steps as f64;
            if kind == Kind::Estimator && steps > 1 {
                continue;
            }
            let inputs: Vec<f64> = (0..200).map(|k| (0.37 * k as f64).sin() * 2.0).collect();
            let two = fmi2_outputs(kind, &inputs, h, steps, &out);
            let f = Fmu::new(kind, "three");
            f.drive(State::StepComplete);
            let mut three = Vec::new();
            let (mut t, u) = (0.0, kind.input());
            let (mut e, mut term, mut early, mut last) = (1u8, 1u8, 1u8, f64::NAN);
            for &x in &inputs {
                let mut y = vec![0.0; out.len()];
                assert_eq!(
                    unsafe {
                        fmi3GetFloat64(f.c, out.as_ptr(), out.len(), y.as_mut_ptr(), y.len())
                    },
                    0
                );
                three.extend(y);
                assert_eq!(unsafe { fmi3SetFloat64(f.c, &u, 1, &x, 1) }, 0);
                for _ in 0..steps {
                    let st = unsafe {
                        fmi3DoStep(f.c, t, h, 1, &mut e, &mut term, &mut early, &mut last)
                    };
                    assert_eq!((st, e, term, early), (0, 0, 0, 0));
                    t += h;
                    assert_eq!(last, t);
                }
            }
            assert_eq!(three, two, "{kind:?}, {steps} steps per sample");
        }
    }
}

// ------------------------------------------------------------------------------------- forged FMU states

/// An instance with the FMU it is of, for the forged-state check of tests/common/forge.rs.
struct Forged(Fmu, Kind);

impl StateApi for Forged {
    fn running(kind: Kind, name: &str) -> Forged {
        let f = Fmu::new(kind, name);
        f.drive(State::StepComplete);
        assert_eq!(unsafe { fmi3SetFloat64(f.c, &kind.vr("u"), 1, &0.7, 1) }, 0);
        let mut f = Forged(f, kind);
        assert_eq!(f.step(0.0, 1.0), 0);
        f
    }

    fn save(&mut self) -> Vec<u8> {
        let c = self.0.c;
        let mut s = null_mut();
        unsafe {
            assert_eq!(fmi3GetFMUState(c, &mut s), 0);
            let mut size = 0usize;
            assert_eq!(fmi3SerializedFMUStateSize(c, s, &mut size), 0);
            let mut buf = vec![0u8; size];
            assert_eq!(fmi3SerializeFMUState(c, s, buf.as_mut_ptr(), size), 0);
            assert_eq!(fmi3FreeFMUState(c, &mut s), 0);
            buf
        }
    }

    fn deserialize(&mut self, bytes: &[u8]) -> (u32, String) {
        let mut s = null_mut();
        let st = unsafe { fmi3DeserializeFMUState(self.0.c, bytes.as_ptr(), bytes.len(), &mut s) };
        if st == 0 {
            assert_eq!(unsafe { fmi3FreeFMUState(self.0.c, &mut s) }, 0);
        }
        (st, self.0.last_log().map(|(_, _, m)| m).unwrap_or_default())
    }

    fn restore(&mut self, bytes: &[u8]) {
        let c = self.0.c;
        let mut s = null_mut();
        unsafe {
            assert_eq!(
                fmi3DeserializeFMUState(c, bytes.as_ptr(), bytes.len(), &mut s),
                0
            );
            assert_eq!(fmi3SetFMUState(c, s), 0);
            assert_eq!(fmi3FreeFMUState(c, &mut s), 0);
        }
    }

    fn step(&mut self, t: f64, h: f64) -> u32 {
        let (mut e, mut term, mut early, mut last) = (0u8, 0u8, 0u8, 0.0);
        unsafe { fmi3DoStep(self.0.c, t, h, 1, &mut e, &mut term, &mut early, &mut last) }
    }

    fn reals(&self) -> Vec<f64> {
        let vrs = self.1.all_of(VarType::Real);
        let mut x = vec![f64::NAN; vrs.len()];
        let st =
            unsafe { fmi3GetFloat64(self.0.c, vrs.as_ptr(), vrs.len(), x.as_mut_ptr(), x.len()) };
        assert_eq!(st, 0);
        x
    }
}

/// A real FMU state with one field forged at a time (tests/common/forge.rs): each is refused with fmi3Error
/// and a log line naming the field; the instance keeps its state and, restored, steps like its twin.
#[test]
fn every_forged_field_of_a_state_is_refused_by_name() {
    for kind in Kind::ALL {
        let failures = forged_states_are_refused::<Forged>(kind);
        assert!(failures.is_empty(), "{}", failures.join("\n"));
    }
}

// ----------------------------------------------------------------------------------------------- fuzzing

/// xorshift64*: a small deterministic generator (the sequence is the test; no dependency needed).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
    fn f64(&mut self) -> f64 {
        match self.below(8) {
            0 => f64::NAN,
            1 => f64::INFINITY,
            2 => -1.0,
            3 => 0.0,
            4 => 1e300,
            _ => self.below(1000) as f64 * 0.01,
        }
    }
}

/// The calls the fuzzer draws from: every function on an instance but fmi3FreeInstance.
fn draw_call(rng: &mut Rng) -> Call {
    let calls: Vec<Call> = Call::ALL
        .iter()
        .copied()
        .filter(|c| {
            !matches!(
                c,
                Call::GetVersion
                    | Call::InstantiateCoSimulation
                    | Call::InstantiateModelExchange
                    | Call::InstantiateScheduledExecution
                    | Call::FreeInstance
            )
        })
        .collect();
    calls[rng.below(calls.len() as u64) as usize]
}

/// The value references and values a random getter or setter passes, drawn for every call whichever it is
/// (the draws are the test's sequence).
struct Args {
    vrs: Vec<u32>,
    /// The values' count: the references' count, now and then one more.
    n_values: usize,
    xs: Vec<f64>,
    is: Vec<i32>,
    bs: Vec<u8>,
    /// Pass NULL for the value references.
    null_vr: bool,
}

impl Args {
    fn draw(kind: Kind, rng: &mut Rng) -> Args {
        let vars = kind.variables();
        let mut vrs: Vec<u32> = (0..rng.below(4))
            .map(|_| match rng.below(4) {
                0 => rng.below(300) as u32,
                _ => vars[rng.below(vars.len() as u64) as usize].vr,
            })
            .collect();
        if rng.below(10) == 0 {
            vrs.push(backlash::fmi3::TIME_VR);
        }
        let n = vrs.len();
        let n_values = if rng.below(6) == 0 { n + 1 } else { n };
        let mut xs = vec![0.0f64; n + 1];
        for x in xs.iter_mut() {
            *x = rng.f64();
        }
        let is = vec![rng.below(5) as i32; n + 1];
        let bs = vec![rng.below(3) as u8; n + 1];
        let null_vr = rng.below(8) == 0;
        Args {
            vrs,
            n_values,
            xs,
            is,
            bs,
            null_vr,
        }
    }

    fn vr_ptr(&self) -> *const u32 {
        if self.null_vr {
            null()
        } else {
            self.vrs.as_ptr()
        }
    }
}

/// One random call with random, often hostile, arguments. Arrays are real buffers or NULL; counts may
/// disagree with them only where the pointer is NULL (the layer cannot know a buffer's length, which the
/// standard makes the importer's promise).
fn random_call(
    f: &mut Fmu,
    kind: Kind,
    rng: &mut Rng,
    states: &mut Vec<Fmi3FmuState>,
) -> (Call, u32) {
    let call = draw_call(rng);
    let c = f.c;
    let mut a = Args::draw(kind, rng);
    let (vr, n, nv) = (a.vr_ptr(), a.vrs.len(), a.n_values);
    // Not a state any instance issued: the bytes of the value buffer.
    let bogus: Fmi3FmuState = a.xs.as_mut_ptr().cast();
    let st = unsafe {
        match call {
            Call::GetFloat64 => fmi3GetFloat64(c, vr, n, a.xs.as_mut_ptr(), nv),
            Call::SetFloat64 => fmi3SetFloat64(c, vr, n, a.xs.as_ptr(), nv),
            Call::GetInt32 => fmi3GetInt32(c, vr, n, a.is.as_mut_ptr(), nv),
            Call::SetInt32 => fmi3SetInt32(c, vr, n, a.is.as_ptr(), nv),
            Call::GetBoolean => fmi3GetBoolean(c, vr, n, a.bs.as_mut_ptr(), nv),
            Call::SetBoolean => fmi3SetBoolean(c, vr, n, a.bs.as_ptr(), nv),
            Call::EnterInitializationMode => fmi3EnterInitializationMode(
                c,
                rng.below(2) as u8,
                rng.f64(),
                rng.f64(),
                rng.below(2) as u8,
                rng.f64(),
            ),
            Call::DoStep => random_step(f, rng),
            Call::GetFmuState => random_get_state(c, rng, states),
            Call::SetFmuState => random_set_state(c, rng, states, bogus),
            Call::FreeFmuState => random_free_state(c, rng, states, bogus),
            Call::SerializeFmuState | Call::SerializedFmuStateSize | Call::DeserializeFmuState => {
                random_serialization(c, call, rng, states)
            }
            Call::SetDebugLogging => random_debug_logging(c, rng),
            _ => call_valid(f, kind, call),
        }
    };
    (call, st)
}

/// fmi3DoStep, now and then at a random time and with a random step size or a NULL output pointer.
fn random_step(f: &Fmu, rng: &mut Rng) -> u32 {
    let (mut e, mut t, mut r, mut l) = (0u8, 0u8, 0u8, 0.0);
    let now = if rng.below(4) == 0 {
        rng.f64()
    } else {
        f.time()
    };
    let h = if rng.below(4) == 0 {
        rng.f64()
    } else {
        [1.0, 0.5, 2.0, 0.3][rng.below(4) as usize]
    };
    unsafe {
        if rng.below(10) == 0 {
            fmi3DoStep(f.c, now, h, 0, null_mut(), &mut t, &mut r, &mut l)
        } else {
            fmi3DoStep(f.c, now, h, 0, &mut e, &mut t, &mut r, &mut l)
        }
    }
}

/// fmi3GetFMUState into a new pointer or over a state already issued; a new state joins `states`.
fn random_get_state(c: Fmi3Instance, rng: &mut Rng, states: &mut Vec<Fmi3FmuState>) -> u32 {
    let mut s = if rng.below(3) == 0 && !states.is_empty() {
        states[rng.below(states.len() as u64) as usize]
    } else {
        null_mut()
    };
    let st = unsafe { fmi3GetFMUState(c, &mut s) };
    if st == 0 && !states.contains(&s) {
        states.push(s);
    }
    st
}

/// fmi3SetFMUState of an issued state or of `bogus`.
fn random_set_state(
    c: Fmi3Instance,
    rng: &mut Rng,
    states: &[Fmi3FmuState],
    bogus: Fmi3FmuState,
) -> u32 {
    let s = match (rng.below(3), states.is_empty()) {
        (0, _) | (_, true) => bogus,
        _ => states[rng.below(states.len() as u64) as usize],
    };
    unsafe { fmi3SetFMUState(c, s) }
}

/// fmi3FreeFMUState of an issued state (which leaves `states`) or of `bogus`.
fn random_free_state(
    c: Fmi3Instance,
    rng: &mut Rng,
    states: &mut Vec<Fmi3FmuState>,
    mut bogus: Fmi3FmuState,
) -> u32 {
    unsafe {
        if states.is_empty() || rng.below(4) == 0 {
            fmi3FreeFMUState(c, &mut bogus)
        } else {
            let mut s = states.swap_remove(rng.below(states.len() as u64) as usize);
            fmi3FreeFMUState(c, &mut s)
        }
    }
}

/// The serialisation calls on the first issued state, up to `call`: size, serialise, then deserialise
/// the bytes, now and then corrupted or cut in half (a new state joins `states`).
fn random_serialization(
    c: Fmi3Instance,
    call: Call,
    rng: &mut Rng,
    states: &mut Vec<Fmi3FmuState>,
) -> u32 {
    let s = states.first().copied().unwrap_or(null_mut());
    let mut size = 0;
    let st = unsafe { fmi3SerializedFMUStateSize(c, s, &mut size) };
    if st != 0 || call == Call::SerializedFmuStateSize {
        return st;
    }
    let mut buf = vec![0u8; size];
    let st = unsafe { fmi3SerializeFMUState(c, s, buf.as_mut_ptr(), size) };
    if st != 0 || call == Call::SerializeFmuState {
        return st;
    }
    if rng.below(2) == 0 && size > 0 {
        let k = rng.below(size as u64) as usize;
        buf[k] = buf[k].wrapping_add(1 + rng.below(200) as u8);
    }
    let cut = if rng.below(4) == 0 { size / 2 } else { size };
    let mut out = null_mut();
    let st = unsafe { fmi3DeserializeFMUState(c, buf.as_ptr(), cut, &mut out) };
    if st == 0 {
        states.push(out);
    }
    st
}

/// fmi3SetDebugLogging with known, unknown and NULL categories, or a NULL array.
fn random_debug_logging(c: Fmi3Instance, rng: &mut Rng) -> u32 {
    let cats = [
        c"logAll".as_ptr(),
        c"logCalls".as_ptr(),
        c"nonsense".as_ptr(),
        null(),
    ];
    let k = rng.below(5) as usize;
    let n = k.min(4);
    unsafe {
        fmi3SetDebugLogging(
            c,
            rng.below(2) as u8,
            n,
            if rng.below(8) == 0 {
                null()
            } else {
                cats.as_ptr()
            },
        )
    }
}

fn fuzz(kind: Kind, calls: u64, seed: u64) {
    let mut rng = Rng(seed | 1);
    let mut f = Fmu::new(kind, "fuzz");
    let mut states = Vec::new();
    for i in 0..calls {
        if rng.below(200) == 0 {
            // Start over: the instance goes, with the states it issued.
            states.clear();
            f = Fmu::new(kind, "fuzz");
        }
        let before = f.log_len();
        let (call, st) = random_call(&mut f, kind, &mut rng, &mut states);
        assert!(st <= 3, "{kind:?} call {i} {}: status {st}", call.name());
        let log = f.sink.lock().unwrap()[before..].to_vec();
        assert!(
            log.iter().all(|l| !l.2.contains("internal error")),
            "{kind:?} call {i} {}: {log:?}",
            call.name()
        );
        if st == 3 {
            assert!(
                log.iter().any(|l| l.1 == "logStatusError"),
                "{kind:?} call {i} {}: fmi3Error without a logged reason",
                call.name()
            );
            assert_eq!(f.state(), State::Error, "{kind:?} call {i} {}", call.name());
        }
        if f.state() == State::Error && rng.below(3) == 0 {
            assert_eq!(unsafe { fmi3Reset(f.c) }, 0);
        }
    }
}

#[test]
fn random_call_sequences_over_both_fmus() {
    let calls = std::env::var("FMI3_FUZZ_CALLS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20_000);
    for (k, kind) in Kind::ALL.into_iter().enumerate() {
        fuzz(kind, calls, 0x5eed_0000 + k as u64);
    }
}
