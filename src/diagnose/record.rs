//! Records: decimation of densely sampled measurements before a diagnosis, and how alike a split excites
//! its two parts.

use crate::stats::std_dev;

/// Block-average decimation by `factor`: output sample i is the mean of input samples
/// `i factor .. (i + 1) factor` of each column (a moving average over the block, which is the anti-alias
/// filter, then one sample per block). Times are block means too, so the columns stay aligned. A trailing
/// partial block is dropped; `factor` 0 or 1 returns the columns unchanged.
pub fn decimate(columns: &[&[f64]], factor: usize) -> Vec<Vec<f64>> {
    if factor <= 1 {
        return columns.iter().map(|c| c.to_vec()).collect();
    }
    columns
        .iter()
        .map(|c| {
            c.chunks_exact(factor)
                .map(|b| b.iter().sum::<f64>() / factor as f64)
                .collect()
        })
        .collect()
}

/// A held-out input whose standard deviation or range is below this share of the fit part's judges little.
pub const POOR_EXCITATION: f64 = 0.25;

/// The input's excitation on the held-out part over the fit part's at the split `n_fit`: the ratios of
/// standard deviation and of range (`NaN` where the fit part's input is constant).
pub fn excitation(u: &[f64], n_fit: usize) -> (f64, f64) {
    let (fit, held) = u.split_at(n_fit);
    excitation_of(fit, held)
}

/// Whether a held-out part whose input's ratios to the fit part's are `(std, range)` ([`excitation_of`])
/// tests a claim about play: both at least [`POOR_EXCITATION`]; not where the fit part's input is constant
/// (the ratios are `NaN`).
pub fn fairly_excited((std, range): (f64, f64)) -> bool {
    std >= POOR_EXCITATION && range >= POOR_EXCITATION
}

/// [`excitation`] of the input's held-out samples `held` over its fit samples `fit`.
pub fn excitation_of(fit: &[f64], held: &[f64]) -> (f64, f64) {
    let range = |v: &[f64]| {
        v.iter().fold(f64::NEG_INFINITY, |m, a| m.max(*a))
            - v.iter().fold(f64::INFINITY, |m, a| m.min(*a))
    };
    let ratio = |a: f64, b: f64| if b > 0.0 { a / b } else { f64::NAN };
    (
        ratio(std_dev(held), std_dev(fit)),
        ratio(range(held), range(fit)),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_means_and_partial_block_dropped() {
        let t: Vec<f64> = (0..10).map(|k| k as f64).collect();
        let u: Vec<f64> = (0..10).map(|k| (k * k) as f64).collect();
        let d = decimate(&[&t, &u], 4);
        assert_eq!(d[0], vec![1.5, 5.5]);
        assert_eq!(
            d[1],
            vec![
                (0.0 + 1.0 + 4.0 + 9.0) / 4.0,
                (16.0 + 25.0 + 36.0 + 49.0) / 4.0
            ]
        );
        assert_eq!(decimate(&[&t], 1)[0], t);
    }
}
