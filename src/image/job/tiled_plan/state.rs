//! A tiled plan between calls: its state's layout and every tile's plan.

use serde::{Deserialize, Serialize};

use crate::adaptive::StopReason;
use crate::image::adaptive::{AdaptiveParams, PlanProgress};
use crate::image::plan::IssuedRound;
use crate::image::ImagePlane;

use super::kept::KeptDiagonals;

/// The tiled state's file name inside a plan's folder (the command line's `plan --tile` and
/// Python's `Plan(tile=...).save`).
pub const TILED_STATE_FILE: &str = "tiled-state.json";

/// The `format` field of a tiled plan's state.
pub const TILED_STATE_FORMAT: &str = "rkwave-tiled-plan";
/// The version of the tiled state layout this build reads and writes.
pub const TILED_STATE_VERSION: u32 = 1;

/// One tile's plan between rounds (module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TilePlanState {
    /// The tile's index in the grid (row-major).
    pub index: usize,
    /// The refiner's parameters on the tile's window: the plan's, the seed mixed with the
    /// index, the base level fixed at the first step (the budget and the least growth are
    /// set per round from the tile's share).
    pub params: AdaptiveParams,
    /// The tile's refinement history.
    pub progress: PlanProgress,
    /// PCG's start for the tile's next fit (per image channel, then per probe channel),
    /// sparse: the start is laid out over every function at the depth limit (`2^(Jx + Jy)`,
    /// 15 MB a tile of 152² with seven channels) but only the tree's are nonzero.
    pub start: Option<SparseStart>,
    /// The bits of the tile's last total predicted detail `eta_t^2` (`None` before its
    /// first step; bits, so a state read back is the same number).
    pub indicator_sq: Option<u64>,
    /// Why the tile's last step stopped it (the tolerance or the depth limit: it gets no more
    /// samples; `None` while it refines).
    pub stop: Option<StopReason>,
    /// Steps the tile has taken.
    pub steps: usize,
}

/// Vectors kept as their lengths and nonzero entries: `(index, bits of the f64)` (bits, so
/// a state read back is the same numbers).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SparseStart {
    /// Length of each vector.
    pub lens: Vec<usize>,
    /// Per vector, its entries whose bits are not those of `+0.0`.
    pub entries: Vec<Vec<(usize, u64)>>,
}

impl TilePlanState {
    pub(super) fn start_f64(&self) -> Option<Vec<Vec<f64>>> {
        self.start.as_ref().map(|s| {
            s.entries
                .iter()
                .zip(&s.lens)
                .map(|(c, &len)| {
                    let mut v = vec![0.0; len];
                    for &(i, b) in c {
                        v[i] = f64::from_bits(b);
                    }
                    v
                })
                .collect()
        })
    }

    pub(super) fn set_start(&mut self, start: Option<Vec<Vec<f64>>>) {
        self.start = start.map(|s| SparseStart {
            lens: s.iter().map(Vec::len).collect(),
            entries: s
                .iter()
                .map(|c| {
                    c.iter()
                        .enumerate()
                        .filter(|(_, v)| v.to_bits() != 0)
                        .map(|(i, v)| (i, v.to_bits()))
                        .collect()
                })
                .collect(),
        });
    }
}

/// A tiled plan between calls (module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TiledPlanState {
    /// Always [`TILED_STATE_FORMAT`].
    pub format: String,
    /// Always [`TILED_STATE_VERSION`] when written by this build.
    pub version: u32,
    /// The image plane.
    pub plane: ImagePlane,
    /// Tile side in pixels.
    pub tile: usize,
    /// Halo in pixels.
    pub halo: usize,
    /// Tiles stepped at once.
    pub workers: usize,
    /// The plan's parameters (the whole image's budget and seed).
    pub params: AdaptiveParams,
    /// Channels of the samples (`None` before the first samples).
    pub channels: Option<usize>,
    /// Every tile's plan.
    pub tiles: Vec<TilePlanState>,
    /// Positions handed out, per round.
    pub issued: Vec<IssuedRound>,
    /// Why the plan stopped (`None` while it runs).
    pub stop: Option<StopReason>,
    /// The tiles' PCG diagonals kept between rounds in memory ([`KeptDiagonals`]; never
    /// written, off unless [`TiledPlanState::keep_diagonals`] turns it on).
    #[serde(skip)]
    pub(super) kept: KeptDiagonals,
}

impl TiledPlanState {
    /// Keeps each tile's PCG diagonal between rounds in this process, up to `bound` bytes in
    /// all (`None`: off, the default: every round rebuilds it, as a plan read back from its
    /// state file does). The fits then differ from the rebuilt ones by PCG's rounding, within
    /// its tolerance (module `kept`); a tile over the bound is rebuilt, counted in the step.
    pub fn keep_diagonals(&mut self, bound: Option<u64>) {
        self.kept = KeptDiagonals {
            bound,
            ..Default::default()
        };
    }
}
