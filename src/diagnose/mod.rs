//! Diagnosis: from a fitted model's residual to the effect the model lacks.
//!
//! - [`residual`]: the statistical tests that trace a residual to its cause.

pub mod bench;
pub mod catalogue;
pub mod decision;
pub mod engine;
pub mod fit;
pub mod model;
pub mod output;
pub mod problem;
pub mod record;
pub mod report;
pub mod residual;
pub mod starts;
pub mod statistics;
pub mod structure;
