//! The figures of the reports, drawn from their typed data: basis functions, dual and
//! reproducing kernels, and the sweep's error against time.

use super::{Figure, Panel, PanelContent, Scale, Series, SeriesStyle};
use crate::report::figures::{BasisFunctionsData, Curve, KernelsData};
use crate::report::sweep::SweepReport;

/// Line series of curves, coloured in order.
fn lines(curves: &[Curve]) -> Vec<Series> {
    curves
        .iter()
        .enumerate()
        .map(|(c, curve)| {
            Series::new(curve.label.clone(), curve.points.clone(), SeriesStyle::Line).with_color(c)
        })
        .collect()
}

/// Charts of functions of `x` stacked in one column, each over the whole domain.
fn stacked_over_domain(domain: [f64; 2], charts: Vec<(String, Vec<Series>, &str)>) -> Figure {
    Figure {
        width: 1100,
        height: 900,
        columns: 1,
        panels: charts
            .into_iter()
            .map(|(title, series, y)| -> PanelContent {
                Panel {
                    title,
                    x_label: "x".into(),
                    y_label: y.into(),
                    series,
                    x_range: Some((domain[0], domain[1])),
                    ..Panel::default()
                }
                .into()
            })
            .collect(),
    }
}

/// Scaling functions (top) and wavelets (bottom) of one level.
pub fn basis_functions_figure(data: &BasisFunctionsData) -> Figure {
    let (n, p, family) = (data.level, data.p, data.family);
    stacked_over_domain(
        data.domain,
        vec![
            (
                format!("CDV scaling functions of V_{n}, p = {p} ({family}{p}), edges included"),
                lines(&data.scaling),
                "φ(x)",
            ),
            (
                format!("CDV wavelets of W_{n}"),
                lines(&data.wavelets),
                "ψ(x)",
            ),
        ],
    )
}

/// Dual kernels `k~_i` (top) and reproducing kernels `k_i` (bottom).
pub fn kernels_figure(data: &KernelsData) -> Figure {
    stacked_over_domain(
        data.domain,
        vec![
            (
                format!(
                    "Dual kernels k~_i(x), p = {}, Psi({}, {}), {} samples",
                    data.p, data.coarse, data.fine, data.samples
                ),
                lines(&data.dual),
                "k~_i(x)",
            ),
            (
                "Reproducing kernels k_i(x)".into(),
                lines(&data.reproducing),
                "k_i(x)",
            ),
        ],
    )
}

/// `max |K~ - K^+|` against local inversion time, one curve per knob, log-log.
pub fn sweep_figure(report: &SweepReport) -> Figure {
    let base = &report.base;
    let series = report
        .curves()
        .into_iter()
        .enumerate()
        .map(|(c, curve)| {
            Series::new(curve.knob.name(), curve.points, SeriesStyle::LineMarkers).with_color(c)
        })
        .collect();
    Figure {
        width: 1000,
        height: 700,
        columns: 1,
        panels: vec![Panel {
            title: format!(
                "max |K~ - K+| vs time (base: p = {}, levels {}..{}, {} {})",
                base.p, base.coarse, base.fine, base.samples, base.layout
            ),
            x_label: "local inversion time (s)".into(),
            y_label: "max |K~ - K+|".into(),
            x_scale: Scale::Log10,
            y_scale: Scale::Log10,
            series,
            ..Panel::default()
        }
        .into()],
    }
}
