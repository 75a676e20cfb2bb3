//! Diagnosis: from a fitted model's residual to the effect the model lacks.
//!
//! - [`residual`]: the statistical tests that trace a residual to its cause.

pub mod residual;
