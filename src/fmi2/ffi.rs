//! The C types of the FMI 2.0 standard headers (fmi2TypesPlatform.h, fmi2FunctionTypes.h), written out here
//! so that the FMU binary needs neither the headers nor bindgen.

use crate::fmi::status::Status;
use std::ffi::{c_char, c_int, c_uint, c_void};

pub type Fmi2Component = *mut c_void;
pub type Fmi2ComponentEnvironment = *mut c_void;
pub type Fmi2FmuState = *mut c_void;
pub type Fmi2ValueReference = c_uint;
pub type Fmi2Real = f64;
pub type Fmi2Integer = c_int;
pub type Fmi2Boolean = c_int;
pub type Fmi2Char = c_char;
pub type Fmi2String = *const c_char;
pub type Fmi2Byte = c_char;

pub const FMI2_TRUE: Fmi2Boolean = 1;
pub const FMI2_FALSE: Fmi2Boolean = 0;

/// fmi2Status.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Fmi2Status {
    Ok = 0,
    Warning = 1,
    Discard = 2,
    Error = 3,
    Fatal = 4,
    Pending = 5,
}

impl Fmi2Status {
    pub fn name(self) -> &'static str {
        match self {
            Fmi2Status::Ok => "fmi2OK",
            Fmi2Status::Warning => "fmi2Warning",
            Fmi2Status::Discard => "fmi2Discard",
            Fmi2Status::Error => "fmi2Error",
            Fmi2Status::Fatal => "fmi2Fatal",
            Fmi2Status::Pending => "fmi2Pending",
        }
    }
}

impl From<Status> for Fmi2Status {
    /// The core's status as FMI 2.0 says it (fmi2Pending is never the answer: steps are synchronous).
    fn from(status: Status) -> Self {
        match status {
            Status::Ok => Fmi2Status::Ok,
            Status::Warning => Fmi2Status::Warning,
            Status::Discard => Fmi2Status::Discard,
            Status::Error => Fmi2Status::Error,
            Status::Fatal => Fmi2Status::Fatal,
        }
    }
}

/// C enums cross the boundary as `unsigned int`, their representation on the supported platforms (and what
/// bindgen makes of the standard headers, which the integration tests check the exports against).
pub type Fmi2StatusC = c_uint;
/// fmi2Type.
pub type Fmi2Type = c_uint;
pub const FMI2_MODEL_EXCHANGE: Fmi2Type = 0;
pub const FMI2_CO_SIMULATION: Fmi2Type = 1;

/// fmi2StatusKind.
pub type Fmi2StatusKind = c_uint;
pub const FMI2_DO_STEP_STATUS: Fmi2StatusKind = 0;
pub const FMI2_PENDING_STATUS: Fmi2StatusKind = 1;
pub const FMI2_LAST_SUCCESSFUL_TIME: Fmi2StatusKind = 2;
pub const FMI2_TERMINATED: Fmi2StatusKind = 3;

/// The logger is variadic C: the layer passes the message as the format, every `%` doubled, and no varargs.
pub type Fmi2CallbackLogger = Option<
    unsafe extern "C" fn(
        Fmi2ComponentEnvironment,
        Fmi2String,
        Fmi2StatusC,
        Fmi2String,
        Fmi2String,
        ...
    ),
>;
pub type Fmi2CallbackAllocateMemory = Option<unsafe extern "C" fn(usize, usize) -> *mut c_void>;
pub type Fmi2CallbackFreeMemory = Option<unsafe extern "C" fn(*mut c_void)>;
pub type Fmi2StepFinished = Option<unsafe extern "C" fn(Fmi2ComponentEnvironment, Fmi2StatusC)>;

/// fmi2CallbackFunctions.
#[repr(C)]
#[derive(Clone, Copy)]
pub struct Fmi2CallbackFunctions {
    pub logger: Fmi2CallbackLogger,
    pub allocate_memory: Fmi2CallbackAllocateMemory,
    pub free_memory: Fmi2CallbackFreeMemory,
    pub step_finished: Fmi2StepFinished,
    pub component_environment: Fmi2ComponentEnvironment,
}
