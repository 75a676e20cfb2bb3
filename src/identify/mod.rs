//! Estimators: each takes samples and returns estimates.
//!
//! - [`mrgia`]: the recursive MRGIA of paper 000 (on-line; also behind MrgiaEstimator.fmu).
//! - [`frequency`]: the frequency-domain LS / separable LS of paper 003 (sine experiments).
//! - [`oe`]: offline output-error refinement, standard errors, Cramer-Rao bound, Monte Carlo study.

#[cfg(feature = "cli")]
pub mod frequency;
pub mod mrgia;
pub mod oe;
#[cfg(test)]
mod test_plants;
