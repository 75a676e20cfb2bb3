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

#[cfg(test)]
mod tests {
    use super::*;

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
    }
}
