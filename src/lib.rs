//! Backlash identification in system-level simulation.
//!
//! - [`plant`]: the physics: the pseudo-Wiener plant of paper 000 (linear block, backlash, sensor), the
//!   polynomial-border backlash and continuous-time linear block of paper 003.
//! - [`identify`]: the estimators: MRGIA (paper 000), frequency LS / separable LS (paper 003).
//! - [`diagnose`]: residual tests that trace a model's error to the effect it lacks.
//! - [`fmi2`]: one FMI 2.0 co-simulation layer, generic over the model, with the protocol-independent core
//!   (the `Model` trait, the instance, the registry); [`fmi3`]: the FMI 3.0 co-simulation layer over the same
//!   core; [`fmus`]: the two adapters, registered in [`FMUS`].
//! - [`api`]: the command line's results as JSON objects, computed from arrays (the program and the Python
//!   package share it).
//! - [`io`]: validated CSV reading, atomic writing; [`report`]: PNG plots; [`stats`]: descriptive statistics.

// Without the default feature `cli` the library is the FMUs alone (plant, estimators, FMI layers): what the
// FMUs' shared library is built from (see Cargo.toml, [features]).
#[cfg(feature = "cli")]
pub mod api;
#[cfg(feature = "cli")]
pub mod diagnose;
pub mod fmi2;
pub mod fmi3;
pub mod fmus;
pub mod identify;
pub mod io;
pub mod plant;
#[cfg(feature = "cli")]
pub mod report;
pub mod stats;

/// The FMUs this library serves, as the protocol layers see them: registered by the adapters in [`fmus`].
pub use fmus::REGISTRY as FMUS;
