//! A model's structure: its orders and input delay. Its own module because both the fits on a record
//! ([`super::problem`]) and the choice among structures ([`super::structure`]) use it, and the choice uses the
//! fits.

use serde::Serialize;

/// A model structure: `na` a coefficients, b_0..b_nb, input delay in samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub struct Structure {
    pub na: usize,
    pub nb: usize,
    pub delay: usize,
}

impl Structure {
    /// Parameters of the backlash model of this structure (a, b, m2, c1, c2).
    pub fn n_params(&self) -> usize {
        self.na + self.nb + 4
    }
}

impl std::fmt::Display for Structure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "na = {}, nb = {}, delay = {}",
            self.na, self.nb, self.delay
        )
    }
}
