//! A tiled plan's round and its final image (module docs of [`super`]), and the state as
//! JSON.

use std::path::Path;
use std::sync::{Mutex, PoisonError};
use std::time::Instant;

use rayon::prelude::*;

use super::error::TiledPlanError;
use super::memory::release_freed_memory;
use super::state::{TilePlanState, TiledPlanState, TILED_STATE_FORMAT, TILED_STATE_VERSION};
use super::stops::{RoundTally, TiledStep};
use super::times::TiledTimes;
use super::window::{keep_owned, plan_window, stitch, tile_bytes, tile_output, window_plane};
use crate::adaptive::StopReason;
use crate::image::adaptive::{
    mix64, AdaptiveError, AdaptiveParams, Decision, FitState, ImagePlan, PixelEstimate,
    SamplePositions,
};
use crate::image::plan::{IssuedRound, ProtocolError};
use crate::image::tiles::{PixelRect, TileGeometry};
use crate::image::{ImageSamples, PixelImage};
use crate::resources::memory_limit;

/// The order-free fingerprint `sum_i h(x_i, y_i) mod 2^64` of positions, added to `start`:
/// the untiled plan's rule (`image::plan`), so a renderer's round is recognised the same way.
pub(super) fn fingerprint(start: u64, xs: &[f64], ys: &[f64]) -> u64 {
    xs.iter().zip(ys).fold(start, |acc, (x, y)| {
        acc.wrapping_add(mix64(x.to_bits() ^ mix64(y.to_bits()).rotate_left(17)))
    })
}

/// The final image of a tiled plan.
#[derive(Clone, Debug)]
pub struct TiledFinal {
    /// The output pixels (the plan's estimate), every tile's interior.
    pub image: PixelImage,
    /// The last round of the samples.
    pub round: usize,
    /// Whether the plan has stopped at that round.
    pub complete: bool,
    /// Where the final image's time went.
    pub times: TiledTimes,
}

/// A tile's step: what the round keeps of it.
pub(super) struct TileOutcome {
    pub(super) state: TilePlanState,
    pub(super) next: SamplePositions,
    pub(super) halo_drawn: usize,
    pub(super) cut: usize,
    pub(super) times: TiledTimes,
    /// The fit's diagonal and its bytes, for `KeptDiagonals::keep` (`None`: not kept).
    pub(super) fit_state: Option<(FitState, u64)>,
}

impl TiledPlanState {
    /// The state as JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("a tiled plan state serialises")
    }

    /// Parses a state written by [`TiledPlanState::to_json`] (`file` names it in errors),
    /// checking its format, version, grid and records.
    pub fn from_json(text: &str, file: &Path) -> Result<Self, TiledPlanError> {
        let bad = |problem: String| ProtocolError::State {
            file: file.to_path_buf(),
            problem,
        };
        let state: Self = serde_json::from_str(text).map_err(|e| bad(e.to_string()))?;
        if state.format != TILED_STATE_FORMAT || state.version != TILED_STATE_VERSION {
            return Err(bad(format!(
                "format `{}` version {}, this build reads `{TILED_STATE_FORMAT}` version \
                 {TILED_STATE_VERSION}",
                state.format, state.version
            ))
            .into());
        }
        let g = TileGeometry::new(state.plane, state.tile, state.halo)
            .map_err(|e| bad(format!("its tile grid: {e}")))?;
        if state.tiles.len() != g.count()
            || state.tiles.iter().enumerate().any(|(i, t)| t.index != i)
            || state.issued.is_empty()
            || state.issued.iter().enumerate().any(|(i, r)| r.round != i)
            || state
                .issued
                .iter()
                .any(|r| u64::from_str_radix(&r.fingerprint, 16).is_err())
            || state.workers == 0
        {
            return Err(bad(format!(
                "{} tile records for a grid of {} tiles, {} rounds recorded",
                state.tiles.len(),
                g.count(),
                state.issued.len()
            ))
            .into());
        }
        Ok(state)
    }

    /// The tile grid.
    pub fn geometry(&self) -> TileGeometry {
        TileGeometry {
            plane: self.plane,
            tile: self.tile,
            halo: self.halo,
        }
    }

    /// The last round handed out.
    pub fn round(&self) -> usize {
        self.issued.len() - 1
    }

    /// Positions handed out so far.
    pub fn positions(&self) -> usize {
        self.issued.last().map_or(0, |r| r.total)
    }

    /// The round whose positions are exactly `samples` (the untiled plan's refusals).
    pub(super) fn matching_round(&self, samples: &ImageSamples) -> Result<usize, ProtocolError> {
        if samples.plane() != self.plane {
            return Err(ProtocolError::Plane {
                state: self.plane,
                given: samples.plane(),
            });
        }
        if let Some(c) = self.channels.filter(|&c| c != samples.channels()) {
            return Err(ProtocolError::Channels {
                state: c,
                given: samples.channels(),
            });
        }
        let f = fingerprint(0, samples.xs(), samples.ys());
        let last = self.round();
        match self.issued.iter().position(|r| {
            r.total == samples.len() && u64::from_str_radix(&r.fingerprint, 16) == Ok(f)
        }) {
            Some(k) if k < last => Err(ProtocolError::AlreadyPlanned {
                given: samples.len(),
                matched: k,
                round: last,
                expected: self.positions(),
            }),
            Some(k) => Ok(k),
            None => Err(ProtocolError::Mismatch {
                given: samples.len(),
                expected: self.positions(),
                round: last,
            }),
        }
    }

    /// The pool of the plan's workers.
    pub(super) fn pool(&self) -> Result<rayon::ThreadPool, TiledPlanError> {
        rayon::ThreadPoolBuilder::new()
            .num_threads(self.workers)
            .build()
            .map_err(|e| TiledPlanError::Pool {
                workers: self.workers,
                reason: e.to_string(),
            })
    }

    /// Memory held beside the tile fits: the samples and two images.
    pub(super) fn held_bytes(&self, samples: &ImageSamples) -> f64 {
        let c = samples.channels() as f64;
        samples.len() as f64 * (16.0 + 8.0 * c) + 2.0 * 8.0 * self.plane.pixels() as f64 * c
    }

    /// Refuses tile `index`'s fit of `n` samples when `workers` of its size beside the held
    /// samples exceed the memory limit (before its window is copied).
    pub(super) fn check_tile(
        &self,
        index: usize,
        n: usize,
        held: f64,
        channels: usize,
    ) -> Result<(), TiledPlanError> {
        let window = plan_window(&self.geometry(), index);
        let per_tile = tile_bytes(&window, &self.params, channels, n as f64);
        let needed = held + self.workers as f64 * per_tile;
        let limit = memory_limit();
        if needed <= limit as f64 {
            return Ok(());
        }
        let g = self.geometry();
        let fits = (1..g.tile).rev().find(|&t| {
            let side = (t + 2 * g.halo.min(t)).next_power_of_two();
            let w = PixelRect {
                x0: 0,
                x1: side.min(window.width()),
                y0: 0,
                y1: side.min(window.height()),
            };
            let scale = (w.pixels() as f64 / window.pixels() as f64).min(1.0);
            held + self.workers as f64 * tile_bytes(&w, &self.params, channels, n as f64 * scale)
                <= limit as f64
        });
        Err(TiledPlanError::TooLarge {
            what: format!("tile {index}'s fit of {n} samples (window {window})"),
            per_tile,
            workers: self.workers,
            held,
            needed,
            limit,
            fix: match fits {
                Some(t) => format!(
                    "a new plan with a {} of at most {t} (or fewer {})",
                    crate::error::Fix::Set(crate::error::Param::Tile),
                    crate::error::Fix::Set(crate::error::Param::Workers)
                ),
                None => format!(
                    "a smaller {} or fewer {}",
                    crate::error::Fix::Set(crate::error::Param::Budget),
                    crate::error::Fix::Set(crate::error::Param::Workers)
                ),
            },
        })
    }

    /// The window-local samples of tile `index` (the indices of [`Self::buckets`]).
    pub(super) fn local(
        &self,
        samples: &ImageSamples,
        index: usize,
        picks: &[u32],
    ) -> ImageSamples {
        let w = plan_window(&self.geometry(), index);
        let (x0, y0) = (w.x0 as f64, w.y0 as f64);
        let xs = picks
            .iter()
            .map(|&i| samples.xs()[i as usize] - x0)
            .collect();
        let ys = picks
            .iter()
            .map(|&i| samples.ys()[i as usize] - y0)
            .collect();
        let values = samples
            .values()
            .iter()
            .map(|v| picks.iter().map(|&i| v[i as usize]).collect())
            .collect();
        ImageSamples::new(window_plane(&w), xs, ys, values)
            .expect("a window's samples, moved by an integer, lie in the window")
    }

    /// The tile's refiner as of its history with `budget` and least growth `growth`; a
    /// budget below the tile's base raised to it (the tile then draws at most its share:
    /// the round cuts the rest).
    pub(super) fn tile_plan(
        &self,
        tile: &TilePlanState,
        budget: usize,
        growth: f64,
    ) -> Result<ImagePlan, ProtocolError> {
        let window = plan_window(&self.geometry(), tile.index);
        let mut params: AdaptiveParams = tile.params;
        params.stop.budget = budget.max(1);
        params.growth.min_growth = growth.clamp(0.0, 10.0);
        match ImagePlan::resume(window_plane(&window), &params, tile.progress.clone()) {
            Err(AdaptiveError::BudgetTooSmall { base, .. }) => {
                params.stop.budget = base;
                Ok(ImagePlan::resume(
                    window_plane(&window),
                    &params,
                    tile.progress.clone(),
                )?)
            }
            other => Ok(other?),
        }
    }

    /// One tile's step on its window's samples with `share` new samples (module docs).
    pub(super) fn step_tile(
        &self,
        tile: &TilePlanState,
        local: &ImageSamples,
        share: usize,
        kept: Option<FitState>,
    ) -> Result<TileOutcome, ProtocolError> {
        let n = local.len();
        let mut times = TiledTimes::default();
        let t = Instant::now();
        let mut plan = self.tile_plan(tile, n + share, share as f64 / n.max(1) as f64)?;
        *plan.start_mut() = tile.start_f64();
        *plan.fit_state_mut() = kept.unwrap_or_default();
        times.rebuild_s = t.elapsed().as_secs_f64();
        let values: Vec<&[f64]> = local.values().iter().map(|v| v.as_slice()).collect();
        let round = plan.step(local.xs(), local.ys(), &values)?;
        times.fit_s = round.fit_s;
        for report in std::iter::once(&round.log.fit).chain(&round.log.final_fit) {
            times.kernel_s += report.kernel_s;
            times.solve_s += report.solve_s;
        }
        times.refine_s = round.refine_s;
        times.position_s = round.position_s;
        let window = plan_window(&self.geometry(), tile.index);
        let mut state = tile.clone();
        state.steps += 1;
        state.indicator_sq =
            Some((round.log.estimate_rms.powi(2) * window.pixels() as f64).to_bits());
        state.set_start(plan.start_mut().take());
        let mut next = SamplePositions::default();
        let (mut halo_drawn, mut cut) = (0, 0);
        match round.decision {
            Decision::Sample(local_next) => {
                halo_drawn = keep_owned(
                    &self.geometry(),
                    tile.index,
                    &window,
                    &local_next,
                    &mut next,
                    false,
                );
                if next.len() > share {
                    cut = next.len() - share;
                    next.xs.truncate(share);
                    next.ys.truncate(share);
                }
                state.progress = plan.progress().clone();
            }
            Decision::Stop(StopReason::Budget) => {}
            Decision::Stop(stop) => state.stop = Some(stop),
        }
        // the diagonal alone, only when kept: the rows (80 bytes a sample at p = 2) of every
        // tile's outcome until the commit were 0.66 GB at 1920x1080
        let fit_state = self.kept.bound.map(|_| {
            let kept = std::mem::take(plan.fit_state_mut());
            let diagonal = FitState {
                diagonal: kept.diagonal,
                ..FitState::default()
            };
            // sums and mask over the window's basis at the depth limit
            (diagonal, 9 * plan.tree().basis().len() as u64)
        });
        drop(plan);
        Ok(TileOutcome {
            state,
            next,
            halo_drawn,
            cut,
            times,
            fit_state,
        })
    }

    /// Every active tile's share of the round's growth `growth` (module docs): by the last
    /// `eta_t^2`, by interior pixels before any indicator, largest remainders.
    pub(super) fn shares(&self, growth: usize) -> Vec<usize> {
        let g = self.geometry();
        let weight = |t: &TilePlanState| match (t.stop, t.indicator_sq) {
            (Some(_), _) => 0.0,
            (None, Some(eta)) => f64::from_bits(eta),
            (None, None) => g.interior(t.index).pixels() as f64,
        };
        let mut weights: Vec<f64> = self.tiles.iter().map(weight).collect();
        let mut total: f64 = weights.iter().sum();
        if total <= 0.0 || !total.is_finite() {
            // no detail left anywhere the indicator sees: by interior pixels
            weights = self
                .tiles
                .iter()
                .map(|t| {
                    if t.stop.is_some() {
                        0.0
                    } else {
                        g.interior(t.index).pixels() as f64
                    }
                })
                .collect();
            total = weights.iter().sum();
        }
        if total <= 0.0 {
            return vec![0; self.tiles.len()];
        }
        let exact: Vec<f64> = weights.iter().map(|w| growth as f64 * w / total).collect();
        let mut shares: Vec<usize> = exact.iter().map(|e| e.floor() as usize).collect();
        let mut order: Vec<usize> = (0..shares.len()).collect();
        order.sort_by(|&a, &b| {
            (exact[b] - exact[b].floor())
                .total_cmp(&(exact[a] - exact[a].floor()))
                .then(a.cmp(&b))
        });
        let mut rest = growth.saturating_sub(shares.iter().sum());
        for &t in order.iter().filter(|&&t| weights[t] > 0.0) {
            if rest == 0 {
                break;
            }
            shares[t] += 1;
            rest -= 1;
        }
        shares
    }

    /// One round on every sample so far (the positions handed out, in any order): every
    /// tile with a share steps, in parallel; then the next positions or the stop. The state
    /// changes only when the whole round succeeded.
    pub fn advance(&mut self, samples: &ImageSamples) -> Result<TiledStep, TiledPlanError> {
        let wall = Instant::now();
        let k = self.matching_round(samples)?;
        if k < self.round() {
            unreachable!("matching_round refuses earlier rounds");
        }
        if let Some(step) = self.stop_before_stepping(samples) {
            return Ok(step);
        }
        let growth = self.growth();
        let shares = self.shares(growth);
        let mut times = TiledTimes::default();
        let t = Instant::now();
        let buckets = self.buckets(samples)?;
        times.buckets_s = t.elapsed().as_secs_f64();
        let held = self.held_bytes(samples) + 4.0 * samples.len() as f64;
        for (t, picks) in buckets.iter().enumerate() {
            if shares[t] > 0 {
                self.check_tile(t, picks.len(), held, samples.channels())?;
            }
        }
        let largest_window = buckets.iter().map(Vec::len).max().unwrap_or(0);
        let pool = self.pool()?;
        // a failed round loses the kept diagonals (solver state only: rebuilt next round)
        let kept = self.kept.take_all(self.tiles.len());
        let outcomes: Vec<Result<Result<TileOutcome, Option<FitState>>, ProtocolError>> = pool
            .install(|| {
                self.tiles
                    .par_iter()
                    // each window's indices dropped once its samples are copied
                    .zip(buckets)
                    .zip(&shares)
                    .zip(kept)
                    .map(|(((tile, picks), &share), kept)| {
                        if share == 0 {
                            return Ok(Err(kept));
                        }
                        let t = Instant::now();
                        let local = self.local(samples, tile.index, &picks);
                        drop(picks);
                        let local_s = t.elapsed().as_secs_f64();
                        let mut outcome = self.step_tile(tile, &local, share, kept)?;
                        drop(local);
                        release_freed_memory();
                        outcome.times.local_s = local_s;
                        Ok(Ok(outcome))
                    })
                    .collect()
            });
        // commit: everything computed, nothing changed yet; a failed tile fails the round
        // before any tile's state is replaced (no copy of the tiles' states is needed)
        let outcomes: Vec<Result<TileOutcome, Option<FitState>>> =
            outcomes.into_iter().collect::<Result<_, _>>()?;
        let t = Instant::now();
        // sized exactly: grown by doubling it could hold twice the round's positions
        let drawn = outcomes.iter().flatten().map(|o| o.next.len()).sum();
        let mut next = SamplePositions {
            xs: Vec::with_capacity(drawn),
            ys: Vec::with_capacity(drawn),
        };
        let (mut stepped, mut halo, mut cut) = (0, 0, 0);
        let mut fit_states = Vec::with_capacity(self.tiles.len());
        for (tile, outcome) in self.tiles.iter_mut().zip(outcomes) {
            match outcome {
                Ok(o) => {
                    stepped += 1;
                    halo += o.halo_drawn;
                    cut += o.cut;
                    times.add_tile(&o.times);
                    next.xs.extend(o.next.xs);
                    next.ys.extend(o.next.ys);
                    *tile = o.state;
                    fit_states.push(o.fit_state);
                }
                // a tile without a share keeps what it kept (its samples did not change)
                Err(kept) => fit_states.push(kept.map(|s| {
                    let bytes = s.diagonal.as_ref().map_or(0, |d| 9 * d.sums().len() as u64);
                    (s, bytes)
                })),
            }
        }
        let (diagonals_kept, diagonals_over) = self.kept.keep(fit_states);
        self.channels = Some(samples.channels());
        let tally = RoundTally {
            growth,
            stepped,
            halo_drawn: halo,
            cut,
            largest_window,
            diagonals_kept,
            diagonals_over,
        };
        let mut step = self.finish_round(next, tally, times);
        // the replaced tile states and the tiles' positions, freed after the last tile's
        // release: half a gigabyte at 3840x2160 held through the caller's render
        release_freed_memory();
        step.times.commit_s = t.elapsed().as_secs_f64();
        step.times.wall_s = wall.elapsed().as_secs_f64();
        Ok(step)
    }

    /// Records the positions `next` handed out as the next round (count and order-free
    /// fingerprint chained from the last round's, the untiled plan's rule); returns its number.
    pub(super) fn issue_round(&mut self, next: &SamplePositions) -> usize {
        let prev = self
            .issued
            .last()
            .expect("a plan has its base round")
            .clone();
        let start = u64::from_str_radix(&prev.fingerprint, 16).expect("checked when read");
        self.issued.push(IssuedRound {
            round: prev.round + 1,
            positions: next.len(),
            total: prev.total + next.len(),
            fingerprint: format!("{:016x}", fingerprint(start, &next.xs, &next.ys)),
        });
        prev.round + 1
    }

    /// Checks that `samples` are the positions of every round handed out (the final image's
    /// samples): only the last round's tiles' trees are kept, so earlier rounds are refused.
    pub(super) fn check_final_samples(&self, samples: &ImageSamples) -> Result<(), TiledPlanError> {
        let k = match self.matching_round(samples) {
            Ok(k) => k,
            Err(ProtocolError::AlreadyPlanned { matched, .. }) => matched,
            Err(e) => return Err(e.into()),
        };
        if k != self.round() {
            return Err(ProtocolError::AlreadyPlanned {
                given: samples.len(),
                matched: k,
                round: self.round(),
                expected: self.positions(),
            }
            .into());
        }
        Ok(())
    }

    /// The final image of `samples` (the positions of rounds `0..=k` for some `k`): every
    /// tile's fit of its window's samples on its tree, warm-started from its carried start,
    /// its output pixels by `estimate` (`None`: the plan's), the interiors stitched.
    pub fn final_image(
        &self,
        samples: &ImageSamples,
        estimate: Option<PixelEstimate>,
    ) -> Result<TiledFinal, TiledPlanError> {
        self.check_final_samples(samples)?;
        let wall = Instant::now();
        let estimate = estimate.unwrap_or(self.params.output.pixels);
        let mut times = TiledTimes::default();
        let counts = self.window_counts(samples)?;
        times.buckets_s = wall.elapsed().as_secs_f64();
        let held = self.held_bytes(samples) + 4.0 * samples.len() as f64;
        for (t, &n) in counts.iter().enumerate() {
            self.check_tile(t, n, held, samples.channels())?;
        }
        drop(counts);
        let pool = self.pool()?;
        let g = self.geometry();
        let (nx, _) = g.grid();
        // each tile's interior stitched as soon as its fit is done (interiors are disjoint, so
        // the order does not matter): every tile's window image held to the end was a second
        // image and more (0.2 GB at 3840x2160)
        let image = Mutex::new(PixelImage::zeros(self.plane, samples.channels()));
        // one band of tile rows at a time: every tile's window indices built first were
        // 0.27 GB at 3840x2160 (`picks`); a band's are the same lists
        let mut tiles: Vec<Result<TiledTimes, ProtocolError>> = Vec::new();
        for rows in self.image_row_bands() {
            let t = Instant::now();
            let buckets = self.band_buckets(samples, rows.clone());
            times.buckets_s += t.elapsed().as_secs_f64();
            let band = &self.tiles[rows.start * nx..rows.end * nx];
            tiles
                .extend(pool.install(|| self.final_band(samples, estimate, band, buckets, &image)));
            if tiles.iter().any(Result::is_err) {
                break;
            }
        }
        for tile_times in tiles {
            let tile_times = tile_times?;
            times.add_tile(&tile_times);
            // stitching, summed over the tiles (thread seconds, as the tiles' phases)
            times.commit_s += tile_times.commit_s;
        }
        let image = image.into_inner().unwrap_or_else(PoisonError::into_inner);
        release_freed_memory();
        times.wall_s = wall.elapsed().as_secs_f64();
        Ok(TiledFinal {
            image,
            round: self.round(),
            complete: self.stop.is_some(),
            times,
        })
    }

    /// The final fit of `tile` on its window's samples `local`, continued from `fit_state`
    /// (the tile's kept diagonal, or an empty state as the band tasks': the same image bit for
    /// bit, `tests/tiled_plan_band.rs`),
    /// and the window's output pixels by `estimate`; the phases' seconds into `times`
    /// (`rebuild_s`, `fit_s`, `kernel_s`, `solve_s`, `output_s`). One implementation for the
    /// one-process final image ([`Self::final_image`]) and the Dask band tasks' (`FinalBandTask`).
    pub(super) fn tile_final_pixels(
        &self,
        tile: &TilePlanState,
        local: &ImageSamples,
        estimate: PixelEstimate,
        fit_state: &mut FitState,
        times: &mut TiledTimes,
    ) -> Result<PixelImage, ProtocolError> {
        let t = Instant::now();
        let plan = self.tile_plan(tile, local.len(), tile.params.growth.min_growth)?;
        let values: Vec<&[f64]> = local.values().iter().map(|v| v.as_slice()).collect();
        let start = tile.start_f64();
        times.rebuild_s = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let (fit, significance) = plan.fit_updating(
            local.xs(),
            local.ys(),
            &values,
            plan.params().fit.solver,
            start.as_deref(),
            fit_state,
        )?;
        times.fit_s = t.elapsed().as_secs_f64();
        times.kernel_s = fit.report.kernel_s;
        times.solve_s = fit.report.solve_s;
        let t = Instant::now();
        let sigma = significance.map_or(0.0, |s| s.level.sigma);
        let pixels = tile_output(&plan, &fit, local, sigma, estimate)?;
        drop((plan, fit));
        times.output_s = t.elapsed().as_secs_f64();
        Ok(pixels)
    }

    /// The final fits of one band's tiles (`band`, with their window indices `buckets`), in
    /// parallel on the current pool, each tile's interior stitched into `image` as soon as
    /// its fit is done; the tiles' times (tile order).
    fn final_band(
        &self,
        samples: &ImageSamples,
        estimate: PixelEstimate,
        band: &[TilePlanState],
        buckets: Vec<Vec<u32>>,
        image: &Mutex<PixelImage>,
    ) -> Vec<Result<TiledTimes, ProtocolError>> {
        let g = self.geometry();
        band.par_iter()
            // each window's indices dropped once its samples are copied
            .zip(buckets)
            .map(|(tile, picks)| {
                // the kept diagonal continued (a copy: the image may be asked again)
                let mut fit_state = self
                    .kept
                    .states
                    .get(tile.index)
                    .cloned()
                    .flatten()
                    .unwrap_or_default();
                let mut times = TiledTimes::default();
                let t = Instant::now();
                let local = self.local(samples, tile.index, &picks);
                drop(picks);
                times.local_s = t.elapsed().as_secs_f64();
                let pixels =
                    self.tile_final_pixels(tile, &local, estimate, &mut fit_state, &mut times)?;
                drop(local);
                let t = Instant::now();
                // poisoned only by a panic in another tile's `stitch`, which rayon passes on
                let mut image = image.lock().unwrap_or_else(PoisonError::into_inner);
                stitch(&mut image, &g, tile.index, &pixels);
                drop(image);
                drop(pixels);
                release_freed_memory();
                times.commit_s = t.elapsed().as_secs_f64();
                Ok(times)
            })
            .collect()
    }
}

impl TiledPlanState {
    /// Checks a later call's `options` (and the image `plane`, if given) against the plan:
    /// each option given must be the plan's own (the untiled plan's rule), naming the first
    /// that differs; first those the tiles refuse (`PlanOptions::check_tiled`).
    pub fn check_options(
        &self,
        plane: Option<crate::image::ImagePlane>,
        options: &super::super::PlanOptions,
    ) -> Result<(), TiledPlanError> {
        options.check_tiled()?;
        if let Some(given) = plane.filter(|&p| p != self.plane) {
            return Err(ProtocolError::Plane {
                state: self.plane,
                given,
            }
            .into());
        }
        let params = options.params(self.plane, &self.params)?;
        let ours = serde_json::to_value(self.params).expect("parameters serialise");
        let theirs = serde_json::to_value(params).expect("parameters serialise");
        if let (Some(a), Some(b)) = (ours.as_object(), theirs.as_object()) {
            if let Some((key, value)) = a.iter().find(|(k, v)| b.get(*k) != Some(*v)) {
                return Err(ProtocolError::OtherParameters {
                    parameter: key.clone(),
                    state: value.to_string(),
                    given: b.get(key).cloned().unwrap_or_default().to_string(),
                }
                .into());
            }
        }
        Ok(())
    }
}
