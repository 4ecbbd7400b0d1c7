//! A tiled round's stops: the plan stopped already, at the budget, at the round limit, or with
//! every tile stopped (module docs of `tiled_plan`); shared by the local round and the banded one.

use super::round::TiledStep;
use super::state::{all_stopped, TiledPlanState};
use super::times::TiledTimes;
use crate::adaptive::StopReason;
use crate::image::adaptive::SamplePositions;
use crate::image::ImageSamples;

impl TiledPlanState {
    /// The stop a round meets before any tile steps: the plan stopped already, or now at the
    /// budget, the round limit, or with every tile stopped (recorded, with the samples'
    /// channels). `None`: the round steps its tiles. Shared by [`Self::advance`] and the
    /// banded round (`band.rs`).
    pub(super) fn stop_before_stepping(&mut self, samples: &ImageSamples) -> Option<TiledStep> {
        if let Some(stop) = self.stop {
            return Some(self.stopped(stop, 0, 0, 0, 0, 0, TiledTimes::default()));
        }
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
        let stop = stop_now?;
        self.channels = Some(samples.channels());
        self.stop = Some(stop);
        Some(self.stopped(stop, 0, 0, 0, 0, 0, TiledTimes::default()))
    }

    #[allow(clippy::too_many_arguments)]
    pub(super) fn stopped(
        &self,
        stop: StopReason,
        growth: usize,
        stepped: usize,
        halo: usize,
        cut: usize,
        largest_window: usize,
        times: TiledTimes,
    ) -> TiledStep {
        TiledStep {
            next: SamplePositions::default(),
            next_positions: 0,
            next_round: None,
            stop: Some(stop),
            total_positions: self.positions(),
            budget: self.params.stop.budget,
            growth,
            tiles_stepped: stepped,
            tiles_stopped: self.tiles.iter().filter(|t| t.stop.is_some()).count(),
            halo_drawn: halo,
            cut,
            largest_window,
            diagonals_kept: 0,
            diagonals_over: 0,
            times,
        }
    }
}
