//! The FMI 2.0 co-simulation state machine: which function may be called in which state.
//!
//! The table is that of the standard (FMI 2.0.x, section 4.2.4, "state machine of calling sequence from
//! master to slave"), written as a match so that a missing case is a compile error. `StepInProgress` and
//! `StepCanceled` exist in the standard for asynchronous steps; this implementation steps synchronously, so
//! an instance is never observed in them, but the table keeps them for completeness. The states themselves
//! are the core's ([`State`]).

use super::ffi::{Fmi2Status, Fmi2StatusC};
use crate::fmi::state::{Api, State};
use crate::fmi::status::Status;

/// Every function of the FMI 2.0 co-simulation API.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Call {
    GetTypesPlatform,
    GetVersion,
    SetDebugLogging,
    Instantiate,
    FreeInstance,
    SetupExperiment,
    EnterInitializationMode,
    ExitInitializationMode,
    Terminate,
    Reset,
    GetReal,
    GetInteger,
    GetBoolean,
    GetString,
    SetReal,
    SetInteger,
    SetBoolean,
    SetString,
    GetFmuState,
    SetFmuState,
    FreeFmuState,
    SerializedFmuStateSize,
    SerializeFmuState,
    DeSerializeFmuState,
    GetDirectionalDerivative,
    SetRealInputDerivatives,
    GetRealOutputDerivatives,
    DoStep,
    CancelStep,
    GetStatus,
    GetRealStatus,
    GetIntegerStatus,
    GetBooleanStatus,
    GetStringStatus,
}

impl Call {
    pub const ALL: [Call; 34] = [
        Call::GetTypesPlatform,
        Call::GetVersion,
        Call::SetDebugLogging,
        Call::Instantiate,
        Call::FreeInstance,
        Call::SetupExperiment,
        Call::EnterInitializationMode,
        Call::ExitInitializationMode,
        Call::Terminate,
        Call::Reset,
        Call::GetReal,
        Call::GetInteger,
        Call::GetBoolean,
        Call::GetString,
        Call::SetReal,
        Call::SetInteger,
        Call::SetBoolean,
        Call::SetString,
        Call::GetFmuState,
        Call::SetFmuState,
        Call::FreeFmuState,
        Call::SerializedFmuStateSize,
        Call::SerializeFmuState,
        Call::DeSerializeFmuState,
        Call::GetDirectionalDerivative,
        Call::SetRealInputDerivatives,
        Call::GetRealOutputDerivatives,
        Call::DoStep,
        Call::CancelStep,
        Call::GetStatus,
        Call::GetRealStatus,
        Call::GetIntegerStatus,
        Call::GetBooleanStatus,
        Call::GetStringStatus,
    ];

    /// The C name of the function.
    pub fn name(self) -> &'static str {
        <Self as Api>::name(self)
    }

    /// Whether the standard allows this call in state `s`.
    pub fn allowed_in(self, s: State) -> bool {
        <Self as Api>::allowed_in(self, s)
    }
}

impl Api for Call {
    type Code = Fmi2StatusC;

    fn code(status: Status) -> Fmi2StatusC {
        Fmi2Status::from(status) as Fmi2StatusC
    }

    fn name(self) -> &'static str {
        match self {
            Call::GetTypesPlatform => "fmi2GetTypesPlatform",
            Call::GetVersion => "fmi2GetVersion",
            Call::SetDebugLogging => "fmi2SetDebugLogging",
            Call::Instantiate => "fmi2Instantiate",
            Call::FreeInstance => "fmi2FreeInstance",
            Call::SetupExperiment => "fmi2SetupExperiment",
            Call::EnterInitializationMode => "fmi2EnterInitializationMode",
            Call::ExitInitializationMode => "fmi2ExitInitializationMode",
            Call::Terminate => "fmi2Terminate",
            Call::Reset => "fmi2Reset",
            Call::GetReal => "fmi2GetReal",
            Call::GetInteger => "fmi2GetInteger",
            Call::GetBoolean => "fmi2GetBoolean",
            Call::GetString => "fmi2GetString",
            Call::SetReal => "fmi2SetReal",
            Call::SetInteger => "fmi2SetInteger",
            Call::SetBoolean => "fmi2SetBoolean",
            Call::SetString => "fmi2SetString",
            Call::GetFmuState => "fmi2GetFMUstate",
            Call::SetFmuState => "fmi2SetFMUstate",
            Call::FreeFmuState => "fmi2FreeFMUstate",
            Call::SerializedFmuStateSize => "fmi2SerializedFMUstateSize",
            Call::SerializeFmuState => "fmi2SerializeFMUstate",
            Call::DeSerializeFmuState => "fmi2DeSerializeFMUstate",
            Call::GetDirectionalDerivative => "fmi2GetDirectionalDerivative",
            Call::SetRealInputDerivatives => "fmi2SetRealInputDerivatives",
            Call::GetRealOutputDerivatives => "fmi2GetRealOutputDerivatives",
            Call::DoStep => "fmi2DoStep",
            Call::CancelStep => "fmi2CancelStep",
            Call::GetStatus => "fmi2GetStatus",
            Call::GetRealStatus => "fmi2GetRealStatus",
            Call::GetIntegerStatus => "fmi2GetIntegerStatus",
            Call::GetBooleanStatus => "fmi2GetBooleanStatus",
            Call::GetStringStatus => "fmi2GetStringStatus",
        }
    }

    fn allowed_in(self, s: State) -> bool {
        use State::*;
        match self {
            Call::GetTypesPlatform | Call::GetVersion => s != Fatal,
            Call::SetDebugLogging => !matches!(s, StartEnd | Fatal),
            Call::Instantiate => s == StartEnd,
            Call::FreeInstance
            | Call::Reset
            | Call::GetFmuState
            | Call::SetFmuState
            | Call::FreeFmuState
            | Call::SerializedFmuStateSize
            | Call::SerializeFmuState
            | Call::DeSerializeFmuState => !matches!(s, StartEnd | StepInProgress | Fatal),
            Call::SetupExperiment | Call::EnterInitializationMode => s == Instantiated,
            Call::ExitInitializationMode => s == InitializationMode,
            Call::Terminate => matches!(s, StepComplete | StepFailed),
            Call::GetReal
            | Call::GetInteger
            | Call::GetBoolean
            | Call::GetString
            | Call::GetDirectionalDerivative => matches!(
                s,
                InitializationMode | StepComplete | StepFailed | StepCanceled | Terminated | Error
            ),
            Call::SetReal | Call::SetInteger | Call::SetBoolean | Call::SetString => {
                matches!(s, Instantiated | InitializationMode | StepComplete)
            }
            Call::SetRealInputDerivatives => {
                matches!(s, Instantiated | InitializationMode | StepComplete)
            }
            Call::GetRealOutputDerivatives => {
                matches!(
                    s,
                    StepComplete | StepFailed | StepCanceled | Terminated | Error
                )
            }
            Call::DoStep => s == StepComplete,
            Call::CancelStep => s == StepInProgress,
            Call::GetStatus
            | Call::GetRealStatus
            | Call::GetIntegerStatus
            | Call::GetBooleanStatus
            | Call::GetStringStatus => {
                matches!(s, StepComplete | StepInProgress | StepFailed | Terminated)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_call_has_a_distinct_c_name_with_the_fmi2_prefix() {
        let mut names: Vec<_> = Call::ALL.iter().map(|c| c.name()).collect();
        assert!(names.iter().all(|n| n.starts_with("fmi2")));
        names.sort();
        names.dedup();
        assert_eq!(names.len(), 34);
    }

    #[test]
    fn spot_checks_against_the_standard_table() {
        assert!(Call::Instantiate.allowed_in(State::StartEnd));
        assert!(!Call::DoStep.allowed_in(State::Instantiated));
        assert!(!Call::DoStep.allowed_in(State::InitializationMode));
        assert!(Call::DoStep.allowed_in(State::StepComplete));
        assert!(!Call::GetReal.allowed_in(State::Instantiated));
        assert!(Call::GetReal.allowed_in(State::Error));
        assert!(!Call::SetReal.allowed_in(State::Terminated));
        assert!(Call::Reset.allowed_in(State::Error));
        assert!(!Call::Reset.allowed_in(State::Fatal));
        assert!(Call::Terminate.allowed_in(State::StepComplete));
        assert!(!Call::Terminate.allowed_in(State::InitializationMode));
    }

    #[test]
    fn the_core_statuses_are_coded_as_fmi2_statuses() {
        let all = [
            Status::Ok,
            Status::Warning,
            Status::Discard,
            Status::Error,
            Status::Fatal,
        ];
        assert_eq!(all.map(Call::code), [0, 1, 2, 3, 4]);
    }
}
