//! The operating point every fit of a diagnosis works about (the fitting room's, so that the structure stage
//! and the linear baseline use it without depending on the search).

use serde::Serialize;

use crate::stats::std_dev;

/// The operating point a diagnosis works about: the fit part's mean input and the record's first output.
/// Every fit, start, linear baseline and effect with a centre (dead zone, saturation, quantization, curved
/// borders) sees deviations from it, so that a record shifted by constants (u + a, y + b), as a sensor's
/// arbitrary zero shifts it, gets the same answer. The output's level is its first sample so that the
/// backlash memory, which starts at 0 about it, starts where the record does: about the fit part's mean
/// instead, a clean paper-plant record's play came out 0.056 (13 standard errors) off, its memory starting
/// far from the plant's.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct OperatingPoint {
    pub u: f64,
    pub y: f64,
}

/// The deviations are rounded to 2^-30 of their scale (a power of two): far below any sensor's resolution,
/// and coarse enough that the rounding of the shift itself (u + a - mean) leaves the same numbers, so that a
/// fit's path does not branch on it.
const GRID_BITS: i32 = 30;

impl OperatingPoint {
    /// The fit part's mean input (the first `n_fit` samples) and the first output.
    pub fn of(u: &[f64], y: &[f64], n_fit: usize) -> Self {
        let n = n_fit.min(u.len()).min(y.len());
        Self {
            u: crate::stats::mean(&u[..n]),
            y: y.first().copied().unwrap_or(0.0),
        }
    }

    /// `v - level`, sample by sample, rounded to 2^-30 of their scale (a power of two).
    pub fn deviations(&self, v: &[f64], level: f64) -> Vec<f64> {
        let d: Vec<f64> = v.iter().map(|a| a - level).collect();
        let s = std_dev(&d);
        if !(s.is_finite() && s > 0.0) {
            return d;
        }
        let q = 2f64.powi(s.log2().floor() as i32 - GRID_BITS);
        d.into_iter().map(|a| (a / q).round() * q).collect()
    }
}
