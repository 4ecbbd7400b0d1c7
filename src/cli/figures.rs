//! Figures of the command line: the library computes their data
//! ([`rkwave::report::figures`]) and builds them ([`rkwave::plot::figures`]); this file
//! writes them.

use std::path::Path;

use rkwave::basis::CdvBasis;
use rkwave::plot::figures::{basis_functions_figure, kernels_figure as kernels_plot};
use rkwave::plot::Figure;
use rkwave::report::figures::{basis_functions, kernels};

use super::CliError;

/// Draws the scaling functions (top) and wavelets (bottom) of the coarse level of `basis`.
pub fn basis_figure(basis: &CdvBasis, path: &Path) -> Result<(), CliError> {
    save(&basis_functions_figure(&basis_functions(basis)?), path)
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

/// Dual kernels `k~_i` (top) and reproducing kernels `k_i` (bottom) of a few samples, with
/// the dense pseudo-inverse (the paper's figure of dual kernels).
pub fn kernels_figure(basis: &CdvBasis, positions: &[f64], path: &Path) -> Result<(), CliError> {
    save(&kernels_plot(&kernels(basis, positions)?), path)
}
