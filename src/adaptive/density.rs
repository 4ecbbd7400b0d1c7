//! Trees from sample density, for samples we did not choose (seed supplement §4: "decide on
//! the local depth of the wavelet tree based on the number of samples in a neighborhood").
//!
//! Uniform levels `Psi(n, N)` ask for about `rho` samples per slot of `V_{N+1}` everywhere.
//! Clustered, gappy or graded samples leave whole supports empty: the uniform solve then has
//! undetermined directions, and whatever fills them (a fallback, a ridge) is not the data. A
//! [`WaveletTree`] lets the local depth follow the local sample count instead:
//!
//! ```text
//! psi_{j,k} in T   <=   samples(C) >= ceil(rho) for every level-(j+1) cell C of supp psi_{j,k}
//! ```
//!
//! closed under "parent present", over the coarsest scaling level `j_min(p)` (coarse
//! functions, whose supports reach across gaps into sampled ground, bridge the gaps). A
//! wavelet that passes the test turns the cells of its support into leaves of level `j + 1`
//! holding `ceil(rho)` samples each; the ancestors the closure adds, and the coarse scaling
//! functions, may have sparse or empty cells in their supports, and the sample-free ones are
//! reported (`empty_regions`). The tree has about one function per `rho` samples where
//! samples are, and the `2^n` coarse scaling functions and a few ancestors elsewhere.

use std::sync::Arc;

use super::tree::interval::{range_in, support_cells, Leaf, WaveletTree, MAX_DEPTH_LIMIT};
use crate::basis::{minimum_level, BasisError, FilterBank};
use crate::sampling::Domain;

/// The tree whose local depth follows the sample count (module docs): scaling functions of
/// level `j_min(p)`, every wavelet up to `max_level` whose level-`(j + 1)` support cells each
/// hold at least `per_leaf` of the ascending unit positions `sorted`, and their ancestors.
///
/// The search descends from the coarse wavelets into the children of every wavelet whose
/// support holds at least `2 (2p - 1) per_leaf` samples (what any descendant needs, its
/// support lying inside), so it visits `O(m / rho)` wavelets per level.
pub fn density_tree(
    bank: Arc<FilterBank>,
    domain: Domain,
    sorted: &[f64],
    per_leaf: usize,
    max_level: u32,
) -> Result<WaveletTree, BasisError> {
    let p = bank.p();
    let coarse = minimum_level(p);
    let max_level = max_level.clamp(coarse, MAX_DEPTH_LIMIT);
    let mut tree = WaveletTree::uniform(bank, coarse, coarse as i32 - 1, max_level, domain)?;
    let count = |level: u32, cell: u64| range_in(sorted, &Leaf { level, cell }).len();
    let mut accepted = Vec::new();
    let mut level = coarse;
    let mut candidates: Vec<usize> = (0..1usize << coarse).collect();
    let cells_per_support = 2 * (2 * p as u64 - 1);
    let enough = per_leaf * cells_per_support as usize;
    while !candidates.is_empty() {
        let mut explored = Vec::new();
        for k in candidates {
            let (lo, hi) = support_cells(p, level, k);
            let cells: Vec<usize> = (2 * lo..=2 * hi + 1).map(|c| count(level + 1, c)).collect();
            if cells.iter().all(|&c| c >= per_leaf) {
                accepted.push((1usize << level) + k);
            }
            if cells.iter().sum::<usize>() >= enough {
                explored.push(k);
            }
        }
        if level == max_level {
            break;
        }
        candidates = explored.iter().flat_map(|&k| [2 * k, 2 * k + 1]).collect();
        level += 1;
    }
    // Ancestors close the tree ("parent present"); the leaves they add in sparse ground are
    // what `empty_regions` reports.
    tree.extend(accepted);
    Ok(tree)
}

/// The maximal sample-free intervals (domain coordinates, `[a, b]` between the neighbouring
/// samples or the domain's ends) that contain a whole leaf of `tree` without samples.
pub fn empty_regions(tree: &WaveletTree, sorted: &[f64]) -> Vec<[f64; 2]> {
    let domain = tree.domain();
    let mut out: Vec<[f64; 2]> = Vec::new();
    for leaf in tree.leaves() {
        if !range_in(sorted, &leaf).is_empty() {
            continue;
        }
        let (lo, hi) = leaf.unit_bounds();
        let before = sorted.partition_point(|&t| t < lo);
        let a = if before == 0 { 0.0 } else { sorted[before - 1] };
        let after = sorted.partition_point(|&t| t <= hi);
        let b = sorted.get(after).copied().unwrap_or(1.0);
        let region = [domain.from_unit(a), domain.from_unit(b)];
        if out.last() != Some(&region) {
            out.push(region);
        }
    }
    out
}
