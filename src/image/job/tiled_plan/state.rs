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

/// Vectors kept as their lengths and nonzero entries (bits, so a state read back is the same
/// numbers). In memory the union of the vectors' nonzero indices is held once (`u32`) beside
/// every vector's bits there (`+0.0`'s where that vector's entry is zero): 36 bytes a tree
/// function for four vectors against 64 as `(index, bits)` pairs per vector, 0.3 GB of 510
/// tiles at 3840x2160 (docs/measurements/scale-out.md). Written as the pairs
/// (`{"lens": [...], "entries": [[[index, bits], ...], ...]}`, the entries whose bits are
/// not those of `+0.0`), so the state file's layout is unchanged.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(into = "SparseStartFile", try_from = "SparseStartFile")]
pub struct SparseStart {
    /// Length of each vector.
    lens: Vec<usize>,
    /// The indices where any vector's entry is not `+0.0`, ascending.
    indices: Vec<u32>,
    /// Per vector, the bits of its entries at `indices`.
    bits: Vec<Vec<u64>>,
}

/// [`SparseStart`] as written: per vector, its `(index, bits)` pairs whose bits are not
/// those of `+0.0`.
#[derive(Clone, Debug, Serialize, Deserialize)]
struct SparseStartFile {
    lens: Vec<usize>,
    entries: Vec<Vec<(usize, u64)>>,
}

impl SparseStart {
    /// The vectors `vectors`, their nonzero entries kept.
    pub fn new(vectors: &[Vec<f64>]) -> Self {
        let longest = vectors.iter().map(Vec::len).max().unwrap_or(0);
        let indices: Vec<u32> = (0..longest)
            .filter(|&i| {
                vectors
                    .iter()
                    .any(|v| v.get(i).is_some_and(|x| x.to_bits() != 0))
            })
            .map(|i| u32::try_from(i).expect("a window's basis has fewer than 2^32 functions"))
            .collect();
        let bits = vectors
            .iter()
            .map(|v| {
                indices
                    .iter()
                    .map(|&i| v.get(i as usize).map_or(0, |x| x.to_bits()))
                    .collect()
            })
            .collect();
        SparseStart {
            lens: vectors.iter().map(Vec::len).collect(),
            indices,
            bits,
        }
    }

    /// The vectors, dense.
    pub fn dense(&self) -> Vec<Vec<f64>> {
        self.lens
            .iter()
            .zip(&self.bits)
            .map(|(&len, bits)| {
                let mut v = vec![0.0; len];
                for (&i, &b) in self.indices.iter().zip(bits) {
                    v[i as usize] = f64::from_bits(b);
                }
                v
            })
            .collect()
    }

    /// Entries whose bits are not those of `+0.0`, over all vectors.
    pub fn nonzero(&self) -> usize {
        self.bits
            .iter()
            .map(|b| b.iter().filter(|&&x| x != 0).count())
            .sum()
    }
}

impl From<SparseStart> for SparseStartFile {
    fn from(s: SparseStart) -> Self {
        let entries = s
            .bits
            .iter()
            .map(|bits| {
                s.indices
                    .iter()
                    .zip(bits)
                    .filter(|(_, &b)| b != 0)
                    .map(|(&i, &b)| (i as usize, b))
                    .collect()
            })
            .collect();
        SparseStartFile {
            lens: s.lens,
            entries,
        }
    }
}

impl TryFrom<SparseStartFile> for SparseStart {
    type Error = String;
    fn try_from(f: SparseStartFile) -> Result<Self, String> {
        if f.lens.len() != f.entries.len() {
            return Err(format!(
                "a carried start of {} vectors with {} entry lists",
                f.lens.len(),
                f.entries.len()
            ));
        }
        let mut vectors = Vec::with_capacity(f.lens.len());
        for (&len, entries) in f.lens.iter().zip(&f.entries) {
            if u32::try_from(len).is_err() {
                return Err(format!("a carried start of length {len}"));
            }
            let mut v = vec![0.0; len];
            for &(i, b) in entries {
                *v.get_mut(i).ok_or_else(|| {
                    format!("a carried start's entry {i} beyond its length {len}")
                })? = f64::from_bits(b);
            }
            vectors.push(v);
        }
        Ok(SparseStart::new(&vectors))
    }
}

impl TilePlanState {
    pub(super) fn start_f64(&self) -> Option<Vec<Vec<f64>>> {
        self.start.as_ref().map(SparseStart::dense)
    }

    pub(super) fn set_start(&mut self, start: Option<Vec<Vec<f64>>>) {
        self.start = start.map(|s| SparseStart::new(&s));
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

/// The stop of a plan whose tiles all stopped: the tolerance when every tile reached it,
/// else the depth limit.
pub(super) fn all_stopped(tiles: &[TilePlanState]) -> StopReason {
    if tiles.iter().all(|t| t.stop == Some(StopReason::Tolerance)) {
        StopReason::Tolerance
    } else {
        StopReason::DepthLimit
    }
}
