//! Figures of the command line, drawn from library values through `rkwave::plot`.

use std::collections::BTreeMap;
use std::path::Path;

use rkwave::basis::{CdvBasis, FunctionKind, Side};
use rkwave::plot::{Figure, Panel, PanelContent, Series, SeriesStyle};
use rkwave::sampling::Domain;

use super::CliError;

/// Which functions of one level to draw: the edge functions (at most four per side) and one
/// interior translate in the middle.
fn chosen(basis: &CdvBasis, level: u32) -> Vec<usize> {
    let p = basis.p();
    let e = basis.bank().edge_count();
    let size = 1usize << level;
    let edges: Vec<usize> = if p <= 4 {
        (0..e).collect()
    } else {
        vec![0, 1, 2, p - 1]
    };
    let mut out: Vec<usize> = edges.clone();
    out.push(size / 2);
    out.extend(edges.iter().map(|k| size - 1 - k));
    out.sort_unstable();
    out.dedup();
    out
}

fn label(basis: &CdvBasis, global: usize) -> String {
    let id = basis.function(global);
    let symbol = match id.kind {
        FunctionKind::Scaling => "φ",
        FunctionKind::Wavelet => "ψ",
    };
    let size = 1usize << id.level;
    match id.side {
        Side::Left => format!("{symbol} left {}", id.index),
        Side::Right => format!("{symbol} right {}", size - 1 - id.index),
        Side::Interior => format!("{symbol} interior m={}", id.index),
    }
}

/// Draws the scaling functions (top) and wavelets (bottom) of the coarse level of `basis`.
pub fn basis_figure(basis: &CdvBasis, path: &Path) -> Result<(), CliError> {
    let n = basis.coarse();
    let single = CdvBasis::with_bank(basis.bank().clone(), n, n, basis.domain())?;
    let size = 1usize << n;
    let scaling = chosen(&single, n);
    let wavelets: Vec<usize> = scaling.iter().map(|k| size + k).collect();
    let mut curves: BTreeMap<usize, Vec<(f64, f64)>> = BTreeMap::new();
    let mut ev = single.evaluator();
    let mut out = Vec::new();
    let points = 2400;
    let domain = basis.domain();
    for i in 0..=points {
        let x = domain.from_unit(i as f64 / points as f64);
        ev.eval_into(x, &mut out)?;
        for &a in scaling.iter().chain(&wavelets) {
            let v = out.iter().find(|v| v.index == a).map_or(0.0, |v| v.value);
            curves.entry(a).or_default().push((x, v));
        }
    }
    let series = |ids: &[usize]| -> Vec<Series> {
        ids.iter()
            .enumerate()
            .map(|(c, a)| {
                Series::new(label(&single, *a), curves[a].clone(), SeriesStyle::Line).with_color(c)
            })
            .collect()
    };
    let family = basis.bank().family().short_name();
    let p = basis.p();
    let fig = stacked_over_domain(
        domain,
        vec![
            (
                format!("CDV scaling functions of V_{n}, p = {p} ({family}{p}), edges included"),
                series(&scaling),
                "φ(x)",
            ),
            (format!("CDV wavelets of W_{n}"), series(&wavelets), "ψ(x)"),
        ],
    );
    save(&fig, path)
}

/// Charts of functions of `x` stacked in one column, each over the whole domain.
fn stacked_over_domain(domain: Domain, charts: Vec<(String, Vec<Series>, &str)>) -> Figure {
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
                    x_range: Some((domain.a(), domain.b())),
                    ..Panel::default()
                }
                .into()
            })
            .collect(),
    }
}

/// Saves as SVG when the extension says so, PNG otherwise; creates the folder.
pub fn save(fig: &Figure, path: &Path) -> Result<(), CliError> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|source| CliError::Write {
            path: dir.to_path_buf(),
            source,
        })?;
    }
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("svg"))
    {
        fig.save_svg(path)?;
    } else {
        fig.save_png(path)?;
    }
    Ok(())
}

/// Dual kernels `k~_i` (top) and reproducing kernels `k_i` (bottom) of a few samples near the
/// left edge, in the interior and near the right edge, for `basis` and `positions`, with the
/// dense pseudo-inverse (the paper's figure of dual kernels).
pub fn kernels_figure(basis: &CdvBasis, positions: &[f64], path: &Path) -> Result<(), CliError> {
    use rkwave::kernel::{kernel_matrix, ActiveSet};
    use rkwave::reconstruct::{dual_kernel, reproducing_kernel};
    let active = ActiveSet::uniform(basis.clone());
    let k = kernel_matrix(&active, positions).map_err(|e| CliError::Invalid(e.to_string()))?;
    let dense =
        rkwave::solve::dense_pinv(&k, 1e-12).map_err(|e| CliError::Invalid(e.to_string()))?;
    let m = positions.len();
    let picks = [0, 3, m / 2, m - 4, m - 1];
    let domain = basis.domain();
    let grid: Vec<f64> = (0..=2000)
        .map(|i| domain.from_unit(i as f64 / 2000.0))
        .collect();
    let mut duals = Vec::new();
    let mut reps = Vec::new();
    for (c, &i) in picks.iter().enumerate() {
        let column: Vec<(usize, f64)> = (0..active.len())
            .map(|a| (a, dense.pinv[(a, i)]))
            .filter(|(_, v)| *v != 0.0)
            .collect();
        let d = dual_kernel(&active, &column, &grid)?;
        let r = reproducing_kernel(&active, &k, i, &grid)?;
        let label = format!("λ_{i} = {:.4}", positions[i]);
        duals.push(
            Series::new(
                label.clone(),
                grid.iter().copied().zip(d).collect(),
                SeriesStyle::Line,
            )
            .with_color(c),
        );
        reps.push(
            Series::new(
                label,
                grid.iter().copied().zip(r).collect(),
                SeriesStyle::Line,
            )
            .with_color(c),
        );
    }
    let n = basis.coarse();
    let fine = basis.fine();
    let fig = stacked_over_domain(
        domain,
        vec![
            (
                format!(
                    "Dual kernels k~_i(x), p = {}, Psi({n}, {fine}), {m} samples",
                    basis.p()
                ),
                duals,
                "k~_i(x)",
            ),
            ("Reproducing kernels k_i(x)".into(), reps, "k_i(x)"),
        ],
    );
    save(&fig, path)
}
