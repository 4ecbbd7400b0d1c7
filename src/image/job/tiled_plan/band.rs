//! A tiled plan's round split into bands of tile rows (issue 40, item 4): the seam a
//! distributed scheduler (Python's `rkwave.dask.TiledPlan`) runs one task per band through.
//!
//! [`TiledPlanState::advance`] is, per round: (1) the round's checks and shares on the
//! whole state (the samples are the positions handed out; the growth
//! `G = min(B - N, ceil(g N))` split over the tiles by their last indicators `eta_t^2`),
//! (2) one independent step per tile with a share, on the samples of its window,
//! (3) the commit of every tile's new state and the next positions, all or nothing. Here the
//! three are separate: [`TiledPlanState::begin_round`] does (1) without changing the state
//! and gives one [`BandTask`] per band of tile rows `[r0, r1)` with the band's tiles' states,
//! their shares and the band's samples `S_b` (every sample in some window of the band, in the
//! order of all the samples); [`BandTask::run`] does (2) for the band alone, anywhere (it
//! needs nothing but the task and `S_b`); [`TiledPlanState::commit_round`] does (3) from the
//! bands' [`BandOutcome`]s.
//!
//! **Same result as the local round.** A tile's window samples taken from `S_b` are those it
//! takes from all the samples, in the same order (`S_b` keeps the samples' order and holds
//! every sample of the band's windows; which window holds a sample depends on its position
//! alone), and its step is the local round's own step function on them: the band's new
//! positions and tile states are the local round's, bit for bit, and the commit concatenates
//! the tiles' positions in tile order as the local round does. A band's task is a pure
//! function of its inputs: rerun (a lost worker), it gives the same outcome.
//!
//! **All or nothing.** [`TiledPlanState::commit_round`] checks that the state is still the
//! one the round began on (its last round and fingerprint) and that the outcomes are those of
//! exactly the tiles given a share, each once, before it changes anything; a missing,
//! repeated or foreign outcome is refused with the state unchanged.
//!
//! The final image is banded the same way: [`TiledPlanState::final_bands`] gives one
//! [`FinalBandTask`] per band, whose [`FinalBandTask::run`] fits the band's tiles and returns
//! their interiors' rows ([`BandStrip`]); [`TiledPlanState::stitch_bands`] assembles them.

use std::ops::Range;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::error::TiledPlanError;
use super::memory::release_freed_memory;
use super::round::TileOutcome;
use super::state::{TilePlanState, TiledPlanState, TILED_STATE_FORMAT, TILED_STATE_VERSION};
use super::stops::RoundTally;
use super::times::TiledTimes;
use super::window::plan_window;
use crate::image::adaptive::{AdaptiveParams, FitState, PixelEstimate, SamplePositions};
use crate::image::plan::ProtocolError;
use crate::image::tiles::TileGeometry;
use crate::image::{ImagePlane, ImageSamples, PixelImage};

/// Why a band's task, the bands' outcomes or their strips were refused.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BandError {
    /// The plan's own refusal (the samples, a tile's step, the memory).
    #[error(transparent)]
    Plan(#[from] TiledPlanError),
    /// A task, an outcome or a strip that does not belong to the grid, round or plan it was
    /// given to (`what` names it; `problem` says what and the way out).
    #[error("{what}: {problem}")]
    Foreign {
        /// What was refused.
        what: &'static str,
        /// What is wrong and the fix.
        problem: String,
    },
}

impl From<ProtocolError> for BandError {
    fn from(e: ProtocolError) -> Self {
        BandError::Plan(e.into())
    }
}

impl BandError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            BandError::Plan(e) => e.kind(),
            BandError::Foreign { .. } => crate::error::ErrorKind::InvalidInput,
        }
    }
}

crate::error::classified!(BandError);

/// The bands of `rows` tile rows each (the last may be shorter) of a grid of `grid_rows`
/// tile rows; `rows` 0 is taken as 1.
pub fn tile_row_bands(grid_rows: usize, rows: usize) -> Vec<Range<usize>> {
    let rows = rows.max(1);
    (0..grid_rows)
        .step_by(rows)
        .map(|r0| r0..(r0 + rows).min(grid_rows))
        .collect()
}

/// What a band's task needs besides its samples: the plan's constants, the band's tile
/// rows and its tiles' states and shares (module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BandTask {
    /// The image plane.
    pub plane: ImagePlane,
    /// Tile side in pixels.
    pub tile: usize,
    /// Halo in pixels.
    pub halo: usize,
    /// The plan's parameters.
    pub params: AdaptiveParams,
    /// The round being planned (the state's last round when it began).
    pub round: usize,
    /// The band's tile rows `[r0, r1)`.
    pub rows: Range<usize>,
    /// The states of the band's tiles given a share, in tile order.
    pub tiles: Vec<TilePlanState>,
    /// Their shares of the round's growth.
    pub shares: Vec<usize>,
    /// Tiles stepped at once inside the task (at least 1).
    pub threads: usize,
}

/// One tile's step in a band: what the commit keeps of it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BandTileOutcome {
    /// The tile's new state.
    pub state: TilePlanState,
    /// The x of the positions it draws next (image coordinates; as bits in a serialised
    /// outcome, so it reads back the same numbers).
    #[serde(with = "f64_bits")]
    pub next_xs: Vec<f64>,
    /// Their y.
    #[serde(with = "f64_bits")]
    pub next_ys: Vec<f64>,
    /// Of those, drawn in its halo.
    pub halo_drawn: usize,
    /// Drawn beyond its share and cut.
    pub cut: usize,
}

/// What a band's task returns.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BandOutcome {
    /// The round it planned.
    pub round: usize,
    /// The band's tile rows.
    pub rows: Range<usize>,
    /// Per tile given a share, in tile order.
    pub tiles: Vec<BandTileOutcome>,
}

/// A round begun on the client (module docs): the stop it reached at once, or the bands'
/// tasks and what the commit checks.
#[derive(Clone, Debug)]
pub enum BandedRound {
    /// The plan stopped (committed already, as the local round does): nothing to run.
    Stopped(super::TiledStep),
    /// The bands to run, then [`TiledPlanState::commit_round`].
    Steps(RoundPlan),
}

/// The bands' tasks of a round and what its commit checks.
#[derive(Clone, Debug)]
pub struct RoundPlan {
    /// The round the state was at (its last round handed out).
    pub round: usize,
    /// That round's fingerprint.
    fingerprint: String,
    /// The round's growth `G`.
    pub growth: usize,
    /// The tiles given a share.
    pub stepped: Vec<usize>,
    /// The largest samples in one tile's window.
    pub largest_window: usize,
    /// The samples' channels.
    pub channels: usize,
    /// One task per band with its samples `S_b` (module docs).
    pub tasks: Vec<(BandTask, ImageSamples)>,
}

/// The rows of a band's tiles' interiors in the final image.
#[derive(Clone, Debug, PartialEq)]
pub struct BandStrip {
    /// The band's tile rows.
    pub rows: Range<usize>,
    /// The image rows `[y0, y1)` it covers.
    pub y: Range<usize>,
    /// Per channel, `(y1 - y0) W` pixels in row-major order.
    pub channels: Vec<Vec<f64>>,
}

/// The final image's task of a band: the plan's constants, the band's tiles and the pixel
/// estimate.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FinalBandTask {
    /// The band's constants and tiles (shares unused).
    pub band: BandTask,
    /// The output pixels.
    pub estimate: PixelEstimate,
}

/// The band's samples: those in some window of `tiles`, in their order (`buckets` the
/// window indices of all the samples).
fn band_samples(samples: &ImageSamples, buckets: &[Vec<u32>], tiles: Range<usize>) -> ImageSamples {
    let mut picks: Vec<usize> = buckets[tiles]
        .iter()
        .flatten()
        .map(|&i| i as usize)
        .collect();
    picks.sort_unstable();
    picks.dedup();
    let xs = picks.iter().map(|&i| samples.xs()[i]).collect();
    let ys = picks.iter().map(|&i| samples.ys()[i]).collect();
    let values = samples
        .values()
        .iter()
        .map(|v| picks.iter().map(|&i| v[i]).collect())
        .collect();
    ImageSamples::new(samples.plane(), xs, ys, values).expect("a subset of valid samples")
}

impl BandTask {
    /// A state holding only the task's constants: the local round's functions run on it
    /// (they read the grid, the parameters and the tile given, never the other tiles).
    fn scratch(&self) -> TiledPlanState {
        TiledPlanState {
            format: TILED_STATE_FORMAT.into(),
            version: TILED_STATE_VERSION,
            plane: self.plane,
            tile: self.tile,
            halo: self.halo,
            workers: self.threads.max(1),
            params: self.params,
            channels: None,
            tiles: Vec::new(),
            issued: Vec::new(),
            stop: None,
            kept: Default::default(),
        }
    }

    /// Checks the task against its grid: every tile in the band's rows, one share each.
    fn check(&self) -> Result<TileGeometry, BandError> {
        let g = TileGeometry::new(self.plane, self.tile, self.halo).map_err(|source| {
            TiledPlanError::Grid {
                param: crate::error::Param::Tile,
                source,
            }
        })?;
        let nx = g.grid().0;
        let in_band =
            |t: &TilePlanState| self.rows.contains(&(t.index / nx)) && t.index < g.count();
        if self.tiles.len() != self.shares.len() || !self.tiles.iter().all(in_band) {
            return Err(BandError::Foreign {
                what: "a band task",
                problem: format!(
                    "{} tiles and {} shares for tile rows {:?} of a {}x{} grid: give the \
                     task begin_round made",
                    self.tiles.len(),
                    self.shares.len(),
                    self.rows,
                    nx,
                    g.grid().1
                ),
            });
        }
        Ok(g)
    }

    /// The band's step (module docs): each tile with a share steps on its window's samples
    /// taken from `samples` (the band's `S_b`), `threads` tiles at once.
    pub fn run(&self, samples: &ImageSamples) -> Result<BandOutcome, BandError> {
        self.check()?;
        let scratch = self.scratch();
        let buckets = scratch.buckets(samples)?;
        let pool = scratch.pool()?;
        let outcomes: Vec<Result<TileOutcome, ProtocolError>> = pool.install(|| {
            self.tiles
                .par_iter()
                .zip(&self.shares)
                .map(|(tile, &share)| {
                    let local = scratch.local(samples, tile.index, &buckets[tile.index]);
                    scratch.step_tile(tile, &local, share, None)
                })
                .collect()
        });
        let mut tiles = Vec::with_capacity(outcomes.len());
        for o in outcomes {
            let o = o?;
            tiles.push(BandTileOutcome {
                state: o.state,
                next_xs: o.next.xs,
                next_ys: o.next.ys,
                halo_drawn: o.halo_drawn,
                cut: o.cut,
            });
        }
        Ok(BandOutcome {
            round: self.round,
            rows: self.rows.clone(),
            tiles,
        })
    }
}

impl FinalBandTask {
    /// The band's tiles' fits of their windows' samples (taken from the band's `samples`)
    /// and their interiors' rows, as [`TiledPlanState::final_image`] makes each tile's.
    pub fn run(&self, samples: &ImageSamples) -> Result<BandStrip, BandError> {
        let g = self.band.check()?;
        let scratch = self.band.scratch();
        let buckets = scratch.buckets(samples)?;
        let pool = scratch.pool()?;
        let images: Vec<Result<PixelImage, ProtocolError>> = pool.install(|| {
            self.band
                .tiles
                .par_iter()
                .map(|tile| {
                    let local = scratch.local(samples, tile.index, &buckets[tile.index]);
                    scratch.tile_final_pixels(
                        tile,
                        &local,
                        self.estimate,
                        &mut FitState::default(),
                        &mut TiledTimes::default(),
                    )
                })
                .collect()
        });
        let nx = g.grid().0;
        let first = self.band.rows.start * nx;
        let last = self.band.rows.end * nx - 1;
        let y = g.interior(first).y0..g.interior(last).y1;
        let width = g.plane.width();
        let mut channels = vec![vec![0.0; y.len() * width]; samples.channels()];
        for (tile, image) in self.band.tiles.iter().zip(images) {
            let image = image?;
            let r = g.interior(tile.index);
            let win = plan_window(&g, tile.index);
            for (c, px) in image.channels.iter().enumerate() {
                for row in r.y0..r.y1 {
                    let src = (row - win.y0) * win.width() + (r.x0 - win.x0);
                    let dst = (row - y.start) * width + r.x0;
                    channels[c][dst..dst + r.width()].copy_from_slice(&px[src..src + r.width()]);
                }
            }
        }
        Ok(BandStrip {
            rows: self.band.rows.clone(),
            y,
            channels,
        })
    }
}

impl TiledPlanState {
    /// The band task of tile rows `rows` with the given tiles and shares (no samples).
    fn band_task(
        &self,
        rows: Range<usize>,
        tiles: Vec<usize>,
        shares: &[usize],
        threads: usize,
    ) -> BandTask {
        BandTask {
            plane: self.plane,
            tile: self.tile,
            halo: self.halo,
            params: self.params,
            round: self.round(),
            rows,
            shares: tiles.iter().map(|&t| shares[t]).collect(),
            tiles: tiles.iter().map(|&t| self.tiles[t].clone()).collect(),
            threads: threads.max(1),
        }
    }

    /// Part (1) of a round (module docs): the local round's checks (the samples are the
    /// positions handed out; the memory of every tile's fit), its stops and its shares, and
    /// one task per band of `rows_per_band` tile rows holding a tile with a share, each
    /// stepping `threads` tiles at once. The state changes only when the plan stops here,
    /// as [`TiledPlanState::advance`] commits that stop.
    pub fn begin_round(
        &mut self,
        samples: &ImageSamples,
        rows_per_band: usize,
        threads: usize,
    ) -> Result<BandedRound, TiledPlanError> {
        let k = self.matching_round(samples)?;
        debug_assert_eq!(k, self.round(), "matching_round refuses earlier rounds");
        if let Some(step) = self.stop_before_stepping(samples) {
            return Ok(BandedRound::Stopped(step));
        }
        let growth = self.growth();
        let shares = self.shares(growth);
        let buckets = self.buckets(samples)?;
        let held = self.held_bytes(samples) + 8.0 * samples.len() as f64;
        for (t, picks) in buckets.iter().enumerate() {
            if shares[t] > 0 {
                self.check_tile(t, picks.len(), held, samples.channels())?;
            }
        }
        let nx = self.geometry().grid().0;
        let mut tasks = Vec::new();
        for rows in tile_row_bands(self.geometry().grid().1, rows_per_band) {
            let tiles = rows.start * nx..rows.end * nx;
            let stepped: Vec<usize> = tiles.clone().filter(|&t| shares[t] > 0).collect();
            if stepped.is_empty() {
                continue;
            }
            let task = self.band_task(rows, stepped, &shares, threads);
            tasks.push((task, band_samples(samples, &buckets, tiles)));
        }
        let last = self.issued.last().expect("a plan has its base round");
        Ok(BandedRound::Steps(RoundPlan {
            round: self.round(),
            fingerprint: last.fingerprint.clone(),
            growth,
            stepped: (0..shares.len()).filter(|&t| shares[t] > 0).collect(),
            largest_window: buckets.iter().map(Vec::len).max().unwrap_or(0),
            channels: samples.channels(),
            tasks,
        }))
    }

    /// Part (3) of a round (module docs): the bands' outcomes committed as one step, after
    /// checking that the state is the one `plan` began on and that the outcomes are those of
    /// exactly its stepped tiles, each once (else refused, the state unchanged).
    pub fn commit_round(
        &mut self,
        plan: &RoundPlan,
        outcomes: Vec<BandOutcome>,
    ) -> Result<super::TiledStep, BandError> {
        let refuse = |problem: String| BandError::Foreign {
            what: "the bands' outcomes",
            problem,
        };
        let last = self.issued.last().expect("a plan has its base round");
        if self.stop.is_some() || self.round() != plan.round || last.fingerprint != plan.fingerprint
        {
            return Err(refuse(format!(
                "the round began at round {}, the plan is now at round {}{}: begin the round \
                 again",
                plan.round,
                self.round(),
                if self.stop.is_some() {
                    " and stopped"
                } else {
                    ""
                }
            )));
        }
        let mut by_tile: Vec<Option<BandTileOutcome>> = vec![None; self.tiles.len()];
        for band in outcomes {
            if band.round != plan.round {
                return Err(refuse(format!(
                    "an outcome of round {} given to round {}: give this round's outcomes",
                    band.round, plan.round
                )));
            }
            for o in band.tiles {
                let t = o.state.index;
                if t >= by_tile.len() || !plan.stepped.contains(&t) || by_tile[t].is_some() {
                    return Err(refuse(format!(
                        "tile {t}'s outcome is not one the round asked for (or given twice): \
                         give each band's outcome once"
                    )));
                }
                by_tile[t] = Some(o);
            }
        }
        if let Some(&t) = plan.stepped.iter().find(|&&t| by_tile[t].is_none()) {
            return Err(refuse(format!(
                "tile {t}'s outcome is missing ({} tiles stepped): give every band's outcome",
                plan.stepped.len()
            )));
        }
        // the diagonals a local round kept belong to trees this round replaces: dropped (the
        // banded rounds keep none; the next local round rebuilds them)
        self.kept.take_all(self.tiles.len());
        // commit: everything checked, nothing changed yet (the local round's order: tiles in
        // index order)
        // sized exactly, as the local round's
        let drawn = by_tile.iter().flatten().map(|o| o.next_xs.len()).sum();
        let mut next = SamplePositions {
            xs: Vec::with_capacity(drawn),
            ys: Vec::with_capacity(drawn),
        };
        let (mut halo, mut cut) = (0, 0);
        let stepped = plan.stepped.len();
        for (t, o) in by_tile.into_iter().enumerate() {
            if let Some(o) = o {
                halo += o.halo_drawn;
                cut += o.cut;
                next.xs.extend(o.next_xs);
                next.ys.extend(o.next_ys);
                self.tiles[t] = o.state;
            }
        }
        self.channels = Some(plan.channels);
        let tally = RoundTally {
            growth: plan.growth,
            stepped,
            halo_drawn: halo,
            cut,
            largest_window: plan.largest_window,
            ..RoundTally::default()
        };
        let step = self.finish_round(next, tally, TiledTimes::default());
        // the replaced tile states and the bands' positions (module `memory`)
        release_freed_memory();
        Ok(step)
    }

    /// The final image's band tasks (module docs): the samples checked as
    /// [`TiledPlanState::final_image`] checks them (the positions of the last round), one
    /// task per band of `rows_per_band` tile rows with its samples.
    pub fn final_bands(
        &self,
        samples: &ImageSamples,
        estimate: Option<PixelEstimate>,
        rows_per_band: usize,
        threads: usize,
    ) -> Result<Vec<(FinalBandTask, ImageSamples)>, TiledPlanError> {
        self.check_final_samples(samples)?;
        let estimate = estimate.unwrap_or(self.params.output.pixels);
        let buckets = self.buckets(samples)?;
        let held = self.held_bytes(samples) + 8.0 * samples.len() as f64;
        for (t, picks) in buckets.iter().enumerate() {
            self.check_tile(t, picks.len(), held, samples.channels())?;
        }
        let nx = self.geometry().grid().0;
        let zero = vec![0; self.tiles.len()];
        Ok(tile_row_bands(self.geometry().grid().1, rows_per_band)
            .into_iter()
            .map(|rows| {
                let tiles = rows.start * nx..rows.end * nx;
                let band = self.band_task(rows, tiles.clone().collect(), &zero, threads);
                let s = band_samples(samples, &buckets, tiles);
                (FinalBandTask { band, estimate }, s)
            })
            .collect())
    }

    /// The final image from every band's strip (each band once), as
    /// [`TiledPlanState::final_image`] stitches it.
    pub fn stitch_bands(
        &self,
        strips: Vec<BandStrip>,
        channels: usize,
    ) -> Result<super::TiledFinal, BandError> {
        let g = self.geometry();
        let mut image = PixelImage::zeros(self.plane, channels);
        let mut covered = vec![false; g.grid().1];
        let width = g.plane.width();
        for s in strips {
            let bad = s.rows.end > covered.len()
                || covered[s.rows.clone()].iter().any(|&c| c)
                || s.channels.len() != channels
                || s.channels.iter().any(|c| c.len() != s.y.len() * width)
                || s.y.end > g.plane.height();
            if bad {
                return Err(BandError::Foreign {
                    what: "the bands' strips",
                    problem: format!(
                        "the strip of tile rows {:?} does not fit the image (or is given \
                         twice): give each band's strip once",
                        s.rows
                    ),
                });
            }
            covered[s.rows.clone()].iter_mut().for_each(|c| *c = true);
            for (c, px) in s.channels.iter().enumerate() {
                image.channels[c][s.y.start * width..s.y.end * width].copy_from_slice(px);
            }
        }
        if let Some(row) = covered.iter().position(|&c| !c) {
            return Err(BandError::Foreign {
                what: "the bands' strips",
                problem: format!("tile row {row} has no strip: give every band's strip"),
            });
        }
        Ok(super::TiledFinal {
            image,
            round: self.round(),
            complete: self.stop.is_some(),
            times: TiledTimes::default(),
        })
    }
}

/// `Vec<f64>` serialised as the bits of its numbers.
mod f64_bits {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(v: &[f64], s: S) -> Result<S::Ok, S::Error> {
        v.iter()
            .map(|x| x.to_bits())
            .collect::<Vec<u64>>()
            .serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
        Ok(Vec::<u64>::deserialize(d)?
            .into_iter()
            .map(f64::from_bits)
            .collect())
    }
}
