//! Fits on a tree from sample density, for samples we did not choose: the tree whose local
//! depth follows the local sample count ([`crate::adaptive::density`]) when uniform levels
//! would leave whole supports empty ([`strongly_non_uniform`]).
//!
//! The coefficients are the global least-squares solution on the tree's active set
//! ([`crate::reconstruct::fit_active`] with the global sparse solve: `K` from
//! [`crate::kernel::kernel_matrix`], equilibrated sparse Cholesky of `K^T K`, a ridge on
//! numerically singular directions, reported). Its accuracy is `cond(K)^2 eps`; the tree keeps
//! `cond(K)` small (`rho` samples per slot), and the tests compare it with the dense SVD.
//!
//! ```
//! use rkwave::reconstruct::{fit, Fallback, FitParams};
//! use rkwave::sampling::Domain;
//!
//! // 2,000 samples in [0, 0.3] and 2,000 in [0.7, 1]: nothing in between.
//! let xs: Vec<f64> = (0..4000)
//!     .map(|i| {
//!         let u = (i % 2000) as f64 / 2000.0 * 0.3;
//!         if i < 2000 { u } else { 0.7 + u }
//!     })
//!     .collect();
//! let ys: Vec<f64> = xs.iter().map(|x| (6.0 * x).sin()).collect();
//! let f = fit(&xs, &[&ys], Domain::UNIT, &FitParams::default())?;
//! let Some(Fallback::DensityTree { empty, .. }) = f.fallbacks.first() else { panic!() };
//! assert!(empty.iter().any(|r| r[0] <= 0.31 && r[1] >= 0.69)); // the gap, reported
//! let v = f.evaluate(&[0.5])?;
//! assert!(v[0][0].abs() < 2.0); // bridged, bounded
//! # Ok::<(), rkwave::reconstruct::ReconstructError>(())
//! ```

use serde::Serialize;

use super::{
    fit_active, min_support_samples, Fallback, Fit, FitParams, Method, ReconstructError,
    SolveReport,
};
use crate::adaptive::density::{density_tree, empty_regions};
use crate::adaptive::tree::interval::MAX_DEPTH_LIMIT;
use crate::basis::FilterBank;
use crate::kernel::{check_positions, LevelChoice, LevelParams};
use crate::sampling::Domain;
use crate::solve::{GlobalLsParams, RankPolicy};

/// Whether automatic uniform levels do not suit these samples: some support of a
/// single-scale level `V_L` holds fewer than two samples, where `L <= N - 1` (two levels below
/// the automatic `V_{N+1}`) is the finest level whose supports hold `m (2p - 1) 2^-L >= 40`
/// samples on average. Uniform, jittered or random samples never do (fewer than two of a
/// Poisson count of mean 40: probability `41 e^-40 ~ 2e-16` per support); clusters, gaps and
/// strongly graded densities do (a gap wider than `(2p - 1) 2^-L ~ 80 / m` suffices). Levels
/// without room (`L < n`) never switch.
pub fn strongly_non_uniform(
    positions: &[f64],
    domain: Domain,
    levels: &LevelChoice,
    p: usize,
) -> bool {
    inspected_level(positions.len(), levels, p).is_some_and(|level| {
        check_positions(domain, positions).is_ok()
            && min_support_samples(positions, domain, level, p) < 2
    })
}

/// The level `L` [`strongly_non_uniform`] inspects for `m` samples, `None` without room.
pub(crate) fn inspected_level(m: usize, levels: &LevelChoice, p: usize) -> Option<u32> {
    let per_support = m as f64 * (2 * p).saturating_sub(1).max(1) as f64 / MEAN_SUPPORT_SAMPLES;
    if levels.fine <= levels.coarse || per_support < 1.0 {
        return None;
    }
    let level = (per_support.log2().floor() as u32).min(levels.fine - 1);
    (level >= levels.coarse).then_some(level)
}

/// Mean samples per support of the level [`strongly_non_uniform`] inspects.
const MEAN_SUPPORT_SAMPLES: f64 = 40.0;

/// Fits `values` at `positions` on the density tree (module docs) with the global sparse
/// least-squares solve (the given one for [`Method::Global`], else the default with a ridge
/// on numerically singular directions), and records [`Fallback::DensityTree`] with the tree's
/// levels, size and empty regions.
pub fn fit_density_tree(
    positions: &[f64],
    values: &[&[f64]],
    domain: Domain,
    params: &FitParams,
    level_params: LevelParams,
) -> Result<Fit, ReconstructError> {
    fit_density_tree_with(
        positions,
        values,
        domain,
        params,
        level_params,
        DensityOptions::default(),
    )
}

/// Which functions of the density tree are fitted.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct DensityOptions {
    /// Least sampled mass `mu_a = sum_i Psi_a(t_i)^2 w_i` (of `int Psi_a^2 = 1`; `w_i` the
    /// sample's share of the line) a function needs to be fitted; the others get
    /// coefficient 0. Larger leaves more of the gaps to the coarse functions.
    pub min_sampled_mass: f64,
    /// Whether the coarse scaling functions are always fitted (they span the coarse level
    /// that bridges the gaps).
    pub keep_scaling: bool,
}

/// The default threshold sits inside the range that both keeps clustered samples' error and
/// bounds the fit across a gap wider than a coarse support; larger thresholds drop scaling
/// functions the clusters need (docs/measurements/one-d.md, "Trees from sample density").
impl Default for DensityOptions {
    fn default() -> Self {
        Self {
            min_sampled_mass: 0.01,
            keep_scaling: false,
        }
    }
}

/// [`fit_density_tree`] with explicit [`DensityOptions`].
pub fn fit_density_tree_with(
    positions: &[f64],
    values: &[&[f64]],
    domain: Domain,
    params: &FitParams,
    level_params: LevelParams,
    options: DensityOptions,
) -> Result<Fit, ReconstructError> {
    check_positions(domain, positions)?;
    let bank = FilterBank::shared(params.p, params.family())?;
    let mut sorted: Vec<f64> = positions.iter().map(|&x| domain.to_unit(x)).collect();
    sorted.sort_by(f64::total_cmp);
    let per_leaf = level_params.rho.ceil().max(1.0) as usize;
    let tree = density_tree(bank, domain, &sorted, per_leaf, MAX_DEPTH_LIMIT)?;
    let empty = empty_regions(&tree, &sorted);
    let full = tree.active_set()?;
    // Functions the samples do not see: sampled mass `mu_a = sum_i Psi_a(t_i)^2 w_i` (w_i the
    // sample's share of the line, `spacing_weights`) below `options.min_sampled_mass` of
    // `int Psi_a^2 = 1` are left out (coefficient 0): fitting them would amplify the data's
    // residual into the gap.
    let weights = spacing_weights(&sorted);
    let order = {
        let mut idx: Vec<usize> = (0..positions.len()).collect();
        idx.sort_by(|&i, &j| positions[i].total_cmp(&positions[j]));
        idx
    };
    let mut w = vec![0.0; positions.len()];
    for (rank, &i) in order.iter().enumerate() {
        w[i] = weights[rank];
    }
    let k = crate::kernel::kernel_matrix(&full, positions)?;
    let mut mass = vec![0.0f64; full.len()];
    for (i, row) in k.outer_iterator().enumerate() {
        for (c, v) in row.iter() {
            mass[c] += v * v * w[i];
        }
    }
    let scaling = 1usize << tree.coarse();
    let seen =
        |a: usize, mu: f64| mu >= options.min_sampled_mass || (options.keep_scaling && a < scaling);
    let kept: Vec<usize> = full
        .indices()
        .iter()
        .zip(&mass)
        .filter(|(&a, &mu)| seen(a, mu))
        .map(|(&a, _)| a)
        .collect();
    let unseen = full.len() - kept.len();
    let active = crate::kernel::ActiveSet::from_indices(full.basis().clone(), kept);
    let fine = tree.depth().max(tree.coarse() as i32) as u32;
    let levels = LevelChoice {
        coarse: tree.coarse(),
        fine,
        oversampling: positions.len() as f64 / active.len().max(1) as f64,
    };
    let global = match params.method {
        Method::Global(gp) => gp,
        _ => GlobalLsParams {
            rank_policy: RankPolicy::Regularize,
            ..GlobalLsParams::default()
        },
    };
    let functions = active.len();
    let mut fitted = fit_active(active, positions, values, Method::Global(global), levels)?;
    let ridge = match &fitted.solve {
        SolveReport::Global(report) => report.ridge,
        _ => 0.0,
    };
    fitted.fallbacks.insert(
        0,
        Fallback::DensityTree {
            coarse: levels.coarse,
            fine,
            functions,
            leaves: tree.leaves().len(),
            ridge,
            unseen,
            empty,
        },
    );
    Ok(fitted)
}

/// Per ascending unit position, the mean of the spacings to its two neighbours, each capped
/// at four times the smaller (a sample beside a gap does not stand for the gap); the one
/// spacing at the ends, `1` for a single sample.
fn spacing_weights(sorted: &[f64]) -> Vec<f64> {
    let n = sorted.len();
    (0..n)
        .map(|i| {
            let left = (i > 0).then(|| sorted[i] - sorted[i - 1]);
            let right = (i + 1 < n).then(|| sorted[i + 1] - sorted[i]);
            match (left, right) {
                (Some(a), Some(b)) => {
                    let cap = 4.0 * a.min(b);
                    0.5 * (a.min(cap) + b.min(cap))
                }
                (Some(a), None) | (None, Some(a)) => a,
                (None, None) => 1.0,
            }
        })
        .collect()
}
