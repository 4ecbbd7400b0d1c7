//! A tiled round's end, shared by the local round and the banded one (module docs of
//! `tiled_plan`): the stops met before any tile steps (the plan stopped already, the budget,
//! the round limit, every tile stopped), the stop or the next round after the tiles stepped,
//! and the round's report ([`TiledStep`], built here alone).

use serde::Serialize;

use super::state::{all_stopped, TiledPlanState};
use super::times::TiledTimes;
use crate::adaptive::StopReason;
use crate::image::adaptive::SamplePositions;
use crate::image::ImageSamples;

/// What one round of a tiled plan did.
#[derive(Clone, Debug, Serialize)]
pub struct TiledStep {
    /// Positions to render next (empty when the plan stopped).
    #[serde(skip)]
    pub next: SamplePositions,
    /// Number of positions to render next.
    pub next_positions: usize,
    /// The round those positions belong to (`None` when the plan stopped).
    pub next_round: Option<usize>,
    /// Why the plan stopped (`None`: render the next positions and call again).
    pub stop: Option<StopReason>,
    /// Positions handed out in all, including the next ones.
    pub total_positions: usize,
    /// The budget.
    pub budget: usize,
    /// The round's growth `G` split over the tiles.
    pub growth: usize,
    /// Tiles stepped this round.
    pub tiles_stepped: usize,
    /// Tiles stopped (the tolerance or the depth limit) after this round.
    pub tiles_stopped: usize,
    /// Positions the tiles drew in their halos (kept: the neighbour that owns the pixels
    /// sees them in its window and tops its slots up only where they lack samples).
    pub halo_drawn: usize,
    /// Positions a tile drew beyond its share, cut (its refiner tops up the children of
    /// marked slots whole; the share is the budget's).
    pub cut: usize,
    /// The largest samples in one tile's window this round.
    pub largest_window: usize,
    /// Tiles whose PCG diagonal is kept for the next round
    /// ([`TiledPlanState::keep_diagonals`]; 0 when off).
    pub diagonals_kept: usize,
    /// Tiles whose diagonal did not fit the bound and is rebuilt next round.
    pub diagonals_over: usize,
    /// Where the round's time went ([`TiledTimes`]).
    pub times: TiledTimes,
}

/// What a round counted besides its positions: the fields of [`TiledStep`] the round fills
/// (all zero for a round that stops before any tile steps).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct RoundTally {
    /// The round's growth `G` split over the tiles.
    pub(super) growth: usize,
    /// Tiles stepped.
    pub(super) stepped: usize,
    /// Positions the tiles drew in their halos.
    pub(super) halo_drawn: usize,
    /// Positions drawn beyond a tile's share, cut.
    pub(super) cut: usize,
    /// The largest samples in one tile's window.
    pub(super) largest_window: usize,
    /// Tiles whose PCG diagonal is kept for the next round.
    pub(super) diagonals_kept: usize,
    /// Tiles whose diagonal did not fit the bound.
    pub(super) diagonals_over: usize,
}

impl TiledPlanState {
    /// The stop a round meets before any tile steps: the plan stopped already, or now at the
    /// budget, the round limit, or with every tile stopped (recorded, with the samples'
    /// channels). `None`: the round steps its tiles. Shared by [`Self::advance`] and the
    /// banded round (`band.rs`).
    pub(super) fn stop_before_stepping(&mut self, samples: &ImageSamples) -> Option<TiledStep> {
        if self.stop.is_none() {
            let n = self.positions();
            let stop_now = if n >= self.params.stop.budget {
                Some(StopReason::Budget)
            } else if self.round() >= self.params.stop.max_rounds {
                Some(StopReason::MaxRounds)
            } else if self.tiles.iter().all(|t| t.stop.is_some()) {
                Some(all_stopped(&self.tiles))
            } else {
                None
            };
            self.stop = Some(stop_now?);
            self.channels = Some(samples.channels());
        }
        Some(self.report(
            SamplePositions::default(),
            RoundTally::default(),
            TiledTimes::default(),
        ))
    }

    /// The round's growth `G = min(B - N, ceil(g N))` (`N` positions handed out, `B` the
    /// budget, `g` the least growth; module docs), once [`Self::stop_before_stepping`] found
    /// `N < B`.
    pub(super) fn growth(&self) -> usize {
        let (n, budget) = (self.positions(), self.params.stop.budget);
        (budget - n).min((self.params.growth.min_growth * n as f64).ceil() as usize)
    }

    /// The end of a round whose tiles stepped (the state's tiles already replaced): the
    /// tiles' positions `next` (in tile order) issued as the next round, or, none drawn, the
    /// plan stopped (every tile stopped: their stop; else the budget). Its report.
    pub(super) fn finish_round(
        &mut self,
        next: SamplePositions,
        tally: RoundTally,
        times: TiledTimes,
    ) -> TiledStep {
        if next.is_empty() {
            self.stop = Some(if self.tiles.iter().all(|t| t.stop.is_some()) {
                all_stopped(&self.tiles)
            } else {
                StopReason::Budget
            });
        } else {
            self.issue_round(&next);
        }
        self.report(next, tally, times)
    }

    /// The round's report as of the state now: the positions `next` to render (empty when the
    /// plan stopped), the round they belong to, the totals and the round's `tally`.
    fn report(&self, next: SamplePositions, tally: RoundTally, times: TiledTimes) -> TiledStep {
        TiledStep {
            next_positions: next.len(),
            next,
            next_round: self.stop.is_none().then(|| self.round()),
            stop: self.stop,
            total_positions: self.positions(),
            budget: self.params.stop.budget,
            growth: tally.growth,
            tiles_stepped: tally.stepped,
            tiles_stopped: self.tiles.iter().filter(|t| t.stop.is_some()).count(),
            halo_drawn: tally.halo_drawn,
            cut: tally.cut,
            largest_window: tally.largest_window,
            diagonals_kept: tally.diagonals_kept,
            diagonals_over: tally.diagonals_over,
            times,
        }
    }
}
