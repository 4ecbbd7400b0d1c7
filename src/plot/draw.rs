//! Rendering a [`Figure`] with plotters: the grid of cells, charts of series with their
//! legend, sparsity patterns, and writing the result as PNG or SVG.

use std::path::Path;
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::register_font;

use super::axes::{resolve_range, to_plot, AxisSpec};
use super::clip::polylines;
use super::layout::Layout;
use super::spec::{Figure, Panel, PanelContent, SeriesStyle, SparsityPanel, PALETTE};
use super::PlotError;

impl Figure {
    /// Renders the figure and writes it as a PNG image to `path` (PNG regardless of the
    /// file extension), atomically and replacing an existing file: [`Figure::write_png`]
    /// with `overwrite = true`.
    pub fn save_png(&self, path: &Path) -> Result<(), PlotError> {
        self.write_png(path, true)
    }

    /// Renders the figure and writes it as an SVG document to `path`, atomically and
    /// replacing an existing file: [`Figure::write_svg`] with `overwrite = true`.
    pub fn save_svg(&self, path: &Path) -> Result<(), PlotError> {
        self.write_svg(path, true)
    }

    /// Writes the figure as SVG if `path` ends in `.svg` (any case), PNG otherwise, through
    /// [`crate::io::output::write_new`]: rendered in memory, written to a temporary file
    /// beside the target and moved into place, so a failure never leaves a partial figure;
    /// without `overwrite`, a target that exists (or appears meanwhile) is left alone and
    /// reported as [`PlotError::Output`].
    pub fn write(&self, path: &Path, overwrite: bool) -> Result<(), PlotError> {
        if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("svg"))
        {
            self.write_svg(path, overwrite)
        } else {
            self.write_png(path, overwrite)
        }
    }

    /// [`Figure::write`] as PNG whatever the extension.
    pub fn write_png(&self, path: &Path, overwrite: bool) -> Result<(), PlotError> {
        let bytes = self.png_bytes_for(path)?;
        crate::io::output::write_new(path, &bytes, overwrite).map_err(PlotError::Output)
    }

    /// [`Figure::write`] as SVG whatever the extension.
    pub fn write_svg(&self, path: &Path, overwrite: bool) -> Result<(), PlotError> {
        let svg = self.svg_for(path)?;
        crate::io::output::write_new(path, svg.as_bytes(), overwrite).map_err(PlotError::Output)
    }

    /// The figure encoded as a PNG file, in memory.
    pub fn png_bytes(&self) -> Result<Vec<u8>, PlotError> {
        self.png_bytes_for(Path::new("<memory>"))
    }

    /// The figure as an SVG document, in memory.
    pub fn svg_string(&self) -> Result<String, PlotError> {
        self.svg_for(Path::new("<memory>"))
    }

    /// Renders and encodes a PNG; `path` only names the figure in errors.
    fn png_bytes_for(&self, path: &Path) -> Result<Vec<u8>, PlotError> {
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
        let mut png = std::io::Cursor::new(Vec::new());
        img.write_to(&mut png, image::ImageFormat::Png)
            .map_err(|source| PlotError::Write {
                path: path.display().to_string(),
                source,
            })?;
        Ok(png.into_inner())
    }

    /// Renders an SVG document; `path` only names the figure in errors.
    fn svg_for(&self, path: &Path) -> Result<String, PlotError> {
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
        Ok(svg)
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

pub(super) fn register_fonts() {
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
    use crate::plot::{Scale, Series};

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
        assert!(matches!(
            err,
            PlotError::Output(crate::io::output::OutputError::NotWritable { .. })
        ));
        cleanup(&dir);
    }

    /// Without `overwrite` an existing figure is left byte for byte; with it, it is replaced
    /// by the figure; no temporary file is left either way; the bytes on disk are the bytes
    /// rendered in memory.
    #[test]
    fn figures_are_written_atomically_and_never_clobbered() {
        use crate::io::output::OutputError;
        let dir = temp_dir("atomic");
        let fig = Figure::new(300, 200, vec![Panel::default().into()]);
        for name in ["f.png", "f.svg"] {
            let path = dir.join(name);
            std::fs::write(&path, b"precious").unwrap();
            let err = fig.write(&path, false).unwrap_err();
            assert!(
                matches!(err, PlotError::Output(OutputError::Appeared { .. })),
                "{err}"
            );
            assert_eq!(std::fs::read(&path).unwrap(), b"precious");
            fig.write(&path, true).unwrap();
            let written = std::fs::read(&path).unwrap();
            if name.ends_with("png") {
                assert_eq!(written, fig.png_bytes().unwrap());
                assert_eq!(&written[1..4], b"PNG");
            } else {
                assert_eq!(written, fig.svg_string().unwrap().into_bytes());
            }
        }
        let fresh = dir.join("new.png");
        fig.write(&fresh, false).unwrap();
        assert!(image::open(&fresh).is_ok());
        let mut names: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        assert_eq!(names, ["f.png", "f.svg", "new.png"]);
        cleanup(&dir);
    }
}
