//! PNG plots with plotters: lines, dashed lines and markers, linear or log axes, and a legend in a
//! column right of the chart (never over the data; long labels wrap; none when no series is labelled).
//! Tick labels are compact, and a tick that is zero up to rounding prints as 0.
//!
//! Robust to awkward data: non-finite points are skipped (a line is broken there rather than joined
//! across the gap), points that a log axis cannot show (`<= 0`) are skipped too, an empty plot gets a
//! default range, and constant data get a range padded around the constant.
//!
//! ```no_run
//! use backlash::report::plot::{Axes, line_plot, Series};
//! let pts: Vec<(f64, f64)> = (0..100).map(|k| (k as f64, (k as f64 / 10.0).sin())).collect();
//! line_plot(
//!     std::path::Path::new("sine.png"),
//!     "A sine",
//!     "k",
//!     "sin(k/10)",
//!     &[Series::line("sin", pts)],
//!     Axes::LINEAR,
//! )
//! .unwrap();
//! ```

use std::borrow::Cow;
use std::ops::Range;
use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, Ranged, ValueFormatter};
use plotters::prelude::*;

/// The plots' one font, DejaVu Sans (its licence: assets/fonts/LICENSE-DejaVu.txt), inside the binary: text looks
/// the same everywhere, and neither the program nor the Python extension links the system's font libraries
/// (fontconfig, freetype), so that the wheel is manylinux2014.
const FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// Registers [`FONT`] as plotters' "sans-serif" (once per process), before anything is drawn.
fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // The bundled file parses (checked by the test `the_bundled_font_registers`).
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

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
    pub label: Cow<'a, str>,
    pub points: Vec<(f64, f64)>,
    pub style: SeriesStyle,
    /// Index into [`PALETTE`] (modulo its length).
    pub color: usize,
}

impl<'a> Series<'a> {
    pub fn new(
        label: impl Into<Cow<'a, str>>,
        points: Vec<(f64, f64)>,
        style: SeriesStyle,
        color: usize,
    ) -> Self {
        Self {
            label: label.into(),
            points,
            style,
            color,
        }
    }

    /// A solid line in colour 0.
    pub fn line(label: impl Into<Cow<'a, str>>, points: Vec<(f64, f64)>) -> Self {
        Self::new(label, points, SeriesStyle::Line, 0)
    }

    /// Markers in colour 0.
    pub fn points(label: impl Into<Cow<'a, str>>, points: Vec<(f64, f64)>) -> Self {
        Self::new(label, points, SeriesStyle::Points, 0)
    }

    /// A dashed line in colour 0.
    pub fn dashed(label: impl Into<Cow<'a, str>>, points: Vec<(f64, f64)>) -> Self {
        Self::new(label, points, SeriesStyle::Dashed, 0)
    }

    /// The same series in another colour.
    pub fn color(mut self, color: usize) -> Self {
        self.color = color;
        self
    }
}

/// How an axis maps values to positions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Scale {
    #[default]
    Linear,
    /// Logarithmic: values `<= 0` cannot be shown and are skipped.
    Log,
}

/// The scales of a chart's horizontal (`x`) and vertical (`y`) axes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Axes {
    pub x: Scale,
    pub y: Scale,
}

impl Axes {
    /// Both axes linear.
    pub const LINEAR: Axes = Axes {
        x: Scale::Linear,
        y: Scale::Linear,
    };
    /// Logarithmic x (a frequency, say), linear y.
    pub const LOG_X: Axes = Axes {
        x: Scale::Log,
        y: Scale::Linear,
    };
    /// Both axes logarithmic.
    pub const LOG_LOG: Axes = Axes {
        x: Scale::Log,
        y: Scale::Log,
    };
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

/// A single-panel PNG (about 1000 x 600 pixels) with a legend beside the chart.
pub fn line_plot(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    axes: Axes,
) -> Result<(), PlotError> {
    let panel = Panel {
        title,
        x_label,
        y_label,
        series: series.to_vec(),
        log_x: axes.x == Scale::Log,
        log_y: axes.y == Scale::Log,
    };
    check_folder(path)?;
    register_font();
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
    register_font();
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

/// A tick whose magnitude is below this fraction of its linear axis' span is zero up to rounding (the
/// tick generator's `-1.39e-17`) and prints as `0`.
const ZERO_TICK: f64 = 1e-9;
/// Blank space around a chart, pixels.
const CHART_MARGIN: u32 = 12;
/// Font size of the legend's labels.
const LEGEND_FONT: u32 = 15;
/// Height of one line of legend text, pixels.
const LEGEND_LINE: u32 = LEGEND_FONT + 4;
/// Vertical space between two legend entries, pixels.
const LEGEND_GAP: u32 = 6;
/// Space between the legend's frame and its content, pixels.
const LEGEND_PAD: u32 = 8;
/// Width of a legend mark (a line, a dashed line or a circle), pixels.
const LEGEND_MARK: u32 = 24;
/// Space between a legend mark and its label, pixels.
const LEGEND_MARK_GAP: u32 = 8;
/// Blank space right of the legend's frame, pixels.
const LEGEND_OUTSIDE: u32 = 8;
/// Everything in a legend column's width except the label text, pixels.
const LEGEND_CHROME: u32 = 2 * LEGEND_PAD + LEGEND_MARK + LEGEND_MARK_GAP + LEGEND_OUTSIDE;
/// The legend column takes at most this fraction of a panel's width; longer labels wrap.
const LEGEND_MAX_FRACTION: f64 = 0.35;

/// A rectangle of pixels inside a panel: left, top, width, height.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Rect {
    x: u32,
    y: u32,
    w: u32,
    h: u32,
}

/// Splits a panel body of `width` x `height` pixels into the chart (left) and a legend column (right)
/// `legend_w` pixels wide, at most [`LEGEND_MAX_FRACTION`] of the width; no column when `legend_w` is 0
/// (no labelled series), so the chart keeps the whole body.
fn legend_layout(width: u32, height: u32, legend_w: u32) -> (Rect, Option<Rect>) {
    let legend_w = legend_w.min((width as f64 * LEGEND_MAX_FRACTION) as u32);
    let chart = Rect {
        x: 0,
        y: 0,
        w: width - legend_w,
        h: height,
    };
    let legend = (legend_w > 0).then_some(Rect {
        x: chart.w,
        y: 0,
        w: legend_w,
        h: height,
    });
    (chart, legend)
}

/// Breaks `text` into lines no wider than `max_w` (as measured by `width_of`) at spaces; a word wider
/// than `max_w` on its own is cut between characters.
fn wrap(text: &str, max_w: u32, width_of: impl Fn(&str) -> u32) -> Vec<String> {
    let mut lines = Vec::new();
    let mut line = String::new();
    for word in text.split_whitespace() {
        let joined = if line.is_empty() {
            word.to_string()
        } else {
            format!("{line} {word}")
        };
        if width_of(&joined) <= max_w {
            line = joined;
            continue;
        }
        if !line.is_empty() {
            lines.push(std::mem::take(&mut line));
        }
        for c in word.chars() {
            line.push(c);
            if line.chars().count() > 1 && width_of(&line) > max_w {
                line.pop();
                lines.push(std::mem::replace(&mut line, c.to_string()));
            }
        }
    }
    if !line.is_empty() {
        lines.push(line);
    }
    lines
}

/// Width of `text` in the legend font on `area`; when the font cannot be measured, 0.6 of the font
/// size per character (a generous average for sans-serif).
fn text_width<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, text: &str) -> u32 {
    area.estimate_text_size(text, &("sans-serif", LEGEND_FONT).into_font().into())
        .map(|(w, _)| w)
        .unwrap_or((text.chars().count() as f64 * 0.6 * LEGEND_FONT as f64).ceil() as u32)
}

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
    title_size: u32,
) -> Result<(), String> {
    let e = |e: &dyn std::fmt::Display| e.to_string();
    let body = area
        .margin(CHART_MARGIN / 2, 0, 0, 0)
        .titled(panel.title, ("sans-serif", title_size))
        .map_err(|x| e(&x))?;
    let labelled: Vec<&Series> = panel
        .series
        .iter()
        .filter(|s| !s.label.is_empty())
        .collect();
    let wanted = labelled
        .iter()
        .map(|s| text_width(&body, &s.label))
        .max()
        .map_or(0, |w| w + LEGEND_CHROME);
    let (w, h) = body.dim_in_pixel();
    let (chart, legend) = legend_layout(w, h, wanted);
    let (chart_area, legend_area) = body.split_horizontally(chart.w);
    draw_data(&chart_area, panel)?;
    if legend.is_some() {
        draw_legend(&legend_area, &labelled)?;
    }
    Ok(())
}

/// Axes, ticks and curves of a panel on `area` (no title, no legend).
fn draw_data<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
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
    let ticks = (
        TickLabels::of(&xr, panel.log_x)
            .whole_numbers(all_whole(panel.series.iter().map(|s| &s.points), |p| p.0)),
        TickLabels::of(&yr, panel.log_y)
            .whole_numbers(all_whole(panel.series.iter().map(|s| &s.points), |p| p.1)),
    );
    match (panel.log_x, panel.log_y) {
        (false, false) => draw_chart(area, panel, ticks, xr, yr),
        (true, false) => draw_chart(area, panel, ticks, xr.log_scale(), yr),
        (false, true) => draw_chart(area, panel, ticks, xr, yr.log_scale()),
        (true, true) => draw_chart(area, panel, ticks, xr.log_scale(), yr.log_scale()),
    }
}

/// Whether the coordinate `of` of every finite point is a whole number (and there is one at least).
fn all_whole<'p>(
    series: impl Iterator<Item = &'p Vec<(f64, f64)>>,
    of: impl Fn(&(f64, f64)) -> f64,
) -> bool {
    let mut any = false;
    for v in series.flatten().map(of).filter(|v| v.is_finite()) {
        if v.fract() != 0.0 {
            return false;
        }
        any = true;
    }
    any
}

/// The legend column: for each labelled series its mark and its label, wrapped to the column's width,
/// in a frame whose top is level with the chart's.
fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    labelled: &[&Series],
) -> Result<(), String> {
    let e = |e: &dyn std::fmt::Display| e.to_string();
    let (w, _) = area.dim_in_pixel();
    let text_w = w.saturating_sub(LEGEND_CHROME).max(1);
    let rows: Vec<(&Series, Vec<String>)> = labelled
        .iter()
        .map(|s| (*s, wrap(&s.label, text_w, |t| text_width(area, t))))
        .collect();
    let lines: u32 = rows.iter().map(|(_, l)| l.len() as u32).sum();
    let top = CHART_MARGIN as i32;
    let height = lines * LEGEND_LINE + (rows.len() as u32 - 1) * LEGEND_GAP + 2 * LEGEND_PAD;
    let right = w.saturating_sub(LEGEND_OUTSIDE + 1) as i32;
    area.draw(&Rectangle::new(
        [(0, top), (right, top + height as i32)],
        RGBColor(160, 160, 160),
    ))
    .map_err(|x| e(&x))?;
    let font = ("sans-serif", LEGEND_FONT).into_font().color(&BLACK);
    let mark_x = LEGEND_PAD as i32;
    let text_x = mark_x + (LEGEND_MARK + LEGEND_MARK_GAP) as i32;
    let mut y = top + LEGEND_PAD as i32;
    for (s, label) in rows {
        draw_mark(area, s, (mark_x, y + LEGEND_LINE as i32 / 2)).map_err(|x| e(&x))?;
        for line in &label {
            area.draw(&Text::new(line.as_str(), (text_x, y), font.clone()))
                .map_err(|x| e(&x))?;
            y += LEGEND_LINE as i32;
        }
        y += LEGEND_GAP as i32;
    }
    Ok(())
}

/// A series' legend mark with its left end at `(x, y)`: a line, a dashed line or a circle.
fn draw_mark<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    s: &Series,
    (x, y): (i32, i32),
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let color = PALETTE[s.color % PALETTE.len()];
    let style = color.stroke_width(2);
    let m = LEGEND_MARK as i32;
    match s.style {
        SeriesStyle::Line => area.draw(&PathElement::new(vec![(x, y), (x + m, y)], style)),
        SeriesStyle::Dashed => {
            area.draw(&PathElement::new(vec![(x, y), (x + 9, y)], style))?;
            area.draw(&PathElement::new(vec![(x + m - 9, y), (x + m, y)], style))
        }
        SeriesStyle::Points => area.draw(&Circle::new((x + m / 2, y), 4, color.filled())),
    }
}

/// How an axis labels its ticks.
#[derive(Debug, Clone, Copy, PartialEq)]
struct TickLabels {
    /// Label only 1, 2, 3 and 5 x 10^k (a log axis over a decade or more, whose key points at every
    /// 1..9 x 10^k would collide, e.g. "4000500060007000").
    thin: bool,
    /// Span of a linear axis (ticks much smaller than it print as 0); 0 on a log axis, whose ticks are
    /// never zero.
    span: f64,
    /// Label whole numbers only (a linear axis whose data are all whole numbers: steps, lags, counts),
    /// so that an axis of whole steps never shows 0.5.
    whole: bool,
}

impl TickLabels {
    fn of(range: &Range<f64>, log: bool) -> Self {
        if log {
            Self {
                thin: range.end / range.start >= 10.0,
                span: 0.0,
                whole: false,
            }
        } else {
            Self {
                thin: false,
                span: range.end - range.start,
                whole: false,
            }
        }
    }

    /// The same labels, whole numbers only when `whole` (and the axis is linear).
    fn whole_numbers(self, whole: bool) -> Self {
        Self {
            whole: whole && self.span > 0.0,
            ..self
        }
    }

    /// [`tick`], or nothing when thinning and `v` is not 1, 2, 3 or 5 times a power of ten, or on a
    /// whole-number axis when `v` is not a whole number.
    fn label(&self, v: f64) -> String {
        if self.whole && (v - v.round()).abs() > ZERO_TICK * self.span {
            return String::new();
        }
        if self.thin && v > 0.0 {
            let m = v / 10f64.powf(v.log10().floor());
            if ![1.0, 2.0, 3.0, 5.0, 10.0]
                .iter()
                .any(|k| (m - k).abs() < 1e-6 * k)
            {
                return String::new();
            }
        }
        tick(v, self.span)
    }
}

/// A compact tick label: at most four significant digits, no trailing zeros, scientific notation for
/// very large or small magnitudes, and `0` for a value that is zero up to rounding on an axis of
/// this `span` (below [`ZERO_TICK`] of it).
fn tick(v: f64, span: f64) -> String {
    let a = v.abs();
    if a == 0.0 || a < ZERO_TICK * span {
        return "0".into();
    }
    if !a.is_finite() {
        return format!("{v}");
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
    (x_ticks, y_ticks): (TickLabels, TickLabels),
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
    let mut chart = ChartBuilder::on(area)
        .margin(CHART_MARGIN)
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
        .x_label_formatter(&|v| x_ticks.label(*v))
        .y_label_formatter(&|v| y_ticks.label(*v))
        .draw()
        .map_err(|x| e(&x))?;
    for s in &panel.series {
        let color = PALETTE[s.color % PALETTE.len()];
        let style = color.stroke_width(2);
        let pieces = runs(&s.points, panel.log_x, panel.log_y);
        match s.style {
            SeriesStyle::Points => {
                let pts = pieces.into_iter().flatten();
                chart
                    .draw_series(pts.map(|p| Circle::new(p, 4, color.filled())))
                    .map_err(|x| e(&x))?;
            }
            SeriesStyle::Line => {
                // Segment by segment: plotters joins the segments of a thick polyline with mitres, which at
                // a sharp spike reach far past it (a series that is never negative was drawn below 0).
                for piece in pieces {
                    let segments = piece
                        .windows(2)
                        .map(|w| PathElement::new(vec![w[0], w[1]], style));
                    chart.draw_series(segments).map_err(|x| e(&x))?;
                }
            }
            SeriesStyle::Dashed => {
                for piece in pieces {
                    chart
                        .draw_series(DashedLineSeries::new(piece, 10, 6, style))
                        .map_err(|x| e(&x))?;
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bundled_font_registers() {
        assert!(plotters::style::register_font("bundled", FontStyle::Normal, FONT).is_ok());
    }

    #[test]
    fn thinned_log_labels_keep_1_2_3_5() {
        let log = TickLabels::of(&(250.0..12000.0), true);
        assert!(log.thin);
        let shown: Vec<String> = [
            300.0, 400.0, 1000.0, 2000.0, 3000.0, 4000.0, 5000.0, 7000.0, 1e4,
        ]
        .iter()
        .map(|&v| log.label(v))
        .collect();
        assert_eq!(
            shown,
            ["300", "", "1000", "2000", "3000", "", "5000", "", "10000"]
        );
        let within_a_decade = TickLabels::of(&(2000.0..9000.0), true);
        assert_eq!(within_a_decade.label(4000.0), "4000");
        assert_eq!(log.label(0.0004), "");
        assert_eq!(log.label(0.0005), "5.00e-4");
        // a log axis never snaps a small tick to zero, however wide it is
        let wide = TickLabels::of(&(1e-14..1e3), true);
        assert_eq!(wide.label(1e-12), "1.00e-12");
    }

    /// An axis whose data are whole numbers (steps 0, 1, 2) labels whole ticks only: 0.5 and 1.5 are
    /// left blank, 0 and 1 printed; data with a fraction anywhere keep every tick.
    #[test]
    fn whole_number_axes_label_whole_ticks_only() {
        let steps = [vec![(0.0, 0.3), (1.0, 0.25)], vec![(0.0, 0.1), (2.0, 0.1)]];
        assert!(all_whole(steps.iter(), |p| p.0));
        assert!(!all_whole(steps.iter(), |p| p.1));
        assert!(!all_whole([vec![(f64::NAN, 1.0)]].iter(), |p| p.0));
        let x = TickLabels::of(&(-0.1..2.1), false).whole_numbers(true);
        let shown: Vec<String> = [0.0, 0.5, 1.0, 1.5, 2.0]
            .iter()
            .map(|&v| x.label(v))
            .collect();
        assert_eq!(shown, ["0", "", "1", "", "2"]);
        let plain = TickLabels::of(&(-0.1..2.1), false).whole_numbers(false);
        assert_eq!(plain.label(0.5), "0.5");
        // a log axis is never a whole-number one
        assert!(
            !TickLabels::of(&(1.0..100.0), true)
                .whole_numbers(true)
                .whole
        );
    }

    #[test]
    fn zero_up_to_rounding_prints_as_zero() {
        assert_eq!(tick(1e-17, 1.0), "0");
        assert_eq!(tick(-1.39e-17, 2.0), "0");
        assert_eq!(tick(1e-17, 1e-16), "1.00e-17");
        assert_eq!(tick(-2e-9, 1.0), "-2.00e-9");
        let lin = TickLabels::of(&(-0.7..1.3), false);
        assert!(!lin.thin);
        assert_eq!(lin.label(-1.39e-17), "0");
        assert_eq!(lin.label(0.2), "0.2");
        let tiny = TickLabels::of(&(-3e-16..5e-16), false);
        assert_eq!(tiny.label(1e-16), "1.00e-16");
    }

    impl Rect {
        fn overlaps(&self, other: &Rect) -> bool {
            self.x < other.x + other.w
                && other.x < self.x + self.w
                && self.y < other.y + other.h
                && other.y < self.y + self.h
        }
    }

    #[test]
    fn legend_column_never_overlaps_the_chart() {
        for (w, h) in [SINGLE_SIZE, PANEL_SIZE, (100, 80)] {
            for wanted in [1, 60, 200, 5000] {
                let (chart, legend) = legend_layout(w, h, wanted);
                let legend = legend.expect("a labelled series gets a legend");
                assert!(!chart.overlaps(&legend), "{w}x{h}, {wanted}: overlap");
                assert_eq!(chart.w + legend.w, w);
                assert_eq!((chart.h, legend.h), (h, h));
                assert!(legend.w <= wanted && legend.w as f64 <= LEGEND_MAX_FRACTION * w as f64);
                assert!(
                    legend.w == wanted || legend.w as f64 >= LEGEND_MAX_FRACTION * w as f64 - 1.0
                );
            }
            let (chart, legend) = legend_layout(w, h, 0);
            assert_eq!((chart, legend), (Rect { x: 0, y: 0, w, h }, None));
        }
        let a = Rect {
            x: 0,
            y: 0,
            w: 10,
            h: 10,
        };
        assert!(a.overlaps(&Rect {
            x: 9,
            y: 9,
            w: 5,
            h: 5
        }));
        assert!(!a.overlaps(&Rect {
            x: 10,
            y: 0,
            w: 5,
            h: 5
        }));
    }

    #[test]
    fn long_labels_wrap_within_the_column() {
        let width = |t: &str| 8 * t.chars().count() as u32;
        let lines = wrap(
            "held-out free-run simulation of the fitted model",
            100,
            width,
        );
        assert_eq!(
            lines,
            [
                "held-out",
                "free-run",
                "simulation",
                "of the",
                "fitted model"
            ]
        );
        assert!(lines.iter().all(|l| width(l) <= 100));
        assert_eq!(wrap("short", 100, width), ["short"]);
        assert_eq!(wrap("abcdefghij", 32, width), ["abcd", "efgh", "ij"]);
        assert_eq!(wrap("abc", 1, width), ["a", "b", "c"]);
        assert!(wrap("", 100, width).is_empty());
    }

    /// RGB pixels of `panel` drawn on a white `size` canvas as [`line_plot`] and [`grid_plot`] draw it.
    fn render(panel: &Panel, size: (u32, u32)) -> Vec<u8> {
        let mut buf = vec![0u8; 3 * (size.0 * size.1) as usize];
        super::register_font();
        {
            let root = BitMapBackend::with_buffer(&mut buf, size).into_drawing_area();
            root.fill(&WHITE).unwrap();
            draw_panel(&root, panel, 20).unwrap();
            root.present().unwrap();
        }
        buf
    }

    /// For each pixel row, the first column and length of its longest run of `color`.
    fn longest_runs(buf: &[u8], size: (u32, u32), color: RGBColor) -> Vec<(usize, usize)> {
        buf.chunks(3 * size.0 as usize)
            .map(|row| {
                let (mut best, mut start, mut len) = ((0, 0), 0, 0);
                for (i, px) in row.chunks(3).enumerate() {
                    if px == [color.0, color.1, color.2] {
                        if len == 0 {
                            start = i;
                        }
                        len += 1;
                        if len > best.1 {
                            best = (start, len);
                        }
                    } else {
                        len = 0;
                    }
                }
                best
            })
            .collect()
    }

    /// A labelled series of overlapping circles that paints its whole data rectangle in one colour: a
    /// legend drawn over the data would cut the rows it covers short.
    #[test]
    fn legend_pixels_stay_off_the_data() {
        let color = 2;
        let rgb = PALETTE[color];
        let fill: Vec<(f64, f64)> = (0..=300)
            .flat_map(|i| (0..=150).map(move |j| (i as f64, j as f64)))
            .collect();
        let label = "every sample of the record, drawn as overlapping circles";
        for size in [SINGLE_SIZE, PANEL_SIZE] {
            let mut panel = Panel {
                title: "Filled",
                x_label: "t",
                y_label: "y",
                series: vec![Series::points(label, fill.clone()).color(color)],
                log_x: false,
                log_y: false,
            };
            let buf = render(&panel, size);
            let runs = longest_runs(&buf, size, rgb);
            let widest = runs.iter().map(|r| r.1).max().unwrap();
            let block: Vec<&(usize, usize)> = runs.iter().filter(|r| r.1 > widest / 2).collect();
            assert!(
                block.len() > size.1 as usize / 2,
                "{size:?}: data block too low"
            );
            for r in &block {
                assert!(
                    r.1 + 8 >= widest,
                    "{size:?}: a row of data is cut: {r:?} of {widest}"
                );
            }
            let data_right = block.iter().map(|r| r.0 + r.1).max().unwrap();
            // the legend's mark, in the series' colour, sits right of the data
            let mark = buf
                .chunks(3 * size.0 as usize)
                .flat_map(|row| row.chunks(3).skip(data_right + 1))
                .filter(|px| *px == [rgb.0, rgb.1, rgb.2])
                .count();
            assert!(mark > 20, "{size:?}: no legend mark right of the data");
            // without a label there is no legend, and the data take its room
            panel.series[0].label = "".into();
            let bare = longest_runs(&render(&panel, size), size, rgb);
            let bare_widest = bare.iter().map(|r| r.1).max().unwrap();
            assert!(
                bare_widest > widest + 50,
                "{size:?}: {bare_widest} vs {widest}"
            );
        }
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
        assert_eq!(tick(0.30000000000000004, 1.0), "0.3");
        assert_eq!(tick(0.0, 0.0), "0");
        assert_eq!(tick(-2.5, 10.0), "-2.5");
        assert_eq!(tick(1234.5678, 1e4), "1235");
        assert_eq!(tick(0.012345, 0.1), "0.01235");
        assert_eq!(tick(1e-7, 1e-6), "1.00e-7");
        assert_eq!(tick(100.0, 0.0), "100");
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
            Axes::LINEAR,
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
            Axes::LOG_LOG,
        )
        .unwrap();
        assert!(is_png(&p));
        let p = tmp("empty.png");
        line_plot(&p, "Nothing", "x", "y", &[], Axes::LOG_X).unwrap();
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
                Axes::LINEAR,
            ),
            Err(PlotError::NoFolder { .. })
        ));
        let _ = std::fs::remove_dir_all(p.parent().unwrap());
    }
}
