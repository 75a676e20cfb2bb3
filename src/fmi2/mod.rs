//! The FMI 2.0 co-simulation layer over the core (`crate::fmi`).
//!
//! What is FMI 2.0 here and nothing else: the 34 exported functions ([`exports`]), their C types and
//! status ([`ffi`]) and the standard's co-simulation calling-sequence table ([`state`]). Argument checks,
//! timing, FMU state and logging are the core's; `fmi2Instantiate` picks the model whose GUID the importer
//! passes among those the binary registered, without naming any.

pub mod exports;
pub mod ffi;
pub mod state;
