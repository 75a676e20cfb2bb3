//! Descriptive statistics used across the crate: one implementation of each.
//!
//! Empty inputs have documented answers (0 for the moments, `None` for a quantile) so that callers never
//! divide by zero.

/// Arithmetic mean; 0 for an empty slice.
pub fn mean(x: &[f64]) -> f64 {
    if x.is_empty() {
        0.0
    } else {
        x.iter().sum::<f64>() / x.len() as f64
    }
}

/// Population standard deviation (divides by n); 0 for an empty slice.
pub fn std_dev(x: &[f64]) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    let m = mean(x);
    (x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / x.len() as f64).sqrt()
}

/// Root mean square of the values; 0 for none.
pub fn rms(v: impl IntoIterator<Item = f64>) -> f64 {
    let (s, n) = v
        .into_iter()
        .fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    if n == 0 { 0.0 } else { (s / n as f64).sqrt() }
}

/// Root mean square of the difference of two equally long series (`a - b`), over the shorter length.
pub fn rms_diff(a: &[f64], b: &[f64]) -> f64 {
    rms(a.iter().zip(b).map(|(x, y)| x - y))
}

/// Lags [`lagged_sums`] sums side by side.
const LAG_LANES: usize = 4;

/// `sum_{k=l}^{n-1} a(k) b(k - l)` for each lag l of `lags` (n the length of `a`; `b` at least as long),
/// each summed in order of k from -0.0 as `Iterator::sum` adds, so bit for bit the sums taken one lag after
/// another; a lag of n or more sums nothing. A few lags (four) advance together in one pass over the series:
/// on a long record (correlations over tens of lags, the Diebold-Mariano variance over n^(1/3) lags) the
/// series are read once per group of lags, not once per lag, and the lags' additions are independent chains
/// side by side, not one chain each waiting on its last addition.
pub fn lagged_sums(a: &[f64], b: &[f64], lags: std::ops::Range<usize>) -> Vec<f64> {
    let n = a.len();
    let mut out = vec![-0.0; lags.len()];
    for (g, sums) in out.chunks_mut(LAG_LANES).enumerate() {
        let first = lags.start + g * LAG_LANES;
        // Past the group's last lag a lane repeats it and is dropped.
        let lag: [usize; LAG_LANES] = std::array::from_fn(|j| first + j.min(sums.len() - 1));
        let mut acc = [-0.0f64; LAG_LANES];
        // Until the group's longest lag every lane adds only from its own lag on; then all of them.
        let full = lag[LAG_LANES - 1].min(n);
        for k in first.min(n)..full {
            for j in 0..LAG_LANES {
                if k >= lag[j] {
                    acc[j] += a[k] * b[k - lag[j]];
                }
            }
        }
        for k in full..n {
            for j in 0..LAG_LANES {
                acc[j] += a[k] * b[k - lag[j]];
            }
        }
        sums.copy_from_slice(&acc[..sums.len()]);
    }
    out
}

/// Whether `value` is below `reference` by more than the fraction `fraction` of it (never for a NaN or an
/// infinite `value`).
pub fn below_by(value: f64, reference: f64, fraction: f64) -> bool {
    value < (1.0 - fraction) * reference
}

/// The q-quantile (0 <= q <= 1) by the nearest rank of the sorted values, `None` for an empty slice.
pub fn quantile(v: &[f64], q: f64) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let i = ((s.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize;
    Some(s[i])
}

/// The median: the middle of the sorted values, the mean of the two middle ones for an even count; `None`
/// for an empty slice.
pub fn median(v: &[f64]) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    // Selection, not a sort: linear in the length (the frequency fit takes the median of every second
    // difference of a record).
    let mut s = v.to_vec();
    let m = s.len() / 2;
    let (lower, upper, _) = s.select_nth_unstable_by(m, f64::total_cmp);
    let upper = *upper;
    Some(if v.len().is_multiple_of(2) {
        let below = lower
            .iter()
            .copied()
            .max_by(f64::total_cmp)
            .unwrap_or(upper);
        0.5 * (below + upper)
    } else {
        upper
    })
}

/// Block means of a stream of rows: every `factor` rows of `width` values become one row of their means (an
/// anti-alias mean before keeping one sample per block); a last, incomplete block is dropped. Factor 1 passes
/// the rows through unchanged.
#[derive(Debug, Clone)]
pub struct BlockMean {
    factor: usize,
    sum: Vec<f64>,
    count: usize,
}

impl BlockMean {
    /// Means of `factor` (at least 1) rows of `width` values each.
    pub fn new(factor: usize, width: usize) -> Self {
        Self {
            factor: factor.max(1),
            sum: vec![0.0; width],
            count: 0,
        }
    }

    /// Adds a row; returns the block's means when this row completes a block.
    pub fn push(&mut self, row: &[f64]) -> Option<&[f64]> {
        if self.count == 0 {
            self.sum.copy_from_slice(row);
        } else {
            self.sum.iter_mut().zip(row).for_each(|(s, v)| *s += v);
        }
        self.count += 1;
        if self.count < self.factor {
            return None;
        }
        self.count = 0;
        if self.factor > 1 {
            let n = self.factor as f64;
            self.sum.iter_mut().for_each(|s| *s /= n);
        }
        Some(&self.sum)
    }
}

/// The block means of whole columns (see [`BlockMean`]): each column `factor` times shorter.
pub fn block_means(columns: &[&[f64]], factor: usize) -> Vec<Vec<f64>> {
    let len = columns.iter().map(|c| c.len()).min().unwrap_or(0);
    let mut out: Vec<Vec<f64>> = vec![Vec::with_capacity(len / factor.max(1)); columns.len()];
    let mut block = BlockMean::new(factor, columns.len());
    let mut row = vec![0.0; columns.len()];
    for k in 0..len {
        row.iter_mut().zip(columns).for_each(|(r, c)| *r = c[k]);
        if let Some(m) = block.push(&row) {
            out.iter_mut().zip(m).for_each(|(o, v)| o.push(*v));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The lagged sums taken side by side are bit for bit each lag's sum taken alone (`Iterator::sum`):
    /// groups of lags that do not fill the lanes, a first lag that is not 0, lags beyond the series (empty
    /// sums), entries of every sign and magnitude.
    #[test]
    fn lagged_sums_equal_each_lag_summed_alone_bit_for_bit() {
        let n = 1001;
        let a: Vec<f64> = (0..n)
            .map(|k| ((k * 7919) % 613) as f64 * 1e-3 - 0.3)
            .collect();
        let b: Vec<f64> = (0..n)
            .map(|k| (k as f64 * 0.37).sin() * 10f64.powi((k % 9) as i32 - 4))
            .collect();
        for lags in [0..7, 3..4, 2..13, 995..1004, 0..0] {
            let got = lagged_sums(&a, &b, lags.clone());
            assert_eq!(got.len(), lags.len());
            for (l, g) in lags.zip(&got) {
                let want: f64 = (l..n).map(|k| a[k] * b[k - l]).sum();
                assert_eq!(g.to_bits(), want.to_bits(), "lag {l}");
            }
        }
    }

    #[test]
    fn values_and_empty_inputs() {
        let x = [2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0];
        assert_eq!(mean(&x), 5.0);
        assert_eq!(std_dev(&x), 2.0);
        assert_eq!(rms([3.0, 4.0]), (12.5f64).sqrt());
        assert_eq!(rms_diff(&[1.0, 2.0], &[1.0, 0.0]), 2f64.sqrt());
        assert_eq!(quantile(&x, 0.0), Some(2.0));
        assert_eq!(quantile(&x, 1.0), Some(9.0));
        assert_eq!(quantile(&x, 0.5), Some(5.0));
        assert_eq!(mean(&[]), 0.0);
        assert_eq!(std_dev(&[]), 0.0);
        assert_eq!(rms(std::iter::empty()), 0.0);
        assert_eq!(quantile(&[], 0.5), None);
        assert_eq!(median(&[3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&[4.0, 1.0, 3.0, 2.0]), Some(2.5));
        assert_eq!(median(&[]), None);
    }

    #[test]
    fn block_means_drop_the_incomplete_block_and_pass_factor_one_through() {
        let t: Vec<f64> = (0..10).map(f64::from).collect();
        let u: Vec<f64> = (0..10).map(|k| f64::from(k * k)).collect();
        let d = block_means(&[&t, &u], 4);
        assert_eq!(d[0], [1.5, 5.5]);
        assert_eq!(
            d[1],
            [(1.0 + 4.0 + 9.0) / 4.0, (16.0 + 25.0 + 36.0 + 49.0) / 4.0]
        );
        assert_eq!(block_means(&[&t], 1)[0], t);
        assert_eq!(block_means(&[&t], 11)[0], Vec::<f64>::new());
    }
}
