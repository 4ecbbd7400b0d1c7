//! Positions that top pixels up to a count of samples, for the coverage rule's fill and the
//! uniform floor in the base (module `coverage`): each pixel's own sequence continued where
//! the pixel is a cell of the tree.

use rand_pcg::Pcg64;

use super::positions::{slot_sobol, PositionPattern};
use super::{AdaptiveParams, SamplePositions};
use crate::adaptive::{Cell, QuadTree};
use crate::image::ImagePlane;

/// `need` positions in each pixel of `short` (`(pixel, need)`, the pixel holding `have`
/// samples of the `m` it should), each moved to the pixel's centre if rounding carries it
/// over the pixel's edge (so that [`crate::image::ImagePlane::pixel_of`] puts it in the pixel).
///
/// Under [`PositionPattern::Sobol`] they are the points `have .. have + need` of the pixel's
/// own Owen-scrambled Sobol (0, 2)-sequence (module `positions`): where the pixel is a cell of
/// the tree (sides that are powers of two) that cell's sequence, so a pixel whose samples are
/// its slot's first `have` points (a slot the tree never deepened) ends with the first `m`
/// points of one (0, 2)-sequence: a `(0, k, 2)`-net of the pixel when `m = 2^k`, one point in
/// every elementary interval of area `2^-k` (the per-pixel stratification of a film's
/// multi-jittered samples). Under [`PositionPattern::Stratified`], and in a pixel the tree
/// deepened (its children's points are not a prefix of the pixel's sequence): jittered
/// strata of the pixel from `rng`'s stream.
pub(super) fn top_up(
    plane: ImagePlane,
    tree: &QuadTree,
    params: &AdaptiveParams,
    short: &[(usize, usize)],
    m: usize,
    rng: &mut Pcg64,
) -> SamplePositions {
    let w = plane.width();
    // the step whose cells are the pixels, if any
    let pixel_step =
        (0..=tree.steps()).find(|&s| tree.cell_dims(s) == (plane.width(), plane.height()));
    let mut out = SamplePositions::default();
    for &(p, need) in short {
        let (px, py) = (p % w, p / w);
        let (x0, y0) = (px as f64, py as f64);
        let rect = [x0, x0 + 1.0, y0, y0 + 1.0];
        let from = out.len();
        // a pixel the tree deepened holds its children's points, not a prefix of its own
        // sequence: jittered strata there (continuing the sequence could repeat a point)
        let deepened = pixel_step.is_some_and(|step| {
            tree.is_active(Cell {
                step,
                kx: px,
                ky: py,
            })
        });
        match params.sampling.pattern {
            PositionPattern::Stratified => out.stratified(rect, need, rng),
            PositionPattern::Sobol if deepened => out.stratified(rect, need, rng),
            PositionPattern::Sobol => {
                // the pixel's cell, or (pixels that are no cell) a key of the pixel's own
                let cell = match pixel_step {
                    Some(step) => Cell {
                        step,
                        kx: px,
                        ky: py,
                    },
                    None => Cell {
                        step: u32::MAX,
                        kx: px,
                        ky: py,
                    },
                };
                let have = m.saturating_sub(need);
                out.append(slot_sobol(params.sampling.seed, cell, rect, have, need));
            }
        }
        for i in from..out.len() {
            if plane.pixel_of(out.xs[i], out.ys[i]) != (px, py) {
                (out.xs[i], out.ys[i]) = (x0 + 0.5, y0 + 0.5);
            }
        }
    }
    out
}
