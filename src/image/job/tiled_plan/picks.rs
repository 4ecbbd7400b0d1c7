//! Each tile's window samples ("picks"): the indices of the samples in each tile's window
//! ([`plan_window`]), for every tile at once or for one band of tile rows at a time.
//!
//! A sample is checked against the windows of the tiles within [`reach`] of its own tile
//! only. Indices are `u32` (4 bytes a sample and window, sized exactly by a counting pass: at
//! 3840x2160 and 8 spp, 66M samples, `usize` lists grown by doubling held up to 1 GB; every
//! tile's `u32` lists together are still 0.27 GB there). A band's lists are the same lists,
//! in the same (ascending) order, as the whole plane's: a band costs one more pass over the
//! samples' positions and holds only its own tiles' indices.

use std::ops::Range;

use super::error::TiledPlanError;
use super::state::TiledPlanState;
use super::window::{plan_window, reach};
use crate::image::tiles::PixelRect;
use crate::image::ImageSamples;
use crate::resources::memory_limit;

impl TiledPlanState {
    /// Every tile's picks (tile order), in one pass; more samples than `u32` holds are
    /// refused.
    pub(super) fn buckets(&self, samples: &ImageSamples) -> Result<Vec<Vec<u32>>, TiledPlanError> {
        self.check_indexable(samples)?;
        let (_, ny) = self.geometry().grid();
        Ok(self.band_buckets(samples, 0..ny))
    }

    /// How many samples each tile's window holds (tile order): the lengths of
    /// [`Self::buckets`] without the lists.
    pub(super) fn window_counts(
        &self,
        samples: &ImageSamples,
    ) -> Result<Vec<usize>, TiledPlanError> {
        self.check_indexable(samples)?;
        let g = self.geometry();
        let (_, ny) = g.grid();
        let mut counts = vec![0usize; g.count()];
        self.visit_windows(samples, 0..ny, &mut |t, _| counts[t] += 1);
        Ok(counts)
    }

    /// The picks of the tiles in tile rows `rows` (tile order, the first the tile at
    /// `(0, rows.start)`): a counting pass, then a filling pass over every sample.
    pub(super) fn band_buckets(&self, samples: &ImageSamples, rows: Range<usize>) -> Vec<Vec<u32>> {
        let (nx, _) = self.geometry().grid();
        let first = rows.start * nx;
        let mut counts = vec![0usize; rows.len() * nx];
        self.visit_windows(samples, rows.clone(), &mut |t, _| counts[t - first] += 1);
        let mut buckets: Vec<Vec<u32>> = counts.iter().map(|&c| Vec::with_capacity(c)).collect();
        // `check_indexable` (or the caller's `buckets`) has refused more than `u32::MAX`
        self.visit_windows(samples, rows, &mut |t, i| buckets[t - first].push(i as u32));
        buckets
    }

    /// Bands of tile rows for the final image: each band at least four tiles a worker (so
    /// the pool stays busy within a band), the last band the rows left.
    pub(super) fn image_row_bands(&self) -> Vec<Range<usize>> {
        let (nx, ny) = self.geometry().grid();
        let rows = (4 * self.workers).div_ceil(nx.max(1)).max(1);
        (0..ny)
            .step_by(rows)
            .map(|r| r..(r + rows).min(ny))
            .collect()
    }

    /// Calls `visit(t, i)` for every sample `i` (in order) and every tile `t` in tile rows
    /// `rows` whose window holds it.
    fn visit_windows(
        &self,
        samples: &ImageSamples,
        rows: Range<usize>,
        visit: &mut dyn FnMut(usize, usize),
    ) {
        let g = self.geometry();
        let (nx, ny) = g.grid();
        let (kx, ky) = reach(&g);
        let windows: Vec<PixelRect> = (0..g.count()).map(|t| plan_window(&g, t)).collect();
        let span = |v: f64, k: usize, n: usize| {
            let own = ((v / g.tile as f64) as usize).min(n - 1);
            (own.saturating_sub(k + 1), (own + k + 1).min(n - 1))
        };
        for (i, (&x, &y)) in samples.xs().iter().zip(samples.ys()).enumerate() {
            let (r0, r1) = span(y, ky, ny);
            let (r0, r1) = (r0.max(rows.start), r1.min(rows.end.saturating_sub(1)));
            if rows.is_empty() || r0 > r1 {
                continue;
            }
            let (c0, c1) = span(x, kx, nx);
            for ty in r0..=r1 {
                for tx in c0..=c1 {
                    let t = ty * nx + tx;
                    if windows[t].contains(x, y) {
                        visit(t, i);
                    }
                }
            }
        }
    }

    /// Refuses more samples than the tiles' `u32` indices hold.
    fn check_indexable(&self, samples: &ImageSamples) -> Result<(), TiledPlanError> {
        if u32::try_from(samples.len()).is_ok() {
            return Ok(());
        }
        let held = self.held_bytes(samples);
        Err(TiledPlanError::TooLarge {
            what: format!(
                "{} samples (the tiles index at most {} samples)",
                samples.len(),
                u32::MAX
            ),
            per_tile: 0.0,
            workers: self.workers,
            held,
            needed: held,
            limit: memory_limit(),
            fix: format!(
                "a smaller {}",
                crate::error::Fix::Set(crate::error::Param::Budget)
            ),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::{TiledPlanOptions, TiledPlanStart};
    use crate::image::job::{PlanBudget, PlanOptions};
    use crate::image::{ImagePlane, ImageSamples};

    /// Positions spread over the plane by a fixed linear congruential sequence (reproducible;
    /// some on the plane's far edges, which windows own half-open except at the border).
    fn samples(plane: ImagePlane, n: usize) -> ImageSamples {
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let (w, h) = (plane.width() as f64, plane.height() as f64);
        let mut xs: Vec<f64> = (0..n).map(|_| next() * w).collect();
        let mut ys: Vec<f64> = (0..n).map(|_| next() * h).collect();
        xs.extend([w, 0.0, w]);
        ys.extend([h, h, 0.0]);
        let values = vec![vec![0.5; xs.len()]];
        ImageSamples::new(plane, xs, ys, values).expect("positions in the plane")
    }

    /// The bands' window indices, concatenated in band order, are every tile's indices built
    /// at once (the same lists in the same order), the counts their lengths, and the bands
    /// cover every tile row once; with and without halos (windows reaching neighbours).
    #[test]
    fn bands_rebuild_every_tiles_indices() {
        for (w, h, tile, halo, workers) in [
            (200, 136, 48, 12, 2),
            (256, 256, 64, 0, 1),
            (300, 70, 32, 20, 3),
        ] {
            let plane = ImagePlane::new(w, h).expect("a plane");
            let options = PlanOptions {
                budget: Some(PlanBudget::PerPixel(4)),
                ..PlanOptions::default()
            };
            let tiles = TiledPlanOptions {
                tile,
                halo: Some(halo),
                workers: Some(workers),
            };
            let (state, _) = TiledPlanStart::new(plane, &options, &tiles)
                .expect("a tiled plan")
                .run(1)
                .expect("its base");
            let s = samples(plane, 5_000);
            let all = state.buckets(&s).expect("indexable");
            let counts = state.window_counts(&s).expect("indexable");
            assert_eq!(counts, all.iter().map(Vec::len).collect::<Vec<_>>());
            let bands = state.image_row_bands();
            let (_, ny) = state.geometry().grid();
            let rows: Vec<usize> = bands.iter().flat_map(|r| r.clone()).collect();
            assert_eq!(rows, (0..ny).collect::<Vec<_>>(), "{w}x{h} tile {tile}");
            let banded: Vec<Vec<u32>> = bands
                .into_iter()
                .flat_map(|rows| state.band_buckets(&s, rows))
                .collect();
            assert_eq!(banded, all, "{w}x{h} tile {tile} halo {halo}");
            // every sample lies in its own tile's window at least
            let covered: usize = all.iter().map(Vec::len).sum();
            assert!(covered >= s.len(), "{covered} < {}", s.len());
        }
    }
}
