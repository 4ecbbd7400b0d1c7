//! Figures of a [`Comparison`]: the images side by side with zoomed crops of the same regions,
//! and error against time.
//!
//! The side-by-side figure is a grid: one column per image (the truth, then each method), one
//! row for the whole image and one per crop. Crops are the two `c x c` windows
//! (`c = min(W, H) / 8`, at least 8) where the truth varies most (sum of squared differences
//! of neighbouring pixels: edges, the zone plate's fine rings, text), non-overlapping, each
//! enlarged by pixel replication (nearest neighbour, so the pixels stay visible).

use std::path::Path;

use plotters::prelude::*;

use super::experiment::Comparison;
use crate::image::PixelImage;
use crate::io::image_file::srgb8;
use crate::plot::raster::{encode_png, fonts};
use crate::plot::{Figure, Panel, PlotError, Scale, Series, SeriesStyle};

/// Side of one tile in the figure, in figure pixels.
const TILE: usize = 256;
/// Height of the label strip above each column.
const LABEL: usize = 28;

/// A crop window `(x0, y0, side)` in pixels.
pub type Crop = (usize, usize, usize);

/// The two non-overlapping windows of side `c` where `truth` varies most (see the module
/// docs), scanning on a grid of step `c / 2`.
pub fn busiest_crops(truth: &PixelImage) -> Vec<Crop> {
    let (w, h) = (truth.plane.width(), truth.plane.height());
    let c = (w.min(h) / 8).max(8).min(w.min(h));
    let step = (c / 2).max(1);
    let energy = |x0: usize, y0: usize| {
        let mut e = 0.0;
        for ch in &truth.channels {
            for y in y0..y0 + c {
                for x in x0..x0 + c {
                    let v = ch[y * w + x];
                    if x + 1 < x0 + c {
                        e += (ch[y * w + x + 1] - v).powi(2);
                    }
                    if y + 1 < y0 + c {
                        e += (ch[(y + 1) * w + x] - v).powi(2);
                    }
                }
            }
        }
        e
    };
    let mut windows = vec![];
    let mut y0 = 0;
    while y0 + c <= h {
        let mut x0 = 0;
        while x0 + c <= w {
            windows.push((energy(x0, y0), x0, y0));
            x0 += step;
        }
        y0 += step;
    }
    windows.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut chosen: Vec<Crop> = vec![];
    for (_, x0, y0) in windows {
        let overlaps = chosen
            .iter()
            .any(|&(a, b, _)| x0 < a + c && a < x0 + c && y0 < b + c && b < y0 + c);
        if !overlaps {
            chosen.push((x0, y0, c));
        }
        if chosen.len() == 2 {
            break;
        }
    }
    chosen
}

/// Copies `image` (or its crop) into the RGB canvas at `(ox, oy)`, scaled by nearest
/// neighbour to `TILE x TILE` (aspect kept, letterboxed).
fn blit(
    canvas: &mut [u8],
    cw: usize,
    image: &PixelImage,
    crop: Option<Crop>,
    ox: usize,
    oy: usize,
) {
    let (w, h) = (image.plane.width(), image.plane.height());
    let (x0, y0, sw, sh) = match crop {
        Some((x0, y0, c)) => (x0, y0, c, c),
        None => (0, 0, w, h),
    };
    let scale = TILE as f64 / sw.max(sh) as f64;
    let rgb = srgb8(image);
    for ty in 0..TILE {
        for tx in 0..TILE {
            let (sx, sy) = ((tx as f64 / scale) as usize, (ty as f64 / scale) as usize);
            if sx >= sw || sy >= sh {
                continue;
            }
            let p = (y0 + sy) * w + (x0 + sx);
            let q = ((oy + ty) * cw + ox + tx) * 3;
            canvas[q..q + 3].copy_from_slice(&rgb[3 * p..3 * p + 3]);
        }
    }
}

/// Writes the side-by-side figure of `cmp` to `path` (PNG); an existing file is replaced only
/// with `overwrite`.
pub fn save_side_by_side(cmp: &Comparison, path: &Path, overwrite: bool) -> Result<(), PlotError> {
    fonts();
    let crops = busiest_crops(&cmp.truth);
    let columns = 1 + cmp.results.len();
    let rows = 1 + crops.len();
    let (cw, ch) = (columns * (TILE + 4), LABEL + rows * (TILE + 4) + LABEL);
    let mut canvas = vec![255u8; cw * ch * 3];
    let images: Vec<(&PixelImage, String)> =
        std::iter::once((&cmp.truth, "truth (box)".to_string()))
            .chain(
                cmp.results
                    .iter()
                    .map(|r| (&r.image, format!("{} {:.2} dB", r.method, r.metrics.psnr))),
            )
            .collect();
    for (col, (img, _)) in images.iter().enumerate() {
        let ox = col * (TILE + 4) + 2;
        blit(&mut canvas, cw, img, None, ox, LABEL);
        for (k, crop) in crops.iter().enumerate() {
            blit(
                &mut canvas,
                cw,
                img,
                Some(*crop),
                ox,
                LABEL + (k + 1) * (TILE + 4),
            );
        }
    }
    let err = |message: String| PlotError::Draw {
        path: path.display().to_string(),
        message,
    };
    {
        let root =
            BitMapBackend::with_buffer(&mut canvas, (cw as u32, ch as u32)).into_drawing_area();
        let style = TextStyle::from(("sans-serif", 16).into_font()).color(&BLACK);
        for (col, (_, label)) in images.iter().enumerate() {
            root.draw_text(label, &style, ((col * (TILE + 4) + 6) as i32, 6))
                .map_err(|e| err(e.to_string()))?;
        }
        let crops_text = crops
            .iter()
            .map(|(x, y, c)| format!("[{x}, {x}+{c}) x [{y}, {y}+{c})"))
            .collect::<Vec<_>>()
            .join(", ");
        let caption = format!(
            "{} at {}, {} spp {}, noise {}; rows: whole image, then crops {crops_text} (nearest-neighbour zoom)",
            cmp.scene, cmp.sampling.plane, cmp.sampling.spp, cmp.sampling.sampler, cmp.sampling.noise
        );
        root.draw_text(&caption, &style, (6, (ch - LABEL + 6) as i32))
            .map_err(|e| err(e.to_string()))?;
        root.present().map_err(|e| err(e.to_string()))?;
    }
    // Encoded in memory, then moved into place atomically; an existing file is replaced only
    // with `overwrite`.
    let png = encode_png(canvas, cw, ch, &path.display().to_string())?;
    crate::io::output::write_new(path, &png, overwrite)?;
    Ok(())
}

/// Writes the PSNR-against-time figure (one series per method, one point per comparison) to
/// `path`; an existing file is replaced only with `overwrite`.
pub fn save_error_vs_time(
    comparisons: &[Comparison],
    path: &Path,
    overwrite: bool,
) -> Result<(), PlotError> {
    let Some(first) = comparisons.first() else {
        return Ok(());
    };
    let series = first
        .results
        .iter()
        .enumerate()
        .map(|(k, r)| {
            let points = comparisons
                .iter()
                .filter_map(|c| c.results.iter().find(|q| q.method == r.method))
                .map(|q| (q.time_s.total.max(1e-4), q.metrics.psnr))
                .collect();
            Series::new(r.method.name(), points, SeriesStyle::Markers).with_color(k)
        })
        .collect();
    let panel = Panel {
        title: format!(
            "PSNR against reconstruction time ({} spp {}, {} scene runs)",
            first.sampling.spp,
            first.sampling.sampler,
            comparisons.len()
        ),
        x_label: "time (s, sampling and truth excluded)".into(),
        y_label: "PSNR (dB) against the box-filtered truth".into(),
        x_scale: Scale::Log10,
        series,
        ..Panel::default()
    };
    Figure::new(900, 600, vec![panel.into()]).write(path, overwrite)
}
