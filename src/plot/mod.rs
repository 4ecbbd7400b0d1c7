//! A tiny declarative plotting layer on top of `plotters`.
//!
//! A plot is described by plain data — a [`Figure`] holding a grid of
//! [`PanelContent`]s, each either a 2D [`Panel`] chart of [`Series`] or a
//! [`SparsityPanel`] showing the nonzero pattern of a sparse matrix — and
//! rendered by a single call, [`Figure::write`] (SVG or PNG by extension; an existing file is
//! replaced only when allowed), [`Figure::save_png`] or [`Figure::save_svg`]. Files are
//! written through [`crate::io::output`]: to a temporary file beside the target, then moved
//! into place, so a failure never leaves a partial figure.
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
//!
//! # Files
//!
//! - `spec.rs`: the figure description (plain data: [`Figure`], [`Panel`], [`Series`], ...);
//! - `layout.rs`: pixel geometry of a cell (margins, label areas, fonts, a title that fits);
//! - `axes.rs`: axes in plot space, tick positions and tick labels;
//! - `clip.rs`: lines broken at gaps and clipped to the axes box (Liang–Barsky);
//! - `figures.rs`: the reports' figures, built from their typed data;
//! - `draw.rs`: rendering a [`Figure`] with plotters and writing PNG or SVG;
//! - `raster.rs`: the font and PNG encoding of figures drawn pixel by pixel.

mod axes;
mod clip;
mod draw;
pub mod figures;
mod layout;
pub mod raster;
mod spec;

pub use spec::{Figure, Panel, PanelContent, Scale, Series, SeriesStyle, SparsityPanel, PALETTE};

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
    /// The rendered figure could not be encoded.
    #[error("cannot encode figure {path}: {source}")]
    Write {
        /// Destination path of the figure.
        path: String,
        /// Underlying encoding error.
        #[source]
        source: image::ImageError,
    },
    /// The figure file must not or cannot be written: it exists (or appeared while the
    /// figure was computed) and overwriting was not allowed, or its directory refuses it.
    #[error(transparent)]
    Output(#[from] crate::io::output::OutputError),
}

impl PlotError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            PlotError::Draw { .. } | PlotError::Write { .. } => {
                crate::error::ErrorKind::WriteFailed
            }
            PlotError::Output(e) => e.kind(),
        }
    }
}

crate::error::classified!(PlotError);
