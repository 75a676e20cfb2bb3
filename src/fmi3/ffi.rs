//! The C types of the FMI 3.0 standard headers (fmi3PlatformTypes.h, fmi3FunctionTypes.h) that the exports
//! use, written out here so that the FMU binary needs neither the headers nor bindgen.

use crate::fmi::status::Status;
use std::ffi::{c_char, c_uint, c_void};

pub type Fmi3Instance = *mut c_void;
pub type Fmi3InstanceEnvironment = *mut c_void;
pub type Fmi3FmuState = *mut c_void;
pub type Fmi3ValueReference = u32;
pub type Fmi3Float64 = f64;
pub type Fmi3Int32 = i32;
pub type Fmi3String = *const c_char;
pub type Fmi3Byte = u8;
/// fmi3Boolean is C `bool`, one byte. It is taken as a byte, so that a value other than 0 or 1 from the
/// importer is read as true rather than being undefined behaviour in Rust.
pub type Fmi3Boolean = u8;
pub const FMI3_TRUE: Fmi3Boolean = 1;
pub const FMI3_FALSE: Fmi3Boolean = 0;

/// fmi3Status.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Fmi3Status {
    Ok = 0,
    Warning = 1,
    Discard = 2,
    Error = 3,
    Fatal = 4,
}

impl From<Status> for Fmi3Status {
    /// The core's status as FMI 3.0 says it.
    fn from(status: Status) -> Self {
        match status {
            Status::Ok => Fmi3Status::Ok,
            Status::Warning => Fmi3Status::Warning,
            Status::Discard => Fmi3Status::Discard,
            Status::Error => Fmi3Status::Error,
            Status::Fatal => Fmi3Status::Fatal,
        }
    }
}

/// fmi3Status as it crosses the boundary: a C enum, `unsigned int` on the supported platforms.
pub type Fmi3StatusC = c_uint;
/// fmi3DependencyKind and fmi3IntervalQualifier (C enums).
pub type Fmi3EnumC = c_uint;

/// fmi3LogMessageCallback: the message is plain text (no printf format, unlike FMI 2.0).
pub type Fmi3LogMessageCallback =
    Option<unsafe extern "C" fn(Fmi3InstanceEnvironment, Fmi3StatusC, Fmi3String, Fmi3String)>;
/// fmi3IntermediateUpdateCallback: accepted and never called (providesIntermediateUpdate="false").
pub type Fmi3IntermediateUpdateCallback = Option<
    unsafe extern "C" fn(
        Fmi3InstanceEnvironment,
        Fmi3Float64,
        Fmi3Boolean,
        Fmi3Boolean,
        Fmi3Boolean,
        Fmi3Boolean,
        *mut Fmi3Boolean,
        *mut Fmi3Float64,
    ),
>;
/// fmi3ClockUpdateCallback, fmi3LockPreemptionCallback, fmi3UnlockPreemptionCallback (scheduled
/// execution, which these FMUs do not implement: taken only to refuse).
pub type Fmi3ClockUpdateCallback = Option<unsafe extern "C" fn(Fmi3InstanceEnvironment)>;
pub type Fmi3PreemptionCallback = Option<unsafe extern "C" fn()>;
