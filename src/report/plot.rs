//! PNG plots with plotters: lines, dashed lines and markers, a legend, linear or log axes.
//!
//! Robust to awkward data: non-finite points are skipped (a line is broken there rather than joined
//! across the gap), points that a log axis cannot show (`<= 0`) are skipped too, an empty plot gets a
//! default range, and constant data get a range padded around the constant.
//!
//! ```no_run
//! use backlash::report::plot::{line_plot, Series};
//! let pts: Vec<(f64, f64)> = (0..100).map(|k| (k as f64, (k as f64 / 10.0).sin())).collect();
//! line_plot(
//!     std::path::Path::new("sine.png"),
//!     "A sine",
//!     "k",
//!     "sin(k/10)",
//!     &[Series::line("sin", pts)],
//!     false,
//!     false,
//! )
//! .unwrap();
//! ```

use std::ops::Range;
use std::path::{Path, PathBuf};

use plotters::chart::SeriesAnno;
use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, Ranged, ValueFormatter};
use plotters::prelude::*;

/// Size of a single-panel plot, pixels.
pub const SINGLE_SIZE: (u32, u32) = (1000, 600);
/// Size of one panel in a grid, pixels.
pub const PANEL_SIZE: (u32, u32) = (620, 420);

/// Distinct colours (the "tab10" palette); a series' `color` indexes it modulo its length.
pub const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SeriesStyle {
    /// Solid line through the points in order.
    Line,
    /// A marker at each point.
    Points,
    /// Dashed line through the points in order.
    Dashed,
}

/// One curve of a plot.
#[derive(Debug, Clone, PartialEq)]
pub struct Series<'a> {
    /// Legend text; an empty label leaves the series out of the legend.
    pub label: &'a str,
    pub points: Vec<(f64, f64)>,
    pub style: SeriesStyle,
    /// Index into [`PALETTE`] (modulo its length).
    pub color: usize,
}

impl<'a> Series<'a> {
    pub fn new(label: &'a str, points: Vec<(f64, f64)>, style: SeriesStyle, color: usize) -> Self {
        Self {
            label,
            points,
            style,
            color,
        }
    }

    /// A solid line in colour 0.
    pub fn line(label: &'a str, points: Vec<(f64, f64)>) -> Self {
        Self::new(label, points, SeriesStyle::Line, 0)
    }

    /// Markers in colour 0.
    pub fn points(label: &'a str, points: Vec<(f64, f64)>) -> Self {
        Self::new(label, points, SeriesStyle::Points, 0)
    }

    /// A dashed line in colour 0.
    pub fn dashed(label: &'a str, points: Vec<(f64, f64)>) -> Self {
        Self::new(label, points, SeriesStyle::Dashed, 0)
    }

    /// The same series in another colour.
    pub fn color(mut self, color: usize) -> Self {
        self.color = color;
        self
    }
}

/// One panel of a [`grid_plot`] (or the whole of a [`line_plot`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Panel<'a> {
    pub title: &'a str,
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub series: Vec<Series<'a>>,
    pub log_x: bool,
    pub log_y: bool,
}

/// Why a plot could not be written.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error("{path}: cannot write the plot: the folder {dir} does not exist")]
    NoFolder { path: PathBuf, dir: PathBuf },
    #[error("{path}: cannot draw the plot: {message}")]
    Draw { path: PathBuf, message: String },
    #[error("grid plot {path}: no panels to draw")]
    NoPanels { path: PathBuf },
}

/// A single-panel PNG (about 1000 x 600 pixels) with a legend.
pub fn line_plot(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    log_x: bool,
    log_y: bool,
) -> Result<(), PlotError> {
    let panel = Panel {
        title,
        x_label,
        y_label,
        series: series.to_vec(),
        log_x,
        log_y,
    };
    check_folder(path)?;
    let root = BitMapBackend::new(path, SINGLE_SIZE).into_drawing_area();
    let err = |e: String| PlotError::Draw {
        path: path.to_path_buf(),
        message: e,
    };
    root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
    draw_panel(&root, &panel, 28).map_err(err)?;
    root.present().map_err(|e| err(e.to_string()))
}

/// Several panels in a grid of `columns` columns (rows as needed), with an overall title.
pub fn grid_plot(
    path: &Path,
    title: &str,
    panels: &[Panel],
    columns: usize,
) -> Result<(), PlotError> {
    if panels.is_empty() {
        return Err(PlotError::NoPanels {
            path: path.to_path_buf(),
        });
    }
    check_folder(path)?;
    let cols = columns.clamp(1, panels.len());
    let rows = panels.len().div_ceil(cols);
    let title_h = 50u32;
    let size = (
        PANEL_SIZE.0 * cols as u32,
        PANEL_SIZE.1 * rows as u32 + title_h,
    );
    let root = BitMapBackend::new(path, size).into_drawing_area();
    let err = |e: String| PlotError::Draw {
        path: path.to_path_buf(),
        message: e,
    };
    root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
    let (top, body) = root.split_vertically(title_h);
    top.titled(title, ("sans-serif", 30))
        .map_err(|e| err(e.to_string()))?;
    let areas = body.split_evenly((rows, cols));
    for (area, panel) in areas.iter().zip(panels) {
        draw_panel(area, panel, 20).map_err(err)?;
    }
    root.present().map_err(|e| err(e.to_string()))
}

fn check_folder(path: &Path) -> Result<(), PlotError> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty())
        && !dir.is_dir()
    {
        return Err(PlotError::NoFolder {
            path: path.to_path_buf(),
            dir: dir.to_path_buf(),
        });
    }
    Ok(())
}

/// Can this value be shown on an axis of this kind?
fn shown(v: f64, log: bool) -> bool {
    v.is_finite() && (!log || v > 0.0)
}

/// Axis range covering the shown values, padded by 5 % (in decades for a log axis); a default range when
/// nothing is shown, a widened one around constant data.
fn axis_range(values: impl Iterator<Item = f64>, log: bool) -> Range<f64> {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|&v| shown(v, log)) {
        let v = if log { v.log10() } else { v };
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if lo > hi {
        return if log { 1.0..10.0 } else { 0.0..1.0 };
    }
    if hi - lo <= 1e-12 * lo.abs().max(hi.abs()).max(1e-300) {
        let pad = if log { 0.5 } else { 0.1 * lo.abs().max(1e-3) };
        lo -= pad;
        hi += pad;
    } else {
        let m = 0.05 * (hi - lo);
        lo -= m;
        hi += m;
    }
    if log {
        10f64.powf(lo)..10f64.powf(hi)
    } else {
        lo..hi
    }
}

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
    title_size: u32,
) -> Result<(), String> {
    let xr = axis_range(
        panel
            .series
            .iter()
            .flat_map(|s| s.points.iter().map(|p| p.0)),
        panel.log_x,
    );
    let yr = axis_range(
        panel
            .series
            .iter()
            .flat_map(|s| s.points.iter().filter(|p| shown(p.0, panel.log_x)))
            .map(|p| p.1),
        panel.log_y,
    );
    match (panel.log_x, panel.log_y) {
        (false, false) => draw_chart(area, panel, title_size, xr, yr),
        (true, false) => draw_chart(area, panel, title_size, xr.log_scale(), yr),
        (false, true) => draw_chart(area, panel, title_size, xr, yr.log_scale()),
        (true, true) => draw_chart(area, panel, title_size, xr.log_scale(), yr.log_scale()),
    }
}

/// A compact tick label: at most four significant digits, no trailing zeros, scientific notation for
/// very large or small magnitudes.
fn tick(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 || !a.is_finite() {
        return if a == 0.0 { "0".into() } else { format!("{v}") };
    }
    if !(1e-3..1e5).contains(&a) {
        return format!("{v:.2e}");
    }
    let decimals = (3 - a.log10().floor() as i32).max(0) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// [`tick`], or nothing when `thin` and `v` is not 1, 2, 3 or 5 times a power of ten.
fn label_of(v: f64, thin: bool) -> String {
    if thin && v > 0.0 {
        let m = v / 10f64.powf(v.log10().floor());
        if ![1.0, 2.0, 3.0, 5.0, 10.0]
            .iter()
            .any(|k| (m - k).abs() < 1e-6 * k)
        {
            return String::new();
        }
    }
    tick(v)
}

/// Runs of consecutive drawable points (a non-drawable point ends a run).
fn runs(points: &[(f64, f64)], log_x: bool, log_y: bool) -> Vec<Vec<(f64, f64)>> {
    let mut out = vec![Vec::new()];
    for &(x, y) in points {
        if shown(x, log_x) && shown(y, log_y) {
            out.last_mut().expect("non-empty").push((x, y));
        } else if !out.last().expect("non-empty").is_empty() {
            out.push(Vec::new());
        }
    }
    out.retain(|r| !r.is_empty());
    out
}

fn draw_chart<DB, X, Y>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
    title_size: u32,
    x: X,
    y: Y,
) -> Result<(), String>
where
    DB: DrawingBackend,
    X: AsRangedCoord<Value = f64>,
    Y: AsRangedCoord<Value = f64>,
    X::CoordDescType: Ranged<ValueType = f64> + ValueFormatter<f64>,
    Y::CoordDescType: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    let e = |e: &dyn std::fmt::Display| e.to_string();
    // A log axis over more than a decade gets a key point at every 1..9 x 10^k, whose labels collide
    // (e.g. "4000500060007000"): label only 1, 2, 3 and 5 x 10^k there.
    let spans_decade = |v: Vec<f64>| {
        let (lo, hi) = v
            .iter()
            .filter(|x| shown(**x, true))
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), &x| {
                (lo.min(x), hi.max(x))
            });
        hi / lo >= 10.0
    };
    let points = |i: usize| -> Vec<f64> {
        panel
            .series
            .iter()
            .flat_map(|s| s.points.iter().map(move |p| if i == 0 { p.0 } else { p.1 }))
            .collect()
    };
    let thin_x = panel.log_x && spans_decade(points(0));
    let thin_y = panel.log_y && spans_decade(points(1));
    let mut chart = ChartBuilder::on(area)
        .caption(panel.title, ("sans-serif", title_size))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(x, y)
        .map_err(|x| e(&x))?;
    chart
        .configure_mesh()
        .x_desc(panel.x_label)
        .y_desc(panel.y_label)
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 17))
        .light_line_style(RGBColor(235, 235, 235))
        .x_labels(10)
        .y_labels(10)
        .x_label_formatter(&|v| label_of(*v, thin_x))
        .y_label_formatter(&|v| label_of(*v, thin_y))
        .draw()
        .map_err(|x| e(&x))?;
    let mut any_label = false;
    for s in &panel.series {
        let color = PALETTE[s.color % PALETTE.len()];
        let style = color.stroke_width(2);
        let pieces = runs(&s.points, panel.log_x, panel.log_y);
        let mut first = true;
        // An unlabelled series gets no legend entry at all (a legend mark alone would show as an empty row).
        let mut label = |anno: &mut SeriesAnno<'_, DB>| {
            let labelled = !s.label.is_empty();
            if labelled {
                any_label = true;
                anno.label(s.label);
            }
            labelled
        };
        match s.style {
            SeriesStyle::Points => {
                let pts: Vec<(f64, f64)> = pieces.into_iter().flatten().collect();
                let anno = chart
                    .draw_series(pts.into_iter().map(|p| Circle::new(p, 4, color.filled())))
                    .map_err(|x| e(&x))?;
                if label(anno) {
                    anno.legend(move |(x, y)| Circle::new((x + 10, y), 4, color.filled()));
                }
            }
            SeriesStyle::Line | SeriesStyle::Dashed => {
                let dashed = s.style == SeriesStyle::Dashed;
                let pieces = if pieces.is_empty() {
                    vec![Vec::new()]
                } else {
                    pieces
                };
                for piece in pieces {
                    let anno = if dashed {
                        chart.draw_series(DashedLineSeries::new(piece, 10, 6, style))
                    } else {
                        chart.draw_series(LineSeries::new(piece, style))
                    }
                    .map_err(|x| e(&x))?;
                    if std::mem::take(&mut first) && label(anno) {
                        if dashed {
                            anno.legend(move |(x, y)| {
                                EmptyElement::at((x, y))
                                    + PathElement::new(vec![(0, 0), (8, 0)], style)
                                    + PathElement::new(vec![(12, 0), (20, 0)], style)
                            });
                        } else {
                            anno.legend(move |(x, y)| {
                                PathElement::new(vec![(x, y), (x + 20, y)], style)
                            });
                        }
                    }
                }
            }
        }
    }
    if any_label {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 15))
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(|x| e(&x))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thinned_log_labels_keep_1_2_3_5() {
        let shown: Vec<String> = [
            300.0, 400.0, 1000.0, 2000.0, 3000.0, 4000.0, 5000.0, 7000.0, 1e4,
        ]
        .iter()
        .map(|&v| label_of(v, true))
        .collect();
        assert_eq!(
            shown,
            ["300", "", "1000", "2000", "3000", "", "5000", "", "10000"]
        );
        assert_eq!(label_of(4000.0, false), "4000");
        assert_eq!(label_of(0.0004, true), "");
        assert_eq!(label_of(0.0005, true), "5.00e-4");
    }

    fn tmp(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("backlash-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir.join(name)
    }

    fn is_png(p: &Path) -> bool {
        let b = std::fs::read(p).unwrap();
        b.len() > 1000 && b[..8] == [0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a]
    }

    #[test]
    fn ranges_are_robust() {
        assert_eq!(axis_range([].into_iter(), false), 0.0..1.0);
        assert_eq!(axis_range([f64::NAN].into_iter(), true), 1.0..10.0);
        let r = axis_range([2.0, 2.0].into_iter(), false);
        assert!(r.start < 2.0 && r.end > 2.0);
        let r = axis_range([0.0, 0.0].into_iter(), false);
        assert!(r.start < 0.0 && r.end > 0.0);
        let r = axis_range([-1.0, 0.0, 10.0, 100.0].into_iter(), true);
        assert!(r.start < 10.0 && r.start > 5.0 && r.end > 100.0 && r.end < 200.0);
    }

    #[test]
    fn ticks_are_compact() {
        assert_eq!(tick(0.30000000000000004), "0.3");
        assert_eq!(tick(0.0), "0");
        assert_eq!(tick(-2.5), "-2.5");
        assert_eq!(tick(1234.5678), "1235");
        assert_eq!(tick(0.012345), "0.01235");
        assert_eq!(tick(1e-7), "1.00e-7");
        assert_eq!(tick(100.0), "100");
    }

    #[test]
    fn runs_break_at_bad_points() {
        let r = runs(
            &[
                (1.0, 1.0),
                (2.0, f64::NAN),
                (3.0, 1.0),
                (4.0, 2.0),
                (5.0, -1.0),
            ],
            false,
            true,
        );
        assert_eq!(r, vec![vec![(1.0, 1.0)], vec![(3.0, 1.0), (4.0, 2.0)]]);
    }

    #[test]
    fn writes_pngs_for_awkward_data() {
        let sine: Vec<(f64, f64)> = (1..200)
            .map(|k| (k as f64 * 0.05, 1.0 + (k as f64 * 0.05).sin().abs()))
            .collect();
        let p = tmp("line.png");
        line_plot(
            &p,
            "Line, dashed, points",
            "x",
            "y",
            &[
                Series::line("line", sine.clone()),
                Series::dashed("dashed", sine.iter().map(|&(x, y)| (x, y + 0.5)).collect())
                    .color(1),
                Series::points("points", vec![(1.0, 1.5), (2.0, f64::NAN), (3.0, 1.2)]).color(2),
                Series::line("empty", Vec::new()).color(3),
            ],
            false,
            false,
        )
        .unwrap();
        assert!(is_png(&p));
        let p = tmp("loglog.png");
        line_plot(
            &p,
            "Log-log",
            "w",
            "|G|",
            &[Series::line("", sine)],
            true,
            true,
        )
        .unwrap();
        assert!(is_png(&p));
        let p = tmp("empty.png");
        line_plot(&p, "Nothing", "x", "y", &[], true, false).unwrap();
        assert!(is_png(&p));
        let p = tmp("grid.png");
        let panel = |t| Panel {
            title: t,
            x_label: "x",
            y_label: "y",
            series: vec![Series::line("const", vec![(0.0, 3.0), (1.0, 3.0)])],
            log_x: false,
            log_y: true,
        };
        grid_plot(&p, "Grid", &[panel("a"), panel("b"), panel("c")], 2).unwrap();
        assert!(is_png(&p));
        assert!(matches!(
            grid_plot(&p, "Grid", &[], 2),
            Err(PlotError::NoPanels { .. })
        ));
        assert!(matches!(
            line_plot(
                Path::new("/nonexistent-dir/x.png"),
                "t",
                "x",
                "y",
                &[],
                false,
                false
            ),
            Err(PlotError::NoFolder { .. })
        ));
        let _ = std::fs::remove_dir_all(p.parent().unwrap());
    }
}
