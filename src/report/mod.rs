//! Reports: the local-vs-global comparison of docs/design.md §5, as plain data that the command line
//! prints and plots.
//!
//! For a basis, a sample layout and a test signal: the approximate pseudo-inverse `K~` of local
//! inversion against the dense `K^+` (element-wise `max |K~ - K^+|`, RMS, relative Frobenius
//! error), the reconstructions `K~ f` and `K^+ f` against each other and against the true signal
//! (RMS on a fine grid), submatrix sizes, local condition numbers, cut-offs and times.
//!
//! The experiments around it, each a function returning a typed `Serialize` report that the
//! command line renders as text, JSON, CSV or a figure:
//! - [`sweep`]: this report over a grid of knobs;
//! - [`scaling`]: time, memory and accuracy of one fit against the number of samples;
//! - [`basis`]: a basis' measured identities and its functions at given positions;
//! - [`reconstruction`]: a user's samples onto a grid, with residuals;
//! - [`figures`]: the data of the basis and kernel figures.

pub mod basis;
pub mod figures;
pub mod reconstruction;
pub mod scaling;
pub mod sweep;

use std::time::Instant;

use serde::Serialize;

use crate::basis::{CdvBasis, FilterFamily};
use crate::kernel::{kernel_matrix, ActiveSet, LevelChoice};
use crate::reconstruct::{Fit, ReconstructError, SolveReport, Timings};
use crate::sampling::{Domain, Layout, Signal};
use crate::solve::{
    compare_sparse_dense, dense_pinv, global_ls, local_inversion, Comparison, GlobalLsParams,
    LocalInversionParams, Summary, DENSE_LIMIT,
};

/// The setting of one report.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct ReportSetting {
    /// Vanishing moments.
    pub p: usize,
    /// Interior filter family ("db" or "sym").
    #[serde(serialize_with = "family_name")]
    pub family: FilterFamily,
    /// Coarse level `n`.
    pub coarse: u32,
    /// Finest wavelet level `N`.
    pub fine: u32,
    /// Samples `m`.
    pub samples: usize,
    /// Sample layout.
    pub layout: Layout,
    /// Seed of random layouts.
    pub seed: u64,
    /// Test signal.
    pub signal: Signal,
    /// Local inversion knobs.
    pub local: LocalInversionParams,
    /// Points of the grid on which reconstructions are compared.
    pub grid: usize,
}

fn family_name<S: serde::Serializer>(f: &FilterFamily, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(f.short_name())
}

/// min / median / max.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Spread {
    /// Smallest.
    pub min: f64,
    /// Median.
    pub median: f64,
    /// Largest.
    pub max: f64,
}

impl From<Summary> for Spread {
    fn from(s: Summary) -> Self {
        Self {
            min: s.min,
            median: s.median,
            max: s.max,
        }
    }
}

/// Submatrix sizes.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Submatrix {
    /// Rows `|jdx|` over groups.
    pub rows: Spread,
    /// Columns `|idx|` over groups.
    pub cols: Spread,
}

/// Reconstruction errors (RMS on the grid).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct ReconstructionErrors {
    /// `K~ f` against `K^+ f`.
    pub local_vs_global: f64,
    /// `K~ f` against the signal.
    pub local_vs_truth: f64,
    /// `K^+ f` against the signal.
    pub global_vs_truth: f64,
}

/// Seconds per stage.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct ReportTimes {
    /// Building `K`.
    pub kernel: f64,
    /// Local inversion (all of `K~`).
    pub local: f64,
    /// Global reference (dense SVD pseudo-inverse, or sparse least squares when too large).
    pub global: f64,
}

/// The local-vs-global report.
#[derive(Clone, Debug, Serialize)]
pub struct LocalGlobalReport {
    /// What was run.
    pub setting: ReportSetting,
    /// Basis functions `P`.
    pub functions: usize,
    /// `m / P`.
    pub oversampling: f64,
    /// Which global reference: "dense_pinv" or "sparse_least_squares".
    pub reference: &'static str,
    /// Submatrix sizes.
    pub submatrix: Submatrix,
    /// `K~` against `K^+` (absent when the dense reference is out of reach).
    pub error: Option<Comparison>,
    /// Reconstructions.
    pub reconstruction: ReconstructionErrors,
    /// Local condition numbers (`s_max / s_min` of each `K1`).
    pub condition: Spread,
    /// Condition number of the whole `K` (dense reference only).
    pub global_condition: Option<f64>,
    /// Groups whose cut-off dropped directions, and directions dropped.
    pub cut: (usize, usize),
    /// Factorizations.
    pub groups: usize,
    /// Times.
    pub time_s: ReportTimes,
}

/// The one RMS of the crate: `sqrt( sum_i (a_i - b_i)^2 / n )`.
pub(crate) use crate::norms::rms_difference as rms;

/// The demo's summary: the measured identities of every basis and the local-vs-global
/// reports.
#[derive(Clone, Debug, Serialize)]
pub struct DemoSummary {
    /// One report per basis.
    pub bases: Vec<basis::BasisReport>,
    /// Local inversion against the global pseudo-inverse.
    pub local_vs_global: Vec<LocalGlobalReport>,
}

/// Runs one report.
pub fn local_vs_global(setting: &ReportSetting) -> Result<LocalGlobalReport, ReconstructError> {
    let domain = Domain::UNIT;
    let basis = CdvBasis::new(
        setting.p,
        setting.family,
        setting.coarse,
        setting.fine,
        domain,
    )?;
    // Refused before allocating: the basis, the samples and K (with its transpose).
    crate::resources::check(
        || {
            format!(
                "a report of {} samples on levels {}..{}",
                setting.samples, setting.coarse, setting.fine
            )
        },
        crate::resources::uniform_basis_bytes(setting.p, setting.fine, 1)
            + crate::resources::grid_bytes(setting.samples, 1)
            + crate::resources::kernel_bytes(
                setting.samples,
                setting.p,
                setting.coarse,
                setting.fine,
            ),
        || "use fewer samples or a smaller fine level N".into(),
    )?;
    let active = ActiveSet::uniform(basis);
    let xs = setting
        .layout
        .generate(setting.samples, domain, setting.seed);
    let f = setting.signal.sample(domain, &xs);
    let t0 = Instant::now();
    let k = kernel_matrix(&active, &xs)?;
    let kernel = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let local = local_inversion(&k, &setting.local)?;
    let local_s = t1.elapsed().as_secs_f64();
    let (m, p) = k.shape();
    let c_local = {
        let mut c = vec![0.0; p];
        sprs::prod::mul_acc_mat_vec_csc(local.pinv.view(), &f, &mut c);
        c
    };
    let t2 = Instant::now();
    let (reference, error, c_global, global_condition) = if m <= DENSE_LIMIT && p <= DENSE_LIMIT {
        let dense = dense_pinv(&k, setting.local.cutoff.max(1e-15))?;
        let cmp = compare_sparse_dense(&local.pinv, dense.pinv.as_ref())?;
        let c = dense.apply(&f)?;
        ("dense_pinv", Some(cmp), c, Some(dense.condition))
    } else {
        let g = global_ls(&k, &[&f], &GlobalLsParams::default())?;
        (
            "sparse_least_squares",
            None,
            g.coefficients[0].clone(),
            None,
        )
    };
    let global_s = t2.elapsed().as_secs_f64();
    let grid: Vec<f64> = (0..setting.grid)
        .map(|i| domain.from_unit(i as f64 / (setting.grid - 1).max(1) as f64))
        .collect();
    let truth = setting.signal.sample(domain, &grid);
    let levels = LevelChoice {
        coarse: setting.coarse,
        fine: setting.fine,
        oversampling: m as f64 / p as f64,
    };
    let eval = |c: Vec<f64>| -> Result<Vec<f64>, ReconstructError> {
        let fit = Fit {
            active: active.clone(),
            coefficients: vec![c],
            levels,
            timings: Timings::default(),
            solve: SolveReport::Given,
            fallbacks: Vec::new(),
        };
        Ok(fit.evaluate(&grid)?.remove(0))
    };
    let r_local = eval(c_local)?;
    let r_global = eval(c_global)?;
    let stats = &local.stats;
    Ok(LocalGlobalReport {
        setting: *setting,
        functions: p,
        oversampling: m as f64 / p as f64,
        reference,
        submatrix: Submatrix {
            rows: stats.rows_summary().into(),
            cols: stats.cols_summary().into(),
        },
        error,
        reconstruction: ReconstructionErrors {
            local_vs_global: rms(&r_local, &r_global),
            local_vs_truth: rms(&r_local, &truth),
            global_vs_truth: rms(&r_global, &truth),
        },
        condition: stats.condition_summary().into(),
        global_condition,
        cut: (stats.cut_groups, stats.cut_total),
        groups: stats.n_groups,
        time_s: ReportTimes {
            kernel,
            local: local_s,
            global: global_s,
        },
    })
}

impl LocalGlobalReport {
    /// The report for people, one group of figures a line.
    pub fn table(&self) -> String {
        let r = self;
        let s = &r.setting;
        let err = r.error.as_ref().map_or_else(
            || "n/a (too large for the dense reference)".to_string(),
            |e| {
                format!(
                    "max |K~ - K+| {:.2e}, RMS {:.2e}, relative Frobenius {:.2e}",
                    e.max_abs, e.rms, e.rel_frobenius
                )
            },
        );
        format!(
            "local vs global: p = {} ({}), levels {}..{}, {} {} samples, P = {} (oversampling {:.2})\n\
             \x20 solver {:?}, rings {}, cut-off {:e}: {} groups, {} cut ({} directions)\n\
             \x20 submatrix rows   min {:.0} median {:.0} max {:.0}\n\
             \x20 submatrix cols   min {:.0} median {:.0} max {:.0}\n\
             \x20 element-wise     {}\n\
             \x20 reconstruction   local vs global {:.2e}, local vs truth {:.2e}, global vs truth {:.2e} (RMS, signal {})\n\
             \x20 local condition  median {:.3e}, max {:.3e}; global {}\n\
             \x20 time             kernel {:.4} s, local {:.4} s, global ({}) {:.4} s\n",
            s.p,
            s.family.short_name(),
            s.coarse,
            s.fine,
            s.samples,
            s.layout,
            r.functions,
            r.oversampling,
            s.local.solver,
            s.local.rings,
            s.local.cutoff,
            r.groups,
            r.cut.0,
            r.cut.1,
            r.submatrix.rows.min,
            r.submatrix.rows.median,
            r.submatrix.rows.max,
            r.submatrix.cols.min,
            r.submatrix.cols.median,
            r.submatrix.cols.max,
            err,
            r.reconstruction.local_vs_global,
            r.reconstruction.local_vs_truth,
            r.reconstruction.global_vs_truth,
            s.signal,
            r.condition.median,
            r.condition.max,
            r.global_condition
                .map_or("n/a".to_string(), |c| format!("{c:.3e}")),
            r.time_s.kernel,
            r.time_s.local,
            r.reference,
            r.time_s.global
        )
    }
}

#[cfg(test)]
mod tests;
