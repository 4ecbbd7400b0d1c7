//! The figures of the 1D adaptive refiner's experiments, laid out from the library's typed
//! data ([`super::refine`]): error against samples, adaptive and uniform, on
//! log-log axes; and the supplement's figure 4 for one run.

use super::refine::{figure4, ComparisonRow, Truth};
use crate::plot::{Figure, Panel, PanelContent, Scale, Series, SeriesStyle, SparsityPanel};
use crate::refine::{RefineError, Refinement};

/// Log-log error against samples, adaptive and uniform.
pub fn error_against_samples(rows: &[ComparisonRow], name: &str) -> Figure {
    let curve = |value: fn(&ComparisonRow) -> f64| -> Vec<(f64, f64)> {
        rows.iter().map(|r| (r.samples as f64, value(r))).collect()
    };
    let panel = Panel {
        title: format!("{name}: error against samples"),
        x_label: "samples".into(),
        y_label: "error".into(),
        x_scale: Scale::Log10,
        y_scale: Scale::Log10,
        series: vec![
            Series::new(
                "adaptive, RMS on grid",
                curve(|r| r.adaptive_l2),
                SeriesStyle::LineMarkers,
            )
            .with_color(3),
            Series::new(
                "uniform, RMS on grid",
                curve(|r| r.uniform_l2),
                SeriesStyle::LineMarkers,
            )
            .with_color(0),
            Series::new(
                "adaptive, L2 (quadrature)",
                curve(|r| r.adaptive_l2_quadrature),
                SeriesStyle::Dashed,
            )
            .with_color(3),
            Series::new(
                "uniform, L2 (quadrature)",
                curve(|r| r.uniform_l2_quadrature),
                SeriesStyle::Dashed,
            )
            .with_color(0),
        ],
        ..Panel::default()
    };
    Figure::new(900, 650, vec![panel.into()])
}

/// Figure 4 of the supplement for this run: reconstruction over the truth, base (grey) and
/// refinement (red) samples as crosses on the axis, the local depth (magenta, scaled into the
/// chart), and below it the pattern of `K^T` with each sample's column at its abscissa. The
/// data come from the library ([`figure4`]); this lays them out.
pub fn figure4_layout(r: &Refinement, truth: Truth<'_>) -> Result<Figure, RefineError> {
    let domain = r.tree.domain();
    let data = figure4(r, truth)?;
    let (lo, hi) = data
        .truth
        .iter()
        .chain(&data.reconstruction)
        .map(|p| p.1)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| {
            (a.min(y), b.max(y))
        });
    let span = if hi > lo { hi - lo } else { 1.0 };
    let (y0, y1) = (lo - 0.18 * span, hi + 0.08 * span);
    let cross_y = lo - 0.11 * span;
    let crosses = |xs: &[f64]| -> Vec<(f64, f64)> { xs.iter().map(|&x| (x, cross_y)).collect() };
    let shallowest = data.depth.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
    let d_lo = if shallowest.is_finite() {
        shallowest - 1.0
    } else {
        0.0
    };
    let d_hi = (r.tree.depth() as f64).max(d_lo + 1.0);
    let depth: Vec<(f64, f64)> = data
        .depth
        .iter()
        .map(|&(x, d)| (x, lo + (d - d_lo) / (d_hi - d_lo) * (hi - lo)))
        .collect();
    let chart = Panel {
        title: format!(
            "adaptive reconstruction of {}: {} samples ({} base), P = {}, depth {}..{}",
            truth.name,
            r.samples.len(),
            r.base_samples(),
            r.columns().len(),
            r.base_depth,
            r.tree.depth()
        ),
        x_label: "x".into(),
        y_label: "f(x)".into(),
        series: vec![
            Series::new("signal", data.truth, SeriesStyle::Line).with_color(7),
            Series::new("reconstruction", data.reconstruction, SeriesStyle::Dashed).with_color(0),
            Series::new(
                format!("local depth ({d_lo} at the bottom, {d_hi} at the top)"),
                depth,
                SeriesStyle::Line,
            )
            .with_color(6),
            Series::new(
                "base samples",
                crosses(&data.base_samples),
                SeriesStyle::Crosses,
            )
            .with_color(7),
            Series::new(
                "refinement samples",
                crosses(&data.refinement_samples),
                SeriesStyle::Crosses,
            )
            .with_color(3),
        ],
        x_range: Some((domain.a(), domain.b())),
        y_range: Some((y0, y1)),
        ..Panel::default()
    };
    let pattern = SparsityPanel {
        title: "K^T: basis functions (coarse on top) x samples (at their abscissa)".into(),
        x_label: "x".into(),
        y_label: "basis function".into(),
        shape: (data.functions, r.samples.len()),
        entries: data.kernel_entries,
        x_positions: Some(r.samples.iter().map(|s| s.x).collect()),
        x_range: Some((domain.a(), domain.b())),
        ..SparsityPanel::default()
    };
    Ok(Figure::new(
        1100,
        1050,
        vec![PanelContent::Chart(chart), PanelContent::Sparsity(pattern)],
    ))
}
