//! Scenes on the image plane that several tests fit, written once.

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rkwave::image::adaptive::{position_normal, ImageOracle};

/// The line `x + 0.3 y = 20` (pixels) that [`straight_edge`] jumps across.
pub const EDGE_OFFSET: f64 = 20.0;

/// A single straight edge: `0.1` left of the line `x + 0.3 y = 20`, `0.8` on and right of it
/// (contrast 0.7, crossing a 48 x 48 image from `(20, 0)` to `(5.6, 48)`).
pub fn straight_edge(x: f64, y: f64) -> f64 {
    if x + 0.3 * y < EDGE_OFFSET {
        0.1
    } else {
        0.8
    }
}

/// Distance of `(x, y)` from the line `x + 0.3 y = 20` of [`straight_edge`].
pub fn edge_distance(x: f64, y: f64) -> f64 {
    (x + 0.3 * y - EDGE_OFFSET).abs() / (1.0f64 + 0.09).sqrt()
}

/// A tensor polynomial of degree `< 2` per variable: in the coarse space of every basis with
/// `p >= 2`, so every wavelet coefficient is zero and a fit reproduces it to rounding.
pub fn polynomial(x: f64, y: f64) -> f64 {
    0.5 + 0.01 * x - 0.02 * y + 0.0003 * x * y
}

/// `spp` jittered (stratified) sample positions per pixel of a `w x h` image, row by row,
/// uniform in each pixel, from the seed.
pub fn jittered(w: usize, h: usize, spp: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
    jittered_with(w, h, spp, &mut Pcg64::seed_from_u64(seed))
}

/// [`jittered`] drawing from `rng`.
pub fn jittered_with(w: usize, h: usize, spp: usize, rng: &mut impl Rng) -> (Vec<f64>, Vec<f64>) {
    let (mut xs, mut ys) = (Vec::new(), Vec::new());
    for py in 0..h {
        for px in 0..w {
            for _ in 0..spp {
                xs.push(px as f64 + rng.random::<f64>());
                ys.push(py as f64 + rng.random::<f64>());
            }
        }
    }
    (xs, ys)
}

/// Three channels on a `w x h` plane (pixel units): a smooth background, two discs with sharp
/// edges and a thin bright line (the replay scene of `benches/plan_loop.py`).
pub struct DiscsAndLine {
    /// Width in pixels.
    pub w: f64,
    /// Height in pixels.
    pub h: f64,
}

impl rkwave::image::adaptive::ImageOracle for DiscsAndLine {
    fn channels(&self) -> usize {
        3
    }
    fn sample(&self, x: f64, y: f64, out: &mut [f64]) {
        let (u, v) = (x / self.w, y / self.h);
        let smooth = 0.3 + 0.2 * (3.0 * u).sin() * (2.0 * v).cos();
        let inside = |r2: f64, r: f64| if r2 < r { 1.0 } else { 0.0 };
        let disc1 = inside((u - 0.35).powi(2) + (v - 0.4).powi(2), 0.04);
        let disc2 = inside((u - 0.7).powi(2) + (v - 0.65).powi(2), 0.015);
        let line = inside((u + 0.5 * v - 0.9).abs(), 0.004);
        out[0] = smooth + 0.5 * disc1 + line;
        out[1] = smooth + 0.4 * disc2;
        out[2] = 0.6 * smooth + 0.3 * disc1 * v;
    }
}

/// Fine stripes past Nyquist on the right half (period 0.7 pixel, slanted), a disc edge on the
/// left, noise of deviation 0.05: texture the tree cannot follow beside an edge it can.
pub struct StripesAndDisc {
    /// Width in pixels.
    pub w: f64,
    /// Height in pixels.
    pub h: f64,
}

impl ImageOracle for StripesAndDisc {
    fn channels(&self) -> usize {
        1
    }
    fn sample(&self, x: f64, y: f64, out: &mut [f64]) {
        let v = if x > 0.5 * self.w {
            0.5 + 0.4 * (std::f64::consts::TAU * (x + 0.3 * y) / 0.7).sin()
        } else {
            let (dx, dy) = (x - 0.25 * self.w, y - 0.5 * self.h);
            let r = 0.2 * self.w.min(self.h);
            if dx * dx + dy * dy < r * r {
                0.9
            } else {
                0.1
            }
        };
        out[0] = v + 0.05 * position_normal(3, x, y, 0);
    }
}

/// Detail at and near Nyquist on an `n x n` image, channel `c` of three at `(x, y)`: vertical
/// stripes of 0.4 cycles a pixel (Nyquist is 0.5), a chirp `cos(pi k r^2)` whose local
/// frequency `k r / n` passes 0.5 cycles a pixel inside the image, and a thin bright line,
/// with a deterministic hash `0.05 sin(12.9898 x + 78.233 y)` so the values are not a
/// low-degree polynomial the fit would reproduce exactly.
pub fn nyquist_value(n: usize, x: f64, y: f64, c: usize) -> f64 {
    let tau = std::f64::consts::TAU;
    let nf = n as f64;
    let stripes = 0.5 + 0.4 * (tau * 0.4 * x).sin();
    let r2 = (x * x + y * y) / (nf * nf);
    let chirp = 0.5 + 0.4 * (std::f64::consts::PI * 0.9 * nf * r2).cos();
    let line = if (y - 0.37 * x - 5.0).abs() < 0.3 {
        0.6
    } else {
        0.0
    };
    let hash = 0.05 * (12.9898 * x + 78.233 * y).sin();
    match c {
        0 => stripes + hash,
        1 => chirp + line,
        _ => 0.5 * stripes + 0.5 * chirp + hash,
    }
}

/// Flat 0.5 everywhere; Gaussian noise of deviation `sigma` (seeded by `seed` through
/// [`position_normal`], a function of the position) on the left half `x < 16` only.
pub struct HalfNoisy {
    pub sigma: f64,
    pub seed: u64,
}

impl ImageOracle for HalfNoisy {
    fn channels(&self) -> usize {
        1
    }
    fn sample(&self, x: f64, y: f64, out: &mut [f64]) {
        out[0] = 0.5;
        if x < 16.0 {
            out[0] += self.sigma * position_normal(self.seed, x, y, 0);
        }
    }
}
