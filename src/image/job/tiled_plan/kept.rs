//! The tiles' PCG diagonals kept between rounds, in memory only (never in the state file).
//!
//! A tile's step is rebuilt from its history ([`crate::image::adaptive::ImagePlan::resume`]),
//! and its fit then sums PCG's Jacobi diagonal `G_aa = sum_i Psi_a(x_i, y_i)^2` over every
//! sample of the window afresh: the multilevel evaluator at every sample, 60-75 % of a
//! round's fit at 512² (docs/measurements/scale-out.md). The tree only grows and a window's
//! samples are the last round's plus new ones, so the sums continue
//! (`DiagonalSums`, the untiled plan's continuation): the new samples over the whole tree,
//! the old ones only where a new function's support covers them. Kept, a tile's diagonal
//! costs `9 |basis|` bytes (the sums and the tree's mask over the window's basis at the
//! depth limit: 0.6 MB for a window of 128² one level below the pixel).
//!
//! **Bound.** Diagonals are kept up to the caller's byte bound in all
//! (`TiledPlanState::keep_diagonals`); a tile whose diagonal would pass it is
//! rebuilt the next round (the step's report counts them, with a note). Off by default, so
//! a plan driven in one process gives the bits of the same plan driven through the state file
//! (the command line's `plan --tile`, which rebuilds every round).
//!
//! **What changes.** Only the order of the diagonal's sums, so its bits differ by rounding;
//! the diagonal only preconditions CG, and every fit still runs to its own tolerance. The
//! coefficients then differ within PCG's relative residual (`1e-4` in a round, the plan's
//! solver tolerance in the final fit), not bit for bit; `tests/tiled_plan.rs` holds the kept
//! and rebuilt plans to the same positions and images within a stated bound.

use crate::image::adaptive::FitState;

/// The tiles' kept diagonals and their bound (module docs).
#[derive(Default)]
pub struct KeptDiagonals {
    /// The bound in bytes (`None`: nothing kept).
    pub(super) bound: Option<u64>,
    /// Per tile, its fit state holding only the diagonal (`None`: rebuilt next round).
    pub(super) states: Vec<Option<FitState>>,
    /// Bytes held by `states`.
    pub(super) bytes: u64,
}

impl KeptDiagonals {
    /// The kept state of every tile, taken out (`tiles` of them; `None` where nothing is kept).
    pub(super) fn take_all(&mut self, tiles: usize) -> Vec<Option<FitState>> {
        let mut states = std::mem::take(&mut self.states);
        states.resize_with(tiles, || None);
        self.bytes = 0;
        states
    }

    /// Keeps tile states after a round, in tile order, while the bound allows; returns the
    /// tiles kept and those that did not fit. `states[t]` is `(state, bytes)` of tile `t`'s
    /// fit (`None`: the tile did not fit this round, nothing to keep).
    pub(super) fn keep(&mut self, states: Vec<Option<(FitState, u64)>>) -> (usize, usize) {
        let Some(bound) = self.bound else {
            return (0, 0);
        };
        let (mut kept, mut over) = (0, 0);
        self.states = states
            .into_iter()
            .map(|s| {
                let (mut state, bytes) = s?;
                if self.bytes + bytes > bound {
                    over += 1;
                    return None;
                }
                // the diagonal only: the rows are 80 bytes a sample (p = 2), the samples' own
                // size twice over
                state.rows = None;
                state.gram = None;
                self.bytes += bytes;
                kept += 1;
                Some(state)
            })
            .collect();
        (kept, over)
    }
}

impl Clone for KeptDiagonals {
    /// A copy keeps the bound, not the diagonals (its next round rebuilds them).
    fn clone(&self) -> Self {
        KeptDiagonals {
            bound: self.bound,
            ..Default::default()
        }
    }
}

impl PartialEq for KeptDiagonals {
    /// Solver state only: two plans are equal whatever they keep.
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl std::fmt::Debug for KeptDiagonals {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "KeptDiagonals {{ bound: {:?}, tiles: {}, bytes: {} }}",
            self.bound,
            self.states.iter().filter(|s| s.is_some()).count(),
            self.bytes
        )
    }
}
