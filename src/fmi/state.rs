//! The instance's state machine, for both protocols: the states of a co-simulation instance, and what a
//! protocol's function must tell the core about itself ([`Api`]): its C name, the states its standard allows
//! it in (the per-version tables are `crate::fmi2::state` and `crate::fmi3::state`), and how the protocol
//! codes a [`Status`].
//!
//! The states are those of the FMI 2.0 co-simulation table; FMI 3.0's states without event or configuration
//! mode are the same ones under other names (its step mode is [`State::StepComplete`]). `StepInProgress` and
//! `StepCanceled` exist in FMI 2.0 for asynchronous steps; steps here are synchronous, so an instance is never
//! observed in them, but the tables keep them for completeness.

use super::status::Status;
use std::panic::{RefUnwindSafe, UnwindSafe};

/// The states of a co-simulation slave.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum State {
    /// Before the instantiate function and after the free function (there is no instance then; used by the
    /// tables).
    StartEnd,
    Instantiated,
    InitializationMode,
    StepComplete,
    StepInProgress,
    StepFailed,
    StepCanceled,
    Terminated,
    Error,
    Fatal,
}

impl State {
    pub const ALL: [State; 10] = [
        State::StartEnd,
        State::Instantiated,
        State::InitializationMode,
        State::StepComplete,
        State::StepInProgress,
        State::StepFailed,
        State::StepCanceled,
        State::Terminated,
        State::Error,
        State::Fatal,
    ];

    pub fn name(self) -> &'static str {
        match self {
            State::StartEnd => "start/end",
            State::Instantiated => "instantiated",
            State::InitializationMode => "initialization mode",
            State::StepComplete => "step complete",
            State::StepInProgress => "step in progress",
            State::StepFailed => "step failed",
            State::StepCanceled => "step canceled",
            State::Terminated => "terminated",
            State::Error => "error",
            State::Fatal => "fatal",
        }
    }
}

/// A function of a protocol's API, as the instance's state machine sees it (FMI 2.0's
/// `crate::fmi2::state::Call`, FMI 3.0's `crate::fmi3::state::Call`).
pub trait Api: Copy + UnwindSafe + RefUnwindSafe {
    /// The C type the protocol's functions return their status in.
    type Code: Copy;
    /// The C name of the function.
    fn name(self) -> &'static str;
    /// Whether the protocol's table allows this function in state `state`.
    fn allowed_in(self, state: State) -> bool;
    /// `status` as the protocol's functions return it: the layer's edge, where the core's [`Status`] becomes
    /// fmi2Status or fmi3Status.
    fn code(status: Status) -> Self::Code;
}
