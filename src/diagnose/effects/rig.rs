//! A test-bench record being set up: the plant, its effects and noise level, and the clean plant's signals,
//! into which each effect draws itself with random magnitudes ([`crate::diagnose::effects::Effect::draw`]).
//! The records themselves are made by `crate::diagnose::bench`.

use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardUniform};

use crate::plant::PlantParams;
use crate::plant::effects::Effects;

/// Random magnitudes: uniform draws and signs from a ChaCha8 generator.
pub struct Draw(pub ChaCha8Rng);

impl Draw {
    /// Uniform in `[lo, hi)`.
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        let r: f64 = StandardUniform.sample(&mut self.0);
        lo + (hi - lo) * r
    }

    /// -1 or +1, each with probability one half (-1 exactly when the uniform draw in its place is below
    /// one half).
    pub fn sign(&mut self) -> f64 {
        if self.uniform(0.0, 1.0) < 0.5 {
            -1.0
        } else {
            1.0
        }
    }
}

/// A record being set up.
pub struct Rig {
    /// The true plant (its delay or orders may exceed the declared ones).
    pub params: PlantParams,
    pub effects: Effects,
    /// std(noise-free output) / noise std.
    pub snr: f64,
    /// A noise std that replaces the one from the SNR.
    pub fixed_noise: Option<f64>,
    /// The clean plant's backlash and linear outputs.
    pub w0: Vec<f64>,
    pub x0: Vec<f64>,
    /// The clean plant's input.
    pub u: Vec<f64>,
    /// Samples of the record.
    pub n: usize,
}
