//! The figure description: plain data that [`Figure::save_png`] and [`Figure::save_svg`]
//! render.

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
}
