//! Estimators: each takes samples and returns estimates.
//!
//! - [`mrgia`]: the recursive MRGIA of paper 000 (on-line; also behind MrgiaEstimator.fmu).
//! - [`frequency`]: the frequency-domain LS / separable LS of paper 003 (sine experiments).

pub mod frequency;
pub mod mrgia;
