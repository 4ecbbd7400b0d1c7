//! The text of `rkwave adapt`'s reports, shared by the command and the demo (which prints the
//! same tables): the library computes the reports (`rkwave::lab::refine`), this formats them.

use std::fmt::Write as _;

use rkwave::lab::refine::{AdaptReport, Comparison};
use rkwave::refine::{RefineError, StopReason};

use super::CliError;

/// Refiner errors, by their kind (a wrapped basis or reconstruction error as itself).
pub fn refine_error(e: RefineError) -> CliError {
    match e {
        RefineError::Basis(b) => CliError::from(b),
        RefineError::Reconstruct(r) => r.into(),
        other => CliError::from(other),
    }
}

/// The report of one refinement against uniform sampling, for people (`rkwave adapt`).
pub fn adapt_table(r: &AdaptReport) -> String {
    let estimated = r.estimated_error.unwrap_or(f64::NAN);
    format!(
        "adaptive {}: {} samples ({} base, {} refinement), P = {}, depth {}..{} (limit {}), \
         {} rounds, stop: {}\n\
         \x20 error      RMS {:.3e} (grid of {}), max {:.3e}; L2/quadrature {:.3e}; estimated {:.3e}\n\
         \x20 uniform    {} samples, P = {}: RMS {:.3e}, max {:.3e}; L2/quadrature {:.3e}\n\
         \x20 ratio      {:.1}x (grid RMS), {:.1}x (L2 by quadrature)\n\
         \x20 time       refine {:.3} s, one round {:.2e} s (mean; last {:.2e} s), full rebuild {:.2e} s\n",
        r.signal,
        r.samples,
        r.base_samples,
        r.refinement_samples,
        r.basis_size,
        r.base_depth,
        r.max_depth,
        r.depth_limit,
        r.rounds.len(),
        stop_name(r.stop),
        r.error_l2,
        r.error_grid_points,
        r.error_max,
        r.error_l2_quadrature,
        estimated,
        r.uniform.samples,
        r.uniform.basis_size,
        r.uniform.error_l2,
        r.uniform.error_max,
        r.uniform.error_l2_quadrature,
        r.ratio_l2,
        r.ratio_l2_quadrature,
        r.time_s.refine,
        r.time_s.round_mean,
        r.time_s.round_last,
        r.time_s.full_rebuild,
    )
}

/// The stop reason as in the JSON (`tolerance`, `depth_limit`, `budget`, `resolution`, ...).
fn stop_name(stop: StopReason) -> String {
    serde_json::to_value(stop)
        .ok()
        .and_then(|v| v.as_str().map(str::to_string))
        .unwrap_or_default()
}

/// Adaptive against uniform over sample counts, for people (`rkwave adapt --compare-uniform`;
/// `grid` the points of the grid the RMS is measured on).
pub fn comparison_table(out: &Comparison, grid: usize) -> String {
    let mut text = String::new();
    let _ = writeln!(
        text,
        "{}: adaptive vs uniform (RMS on a grid of {}; L2 by quadrature)",
        out.signal, grid
    );
    let _ = writeln!(
        text,
        "{:>8} {:>8} {:>5} {:>11} {:>11} {:>10} {:>11} {:>11} {:>10}",
        "budget",
        "samples",
        "depth",
        "adapt RMS",
        "unif RMS",
        "ratio",
        "adapt L2",
        "unif L2",
        "ratio"
    );
    for row in &out.comparison {
        let _ = writeln!(
            text,
            "{:>8} {:>8} {:>5} {:>11.3e} {:>11.3e} {:>10.1} {:>11.3e} {:>11.3e} {:>10.1}",
            row.budget,
            row.samples,
            row.max_depth,
            row.adaptive_l2,
            row.uniform_l2,
            row.ratio_l2,
            row.adaptive_l2_quadrature,
            row.uniform_l2_quadrature,
            row.ratio_l2_quadrature
        );
    }
    text
}
