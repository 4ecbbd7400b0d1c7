//! Figures of the command line: the library computes their data
//! ([`rkwave::report::figures`]) and builds them ([`rkwave::plot::figures`]); this file
//! writes them.

use std::path::Path;

use rkwave::basis::CdvBasis;
use rkwave::plot::figures::{basis_functions_figure, kernels_figure as kernels_plot};
use rkwave::plot::{Figure, PlotError};
use rkwave::report::figures::{basis_functions, kernels};

use super::CliError;

/// Draws the scaling functions (top) and wavelets (bottom) of the coarse level of `basis`;
/// an existing file is replaced only with `force`.
pub fn basis_figure(basis: &CdvBasis, path: &Path, force: bool) -> Result<(), CliError> {
    save_new(
        &basis_functions_figure(&basis_functions(basis)?),
        path,
        force,
    )
}

/// Saves as SVG when the extension says so, PNG otherwise, replacing an existing file (for
/// commands that checked the target with `check_writable` and `--force` already); creates
/// the folder; atomic (see [`save_new`]).
pub fn save(fig: &Figure, path: &Path) -> Result<(), CliError> {
    save_new(fig, path, true)
}

/// Saves as SVG when the extension says so, PNG otherwise, through a temporary file beside
/// the target moved into place at the end; without `force`, a target that exists or appeared
/// while the figure was computed is left alone (exit code 2). Creates the folder.
pub fn save_new(fig: &Figure, path: &Path, force: bool) -> Result<(), CliError> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|source| CliError::Write {
            path: dir.to_path_buf(),
            source,
        })?;
    }
    fig.write(path, force).map_err(|e| match e {
        PlotError::Output(o) => CliError::from(o),
        other => CliError::from(other),
    })
}

/// Dual kernels `k~_i` (top) and reproducing kernels `k_i` (bottom) of a few samples, with
/// the dense pseudo-inverse (the paper's figure of dual kernels); an existing file is
/// replaced only with `force`.
pub fn kernels_figure(
    basis: &CdvBasis,
    positions: &[f64],
    path: &Path,
    force: bool,
) -> Result<(), CliError> {
    save_new(&kernels_plot(&kernels(basis, positions)?), path, force)
}
