//! Records: decimation of densely sampled measurements before a diagnosis.

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
