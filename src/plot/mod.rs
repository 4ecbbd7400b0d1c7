//! A tiny declarative plotting layer on top of `plotters`.
//!
//! A plot is described by plain data — a [`Figure`] holding a grid of
//! [`PanelContent`]s, each either a 2D [`Panel`] chart of [`Series`] or a
//! [`SparsityPanel`] showing the nonzero pattern of a sparse matrix — and
//! rendered by a single call, [`Figure::save_png`] or [`Figure::save_svg`].
//!
//! Rendering never panics on awkward data: NaN and infinite coordinates are
//! skipped (a line is broken at such a point), non-positive values are
//! skipped on [`Scale::Log10`] axes, and empty series or panels draw an empty
//! frame.  Lines are clipped to the plot area, markers outside it are dropped.
//!
//! Text is rendered with the DejaVu Sans font embedded in the binary, so no
//! system font configuration is needed.
//!
//! # Aligning a sparsity pattern under a chart
//!
//! Panels in the same grid column share the same left/right label-area
//! geometry, so their plot areas line up horizontally.  To draw the
//! transposed kernel matrix `K^T` (basis functions × samples) under a 1D plot
//! with column `j` placed at sample abscissa `x_j`, put the chart and the
//! sparsity panel in one column, set [`SparsityPanel::x_positions`] to the
//! sample positions, and give both panels the same `x_range` (with
//! `x_range: None` both use the exact data extent without padding, so they
//! also line up when the chart's x extent equals the sample extent).
//!
//! ```no_run
//! use rkwave::plot::{Figure, Panel, Scale, Series, SeriesStyle, SparsityPanel};
//!
//! let xs: Vec<f64> = (0..50).map(|i| i as f64 / 49.0).collect();
//! let samples: Vec<(f64, f64)> = xs.iter().map(|&x| (x, (6.0 * x).sin())).collect();
//! let chart = Panel {
//!     title: "Reconstruction".into(),
//!     x_label: "x".into(),
//!     y_label: "f(x)".into(),
//!     series: vec![
//!         Series::new("samples", samples.clone(), SeriesStyle::Markers),
//!         Series::new("fit", samples, SeriesStyle::Line),
//!     ],
//!     x_range: Some((0.0, 1.0)),
//!     ..Panel::default()
//! };
//! // K has one row per sample and one column per basis function; K^T is drawn.
//! let kt_entries: Vec<(usize, usize)> = (0..50).map(|s| (s / 5, s)).collect();
//! let pattern = SparsityPanel {
//!     title: "K^T".into(),
//!     x_label: "x".into(),
//!     y_label: "basis index".into(),
//!     shape: (10, 50),
//!     entries: kt_entries,
//!     x_positions: Some(xs),
//!     x_range: Some((0.0, 1.0)),
//!     ..SparsityPanel::default()
//! };
//! let fig = Figure {
//!     width: 900,
//!     height: 900,
//!     columns: 1,
//!     panels: vec![chart.into(), pattern.into()],
//! };
//! fig.save_png("fit.png".as_ref())?;
//! fig.save_svg("fit.svg".as_ref())?;
//! # Ok::<(), rkwave::plot::PlotError>(())
//! ```

use std::path::Path;
use std::sync::Once;

use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::register_font;

/// Error returned when a figure cannot be rendered or written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlotError {
    /// The figure could not be drawn (invalid description or a backend failure).
    #[error("cannot draw figure {path}: {message}")]
    Draw {
        /// Destination path of the figure.
        path: String,
        /// Description of what went wrong.
        message: String,
    },
    /// The rendered figure could not be encoded or written to disk.
    #[error("cannot write figure {path}: {source}")]
    Write {
        /// Destination path of the figure.
        path: String,
        /// Underlying encoding or I/O error.
        #[source]
        source: image::ImageError,
    },
}

/// The colour palette used for series (matplotlib's "tab10"), as RGB triples.
///
/// [`Series::color`] indexes into it (modulo its length).
pub const PALETTE: [(u8, u8, u8); 10] = [
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (214, 39, 40),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (127, 127, 127),
    (188, 189, 34),
    (23, 190, 207),
];

/// How the points of a [`Series`] are drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SeriesStyle {
    /// Solid polyline through the points.
    #[default]
    Line,
    /// Dashed polyline through the points.
    Dashed,
    /// Filled circular markers, no line.
    Markers,
    /// Solid polyline with filled circular markers at the points.
    LineMarkers,
    /// Diagonal-cross markers, no line.
    Crosses,
}

/// Axis scale.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Scale {
    /// Linear axis.
    #[default]
    Linear,
    /// Base-10 logarithmic axis; non-positive values are skipped.
    Log10,
}

/// One labelled data series of a [`Panel`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Series {
    /// Legend label; an empty label keeps the series out of the legend.
    pub label: String,
    /// Points `(x, y)` in drawing order; non-finite points break lines.
    pub points: Vec<(f64, f64)>,
    /// How the points are drawn.
    pub style: SeriesStyle,
    /// Index into [`PALETTE`] (modulo its length); `None` uses the series'
    /// position within its panel.
    pub color: Option<usize>,
}

impl Series {
    /// A series with automatic colour.
    pub fn new(label: impl Into<String>, points: Vec<(f64, f64)>, style: SeriesStyle) -> Self {
        Series {
            label: label.into(),
            points,
            style,
            color: None,
        }
    }

    /// The same series with an explicit [`PALETTE`] index.
    pub fn with_color(mut self, color: usize) -> Self {
        self.color = Some(color);
        self
    }
}

/// A 2D chart: axes, labels, a legend and a set of series.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Panel {
    /// Title drawn above the chart (omitted when empty).
    pub title: String,
    /// Label of the horizontal axis.
    pub x_label: String,
    /// Label of the vertical axis.
    pub y_label: String,
    /// Scale of the horizontal axis.
    pub x_scale: Scale,
    /// Scale of the vertical axis.
    pub y_scale: Scale,
    /// The data series, drawn in order (later ones on top).
    pub series: Vec<Series>,
    /// Horizontal range in data units; `None` uses the exact data extent.
    pub x_range: Option<(f64, f64)>,
    /// Vertical range in data units; `None` uses the data extent plus 5 % padding.
    pub y_range: Option<(f64, f64)>,
}

/// The nonzero pattern of a sparse matrix, drawn as dots with row 0 at the top.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SparsityPanel {
    /// Title drawn above the pattern (omitted when empty).
    pub title: String,
    /// Label of the horizontal (column) axis.
    pub x_label: String,
    /// Label of the vertical (row) axis.
    pub y_label: String,
    /// Matrix shape `(rows, cols)`.
    pub shape: (usize, usize),
    /// Positions `(row, col)` of the nonzero entries; each must lie inside `shape`.
    pub entries: Vec<(usize, usize)>,
    /// Optional abscissa of every column (length `cols`), placing column `j`
    /// at `x_positions[j]` on a data axis instead of at index `j`; columns
    /// with a non-finite (or, on a log axis, non-positive) position are skipped.
    pub x_positions: Option<Vec<f64>>,
    /// Scale of the data axis; only used together with `x_positions`.
    pub x_scale: Scale,
    /// Horizontal range in data units, only used together with `x_positions`;
    /// `None` uses the exact extent of the positions.
    pub x_range: Option<(f64, f64)>,
    /// Index into [`PALETTE`] of the dot colour; `None` uses the first colour.
    pub color: Option<usize>,
}

/// What a grid cell of a [`Figure`] shows.
#[derive(Debug, Clone, PartialEq)]
pub enum PanelContent {
    /// A 2D chart of data series.
    Chart(Panel),
    /// A sparse-matrix nonzero pattern.
    Sparsity(SparsityPanel),
}

impl From<Panel> for PanelContent {
    fn from(panel: Panel) -> Self {
        PanelContent::Chart(panel)
    }
}

impl From<SparsityPanel> for PanelContent {
    fn from(panel: SparsityPanel) -> Self {
        PanelContent::Sparsity(panel)
    }
}

/// A figure: panels laid out row by row in a grid of equally sized cells.
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// The panels, filling the grid row by row.
    pub panels: Vec<PanelContent>,
    /// Number of grid columns (0 is treated as 1); the row count follows
    /// from the number of panels.
    pub columns: usize,
}

impl Figure {
    /// A single-column figure of the given size.
    pub fn new(width: u32, height: u32, panels: Vec<PanelContent>) -> Self {
        Figure {
            width,
            height,
            panels,
            columns: 1,
        }
    }

    /// Renders the figure and writes it as a PNG image to `path`
    /// (PNG regardless of the file extension).
    pub fn save_png(&self, path: &Path) -> Result<(), PlotError> {
        let draw_err = |message: String| PlotError::Draw {
            path: path.display().to_string(),
            message,
        };
        let (w, h) = (self.width, self.height);
        if w == 0 || h == 0 || u64::from(w) * u64::from(h) > MAX_PIXELS {
            return Err(draw_err(format!("invalid figure size {w}x{h}")));
        }
        let mut rgb = vec![0u8; w as usize * h as usize * 3];
        {
            let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
            self.render(&root).map_err(draw_err)?;
            root.present().map_err(|e| draw_err(e.to_string()))?;
        }
        let img = image::RgbImage::from_raw(w, h, rgb)
            .ok_or_else(|| draw_err("pixel buffer has the wrong size".into()))?;
        img.save_with_format(path, image::ImageFormat::Png)
            .map_err(|source| PlotError::Write {
                path: path.display().to_string(),
                source,
            })
    }

    /// Renders the figure and writes it as an SVG document to `path`.
    pub fn save_svg(&self, path: &Path) -> Result<(), PlotError> {
        let draw_err = |message: String| PlotError::Draw {
            path: path.display().to_string(),
            message,
        };
        let (w, h) = (self.width, self.height);
        if w == 0 || h == 0 {
            return Err(draw_err(format!("invalid figure size {w}x{h}")));
        }
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, (w, h)).into_drawing_area();
            self.render(&root).map_err(draw_err)?;
            root.present().map_err(|e| draw_err(e.to_string()))?;
        }
        std::fs::write(path, svg).map_err(|e| PlotError::Write {
            path: path.display().to_string(),
            source: image::ImageError::IoError(e),
        })
    }

    fn render<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        register_fonts();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        if self.panels.is_empty() {
            return Ok(());
        }
        let cols = self.columns.max(1);
        let rows = self.panels.len().div_ceil(cols);
        let cells = root.split_evenly((rows, cols));
        for (panel, cell) in self.panels.iter().zip(cells.iter()) {
            let layout = Layout::for_cell(cell.dim_in_pixel());
            match panel {
                PanelContent::Chart(p) => draw_chart(cell, p, &layout)?,
                PanelContent::Sparsity(p) => draw_sparsity(cell, p, &layout)?,
            }
        }
        Ok(())
    }
}

/// Largest accepted bitmap, in pixels.
const MAX_PIXELS: u64 = 1 << 28;

fn register_fonts() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        for family in ["sans-serif", "serif", "monospace"] {
            // The embedded DejaVu fonts are valid, so registration cannot fail.
            let _ = register_font(family, FontStyle::Normal, dejavu::sans::regular());
            let _ = register_font(family, FontStyle::Bold, dejavu::sans::bold());
        }
    });
}

fn palette_color(index: usize) -> RGBColor {
    let (r, g, b) = PALETTE[index % PALETTE.len()];
    RGBColor(r, g, b)
}

/// Pixel sizes shared by all panel kinds of a cell, so stacked panels align.
struct Layout {
    scale: f64,
    margin: u32,
    x_area: u32,
    y_area: u32,
    plot_w: f64,
    plot_h: f64,
}

impl Layout {
    fn for_cell((w, h): (u32, u32)) -> Self {
        let scale = (f64::from(h) / 380.0)
            .min(f64::from(w) / 560.0)
            .clamp(0.7, 2.5);
        let px = |v: f64| (v * scale).round() as u32;
        let (margin, x_area, y_area) = (px(12.0), px(48.0), px(80.0));
        let caption = px(30.0);
        Layout {
            scale,
            margin,
            x_area,
            y_area,
            plot_w: (f64::from(w) - f64::from(y_area + 3 * margin)).max(10.0),
            plot_h: (f64::from(h) - f64::from(x_area + caption + 2 * margin)).max(10.0),
        }
    }

    fn px(&self, v: f64) -> u32 {
        ((v * self.scale).round() as u32).max(1)
    }

    fn font(&self, size: f64, style: FontStyle) -> TextStyle<'static> {
        TextStyle::from(FontDesc::new(
            FontFamily::SansSerif,
            size * self.scale,
            style,
        ))
    }

    fn x_ticks(&self) -> usize {
        ((self.plot_w / (90.0 * self.scale)) as usize).clamp(2, 10)
    }

    fn y_ticks(&self) -> usize {
        ((self.plot_h / (45.0 * self.scale)) as usize).clamp(2, 8)
    }

    fn chart<'a, DB: DrawingBackend>(
        &self,
        area: &'a DrawingArea<DB, Shift>,
        title: &str,
        x: &AxisSpec,
        y: &AxisSpec,
    ) -> Result<ChartContext<'a, DB, Cartesian2d<Axis, Axis>>, String> {
        let mut builder = ChartBuilder::on(area);
        builder
            .margin(self.margin)
            .margin_right(self.margin * 2)
            .x_label_area_size(self.x_area)
            .y_label_area_size(self.y_area);
        if !title.is_empty() {
            builder.caption(title, self.font(18.0, FontStyle::Bold));
        }
        builder
            .build_cartesian_2d(x.coord(), y.coord())
            .map_err(|e| e.to_string())
    }

    fn mesh<DB: DrawingBackend>(
        &self,
        chart: &mut ChartContext<'_, DB, Cartesian2d<Axis, Axis>>,
        x: &AxisSpec,
        y: &AxisSpec,
        x_label: &str,
        y_label: &str,
        grid: bool,
    ) -> Result<(), String> {
        let x_fmt = |v: &f64| x.label(*v);
        let y_fmt = |v: &f64| y.label(*v);
        let mut mesh = chart.configure_mesh();
        mesh.x_desc(x_label)
            .y_desc(y_label)
            .x_label_formatter(&x_fmt)
            .y_label_formatter(&y_fmt)
            .label_style(self.font(13.0, FontStyle::Normal))
            .axis_desc_style(self.font(15.0, FontStyle::Normal))
            .bold_line_style(RGBColor(215, 215, 215))
            .light_line_style(RGBColor(238, 238, 238));
        if !grid {
            mesh.disable_mesh();
        }
        mesh.draw().map_err(|e| e.to_string())?;
        // Frame around the plot area.
        chart
            .plotting_area()
            .draw(&Rectangle::new(
                [(x.lo, y.lo), (x.hi, y.hi)],
                BLACK.stroke_width(1),
            ))
            .map_err(|e| e.to_string())
    }
}

type Axis = AxisSpec;

/// How tick values are turned into labels.
#[derive(Debug, Clone, Copy)]
enum TickFmt {
    /// Plain values with the given tick step; scientific notation if `sci`.
    Linear { step: f64, sci: bool },
    /// Log-space values `v` labelled as `10^v` rounded to one significant digit.
    Powers,
    /// Log-space values labelled as `10^v` on a linear grid of the given step.
    LogLinear { step: f64, sci: bool },
    /// Row indices drawn upside down: the label of `v` is `-v`.
    NegatedIndex { step: f64 },
}

/// One resolved axis, in plot space (log10 of the data on log axes).
#[derive(Debug, Clone)]
struct AxisSpec {
    lo: f64,
    hi: f64,
    major: Vec<f64>,
    minor: Vec<f64>,
    fmt: TickFmt,
}

/// Plotters coordinate: a linear map of `[lo, hi]` with our own tick positions
/// (bold grid lines and labels at `major`, light grid lines at `minor`).
impl Ranged for AxisSpec {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, v: &f64, limit: (i32, i32)) -> i32 {
        let t = (v - self.lo) / (self.hi - self.lo);
        let len = f64::from(limit.1 - limit.0);
        if !t.is_finite() {
            return limit.0;
        }
        let pixel = (len * t).round().clamp(-1e7, 1e7);
        limit.0 + pixel as i32
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            self.minor.clone()
        } else {
            self.major.clone()
        }
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.lo..self.hi
    }
}

impl AxisSpec {
    fn coord(&self) -> Axis {
        self.clone()
    }

    fn contains(&self, v: f64) -> bool {
        let eps = (self.hi - self.lo) * 1e-9;
        v >= self.lo - eps && v <= self.hi + eps
    }

    fn label(&self, v: f64) -> String {
        match self.fmt {
            TickFmt::Linear { step, sci } => fmt_tick(v, step, sci),
            TickFmt::Powers => fmt_power(v),
            TickFmt::LogLinear { step, sci } => fmt_tick(10f64.powf(v), step, sci),
            TickFmt::NegatedIndex { step } => fmt_tick(-v, step, false),
        }
    }

    /// An axis over `[lo, hi]` in plot space with about `target` labelled ticks.
    fn new(lo: f64, hi: f64, scale: Scale, target: usize) -> Self {
        match scale {
            Scale::Linear => {
                let (major, step) = linear_ticks(lo, hi, target, false);
                let m = lo.abs().max(hi.abs());
                let sci = !(1e-3..1e5).contains(&m);
                AxisSpec {
                    lo,
                    hi,
                    major,
                    minor: Vec::new(),
                    fmt: TickFmt::Linear { step, sci },
                }
            }
            Scale::Log10 => log_axis(lo, hi, target),
        }
    }

    /// An axis of integer indices `0..n` centred on the cells, with the
    /// direction flipped (index `i` at `-i`) when `negate` is set.
    fn index(n: usize, target: usize, negate: bool) -> Self {
        let (lo, hi) = (-0.5, n.max(1) as f64 - 0.5);
        let (ticks, step) = linear_ticks(lo, hi, target, true);
        if negate {
            AxisSpec {
                lo: -hi,
                hi: -lo,
                major: ticks.iter().map(|t| -t).collect(),
                minor: Vec::new(),
                fmt: TickFmt::NegatedIndex { step },
            }
        } else {
            AxisSpec {
                lo,
                hi,
                major: ticks,
                minor: Vec::new(),
                fmt: TickFmt::Linear { step, sci: false },
            }
        }
    }
}

/// "Nice" tick step (1, 2, 2.5 or 5 times a power of ten) for about `target` ticks.
fn nice_step(span: f64, target: usize) -> f64 {
    let raw = span / target.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let f = raw / mag;
    let nice = if f <= 1.0 {
        1.0
    } else if f <= 2.0 {
        2.0
    } else if f <= 2.5 {
        2.5
    } else if f <= 5.0 {
        5.0
    } else {
        10.0
    };
    nice * mag
}

/// Multiples of a nice step inside `[lo, hi]`, and the step.
fn linear_ticks(lo: f64, hi: f64, target: usize, integer: bool) -> (Vec<f64>, f64) {
    let span = hi - lo;
    if !(span.is_finite() && span > 0.0) {
        return (vec![lo], 1.0);
    }
    let mut step = nice_step(span, target);
    if integer {
        step = step.max(1.0).round();
    }
    let start = (lo / step - 1e-9).ceil();
    let end = (hi / step + 1e-9).floor();
    let count = (end - start).clamp(-1.0, 200.0);
    let ticks = (0..=count as i64)
        .map(|k| {
            let v = (start + k as f64) * step;
            if v.abs() < step * 1e-9 {
                0.0
            } else {
                v
            }
        })
        .collect();
    (ticks, step)
}

/// A log10 axis over `[lo, hi]` (already in log space).
fn log_axis(lo: f64, hi: f64, target: usize) -> AxisSpec {
    let decades = hi - lo;
    let inside = |v: &f64| *v >= lo - 1e-9 && *v <= hi + 1e-9;
    let (first, last) = (lo.floor() as i64, hi.ceil() as i64);
    let mantissas = |ms: &[f64]| -> Vec<f64> {
        (first..=last)
            .flat_map(|k| ms.iter().map(move |m| k as f64 + m.log10()))
            .filter(inside)
            .collect()
    };
    if decades >= 2.0 {
        let step = nice_step(decades, target).max(1.0).round() as i64;
        let (major, minor): (Vec<f64>, Vec<f64>) = (first..=last)
            .map(|k| k as f64)
            .filter(inside)
            .partition(|k| (*k as i64).rem_euclid(step) == 0);
        let minor = if step == 1 && decades <= 12.0 {
            mantissas(&[2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0])
        } else if minor.len() <= 30 {
            minor
        } else {
            Vec::new()
        };
        AxisSpec {
            lo,
            hi,
            major,
            minor,
            fmt: TickFmt::Powers,
        }
    } else if decades >= 0.6 {
        AxisSpec {
            lo,
            hi,
            major: mantissas(&[1.0, 2.0, 5.0]),
            minor: mantissas(&[3.0, 4.0, 6.0, 7.0, 8.0, 9.0]),
            fmt: TickFmt::Powers,
        }
    } else {
        let (vlo, vhi) = (10f64.powf(lo), 10f64.powf(hi));
        let (ticks, step) = linear_ticks(vlo, vhi, target, false);
        AxisSpec {
            lo,
            hi,
            major: ticks
                .into_iter()
                .filter(|t| *t > 0.0)
                .map(f64::log10)
                .collect(),
            minor: Vec::new(),
            fmt: TickFmt::LogLinear {
                step,
                sci: !(1e-3..1e5).contains(&vhi),
            },
        }
    }
}

/// Formats a tick value with as many digits as the tick step needs.
fn fmt_tick(v: f64, step: f64, sci: bool) -> String {
    if !v.is_finite() {
        return String::new();
    }
    if v.abs() < step.abs() * 1e-6 {
        return "0".into();
    }
    // Decimals needed to represent multiples of `step` exactly.
    let decimals = (0..=12)
        .find(|&d| {
            let s = step * 10f64.powi(d);
            (s - s.round()).abs() < 1e-6 * s.max(1.0)
        })
        .unwrap_or(12);
    if sci {
        let sig = (v.abs().log10().floor() as i32 + decimals + 1).clamp(1, 12) as usize;
        trim_sci(&format!("{:.*e}", sig - 1, v))
    } else {
        format!("{:.*}", decimals as usize, v)
    }
}

/// Formats `10^v` rounded to one significant digit (`v` is near `log10(m 10^k)`).
fn fmt_power(v: f64) -> String {
    let mut k = v.floor();
    let mut m = 10f64.powf(v - k).round();
    if m >= 10.0 {
        m = 1.0;
        k += 1.0;
    }
    let k = k as i32;
    if (-3..=4).contains(&k) {
        format!("{:.*}", (-k).max(0) as usize, m * 10f64.powi(k))
    } else if m == 1.0 {
        format!("1e{k}")
    } else {
        format!("{m}e{k}")
    }
}

/// Removes trailing zeros of a mantissa: `"2.50e-5"` → `"2.5e-5"`, `"1.0e3"` → `"1e3"`.
fn trim_sci(s: &str) -> String {
    match s.split_once('e') {
        Some((mant, exp)) if mant.contains('.') => {
            let mant = mant.trim_end_matches('0').trim_end_matches('.');
            format!("{mant}e{exp}")
        }
        _ => s.to_string(),
    }
}

/// Maps a data value to plot space; `None` if it cannot be shown on `scale`.
fn to_plot(v: f64, scale: Scale) -> Option<f64> {
    let t = match scale {
        Scale::Linear => v,
        Scale::Log10 if v > 0.0 => v.log10(),
        Scale::Log10 => return None,
    };
    t.is_finite().then_some(t)
}

/// Resolves an axis interval in plot space from an optional explicit range
/// and the data values, padding auto ranges by `pad` of their span.
fn resolve_range(
    explicit: Option<(f64, f64)>,
    scale: Scale,
    data: impl Iterator<Item = f64>,
    pad: f64,
) -> (f64, f64) {
    let fixed = explicit.and_then(|(a, b)| Some((to_plot(a, scale)?, to_plot(b, scale)?)));
    let (lo, hi, auto) = match fixed {
        Some((a, b)) => (a.min(b), a.max(b), false),
        None => {
            let (lo, hi) = data.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            });
            if lo > hi {
                return (0.0, 1.0);
            }
            (lo, hi, true)
        }
    };
    let span = hi - lo;
    if span <= lo.abs().max(hi.abs()).max(1e-300) * 1e-12 {
        let d = if lo == 0.0 { 0.5 } else { lo.abs() * 0.05 };
        return (lo - d, hi + d);
    }
    if auto {
        (lo - pad * span, hi + pad * span)
    } else {
        (lo, hi)
    }
}

/// Clips the segment `p`–`q` to the box (Liang–Barsky); returns the clipped
/// segment and whether its start/end were moved.
#[allow(clippy::type_complexity)]
fn clip_segment(
    p: (f64, f64),
    q: (f64, f64),
    x: &AxisSpec,
    y: &AxisSpec,
) -> Option<((f64, f64), (f64, f64), bool, bool)> {
    let (dx, dy) = (q.0 - p.0, q.1 - p.1);
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (num, den) in [
        (p.0 - x.lo, -dx),
        (x.hi - p.0, dx),
        (p.1 - y.lo, -dy),
        (y.hi - p.1, dy),
    ] {
        if den == 0.0 {
            if num < 0.0 {
                return None;
            }
        } else {
            let t = num / den;
            if den < 0.0 {
                t0 = t0.max(t);
            } else {
                t1 = t1.min(t);
            }
        }
    }
    if t0 > t1 {
        return None;
    }
    let at = |t: f64| (p.0 + t * dx, p.1 + t * dy);
    Some((
        if t0 > 0.0 { at(t0) } else { p },
        if t1 < 1.0 { at(t1) } else { q },
        t0 > 0.0,
        t1 < 1.0,
    ))
}

/// Splits a series into visible polylines: broken at unplottable points and
/// clipped to the axes box.
fn polylines(points: &[Option<(f64, f64)>], x: &AxisSpec, y: &AxisSpec) -> Vec<Vec<(f64, f64)>> {
    let mut lines = Vec::new();
    let mut current: Vec<(f64, f64)> = Vec::new();
    for pair in points.windows(2) {
        let (Some(p), Some(q)) = (pair[0], pair[1]) else {
            if current.len() > 1 {
                lines.push(std::mem::take(&mut current));
            }
            current.clear();
            continue;
        };
        match clip_segment(p, q, x, y) {
            None => {
                if current.len() > 1 {
                    lines.push(std::mem::take(&mut current));
                }
                current.clear();
            }
            Some((a, b, a_moved, b_moved)) => {
                if current.is_empty() || a_moved {
                    if current.len() > 1 {
                        lines.push(std::mem::take(&mut current));
                    }
                    current = vec![a];
                }
                current.push(b);
                if b_moved {
                    lines.push(std::mem::take(&mut current));
                }
            }
        }
    }
    if current.len() > 1 {
        lines.push(current);
    }
    lines
}

fn draw_chart<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
    layout: &Layout,
) -> Result<(), String> {
    // Plot-space points; `None` marks points that cannot be shown.
    let series_points: Vec<Vec<Option<(f64, f64)>>> = panel
        .series
        .iter()
        .map(|s| {
            s.points
                .iter()
                .map(|&(px, py)| Some((to_plot(px, panel.x_scale)?, to_plot(py, panel.y_scale)?)))
                .collect()
        })
        .collect();
    let all = || series_points.iter().flatten().flatten();
    let (xlo, xhi) = resolve_range(panel.x_range, panel.x_scale, all().map(|p| p.0), 0.0);
    // Auto y range: only from points inside the x range.
    let in_x = |p: &&(f64, f64)| p.0 >= xlo && p.0 <= xhi;
    let (ylo, yhi) = resolve_range(
        panel.y_range,
        panel.y_scale,
        all().filter(in_x).map(|p| p.1),
        0.05,
    );
    let x = AxisSpec::new(xlo, xhi, panel.x_scale, layout.x_ticks());
    let y = AxisSpec::new(ylo, yhi, panel.y_scale, layout.y_ticks());

    let mut chart = layout.chart(area, &panel.title, &x, &y)?;
    layout.mesh(&mut chart, &x, &y, &panel.x_label, &panel.y_label, true)?;

    let line_w = layout.px(2.0);
    let radius = layout.px(3.5);
    let cross = layout.px(4.0);
    let (dash, gap) = (layout.px(8.0), layout.px(5.0));
    // Legend symbol geometry: width `sym`, dash pieces and marker at its centre.
    let sym = layout.px(22.0) as i32;
    let (piece, mid) = (sym * 2 / 5, sym / 2);
    let mut any_label = false;
    for (i, (series, points)) in panel.series.iter().zip(&series_points).enumerate() {
        let color = palette_color(series.color.unwrap_or(i));
        let line_style = color.stroke_width(line_w);
        let visible = || {
            points
                .iter()
                .flatten()
                .copied()
                .filter(|p| x.contains(p.0) && y.contains(p.1))
        };
        let lines = || polylines(points, &x, &y);
        let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        match series.style {
            SeriesStyle::Line | SeriesStyle::LineMarkers => {
                for l in lines() {
                    chart
                        .draw_series(LineSeries::new(l, line_style))
                        .map_err(err)?;
                }
            }
            SeriesStyle::Dashed => {
                for l in lines() {
                    chart
                        .draw_series(DashedLineSeries::new(l, dash, gap, line_style))
                        .map_err(err)?;
                }
            }
            SeriesStyle::Markers => {}
            SeriesStyle::Crosses => {
                chart
                    .draw_series(visible().map(|p| Cross::new(p, cross, line_style)))
                    .map_err(err)?;
            }
        }
        if matches!(
            series.style,
            SeriesStyle::Markers | SeriesStyle::LineMarkers
        ) {
            chart
                .draw_series(visible().map(|p| Circle::new(p, radius, color.filled())))
                .map_err(err)?;
        }
        if series.label.is_empty() {
            continue;
        }
        // An empty series that only carries the legend entry.
        let anno = chart
            .draw_series(std::iter::empty::<EmptyElement<(f64, f64), DB>>())
            .map_err(err)?;
        anno.label(series.label.as_str());
        any_label = true;
        match series.style {
            SeriesStyle::Line => anno.legend(move |(lx, ly)| {
                PathElement::new(vec![(lx, ly), (lx + sym, ly)], line_style)
            }),
            SeriesStyle::LineMarkers => anno.legend(move |(lx, ly)| {
                EmptyElement::at((lx, ly))
                    + PathElement::new(vec![(0, 0), (sym, 0)], line_style)
                    + Circle::new((mid, 0), radius, color.filled())
            }),
            SeriesStyle::Dashed => anno.legend(move |(lx, ly)| {
                EmptyElement::at((lx, ly))
                    + PathElement::new(vec![(0, 0), (piece, 0)], line_style)
                    + PathElement::new(vec![(sym - piece, 0), (sym, 0)], line_style)
            }),
            SeriesStyle::Markers => {
                anno.legend(move |(lx, ly)| Circle::new((lx + mid, ly), radius, color.filled()))
            }
            SeriesStyle::Crosses => {
                anno.legend(move |(lx, ly)| Cross::new((lx + mid, ly), cross, line_style))
            }
        };
    }
    if any_label {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .margin(layout.px(8.0))
            .legend_area_size(sym as u32 + layout.px(6.0))
            .label_font(layout.font(13.0, FontStyle::Normal))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(160, 160, 160))
            .draw()
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

fn draw_sparsity<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &SparsityPanel,
    layout: &Layout,
) -> Result<(), String> {
    let (rows, cols) = panel.shape;
    if let Some(&(r, c)) = panel.entries.iter().find(|&&(r, c)| r >= rows || c >= cols) {
        return Err(format!(
            "sparsity entry ({r}, {c}) outside matrix shape {rows}x{cols}"
        ));
    }
    let positions: Option<Vec<Option<f64>>> = match &panel.x_positions {
        Some(xs) if xs.len() != cols => {
            return Err(format!(
                "{} x positions given for a matrix with {cols} columns",
                xs.len()
            ));
        }
        Some(xs) => Some(xs.iter().map(|&v| to_plot(v, panel.x_scale)).collect()),
        None => None,
    };
    let x = match &positions {
        Some(ps) => {
            let (lo, hi) = resolve_range(
                panel.x_range,
                panel.x_scale,
                ps.iter().flatten().copied(),
                0.0,
            );
            AxisSpec::new(lo, hi, panel.x_scale, layout.x_ticks())
        }
        None => AxisSpec::index(cols, layout.x_ticks(), false),
    };
    let y = AxisSpec::index(rows, layout.y_ticks(), true);

    let mut chart = layout.chart(area, &panel.title, &x, &y)?;
    layout.mesh(&mut chart, &x, &y, &panel.x_label, &panel.y_label, false)?;

    // Dot size from the pixel pitch of the matrix cells.
    let pitch = (layout.plot_h / rows.max(1) as f64).min(layout.plot_w / cols.max(1) as f64);
    let radius = (pitch * 0.4).clamp(1.0, 3.0 * layout.scale).round() as u32;
    let color = palette_color(panel.color.unwrap_or(0));
    let dots = panel.entries.iter().filter_map(|&(r, c)| {
        let px = match &positions {
            Some(ps) => ps[c]?,
            None => c as f64,
        };
        x.contains(px)
            .then(|| Circle::new((px, -(r as f64)), radius, color.filled()))
    });
    chart.draw_series(dots).map_err(|e| e.to_string())?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Scratch directory for one test; set `RKWAVE_KEEP_PLOTS` to keep the
    /// files for inspection.
    fn temp_dir(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("rkwave_plot_{}_{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn sample_figure() -> Figure {
        let n = 40;
        let xs: Vec<f64> = (0..n).map(|i| i as f64 / (n - 1) as f64).collect();
        let f = |x: f64| (6.0 * x).sin() * (-x).exp();
        let fine: Vec<(f64, f64)> = (0..=200)
            .map(|i| i as f64 / 200.0)
            .map(|x| (x, f(x)))
            .collect();
        let samples: Vec<(f64, f64)> = xs.iter().map(|&x| (x, f(x) + 0.05)).collect();
        let mut with_nan = fine.clone();
        with_nan[100] = (f64::NAN, 0.0);
        with_nan[120].1 = f64::INFINITY;
        let chart = Panel {
            title: "Reconstruction".into(),
            x_label: "x".into(),
            y_label: "f(x)".into(),
            series: vec![
                Series::new("exact", fine.clone(), SeriesStyle::Line),
                Series::new("samples", samples, SeriesStyle::Markers),
                Series::new(
                    "shifted",
                    with_nan.iter().map(|&(x, y)| (x, y - 0.3)).collect(),
                    SeriesStyle::Dashed,
                ),
                Series::new("empty", vec![], SeriesStyle::LineMarkers),
            ],
            x_range: Some((0.0, 1.0)),
            ..Panel::default()
        };
        let conv = Panel {
            title: "Convergence".into(),
            x_label: "degrees of freedom".into(),
            y_label: "L2 error".into(),
            x_scale: Scale::Log10,
            y_scale: Scale::Log10,
            series: vec![
                Series::new(
                    "error",
                    (0..8)
                        .map(|k| (2f64.powi(k + 2), 2f64.powi(-2 * k)))
                        .chain([(0.0, 1.0), (10.0, -1.0), (f64::NAN, 1.0)])
                        .collect(),
                    SeriesStyle::LineMarkers,
                ),
                Series::new(
                    "O(h^2)",
                    (0..8)
                        .map(|k| (2f64.powi(k + 2), 0.5 * 2f64.powi(-2 * k)))
                        .collect(),
                    SeriesStyle::Crosses,
                )
                .with_color(3),
            ],
            ..Panel::default()
        };
        let rows = 12;
        let entries: Vec<(usize, usize)> = (0..rows)
            .flat_map(|r| {
                let xs = &xs;
                (0..n).filter_map(move |c| {
                    let centre = (r as f64 + 0.5) / rows as f64;
                    ((xs[c] - centre).abs() < 0.15).then_some((r, c))
                })
            })
            .collect();
        let sparsity = SparsityPanel {
            title: "K^T".into(),
            x_label: "x".into(),
            y_label: "basis index".into(),
            shape: (rows, n),
            entries: entries.clone(),
            x_positions: Some(xs.clone()),
            x_range: Some((0.0, 1.0)),
            ..SparsityPanel::default()
        };
        let plain = SparsityPanel {
            title: "K^T (column index)".into(),
            x_label: "sample".into(),
            y_label: "row".into(),
            shape: (rows, n),
            entries,
            color: Some(1),
            ..SparsityPanel::default()
        };
        Figure {
            width: 1200,
            height: 800,
            columns: 2,
            panels: vec![chart.into(), conv.into(), sparsity.into(), plain.into()],
        }
    }

    #[test]
    fn renders_png_and_svg() {
        let dir = temp_dir("render");
        let fig = sample_figure();
        let png = dir.join("figure.png");
        let svg = dir.join("figure.svg");
        fig.save_png(&png).unwrap();
        fig.save_svg(&svg).unwrap();
        assert!(png.is_file());
        assert!(svg.is_file());
        let img = image::open(&png).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (1200, 800));
        let first = *img.get_pixel(0, 0);
        assert!(img.pixels().any(|p| *p != first));
        let text = std::fs::read_to_string(&svg).unwrap();
        assert!(text.starts_with("<svg"));
        assert!(text.contains("Convergence"));
        cleanup(&dir);
    }

    fn cleanup(dir: &Path) {
        if std::env::var_os("RKWAVE_KEEP_PLOTS").is_none() {
            let _ = std::fs::remove_dir_all(dir);
        }
    }

    #[test]
    fn degenerate_inputs_do_not_panic() {
        let dir = temp_dir("degenerate");
        let nan_only = Panel {
            series: vec![
                Series::new("nan", vec![(f64::NAN, f64::NAN); 3], SeriesStyle::Line),
                Series::new("", vec![], SeriesStyle::Markers),
                Series::new("one", vec![(1.0, 1.0)], SeriesStyle::Dashed),
            ],
            ..Panel::default()
        };
        let log_nonpositive = Panel {
            x_scale: Scale::Log10,
            y_scale: Scale::Log10,
            series: vec![Series::new(
                "neg",
                vec![(-1.0, 0.0), (0.0, -2.0), (3.0, f64::NAN)],
                SeriesStyle::LineMarkers,
            )],
            x_range: Some((-1.0, 10.0)),
            ..Panel::default()
        };
        let empty_matrix = SparsityPanel::default();
        let fig = Figure::new(
            500,
            900,
            vec![
                nan_only.into(),
                log_nonpositive.into(),
                Panel::default().into(),
                empty_matrix.into(),
            ],
        );
        fig.save_png(&dir.join("degenerate.png")).unwrap();
        fig.save_svg(&dir.join("degenerate.svg")).unwrap();
        Figure::new(300, 200, vec![])
            .save_png(&dir.join("blank.png"))
            .unwrap();
        cleanup(&dir);
    }

    #[test]
    fn invalid_descriptions_are_errors() {
        let dir = temp_dir("invalid");
        let bad = SparsityPanel {
            shape: (2, 2),
            entries: vec![(0, 5)],
            ..SparsityPanel::default()
        };
        let err = Figure::new(300, 200, vec![bad.into()])
            .save_png(&dir.join("bad.png"))
            .unwrap_err();
        assert!(matches!(err, PlotError::Draw { .. }));
        let err = Figure::new(0, 200, vec![])
            .save_svg(&dir.join("zero.svg"))
            .unwrap_err();
        assert!(matches!(err, PlotError::Draw { .. }));
        let err = Figure::new(300, 200, vec![])
            .save_png(&dir.join("missing_dir").join("x.png"))
            .unwrap_err();
        assert!(matches!(err, PlotError::Write { .. }));
        cleanup(&dir);
    }

    #[test]
    fn lines_break_at_gaps_and_clip() {
        let axis = AxisSpec::new(0.0, 1.0, Scale::Linear, 5);
        let pts = [
            Some((0.1, 0.5)),
            Some((0.2, 0.5)),
            None,
            Some((0.3, 0.5)),
            Some((0.5, 0.5)),
            Some((1.5, 0.5)),
            Some((2.0, 0.5)),
            Some((0.9, 0.5)),
        ];
        let lines = polylines(&pts, &axis, &axis);
        assert_eq!(
            lines,
            vec![
                vec![(0.1, 0.5), (0.2, 0.5)],
                vec![(0.3, 0.5), (0.5, 0.5), (1.0, 0.5)],
                vec![(1.0, 0.5), (0.9, 0.5)],
            ]
        );
        assert!(polylines(&[], &axis, &axis).is_empty());
        assert!(polylines(&[Some((0.5, 0.5))], &axis, &axis).is_empty());
    }

    #[test]
    fn tick_labels() {
        assert_eq!(fmt_tick(0.2, 0.2, false), "0.2");
        assert_eq!(fmt_tick(7.5, 2.5, false), "7.5");
        assert_eq!(fmt_tick(1e-17, 0.5, false), "0");
        assert_eq!(fmt_tick(2e5, 1e5, true), "2e5");
        assert_eq!(fmt_power(-2.0), "0.01");
        assert_eq!(fmt_power(2f64.log10() + 6.0), "2e6");
        assert_eq!(fmt_power(3.0), "1000");
        let (ticks, step) = linear_ticks(-0.5, 39.5, 5, true);
        assert_eq!(step, 10.0);
        assert_eq!(ticks, vec![0.0, 10.0, 20.0, 30.0]);
    }
}
