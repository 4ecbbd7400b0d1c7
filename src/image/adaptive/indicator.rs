//! The refinement indicator on the image plane: predicted coefficients of the missing cells.
//!
//! For a slot `C` at step `t >= 1` (inactive, parent `P` active), let `m = max |c_a|` over the
//! three functions `a` of `P` (`|c|` is the norm over the channels), and `r = M(P) / M(P')` the
//! decay ratio of the largest magnitudes `M` within one cell (`|dk| <= 1` per axis) of `P` and
//! of the grandparent `P'` (the neighbourhoods keep `r` from jumping where an edge just enters a
//! support). Unlike 1D, `m` itself leaves the neighbours out: measured on a straight edge,
//! their maximum gave the cells beside the edge the edge's own priority and spread the
//! refinement over a band three parent cells wide (the supports of `P`'s functions already
//! reach one cell beyond it). `r` is clamped to `[2^-(p+1), r_max]` (`2^-(p+1)`: a smooth
//! region, where 2D coefficients decay like `2^{-j(p+1)}`; `1/2`: a straight edge, used at
//! `t = 1` where there is no grandparent). The
//! three functions of `C` are predicted at `r m` each, and its subtree with the edge model
//! (the edge crosses two of four children, so the energy per level falls by `2 r^2`, capped at
//! 0.81):
//!
//! `eta_C^2 = 3 (r m)^2 / (1 - min(2 r^2, 0.81))`.
//!
//! `sum eta_C^2` over the slots estimates the squared `L2` error `int (f - f~)^2` (orthonormal
//! basis on the rectangle, pixel units), so `sqrt(sum eta^2 / (W H))` is the estimated RMS
//! error per unit area. Slots at the depth limit count in the estimate but cannot be marked.
//!
//! *Noise* ([`super::significance`]): with a test given, a slot below the depth limit is
//! markable only if `m` exceeds its parent's threshold `sigma sqrt(v_P q)`; the others
//! are counted (`insignificant`) and kept in `total_sq` (the estimate stays conservative) but
//! never marked.
//!
//! Tried besides: nothing yet in 2D (the 1D refiner's residual indicator at probe points is the
//! next candidate; see the issue notes).

use crate::adaptive::{Cell, QuadTree};

/// The indicator of one fit.
#[derive(Clone, Debug, Default)]
pub struct Indication {
    /// Markable slots (below the depth limit) and their indicators, largest first (ties by
    /// cell, so the order is deterministic).
    pub units: Vec<(Cell, f64)>,
    /// Estimated squared error over the image, `sum eta^2` over every slot.
    pub total_sq: f64,
    /// The part of it that marking can reduce (significant slots below the depth limit).
    pub markable_sq: f64,
    /// Slots below the depth limit whose parent's detail is within the noise (not markable),
    /// largest indicator first.
    pub insignificant: Vec<(Cell, f64)>,
    /// Slots at the depth limit (never markable) and their indicators, in slot order.
    pub at_limit: Vec<(Cell, f64)>,
}

/// `max_a |c_a|` (norm over channels) over the three functions of `cell`.
fn magnitude(tree: &QuadTree, coefficients: &[Vec<f64>], cell: Cell) -> f64 {
    tree.cell_functions(cell)
        .into_iter()
        .map(|f| coefficients.iter().map(|c| c[f] * c[f]).sum::<f64>().sqrt())
        .fold(0.0, f64::max)
}

/// `max_a |c_a|` over the active cells within one cell of `cell` (`|dk| <= 1` per axis).
fn neighbourhood(tree: &QuadTree, coefficients: &[Vec<f64>], cell: Cell) -> f64 {
    tree.neighbourhood(cell)
        .filter(|&q| tree.is_active(q))
        .map(|q| magnitude(tree, coefficients, q))
        .fold(0.0, f64::max)
}

/// The indicator of every slot of `tree` from the fit's coefficients (full Mallat layout per
/// channel), the decay ratio capped at `max_ratio` (`r_max`, at least `2^-(p+1)`); with
/// `threshold`, only slots whose parent `P` has `m > threshold(P)` are markable.
pub fn indicate(
    tree: &QuadTree,
    coefficients: &[Vec<f64>],
    max_ratio: f64,
    threshold: Option<&dyn Fn(Cell) -> f64>,
) -> Indication {
    let p = tree.basis().p() as i32;
    let min_ratio = (-(p + 1) as f64).exp2();
    let max_ratio = max_ratio.max(min_ratio);
    let mut out = Indication::default();
    for slot in tree.leaves() {
        let Some(parent) = slot.parent() else {
            continue;
        };
        let m = magnitude(tree, coefficients, parent);
        let r = match parent.parent() {
            Some(grand) => {
                let mg = neighbourhood(tree, coefficients, grand);
                if mg > 0.0 {
                    (neighbourhood(tree, coefficients, parent) / mg).clamp(min_ratio, max_ratio)
                } else {
                    max_ratio
                }
            }
            None => 0.5,
        };
        let eta = (3.0 * (r * m).powi(2) / (1.0 - (2.0 * r * r).min(0.81))).sqrt();
        out.total_sq += eta * eta;
        if slot.step < tree.steps() {
            if threshold.is_some_and(|t| m <= t(parent)) {
                out.insignificant.push((slot, eta));
            } else {
                out.markable_sq += eta * eta;
                out.units.push((slot, eta));
            }
        } else {
            out.at_limit.push((slot, eta));
        }
    }
    for list in [&mut out.units, &mut out.insignificant] {
        list.sort_by(|a, b| b.1.total_cmp(&a.1).then_with(|| a.0.cmp(&b.0)));
    }
    out
}
