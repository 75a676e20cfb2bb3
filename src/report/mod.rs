//! Reports: figures written by the command line (Bode and border plots of the frequency experiments,
//! convergence plots of the estimators).
//!
//! - [`plot`]: PNG line/point plots with a legend, linear or logarithmic axes, one or several panels.

pub mod plot;

pub use plot::{Axes, Panel, PlotError, Scale, Series, SeriesStyle, grid_plot, line_plot};

/// A number for people: 0 as "0", four decimals in [1e-3, 1e4), four significant digits in scientific
/// notation outside (so that a tiny error never prints as 0.0000).
pub fn number(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if v.abs() >= 1e4 || v.abs() < 1e-3 {
        format!("{v:.3e}")
    } else {
        format!("{v:.4}")
    }
}

#[cfg(test)]
mod tests {
    use super::number;

    #[test]
    fn numbers_keep_their_digits_at_any_scale() {
        assert_eq!(number(0.0), "0");
        assert_eq!(number(0.12345), "0.1235");
        assert_eq!(number(2.5e-9), "2.500e-9");
        assert_eq!(number(-123456.0), "-1.235e5");
        assert_eq!(number(1e-3), "0.0010");
    }
}
