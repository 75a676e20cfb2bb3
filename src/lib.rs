//! Backlash identification in system-level simulation.
//!
//! - [`plant`]: the physics: the pseudo-Wiener plant of paper 000 (linear block, backlash, sensor), the
//!   polynomial-border backlash and continuous-time linear block of paper 003.
//! - [`identify`]: the estimators: MRGIA (paper 000), frequency LS / separable LS (paper 003).
//! - [`compensate`]: the backlash inverse and the adaptive compensation loop.
//! - [`diagnose`]: residual tests that trace a model's error to the effect it lacks.
//! - [`fmi`]: the protocol-independent core of the FMUs (the `Model` trait, the instance, timing, FMU state,
//!   the C boundary, the registry); [`fmi2`] and [`fmi3`]: the FMI 2.0 and 3.0 co-simulation layers over it;
//!   [`fmus`]: the two adapters, registered through the core's seam.
//! - [`api`]: the command line's results as JSON objects, computed from arrays (the program and the Python
//!   package share it).
//! - [`io`]: validated CSV reading, atomic writing; [`report`]: PNG plots; [`stats`]: descriptive statistics.

// Without the default feature `cli` the library is the FMUs alone (plant, estimators, FMI layers): what the
// FMUs' shared library is built from (see Cargo.toml, [features]).
#[cfg(feature = "cli")]
pub mod api;
pub mod compensate;
#[cfg(feature = "cli")]
pub mod diagnose;
pub mod fmi;
pub mod fmi2;
pub mod fmi3;
pub mod fmus;
pub mod identify;
#[cfg(feature = "cli")]
pub mod io;
pub mod plant;
#[cfg(feature = "cli")]
pub mod progress;
#[cfg(feature = "cli")]
pub mod report;
pub mod stats;
