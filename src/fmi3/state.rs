//! The FMI 3.0 co-simulation state machine: which function may be called in which state.
//!
//! The table follows the standard (FMI 3.0, section 4.2 "state machine for co-simulation", and 2.3 for the
//! common functions), for an FMU without event mode (hasEventMode="false"), configuration mode, clocks or
//! intermediate update: the states are those of the core's [`State`] enum, read as FMI 3.0's
//! `Instantiated`, `Initialization Mode`, `Step Mode` (= [`State::StepComplete`]), `Terminated`, and the
//! error states. A step cut short with fmi3Discard leaves the instance in [`State::StepFailed`], as in the
//! FMI 2.0 layer: the master reads `lastSuccessfulTime`, then terminates or restores an FMU state.
//!
//! Functions these FMUs do not provide (other types, clocks, event and configuration mode, derivatives,
//! dependencies, model exchange and scheduled execution) are allowed wherever an instance exists, so that the answer is their own "not provided"
//! error rather than a state error; written as a match, a missing case is a compile error.

use super::ffi::{Fmi3Status, Fmi3StatusC};
use crate::fmi::state::{Api, State};
use crate::fmi::status::Status;

macro_rules! calls {
    ($($variant:ident => $name:literal,)*) => {
        /// Every function of the FMI 3.0 API (fmi3Functions.h). All are exported, those of model exchange and
        /// scheduled execution too (answering "not provided"): importers such as FMPy load every one of them
        /// whatever the interface they use, as the Reference FMUs export them all.
        #[derive(Debug, Clone, Copy, PartialEq, Eq)]
        pub enum Call {
            $($variant,)*
        }

        impl Call {
            pub const ALL: &'static [Call] = &[$(Call::$variant,)*];

            /// The C name of the function.
            pub fn name(self) -> &'static str {
                match self {
                    $(Call::$variant => $name,)*
                }
            }
        }
    };
}

calls! {
    GetVersion => "fmi3GetVersion",
    SetDebugLogging => "fmi3SetDebugLogging",
    InstantiateModelExchange => "fmi3InstantiateModelExchange",
    InstantiateCoSimulation => "fmi3InstantiateCoSimulation",
    InstantiateScheduledExecution => "fmi3InstantiateScheduledExecution",
    FreeInstance => "fmi3FreeInstance",
    EnterInitializationMode => "fmi3EnterInitializationMode",
    ExitInitializationMode => "fmi3ExitInitializationMode",
    EnterEventMode => "fmi3EnterEventMode",
    Terminate => "fmi3Terminate",
    Reset => "fmi3Reset",
    GetFloat32 => "fmi3GetFloat32",
    GetFloat64 => "fmi3GetFloat64",
    GetInt8 => "fmi3GetInt8",
    GetUInt8 => "fmi3GetUInt8",
    GetInt16 => "fmi3GetInt16",
    GetUInt16 => "fmi3GetUInt16",
    GetInt32 => "fmi3GetInt32",
    GetUInt32 => "fmi3GetUInt32",
    GetInt64 => "fmi3GetInt64",
    GetUInt64 => "fmi3GetUInt64",
    GetBoolean => "fmi3GetBoolean",
    GetString => "fmi3GetString",
    GetBinary => "fmi3GetBinary",
    GetClock => "fmi3GetClock",
    SetFloat32 => "fmi3SetFloat32",
    SetFloat64 => "fmi3SetFloat64",
    SetInt8 => "fmi3SetInt8",
    SetUInt8 => "fmi3SetUInt8",
    SetInt16 => "fmi3SetInt16",
    SetUInt16 => "fmi3SetUInt16",
    SetInt32 => "fmi3SetInt32",
    SetUInt32 => "fmi3SetUInt32",
    SetInt64 => "fmi3SetInt64",
    SetUInt64 => "fmi3SetUInt64",
    SetBoolean => "fmi3SetBoolean",
    SetString => "fmi3SetString",
    SetBinary => "fmi3SetBinary",
    SetClock => "fmi3SetClock",
    GetNumberOfVariableDependencies => "fmi3GetNumberOfVariableDependencies",
    GetVariableDependencies => "fmi3GetVariableDependencies",
    GetFmuState => "fmi3GetFMUState",
    SetFmuState => "fmi3SetFMUState",
    FreeFmuState => "fmi3FreeFMUState",
    SerializedFmuStateSize => "fmi3SerializedFMUStateSize",
    SerializeFmuState => "fmi3SerializeFMUState",
    DeserializeFmuState => "fmi3DeserializeFMUState",
    GetDirectionalDerivative => "fmi3GetDirectionalDerivative",
    GetAdjointDerivative => "fmi3GetAdjointDerivative",
    EnterConfigurationMode => "fmi3EnterConfigurationMode",
    ExitConfigurationMode => "fmi3ExitConfigurationMode",
    GetIntervalDecimal => "fmi3GetIntervalDecimal",
    GetIntervalFraction => "fmi3GetIntervalFraction",
    GetShiftDecimal => "fmi3GetShiftDecimal",
    GetShiftFraction => "fmi3GetShiftFraction",
    SetIntervalDecimal => "fmi3SetIntervalDecimal",
    SetIntervalFraction => "fmi3SetIntervalFraction",
    SetShiftDecimal => "fmi3SetShiftDecimal",
    SetShiftFraction => "fmi3SetShiftFraction",
    EvaluateDiscreteStates => "fmi3EvaluateDiscreteStates",
    UpdateDiscreteStates => "fmi3UpdateDiscreteStates",
    EnterStepMode => "fmi3EnterStepMode",
    GetOutputDerivatives => "fmi3GetOutputDerivatives",
    DoStep => "fmi3DoStep",
    EnterContinuousTimeMode => "fmi3EnterContinuousTimeMode",
    CompletedIntegratorStep => "fmi3CompletedIntegratorStep",
    SetTime => "fmi3SetTime",
    SetContinuousStates => "fmi3SetContinuousStates",
    GetContinuousStateDerivatives => "fmi3GetContinuousStateDerivatives",
    GetEventIndicators => "fmi3GetEventIndicators",
    GetContinuousStates => "fmi3GetContinuousStates",
    GetNominalsOfContinuousStates => "fmi3GetNominalsOfContinuousStates",
    GetNumberOfEventIndicators => "fmi3GetNumberOfEventIndicators",
    GetNumberOfContinuousStates => "fmi3GetNumberOfContinuousStates",
    ActivateModelPartition => "fmi3ActivateModelPartition",
}

/// The groups of calls that share a state rule in the FMI 3.0 co-simulation state machine.
#[derive(Clone, Copy)]
enum Rule {
    /// fmi3GetVersion: anywhere but after a fatal error.
    NotFatal,
    Instantiate,
    /// Calls on an instance outside a step in progress (logging, free, reset, FMU states).
    Instance,
    EnterInitialization,
    ExitInitialization,
    Terminate,
    Get,
    Set,
    DoStep,
    /// Functions this FMU does not provide.
    NotProvided,
}

impl Call {
    /// The state rule this call follows: every call of the standard in exactly one group.
    fn rule(self) -> Rule {
        match self {
            Call::GetVersion => Rule::NotFatal,
            Call::InstantiateModelExchange
            | Call::InstantiateCoSimulation
            | Call::InstantiateScheduledExecution => Rule::Instantiate,
            Call::SetDebugLogging
            | Call::FreeInstance
            | Call::Reset
            | Call::GetFmuState
            | Call::SetFmuState
            | Call::FreeFmuState
            | Call::SerializedFmuStateSize
            | Call::SerializeFmuState
            | Call::DeserializeFmuState => Rule::Instance,
            Call::EnterInitializationMode => Rule::EnterInitialization,
            Call::ExitInitializationMode => Rule::ExitInitialization,
            Call::Terminate => Rule::Terminate,
            Call::GetFloat64 | Call::GetInt32 | Call::GetBoolean => Rule::Get,
            Call::SetFloat64 | Call::SetInt32 | Call::SetBoolean => Rule::Set,
            Call::DoStep => Rule::DoStep,
            Call::EnterEventMode
            | Call::GetFloat32
            | Call::GetInt8
            | Call::GetUInt8
            | Call::GetInt16
            | Call::GetUInt16
            | Call::GetUInt32
            | Call::GetInt64
            | Call::GetUInt64
            | Call::GetString
            | Call::GetBinary
            | Call::GetClock
            | Call::SetFloat32
            | Call::SetInt8
            | Call::SetUInt8
            | Call::SetInt16
            | Call::SetUInt16
            | Call::SetUInt32
            | Call::SetInt64
            | Call::SetUInt64
            | Call::SetString
            | Call::SetBinary
            | Call::SetClock
            | Call::GetNumberOfVariableDependencies
            | Call::GetVariableDependencies
            | Call::GetDirectionalDerivative
            | Call::GetAdjointDerivative
            | Call::EnterConfigurationMode
            | Call::ExitConfigurationMode
            | Call::GetIntervalDecimal
            | Call::GetIntervalFraction
            | Call::GetShiftDecimal
            | Call::GetShiftFraction
            | Call::SetIntervalDecimal
            | Call::SetIntervalFraction
            | Call::SetShiftDecimal
            | Call::SetShiftFraction
            | Call::EvaluateDiscreteStates
            | Call::UpdateDiscreteStates
            | Call::EnterStepMode
            | Call::GetOutputDerivatives
            | Call::EnterContinuousTimeMode
            | Call::CompletedIntegratorStep
            | Call::SetTime
            | Call::SetContinuousStates
            | Call::GetContinuousStateDerivatives
            | Call::GetEventIndicators
            | Call::GetContinuousStates
            | Call::GetNominalsOfContinuousStates
            | Call::GetNumberOfEventIndicators
            | Call::GetNumberOfContinuousStates
            | Call::ActivateModelPartition => Rule::NotProvided,
        }
    }
}

impl Api for Call {
    type Code = Fmi3StatusC;

    fn code(status: Status) -> Fmi3StatusC {
        Fmi3Status::from(status) as Fmi3StatusC
    }

    fn name(self) -> &'static str {
        Call::name(self)
    }

    fn allowed_in(self, s: State) -> bool {
        use State::*;
        let instance = !matches!(s, StartEnd | Fatal);
        match self.rule() {
            Rule::NotFatal => s != Fatal,
            Rule::Instantiate => s == StartEnd,
            Rule::Instance => instance && s != StepInProgress,
            Rule::EnterInitialization => s == Instantiated,
            Rule::ExitInitialization => s == InitializationMode,
            Rule::Terminate => matches!(s, StepComplete | StepFailed),
            Rule::Get => matches!(
                s,
                InitializationMode | StepComplete | StepFailed | Terminated | Error
            ),
            Rule::Set => matches!(s, Instantiated | InitializationMode | StepComplete),
            Rule::DoStep => s == StepComplete,
            // Not provided: answered with their own reason wherever an instance exists.
            Rule::NotProvided => instance,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_call_has_a_distinct_c_name_with_the_fmi3_prefix() {
        let mut names: Vec<_> = Call::ALL.iter().map(|c| c.name()).collect();
        assert!(names.iter().all(|n| n.starts_with("fmi3")));
        names.sort();
        names.dedup();
        assert_eq!(names.len(), 75);
    }

    #[test]
    fn spot_checks_against_the_standard_table() {
        assert!(Call::InstantiateCoSimulation.allowed_in(State::StartEnd));
        assert!(!Call::DoStep.allowed_in(State::Instantiated));
        assert!(!Call::DoStep.allowed_in(State::InitializationMode));
        assert!(Call::DoStep.allowed_in(State::StepComplete));
        assert!(!Call::GetFloat64.allowed_in(State::Instantiated));
        assert!(Call::GetFloat64.allowed_in(State::Error));
        assert!(!Call::SetFloat64.allowed_in(State::Terminated));
        assert!(Call::Reset.allowed_in(State::Error));
        assert!(!Call::Reset.allowed_in(State::Fatal));
        assert!(!Call::Terminate.allowed_in(State::InitializationMode));
        // fmi3GetVersion needs no instance and is refused only after a fatal error.
        assert!(Call::GetVersion.allowed_in(State::StartEnd));
        assert!(Call::GetVersion.allowed_in(State::StepComplete));
        assert!(!Call::GetVersion.allowed_in(State::Fatal));
    }

    #[test]
    fn the_core_statuses_are_coded_as_fmi3_statuses() {
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
