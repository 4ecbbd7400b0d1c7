//! The plan on tiles (issue 40, item 2): the renderer's adaptive loop on the tile grid of
//! `reconstruct --dim 2 --tile`, in memory bounded by the tile and the workers.
//!
//! **Tiles.** The grid ([`TileGeometry`]: tile `T`, halo `H_a`, default
//! [`crate::image::tiles::DEFAULT_HALO`]) gives tile `t` its interior `R_t` and its window
//! `R_t^+` (the interior grown by the halo, clipped at the border). Tile `t` runs the
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
//! per-tile history and `workers` tile fits. A round ([`TiledPlanState::advance`]) computes
//! everything first and changes the state only when every tile succeeded: committed as one
//! step, or not at all.
//!
//! **Memory.** [`TiledPlanStart::check_memory`] refuses, before anything is allocated, a
//! tile whose fit (`workers` of them at once), beside the samples and the image, would exceed
//! the memory limit, naming the largest tile that would fit; a round refuses a tile whose
//! actual samples would (the shares are not fixed, so a tile may hold more than its average).
//!
//! **Final image.** Every tile fits all samples in its window on its tree
//! ([`ImagePlan::fit_updating`], warm-started) and makes the plan's output pixels
//! ([`output_pixels`]); the image keeps each tile's interior, as the uniform tiles stitch.
//!
//! Why `image::job::tiled_plan`: it is a job built on the plan's refiner and the tile grid,
//! beside [`super::PlanStart`] and [`super::TiledJob`]; neither the state machine
//! (`image::plan`) nor the tiles (`image::tiles`) call back into it.

mod round;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::adaptive::StopReason;
use crate::error::{ErrorKind, Fix, Param};
use crate::image::adaptive::correction::output_pixels;
use crate::image::adaptive::{AdaptiveParams, ImagePlan, PlanProgress, SamplePositions};
use crate::image::plan::{IssuedRound, ProtocolError};
use crate::image::tiles::{PixelRect, TileGeometry, TileGeometryError, DEFAULT_HALO};
use crate::image::{ImagePlane, PixelImage};
use crate::resources::{format_bytes, memory_limit, ImageRequest};

use super::{JobError, PlanOptions, PlanStart};

pub use round::{TiledFinal, TiledStep};

/// The `format` field of a tiled plan's state.
pub const TILED_STATE_FORMAT: &str = "rkwave-tiled-plan";
/// The version of the tiled state layout this build reads and writes.
pub const TILED_STATE_VERSION: u32 = 1;

/// How far a tile's samples may exceed its average share before the round's own check
/// refuses it: the start's memory check counts `CONCENTRATION` times the window's share of
/// the budget (the global marking moves samples between tiles).
pub const CONCENTRATION: f64 = 4.0;

/// The tiles of a tiled plan.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TiledPlanOptions {
    /// Tile side in pixels (at least 1, at most the image's shorter side).
    pub tile: usize,
    /// Halo in pixels, at most the tile (default [`DEFAULT_HALO`] clipped to the tile).
    pub halo: Option<usize>,
    /// Tiles stepped at once, at least 1 (default: the machine's threads).
    pub workers: Option<usize>,
}

/// Why a tiled plan was refused.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum TiledPlanError {
    /// The plan's options (budget, ranges).
    #[error(transparent)]
    Job(#[from] JobError),
    /// The plan's protocol: samples that are not the positions handed out, a state of
    /// another plan, a refiner's refusal.
    #[error(transparent)]
    Protocol(#[from] ProtocolError),
    /// The tile grid (`param` at fault).
    #[error("{}: {source}", Fix::Set(*param))]
    Grid {
        /// The parameter at fault.
        param: Param,
        /// The grid's refusal.
        source: TileGeometryError,
    },
    /// Workers 0.
    #[error(
        "workers 0: give at least 1 ({} 1 or more: tiles stepped at once)",
        Fix::Set(Param::Workers)
    )]
    Workers,
    /// A tile's fit beside the samples and the image exceeds the memory limit.
    #[error(
        "{what} would need about {} of memory ({} per tile fit x {workers} workers, {} of \
         samples and images), above the limit of {}: {fix}",
        format_bytes(*needed),
        format_bytes(*per_tile),
        format_bytes(*held),
        format_bytes(*limit as f64)
    )]
    TooLarge {
        /// What was checked.
        what: String,
        /// Bytes of one tile's fit.
        per_tile: f64,
        /// Tiles at once.
        workers: usize,
        /// Bytes of the samples and images held beside.
        held: f64,
        /// Bytes in all.
        needed: f64,
        /// The memory limit.
        limit: u64,
        /// The way out (the tile size that would fit, or fewer workers, or a smaller budget).
        fix: String,
    },
    /// The thread pool could not be built.
    #[error(
        "the pool of {workers} workers could not start ({reason}): give fewer {}",
        Fix::Set(Param::Workers)
    )]
    Pool {
        /// Workers asked for.
        workers: usize,
        /// The system's reason.
        reason: String,
    },
}

impl TiledPlanError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> ErrorKind {
        match self {
            TiledPlanError::Job(e) => e.kind(),
            TiledPlanError::Protocol(e) => e.kind(),
            TiledPlanError::Grid { .. } | TiledPlanError::Workers => ErrorKind::InvalidInput,
            TiledPlanError::TooLarge { .. } | TiledPlanError::Pool { .. } => {
                ErrorKind::ResourceLimit
            }
        }
    }

    /// The parameter at fault, where one is (the front ends spell it).
    pub fn param(&self) -> Option<Param> {
        match self {
            TiledPlanError::Grid { param, .. } => Some(*param),
            TiledPlanError::Workers | TiledPlanError::Pool { .. } => Some(Param::Workers),
            TiledPlanError::TooLarge { .. } => Some(Param::Tile),
            _ => None,
        }
    }
}

crate::error::classified!(TiledPlanError);

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
    fn start_f64(&self) -> Option<Vec<Vec<f64>>> {
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

    fn set_start(&mut self, start: Option<Vec<Vec<f64>>>) {
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
}

/// A new tiled plan, validated, nothing allocated yet.
#[derive(Debug, Clone)]
pub struct TiledPlanStart {
    start: PlanStart,
    geometry: TileGeometry,
    workers: usize,
    clipped_halo: bool,
}

impl TiledPlanStart {
    /// Validates a tiled plan on `plane`: the plan's options as [`PlanStart::new`], the grid
    /// ([`TileGeometry::new`]), the workers. Allocates nothing.
    pub fn new(
        plane: ImagePlane,
        options: &PlanOptions,
        tiles: &TiledPlanOptions,
    ) -> Result<TiledPlanStart, TiledPlanError> {
        let start = PlanStart::new(plane, options)?;
        let halo = tiles.halo.unwrap_or(DEFAULT_HALO.min(tiles.tile));
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
            clipped_halo: tiles.halo.is_none() && tiles.tile < DEFAULT_HALO,
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

    /// The decisions made for the caller (the halo clipped to the tile).
    pub fn notes(&self) -> Vec<String> {
        let mut notes = Vec::new();
        if self.clipped_halo {
            notes.push(format!(
                "halo {}: the default halo {DEFAULT_HALO} clipped to the tile size (a halo is \
                 at most one tile)",
                self.geometry.halo
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
            let window = g.window(index);
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
        };
        Ok((state, base))
    }
}

/// A distinct 64-bit word per tile index, mixed into the tile's seed.
fn mix_index(index: usize) -> u64 {
    crate::image::adaptive::mix64(
        0x7469_6c65_u64 ^ (index as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15),
    )
}

/// The window as an image plane of its own (window-local coordinates).
fn window_plane(window: &PixelRect) -> ImagePlane {
    ImagePlane::new(window.width(), window.height()).expect("a window of a valid grid has pixels")
}

/// Whether the global position `(x, y)` is owned by tile `index`: in its interior, half-open
/// except at the image border.
fn owns(g: &TileGeometry, index: usize, x: f64, y: f64) -> bool {
    let r = g.interior(index);
    let (w, h) = (g.plane.width(), g.plane.height());
    let in_axis = |v: f64, lo: usize, hi: usize, size: usize| {
        v >= lo as f64 && (v < hi as f64 || (hi == size && v <= hi as f64))
    };
    in_axis(x, r.x0, r.x1, w) && in_axis(y, r.y0, r.y1, h)
}

/// The positions of `local` (window-local, tile `index`) moved to the image's coordinates
/// and appended to `out`: all of them (`owned_only` false), or those the tile owns; the
/// count outside its interior is returned (dropped with `owned_only`).
fn keep_owned(
    g: &TileGeometry,
    index: usize,
    window: &PixelRect,
    local: &SamplePositions,
    out: &mut SamplePositions,
    owned_only: bool,
) -> usize {
    let mut outside = 0;
    for (&x, &y) in local.xs.iter().zip(&local.ys) {
        let (gx, gy) = (x + window.x0 as f64, y + window.y0 as f64);
        let owned = owns(g, index, gx, gy);
        outside += usize::from(!owned);
        if owned || !owned_only {
            out.xs.push(gx);
            out.ys.push(gy);
        }
    }
    outside
}

/// `(held, per_tile)` bytes of a tiled plan on `g`: the budget's samples (positions and
/// values, twice: the caller's and a tile's window copy at most `workers` at once is counted
/// in the tile) and two output images; one tile's fit on its window with [`CONCENTRATION`]
/// times its share of the budget ([`tile_bytes`]). The largest window is counted.
fn sizes(g: &TileGeometry, params: &AdaptiveParams, channels: usize, budget: f64) -> (f64, f64) {
    let held = budget * (16.0 + 8.0 * channels as f64)
        + 2.0 * 8.0 * g.plane.pixels() as f64 * channels as f64;
    let window = (0..g.count().min(4))
        .map(|t| g.window(t))
        .max_by_key(|w| w.pixels());
    let window = window.expect("a grid has tiles");
    let share =
        (budget * CONCENTRATION * window.pixels() as f64 / g.plane.pixels() as f64).min(budget);
    (held, tile_bytes(&window, params, channels, share))
}

/// Bytes of one tile's fit on `window` with `samples` samples: the untiled plan's estimate of
/// a plan on that plane ([`ImageRequest::tree`] by PCG at the depth limit, with the noise
/// test's probe channels), plus the window's copy of its samples.
pub fn tile_bytes(
    window: &PixelRect,
    params: &AdaptiveParams,
    channels: usize,
    samples: f64,
) -> f64 {
    let probes = if params.noise.false_alarm > 0.0 {
        params.noise.probes
    } else {
        0
    };
    let fit = ImageRequest::tree(
        (window.width(), window.height()),
        channels + probes,
        samples,
        params.tree.p,
        params.quad.below_pixel,
        params.tree.rho,
        false,
        2,
    );
    fit.estimate().total() + samples * (16.0 + 8.0 * channels as f64)
}

/// The final image's stitch: tile `index`'s window pixels `tile` into `image` (its interior).
fn stitch(image: &mut PixelImage, g: &TileGeometry, index: usize, tile: &PixelImage) {
    let r = g.interior(index);
    let win = g.window(index);
    let width = g.plane.width();
    let ww = win.width();
    for (c, px) in tile.channels.iter().enumerate() {
        for y in r.y0..r.y1 {
            let src = (y - win.y0) * ww + (r.x0 - win.x0);
            image.channels[c][y * width + r.x0..y * width + r.x1]
                .copy_from_slice(&px[src..src + r.width()]);
        }
    }
}

/// The tile's output pixels from its fit (module docs), for [`round`].
fn tile_output(
    plan: &ImagePlan,
    fit: &crate::image::adaptive::TreeFit,
    local: &crate::image::ImageSamples,
    sigma: f64,
    estimate: crate::image::adaptive::PixelEstimate,
) -> Result<PixelImage, ProtocolError> {
    let (_, image, _) = output_pixels(
        plan.tree(),
        fit,
        local.xs(),
        local.ys(),
        local.values(),
        estimate,
        sigma,
        plan.params().output.residual_z,
    )
    .map_err(ProtocolError::from)?;
    Ok(image)
}
