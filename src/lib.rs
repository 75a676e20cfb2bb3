//! Backlash identification in system-level simulation.
//!
//! - [`plant`]: the pseudo-Wiener plant of paper 000 (linear block, backlash, sensor).
//! - [`identify`]: the estimators (MRGIA of paper 000).
//! - `fmi2`: one FMI 2.0 co-simulation layer, generic over the model; `fmus`: the two adapters.

pub mod fmi2;
pub mod fmus;
pub mod identify;
pub mod io;
pub mod plant;
pub mod report;
