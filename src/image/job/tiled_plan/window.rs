//! A tile's window: its plane, the positions it owns, its share of memory, and its pixels
//! stitched into the image.

use crate::image::adaptive::correction::output_pixels;
use crate::image::adaptive::{AdaptiveParams, ImagePlan, SamplePositions};
use crate::image::plan::ProtocolError;
use crate::image::tiles::{PixelRect, TileGeometry};
use crate::image::{ImagePlane, PixelImage};
use crate::resources::ImageRequest;

/// How far a tile's samples may exceed its average share before the round's own check
/// refuses it: the start's memory check counts `CONCENTRATION` times the window's share of
/// the budget (the global marking moves samples between tiles).
pub const CONCENTRATION: f64 = 4.0;

/// A distinct 64-bit word per tile index, mixed into the tile's seed.
pub(super) fn mix_index(index: usize) -> u64 {
    crate::image::adaptive::mix64(
        0x7469_6c65_u64 ^ (index as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15),
    )
}

/// Tile `index`'s window in the tiled plan: on each axis the interior `[a, b)` grown to the
/// side `W = min(n, 2^ceil(log2(b - a + 2 H_a)))` (`n` the image's side), centred on the
/// interior and shifted to lie inside the image. `W` is a power of two unless the image's
/// side is smaller: the tile's tree on `[0, W)` then has cells of `W 2^-L` pixels at level
/// `L`, so its slots at pixel level **are** the window's pixels (on a side such as the uniform
/// tiles' `T + 2 H_a = 88` the finest slots straddle pixels and the base is coarser than a
/// pixel: docs/measurements/scale-out.md). The halo is inside the window: at least `H_a`
/// on each side away from the image border, more where the power of two or the border leaves
/// room. With `H_a = 0` and a power-of-two tile the window is the interior, aligned with the
/// untiled plan's cells at every level (tile origins are multiples of `T`).
pub fn plan_window(g: &TileGeometry, index: usize) -> PixelRect {
    let r = g.interior(index);
    let (x0, x1) = axis_window(r.x0, r.x1, g.halo, g.plane.width());
    let (y0, y1) = axis_window(r.y0, r.y1, g.halo, g.plane.height());
    PixelRect { x0, x1, y0, y1 }
}

/// One axis of [`plan_window`]: `[lo, hi)` in an image side of `size`.
fn axis_window(lo: usize, hi: usize, halo: usize, size: usize) -> (usize, usize) {
    let side = hi - lo;
    let want = (side + 2 * halo).next_power_of_two().min(size);
    let start = lo.saturating_sub((want - side) / 2).min(size - want);
    (start, start + want)
}

/// How many tiles' windows are not a power of two on some axis (the image's side is smaller).
pub(super) fn windows_not_dyadic(g: &TileGeometry) -> usize {
    (0..g.count())
        .filter(|&t| {
            let w = plan_window(g, t);
            !w.width().is_power_of_two() || !w.height().is_power_of_two()
        })
        .count()
}

/// `(kx, ky)`: how many tiles beyond its own a window reaches on each axis, at most
/// (`ceil(e / T)`, `e` the largest extent of a window past its interior).
pub(super) fn reach(g: &TileGeometry) -> (usize, usize) {
    let (mut ex, mut ey) = (0, 0);
    for t in 0..g.count() {
        let (r, w) = (g.interior(t), plan_window(g, t));
        ex = ex.max(r.x0 - w.x0).max(w.x1 - r.x1);
        ey = ey.max(r.y0 - w.y0).max(w.y1 - r.y1);
    }
    (ex.div_ceil(g.tile), ey.div_ceil(g.tile))
}

/// The window as an image plane of its own (window-local coordinates).
pub(super) fn window_plane(window: &PixelRect) -> ImagePlane {
    ImagePlane::new(window.width(), window.height()).expect("a window of a valid grid has pixels")
}

/// Whether the global position `(x, y)` is owned by tile `index`: in its interior, half-open
/// except at the image border.
pub(super) fn owns(g: &TileGeometry, index: usize, x: f64, y: f64) -> bool {
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
pub(super) fn keep_owned(
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
pub(super) fn sizes(
    g: &TileGeometry,
    params: &AdaptiveParams,
    channels: usize,
    budget: f64,
) -> (f64, f64) {
    let held = budget * (16.0 + 8.0 * channels as f64)
        + 2.0 * 8.0 * g.plane.pixels() as f64 * channels as f64;
    let window = (0..g.count().min(4))
        .map(|t| plan_window(g, t))
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
pub(super) fn stitch(image: &mut PixelImage, g: &TileGeometry, index: usize, tile: &PixelImage) {
    let r = g.interior(index);
    let win = plan_window(g, index);
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
pub(super) fn tile_output(
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
