//! Where a tiled plan's round and final image spend their time (`TiledStep::times`,
//! `TiledFinal::times`; the command line's `--json`).

use serde::Serialize;

/// Where a tiled round's (or final image's) time went, in seconds. The per-tile phases are
/// summed over the tiles (CPU seconds of the workers, `workers` of them at once); `buckets_s`,
/// a round's `commit_s` and `wall_s` are the caller's wall clock.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct TiledTimes {
    /// Sorting the samples into the tiles' windows (one pass, wall).
    pub buckets_s: f64,
    /// Copying each window's samples to window-local coordinates (sum over tiles).
    pub local_s: f64,
    /// Building each tile's refiner from its history, or taking the one kept (sum).
    pub rebuild_s: f64,
    /// The tiles' fits, the noise test's included (sum; the final image's fit too).
    pub fit_s: f64,
    /// Of `fit_s`: the fits' single-scale rows and exact diagonal (PCG's `kernel_s`; sum).
    pub kernel_s: f64,
    /// Of `fit_s`: the fits' solves (PCG's iterations; sum).
    pub solve_s: f64,
    /// Indicator, stop test, tally and marking (sum).
    pub refine_s: f64,
    /// Deepening and drawing the next positions (sum).
    pub position_s: f64,
    /// The final image's output pixels (sum; 0 in a round).
    pub output_s: f64,
    /// Committing the round (wall), or stitching the final image's tiles (sum).
    pub commit_s: f64,
    /// The whole call (wall).
    pub wall_s: f64,
}

impl TiledTimes {
    /// The per-tile phases of `other` added to these.
    pub(super) fn add_tile(&mut self, other: &TiledTimes) {
        self.local_s += other.local_s;
        self.rebuild_s += other.rebuild_s;
        self.fit_s += other.fit_s;
        self.kernel_s += other.kernel_s;
        self.solve_s += other.solve_s;
        self.refine_s += other.refine_s;
        self.position_s += other.position_s;
        self.output_s += other.output_s;
    }
}
