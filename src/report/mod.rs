//! Reports: figures written by the command line (Bode and border plots of the frequency experiments,
//! convergence plots of the estimators).
//!
//! - [`plot`]: PNG line/point plots with a legend, linear or logarithmic axes, one or several panels.

pub mod plot;

pub use plot::{Axes, Panel, PlotError, Scale, Series, SeriesStyle, grid_plot, line_plot};

/// A number for people: 0 as "0", four decimals in [1e-2, 1e4), four significant digits in scientific
/// notation outside (so that a small error keeps its digits: 5.123e-3, never 0.0051 or 0.0000). The one
/// rule of the diagnosis's text, JSON-side sentences and report, so that they print a figure alike.
pub fn number(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if v.abs() >= 1e4 || v.abs() < 1e-2 {
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
        assert_eq!(number(0.01), "0.0100");
        assert_eq!(number(9.99e-3), "9.990e-3");
        assert_eq!(number(-1e-3), "-1.000e-3");
        assert_eq!(number(9999.0), "9999.0000");
    }
}
