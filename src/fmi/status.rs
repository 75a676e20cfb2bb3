//! The core's answer to a call, before a protocol layer codes it as its own C status.

/// How a call went, in the words both standards share: fmi2Status and fmi3Status both have these five
/// (FMI 2.0's fmi2Pending, for asynchronous steps, never arises: steps here are synchronous). Each layer maps
/// a `Status` to its own C status at its edge ([`Api::code`](super::state::Api::code)).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Status {
    Ok,
    Warning,
    Discard,
    Error,
    Fatal,
}

/// What the body of a call returns: how it went, or why it is refused (the reason is logged and the call
/// answers [`Status::Error`]).
pub type Outcome = Result<Status, String>;
