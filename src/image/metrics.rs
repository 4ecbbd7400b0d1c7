//! Image error metrics of a reconstruction `I` against a reference `R` (both linear, peak 1),
//! over all `n` pixel values of all channels:
//!
//! * `RMSE = sqrt(mean (I - R)^2)`;
//! * `PSNR = 10 log10(1 / MSE)` dB (peak value 1; infinite for identical images);
//! * relative MSE `mean((I - R)^2 / (R^2 + 0.01))`, the adaptive-rendering literature's metric;
//! * SSIM (Wang, Bovik, Sheikh & Simoncelli 2004): local means, variances and covariance with
//!   an 11 x 11 Gaussian window (`sigma = 1.5`, truncated at `3.5 sigma`, normalised, image
//!   borders mirrored `d c b a | a b c d`), `C1 = (0.01 L)^2`, `C2 = (0.03 L)^2`, `L = 1`,
//!   `SSIM = (2 mu_x mu_y + C1)(2 s_xy + C2) / ((mu_x^2 + mu_y^2 + C1)(s_x^2 + s_y^2 + C2))`,
//!   averaged over the pixels at least 5 from the border, then over channels — exactly
//!   scikit-image's `structural_similarity(..., gaussian_weights=True, sigma=1.5,
//!   use_sample_covariance=False, data_range=1)` (checked against stored values in
//!   `tests/image_metrics.rs`).

use serde::Serialize;

use super::PixelImage;

/// The four metrics of one image against its reference.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ImageMetrics {
    /// Peak signal-to-noise ratio in dB, peak 1.
    pub psnr: f64,
    /// Root-mean-square error.
    pub rmse: f64,
    /// `mean((I - R)^2 / (R^2 + 0.01))`.
    pub rel_mse: f64,
    /// Mean structural similarity (Gaussian window, sigma 1.5).
    pub ssim: f64,
}

/// All four metrics of `image` against `reference` (same resolution and channel count: a
/// broken contract otherwise).
pub fn compare(image: &PixelImage, reference: &PixelImage) -> ImageMetrics {
    assert_eq!(image.plane, reference.plane, "metrics: resolutions differ");
    assert_eq!(
        image.channel_count(),
        reference.channel_count(),
        "metrics: channel counts differ"
    );
    let (mut se, mut rel, mut n) = (0.0, 0.0, 0usize);
    for (a, r) in image.channels.iter().zip(&reference.channels) {
        for (x, y) in a.iter().zip(r) {
            let d = x - y;
            se += d * d;
            rel += d * d / (y * y + 0.01);
            n += 1;
        }
    }
    let mse = se / n as f64;
    let ssim = image
        .channels
        .iter()
        .zip(&reference.channels)
        .map(|(a, r)| ssim_channel(a, r, image.plane.width(), image.plane.height()))
        .sum::<f64>()
        / image.channel_count() as f64;
    ImageMetrics {
        psnr: 10.0 * (1.0 / mse).log10(),
        rmse: mse.sqrt(),
        rel_mse: rel / n as f64,
        ssim,
    }
}

/// Standard deviation of the SSIM window.
pub const SSIM_SIGMA: f64 = 1.5;
/// Half-width of the window: `int(3.5 sigma + 0.5) = 5`.
const SSIM_RADIUS: usize = 5;

fn gaussian_window() -> [f64; 2 * SSIM_RADIUS + 1] {
    let mut w = [0.0; 2 * SSIM_RADIUS + 1];
    for (i, v) in w.iter_mut().enumerate() {
        let x = i as f64 - SSIM_RADIUS as f64;
        *v = (-0.5 * x * x / (SSIM_SIGMA * SSIM_SIGMA)).exp();
    }
    let s: f64 = w.iter().sum();
    w.map(|v| v / s)
}

/// Mirror index `i` into `0..n` (scipy.ndimage's `reflect`: `d c b a | a b c d | d c b a`).
fn reflect(mut i: isize, n: usize) -> usize {
    let n = n as isize;
    loop {
        if i < 0 {
            i = -i - 1;
        } else if i >= n {
            i = 2 * n - i - 1;
        } else {
            return i as usize;
        }
    }
}

/// Separable Gaussian filtering of a `w x h` row-major image with mirrored borders.
fn blur(img: &[f64], w: usize, h: usize) -> Vec<f64> {
    let k = gaussian_window();
    let r = SSIM_RADIUS as isize;
    let mut tmp = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            tmp[y * w + x] = (-r..=r)
                .map(|d| k[(d + r) as usize] * img[y * w + reflect(x as isize + d, w)])
                .sum();
        }
    }
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            out[y * w + x] = (-r..=r)
                .map(|d| k[(d + r) as usize] * tmp[reflect(y as isize + d, h) * w + x])
                .sum();
        }
    }
    out
}

/// Mean SSIM of one channel (see the module docs); images smaller than the window (a side
/// below 11) are averaged over all pixels instead of the cropped interior.
pub fn ssim_channel(a: &[f64], b: &[f64], w: usize, h: usize) -> f64 {
    let (c1, c2) = (0.01f64.powi(2), 0.03f64.powi(2));
    let prod = |f: &dyn Fn(usize) -> f64| (0..w * h).map(f).collect::<Vec<f64>>();
    let ux = blur(a, w, h);
    let uy = blur(b, w, h);
    let uxx = blur(&prod(&|i| a[i] * a[i]), w, h);
    let uyy = blur(&prod(&|i| b[i] * b[i]), w, h);
    let uxy = blur(&prod(&|i| a[i] * b[i]), w, h);
    let pad = if w > 2 * SSIM_RADIUS && h > 2 * SSIM_RADIUS {
        SSIM_RADIUS
    } else {
        0
    };
    let (mut sum, mut n) = (0.0, 0usize);
    for y in pad..h - pad {
        for x in pad..w - pad {
            let i = y * w + x;
            let (vx, vy, vxy) = (
                uxx[i] - ux[i] * ux[i],
                uyy[i] - uy[i] * uy[i],
                uxy[i] - ux[i] * uy[i],
            );
            let s = (2.0 * ux[i] * uy[i] + c1) * (2.0 * vxy + c2)
                / ((ux[i] * ux[i] + uy[i] * uy[i] + c1) * (vx + vy + c2));
            sum += s;
            n += 1;
        }
    }
    sum / n as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::ImagePlane;

    #[test]
    fn identical_images_are_perfect_and_a_constant_offset_has_known_metrics() {
        let plane = ImagePlane::new(16, 12).unwrap();
        let r = PixelImage {
            plane,
            channels: vec![(0..192).map(|i| (i % 7) as f64 / 7.0).collect()],
        };
        let m = compare(&r, &r);
        assert_eq!((m.rmse, m.rel_mse), (0.0, 0.0));
        assert!(m.psnr.is_infinite());
        assert!((m.ssim - 1.0).abs() < 1e-12);
        let mut i = r.clone();
        i.channels[0].iter_mut().for_each(|v| *v += 0.1);
        let m = compare(&i, &r);
        // MSE = 0.01: PSNR = 20 dB exactly, RMSE = 0.1.
        assert!((m.psnr - 20.0).abs() < 1e-9 && (m.rmse - 0.1).abs() < 1e-12);
        let rel: f64 = r.channels[0]
            .iter()
            .map(|y| 0.01 / (y * y + 0.01))
            .sum::<f64>()
            / 192.0;
        assert!((m.rel_mse - rel).abs() < 1e-12);
        assert!(m.ssim < 1.0);
        assert_eq!(reflect(-1, 4), 0);
        assert_eq!(reflect(5, 4), 2);
        assert_eq!(reflect(-6, 4), 2);
    }
}
