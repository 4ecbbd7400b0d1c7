//! Figures of an adaptive run: the 2D analogue of the supplement's figure 4 (the adaptive
//! reconstruction, the local depth of the wavelet tree, and the samples: base set and
//! refinement), side by side.
//!
//! * [`depth_image`]: the local depth `d(x, y)` at every pixel centre (the local space is
//!   `V_{cx+d} (x) V_{cy+d}`), coloured from the base step (dark) to the depth limit (yellow);
//! * [`samples_image`]: every sample as one pixel of a finer raster, base samples grey, the
//!   refinement's red (drawn last, so they stay visible in dense regions);
//! * [`save_adaptive_figure`]: the three panels in one PNG with a colour key of the levels,
//!   written through [`crate::io::output`] (never replacing a file without `overwrite`).

use std::path::Path;

use plotters::prelude::*;

use super::refiner::AdaptiveImage;
use crate::image::{ImagePlane, PixelImage};
use crate::io::image_file::srgb8;
use crate::plot::PlotError;

/// Colour stops from the base step to the depth limit (viridis, linear RGB).
const STOPS: [[f64; 3]; 5] = [
    [0.072, 0.004, 0.087],
    [0.036, 0.090, 0.302],
    [0.012, 0.288, 0.268],
    [0.270, 0.590, 0.050],
    [0.930, 0.850, 0.015],
];
/// Grey of base samples and red of refinement samples (linear RGB).
const BASE_GREY: [f64; 3] = [0.08, 0.08, 0.08];
const REFINE_RED: [f64; 3] = [0.9, 0.02, 0.02];

/// Largest panel side in figure pixels (smaller images are enlarged to at least `MIN_PANEL`).
const MAX_PANEL: usize = 768;
const MIN_PANEL: usize = 320;
const LABEL: usize = 28;
const GAP: usize = 6;

/// The colour of depth `t` in `[0, 1]` (0: the base step, 1: the depth limit).
fn colour(t: f64) -> [f64; 3] {
    let x = t.clamp(0.0, 1.0) * (STOPS.len() - 1) as f64;
    let i = (x.floor() as usize).min(STOPS.len() - 2);
    let f = x - i as f64;
    std::array::from_fn(|c| STOPS[i][c] * (1.0 - f) + STOPS[i + 1][c] * f)
}

/// Base step and span (steps from the base to the limit, at least 1) of a run.
fn depth_range(run: &AdaptiveImage) -> (u32, u32) {
    let base = run.report.base_levels.0 - run.report.coarse_levels.0;
    (base, run.tree.steps().saturating_sub(base).max(1))
}

fn plane_of(run: &AdaptiveImage) -> ImagePlane {
    let b = run.tree.basis();
    ImagePlane::new(b.width(), b.height()).expect("the basis has a valid size")
}

/// The local depth at every pixel centre as an RGB image: the base step dark, the depth limit
/// yellow (the colour key is in [`save_adaptive_figure`]).
pub fn depth_image(run: &AdaptiveImage) -> PixelImage {
    let plane = plane_of(run);
    let (base, span) = depth_range(run);
    let mut img = PixelImage::zeros(plane, 3);
    for (i, d) in run.tree.depth_map().into_iter().enumerate() {
        let rgb = colour((d.saturating_sub(base)) as f64 / span as f64);
        for (c, v) in rgb.into_iter().enumerate() {
            img.channels[c][i] = v;
        }
    }
    img
}

/// The sample positions on a raster `scale` times finer than the image, white background:
/// base samples grey, refinement samples red.
pub fn samples_image(run: &AdaptiveImage, scale: usize) -> PixelImage {
    let plane = plane_of(run);
    let scale = scale.max(1);
    let big = ImagePlane::new(plane.width() * scale, plane.height() * scale)
        .expect("a multiple of a valid plane");
    let mut img = PixelImage {
        plane: big,
        channels: vec![vec![1.0; big.pixels()]; 3],
    };
    for base in [true, false] {
        let rgb = if base { BASE_GREY } else { REFINE_RED };
        for ((&x, &y), &r) in run.xs.iter().zip(&run.ys).zip(&run.round_of) {
            if (r == 0) != base {
                continue;
            }
            let (px, py) = big.pixel_of(x * scale as f64, y * scale as f64);
            for (c, v) in rgb.into_iter().enumerate() {
                img.channels[c][py * big.width() + px] = v;
            }
        }
    }
    img
}

/// Panel size `(w, h)` in figure pixels for an image plane: the longer side between
/// [`MIN_PANEL`] and [`MAX_PANEL`], an integer multiple or fraction of the image when possible.
fn panel_size(plane: ImagePlane) -> (usize, usize) {
    let long = plane.width().max(plane.height());
    let side = long.clamp(MIN_PANEL, MAX_PANEL);
    let (w, h) = (
        (plane.width() * side).div_ceil(long),
        (plane.height() * side).div_ceil(long),
    );
    (w.max(1), h.max(1))
}

/// Copies `image` into the canvas at `(ox, oy)`, nearest neighbour to `pw x ph`.
fn blit(
    canvas: &mut [u8],
    cw: usize,
    image: &PixelImage,
    ox: usize,
    oy: usize,
    pw: usize,
    ph: usize,
) {
    let (w, h) = (image.plane.width(), image.plane.height());
    let rgb = srgb8(image);
    for ty in 0..ph {
        let sy = (ty * h / ph).min(h - 1);
        for tx in 0..pw {
            let sx = (tx * w / pw).min(w - 1);
            let p = 3 * (sy * w + sx);
            let q = 3 * ((oy + ty) * cw + ox + tx);
            canvas[q..q + 3].copy_from_slice(&rgb[p..p + 3]);
        }
    }
}

/// The figure as PNG bytes: `image` (the adaptive reconstruction), the local depth and the
/// samples side by side, with `title` under them and a colour key of the levels.
pub fn adaptive_figure_png(
    run: &AdaptiveImage,
    image: &PixelImage,
    title: &str,
) -> Result<Vec<u8>, PlotError> {
    crate::plot::raster::fonts();
    let plane = plane_of(run);
    let (pw, ph) = panel_size(plane);
    let scale = pw.div_ceil(plane.width()).max(1);
    let samples = samples_image(run, scale);
    let depth = depth_image(run);
    let (base, span) = depth_range(run);
    let (cx, _) = run.tree.basis().coarse_levels();
    let key = span as usize + 1;
    let (cw, ch) = (3 * pw + 4 * GAP, LABEL + ph + 2 * LABEL + GAP);
    let mut canvas = vec![255u8; cw * ch * 3];
    for (k, img) in [image, &depth, &samples].into_iter().enumerate() {
        blit(&mut canvas, cw, img, GAP + k * (pw + GAP), LABEL, pw, ph);
    }
    let err = |message: String| PlotError::Draw {
        path: "adaptive figure".into(),
        message,
    };
    let base_n = run.round_of.iter().filter(|&&r| r == 0).count();
    {
        let root =
            BitMapBackend::with_buffer(&mut canvas, (cw as u32, ch as u32)).into_drawing_area();
        let style = TextStyle::from(("sans-serif", 15).into_font()).color(&BLACK);
        let labels = [
            "adaptive wavelet reconstruction".to_string(),
            format!("local depth (level {} .. {})", cx + base, cx + base + span),
            format!(
                "samples: {} base (grey), {} added (red)",
                base_n,
                run.xs.len() - base_n
            ),
        ];
        for (k, label) in labels.iter().enumerate() {
            root.draw_text(label, &style, ((GAP + k * (pw + GAP) + 4) as i32, 6))
                .map_err(|e| err(e.to_string()))?;
        }
        // colour key of the depth panel
        let (kx, ky) = (GAP + pw + GAP, LABEL + ph + 6);
        let box_w = (pw / key).clamp(12, 60);
        for s in 0..key {
            let swatch = PixelImage {
                plane: ImagePlane::new(1, 1).expect("1x1"),
                channels: colour(s as f64 / span as f64).map(|v| vec![v]).to_vec(),
            };
            let rgb = srgb8(&swatch);
            let (r, g, b) = (rgb[0], rgb[1], rgb[2]);
            let x0 = (kx + s * box_w) as i32;
            root.draw(&Rectangle::new(
                [(x0, ky as i32), (x0 + box_w as i32 - 2, ky as i32 + 14)],
                RGBColor(r, g, b).filled(),
            ))
            .map_err(|e| err(e.to_string()))?;
        }
        root.draw_text(
            &format!("level {} (left) .. {} (right)", cx + base, cx + base + span),
            &style,
            ((kx + key * box_w + 6) as i32, ky as i32),
        )
        .map_err(|e| err(e.to_string()))?;
        root.draw_text(title, &style, (GAP as i32, (ch - LABEL + 4) as i32))
            .map_err(|e| err(e.to_string()))?;
        root.present().map_err(|e| err(e.to_string()))?;
    }
    crate::plot::raster::encode_png(canvas, cw, ch, "adaptive figure")
}

/// Writes [`adaptive_figure_png`] to `path`; an existing file is replaced only with
/// `overwrite`.
pub fn save_adaptive_figure(
    run: &AdaptiveImage,
    image: &PixelImage,
    title: &str,
    path: &Path,
    overwrite: bool,
) -> Result<(), PlotError> {
    let png = adaptive_figure_png(run, image, title).map_err(|e| match e {
        PlotError::Draw { message, .. } => PlotError::Draw {
            path: path.display().to_string(),
            message,
        },
        e => e,
    })?;
    crate::io::output::write_new(path, &png, overwrite)?;
    Ok(())
}
