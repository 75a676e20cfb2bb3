//! Reports: figures written by the command line (Bode and border plots of the frequency experiments,
//! convergence plots of the estimators).
//!
//! - [`plot`]: PNG line/point plots with a legend, linear or logarithmic axes, one or several panels.

pub mod plot;

pub use plot::{Axes, Panel, PlotError, Scale, Series, SeriesStyle, grid_plot, line_plot};
