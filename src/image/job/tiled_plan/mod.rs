//! The plan on tiles (issue 40, item 2): the renderer's adaptive loop on the tile grid of
//! `reconstruct --dim 2 --tile`, in memory bounded by the tile and the workers.
//!
//! **Tiles.** The grid ([`TileGeometry`]: tile `T`, halo `H_a`, default
//! [`PLAN_DEFAULT_HALO`] = 0) gives tile `t` its interior `R_t` and its window `R_t^+`: the
//! interior grown by the halo **to a power of two** on each axis, inside the image
//! ([`plan_window`]; the image's side where that is smaller). A power-of-two window makes the
//! tile's slots at pixel level its pixels, as the untiled plan's are on a power-of-two image:
//! windows of `T + 2 H_a` pixels (88 at `T = 64`, `H_a = 12`) started the tiles' trees with
//! slots coarser than a pixel and bunched their samples, 1-2.7 dB below the untiled plan
//! (docs/measurements/scale-out.md). Tile `t` runs the
//! untiled plan's refiner ([`ImagePlan`]) on the window as an image of its own
//! (`|R_t^+|` pixels, window-local coordinates `x - x0(R_t^+)`, exact in `f64`): its own
//! quadtree and its own fits, on **every** sample in the window (its own and its
//! neighbours' in the halo). The base positions are drawn per tile and kept where the tile
//! *owns* them (its interior, half-open `[x0, x1) x [y0, y1)`, closed at the image border),
//! so the base covers every pixel once. A round's positions a tile draws are all kept, also
//! those in its halo: the neighbour owning those pixels sees them in its own window and tops
//! its slots up only where they still lack samples. (Discarding them instead was tried: the
//! tiles' cells in a halo are not the neighbour's cells, so a tile's halo slots stayed short
//! and it drew there again every round; at 128² with tiles of 64 up to 96 % of a round's
//! draws were discarded and the plan ran to its round limit.)
//!
//! **One global budget.** A round of the tiled plan is one step of every tile, in parallel
//! (rayon, at most `workers` tiles at once). The round's growth is the untiled plan's,
//! `G = min(B - N, ceil(g N))` (`N` positions handed out so far, `g` the least growth, `B`
//! the budget), and it is split over the tiles by their indicators: tile `t` gets
//! `a_t = G eta_t^2 / sum_s eta_s^2` samples (largest remainders to make the sum `G`), where
//! `eta_t^2 = |R_t^+| e_t^2` is the tile's total predicted detail (`e_t`, the RMS estimate
//! its last step's indicator logged). So the samples go where the scene needs them across
//! tiles, as the untiled plan's Dörfler marking sends them, not a fixed share per tile; inside
//! a tile its own marking places them. What was chosen here: the indicator of a tile's
//! **last** step decides its share of the next (one step per round; the step that fits also
//! marks), and the first step's shares are by interior pixels (no indicator yet). A tile
//! gets `a_t` by running its step with budget `n_t + a_t` and least growth `a_t / n_t`
//! (`n_t` the samples in its window); a tile whose step stopped for the tolerance or the
//! depth limit gets no more samples. The plan stops when `N >= B`, when every tile stopped,
//! when a round hands out nothing, or at the round limit.
//!
//! **State.** Per tile: its parameters (the plan's, the seed mixed with the tile index so
//! tiles draw different positions, the base level fixed at the tile's first step), its
//! refinement history ([`PlanProgress`]), PCG's start (bits, so a state read back continues
//! bit for bit) and its last `eta_t^2`; beside them the record of positions handed out
//! ([`IssuedRound`]: count and order-free fingerprint per round, the untiled plan's rule).
//! Between rounds nothing else is held: each tile's tree and fit are rebuilt from its history
//! for its step ([`ImagePlan::resume`]) and dropped after, so memory holds the samples, the
//! per-tile history and `workers` tile fits; in one process each tile's PCG diagonal may be
//! kept for its next fit, up to a bound ([`TiledPlanState::keep_diagonals`], off by default:
//! the sums then continue, the fits change by rounding only). A round
//! ([`TiledPlanState::advance`]) computes everything first and changes the state only when
//! every tile succeeded: committed as one step, or not at all.
//!
//! **Memory.** [`TiledPlanStart::check_memory`] refuses, before anything is allocated, a
//! tile whose fit (`workers` of them at once), beside the samples and the image, would exceed
//! the memory limit, naming the largest tile that would fit; a round refuses a tile whose
//! actual samples would (the shares are not fixed, so a tile may hold more than its average).
//! After each tile and each commit the pages the allocator holds free are handed back to the
//! system (module `memory`), so the resident set follows the bytes live instead of the
//! tiles' fits' high-water mark.
//!
//! **Final image.** Every tile fits all samples in its window on its tree
//! ([`ImagePlan::fit_updating`], warm-started) and makes the plan's output pixels
//! (`output_pixels`); the image keeps each tile's interior, as the uniform tiles stitch.
//!
//! Why `image::job::tiled_plan`: it is a job built on the plan's refiner and the tile grid,
//! beside [`super::PlanStart`] and [`super::TiledJob`]; neither the state machine
//! (`image::plan`) nor the tiles (`image::tiles`) call back into it.

mod band;
mod error;
mod held;
mod kept;
mod memory;
mod picks;
mod round;
mod state;
mod stops;
mod times;
mod window;

use crate::error::{Fix, Param};
use crate::image::adaptive::{AdaptiveParams, ImagePlan, PlanProgress, SamplePositions};
use crate::image::plan::{IssuedRound, ProtocolError};
use crate::image::tiles::{TileGeometry, TileGeometryError};
use crate::image::ImagePlane;
use crate::resources::memory_limit;

use super::{PlanOptions, PlanStart};

pub use band::{
    tile_row_bands, BandError, BandOutcome, BandStrip, BandTask, BandTileOutcome, BandedRound,
    FinalBandTask, RoundPlan,
};
pub use error::TiledPlanError;
pub use held::{
    tile_record, HeldBand, HeldBandOutcome, HeldBandTask, HeldBands, HeldFinalBandTask,
};
pub use round::TiledFinal;
pub use state::{
    SparseStart, TilePlanState, TiledPlanState, TILED_STATE_FILE, TILED_STATE_FORMAT,
    TILED_STATE_VERSION,
};
pub use stops::TiledStep;
pub use times::TiledTimes;
use window::{keep_owned, mix_index, sizes, window_plane, windows_not_dyadic};
pub use window::{plan_window, tile_bytes, CONCENTRATION};

/// The tiled plan's default halo: none. A power-of-two tile is then its own window, and its
/// tree's cells are the untiled plan's cells on its interior at every level (the basis is on
/// the interval, so a tile needs no halo to fit its border). At 128², 8 spp, tiles of 64
/// (docs/measurements/scale-out.md) halo 0 is within the untiled plan's PSNR on the three
/// analytic scenes where windows of 88 pixels (the uniform tiles' halo 12) lost 1-2.7 dB.
pub const PLAN_DEFAULT_HALO: usize = 0;

/// The tiles of a tiled plan.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TiledPlanOptions {
    /// Tile side in pixels (at least 1, at most the image's shorter side).
    pub tile: usize,
    /// Halo in pixels, at most the tile (default [`PLAN_DEFAULT_HALO`]); a tile's window is its
    /// interior grown by the halo to a power of two ([`plan_window`]).
    pub halo: Option<usize>,
    /// Tiles stepped at once, at least 1 (default: the machine's threads).
    pub workers: Option<usize>,
}

/// A new tiled plan, validated, nothing allocated yet.
#[derive(Debug, Clone)]
pub struct TiledPlanStart {
    start: PlanStart,
    geometry: TileGeometry,
    workers: usize,
}

impl TiledPlanStart {
    /// Validates a tiled plan on `plane`: the plan's options as [`PlanStart::new`] and those
    /// the tiles refuse ([`PlanOptions::check_tiled`]), the grid ([`TileGeometry::new`]), the
    /// workers. Allocates nothing.
    pub fn new(
        plane: ImagePlane,
        options: &PlanOptions,
        tiles: &TiledPlanOptions,
    ) -> Result<TiledPlanStart, TiledPlanError> {
        let start = PlanStart::new(plane, options)?;
        options.check_tiled()?;
        let halo = tiles.halo.unwrap_or(PLAN_DEFAULT_HALO);
        let geometry = TileGeometry::new(plane, tiles.tile, halo).map_err(|source| {
            let param = match source {
                TileGeometryError::HaloLargerThanTile { .. } => Param::Halo,
                _ => Param::Tile,
            };
            TiledPlanError::Grid { param, source }
        })?;
        let workers = match tiles.workers {
            Some(0) => return Err(TiledPlanError::Workers),
            Some(n) => n,
            None => rayon::current_num_threads().max(1),
        };
        Ok(TiledPlanStart {
            start,
            geometry,
            workers,
        })
    }

    /// The plan's parameters, defaults filled in.
    pub fn params(&self) -> &AdaptiveParams {
        self.start.params()
    }

    /// The tile grid.
    pub fn geometry(&self) -> &TileGeometry {
        &self.geometry
    }

    /// The decisions made for the caller: windows grown past the interior and the halo to a
    /// power of two, windows that cannot be one (the image's side is smaller).
    pub fn notes(&self) -> Vec<String> {
        let g = &self.geometry;
        let mut notes = Vec::new();
        let w = plan_window(g, 0);
        if w.width() > g.tile + 2 * g.halo || w.height() > g.tile + 2 * g.halo {
            notes.push(format!(
                "windows of {}x{} pixels: each tile's interior ({} pixels) and halo ({}) grown \
                 to a power of two so that the tile's slots at pixel level are pixels",
                w.width(),
                w.height(),
                g.tile,
                g.halo
            ));
        }
        let odd = windows_not_dyadic(g);
        if odd > 0 {
            notes.push(format!(
                "{odd} of the {} tile windows are not a power of two in pixels (the image's \
                 side is smaller): their finest slots straddle pixels",
                g.count()
            ));
        }
        notes
    }

    /// The memory of the tiled plan from its sizes (module docs): `workers` tile fits, each
    /// the untiled plan's estimate ([`tile_bytes`]) on a window with [`CONCENTRATION`] times
    /// its share of the budget, beside the budget's samples and the output image. Refused
    /// above the memory limit with the largest tile size that would fit (none: fewer
    /// workers or a smaller budget).
    pub fn check_memory(&self, channels: usize) -> Result<(), TiledPlanError> {
        let params = self.params();
        let budget = params.stop.budget as f64;
        let g = &self.geometry;
        let (held, per_tile) = sizes(g, params, channels, budget);
        let needed = held + self.workers as f64 * per_tile;
        let limit = memory_limit();
        if needed <= limit as f64 {
            return Ok(());
        }
        let fits = (1..g.tile).rev().find(|&t| {
            TileGeometry::new(g.plane, t, g.halo.min(t)).is_ok_and(|smaller| {
                let (h, p) = sizes(&smaller, params, channels, budget);
                h + self.workers as f64 * p <= limit as f64
            })
        });
        let fix = match fits {
            Some(t) => format!(
                "a {} of at most {t} (or fewer {})",
                Fix::Set(Param::Tile),
                Fix::Set(Param::Workers)
            ),
            None => format!(
                "no tile size fits beside the samples: a smaller {} or fewer {}",
                Fix::Set(Param::Budget),
                Fix::Set(Param::Workers)
            ),
        };
        Err(TiledPlanError::TooLarge {
            what: format!(
                "a tiled plan of {} samples on {} pixels in tiles of {} (halo {})",
                params.stop.budget, g.plane, g.tile, g.halo
            ),
            per_tile,
            workers: self.workers,
            held,
            needed,
            limit,
            fix,
        })
    }

    /// Starts the plan (memory checked first for `channels`, three for a renderer's RGB when
    /// not known): every tile's refiner built on its window with its share of the budget,
    /// the base positions each draws in its interior.
    pub fn run(
        &self,
        channels: usize,
    ) -> Result<(TiledPlanState, SamplePositions), TiledPlanError> {
        self.check_memory(channels)?;
        let g = &self.geometry;
        let params = *self.params();
        let mut tiles = Vec::with_capacity(g.count());
        let mut base = SamplePositions::default();
        for index in 0..g.count() {
            let window = plan_window(g, index);
            let share =
                params.stop.budget as f64 * window.pixels() as f64 / g.plane.pixels() as f64;
            let mut tp = params;
            tp.sampling.seed =
                crate::image::adaptive::mix64(params.sampling.seed ^ mix_index(index));
            tp.stop.budget = (share.ceil() as usize).max(1);
            // a share below the tile's base: the base's size (the first round's shares are
            // the budget's, so the plan's budget holds)
            let plan = match ImagePlan::new(window_plane(&window), &tp) {
                Err(crate::image::adaptive::AdaptiveError::BudgetTooSmall { base, .. }) => {
                    tp.stop.budget = base;
                    ImagePlan::new(window_plane(&window), &tp)
                }
                other => other,
            }
            .map_err(ProtocolError::from)?;
            tp.quad.base_level = Some(plan.tree().basis().coarse_levels().0 + plan.base_steps());
            let positions = plan.base_positions();
            keep_owned(g, index, &window, &positions, &mut base, true);
            tiles.push(TilePlanState {
                index,
                params: tp,
                progress: PlanProgress::default(),
                start: None,
                indicator_sq: None,
                stop: None,
                steps: 0,
            });
        }
        let state = TiledPlanState {
            format: TILED_STATE_FORMAT.into(),
            version: TILED_STATE_VERSION,
            plane: g.plane,
            tile: g.tile,
            halo: g.halo,
            workers: self.workers,
            params,
            channels: None,
            tiles,
            issued: vec![IssuedRound {
                round: 0,
                positions: base.len(),
                total: base.len(),
                fingerprint: format!("{:016x}", round::fingerprint(0, &base.xs, &base.ys)),
            }],
            stop: None,
            kept: Default::default(),
        };
        Ok((state, base))
    }
}
