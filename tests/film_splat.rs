//! The film-filter splat behind every PSNR comparison, against a naive oracle: for each film
//! filter (box, triangle, gaussian, mitchell, lanczos) a slow, obviously correct per-pixel
//! weighted average written here from the filter's formula, visiting every sample for every
//! pixel (no binning, no search window), on random samples.
//!
//! The conventions, as `src/image/filters.rs` and `src/image/splat.rs` state them: pixel
//! `(X, Y)` has its centre at `(X + 1/2, Y + 1/2)`; a sample at offset `(dx, dy)` from it
//! weighs `w = f(dx) f(dy)` if `|dx| <= r` and `|dy| <= r`, else nothing; the filters are not
//! normalised (the average divides by `sum w`); when `|sum w| <= 1e-3 sum |w|` the average
//! uses `|w|`; a pixel with no sample within the radius takes the mean of the samples in the
//! nearest non-empty Chebyshev ring of pixels, a sample belonging to pixel
//! `(min(floor x, W - 1), min(floor y, H - 1))`.
//!
//! Tolerance, per pixel. The library and the oracle add the same terms in other orders and
//! evaluate the profiles by other expressions. With `n` samples within the radius,
//! `N = sum w_i f_i` and `D = sum w_i`: recursive summation errs by at most
//! `n eps sum |w_i f_i|` and `n eps sum |w_i|`, and a weight by at most `16 eps w_max` in
//! absolute terms (`w_max` the largest weight of the filter; absolute because near a zero of
//! a lobe the relative error of `sin(pi x)` is unbounded but its absolute error is
//! `~ pi r eps`). Then `|I - I_oracle| <= 2 (e_N + |I| e_D) / |D|`, the factor 2 for the
//! second-order terms and the division. Where `|D|` is within that rounding of the
//! cancellation threshold the two may take different branches; such pixels are counted and
//! must be rare.

mod common;

use std::f64::consts::PI;

use common::scenes::straight_edge;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rkwave::image::filters::FilmFilterKind;
use rkwave::image::splat::splat;
use rkwave::image::{ImagePlane, ImageSamples};

/// A film filter written from its formula (pbrt-v4's defaults, as the library documents).
#[derive(Clone, Copy, Debug)]
enum Formula {
    /// `1` for `|x| <= 1/2`.
    Box,
    /// `max(0, 2 - |x|)`.
    Tent,
    /// `max(0, g(x) - g(3/2))`, `g` the normal density of deviation `1/2`, for `|x| <= 3/2`.
    Gaussian,
    /// Mitchell–Netravali with `B = C = 1/3` stretched to radius 2: `k(x)` on `[-2, 2]`.
    Mitchell,
    /// `sinc(x) sinc(x / 3)` for `|x| <= 4`.
    Lanczos,
}

impl Formula {
    fn of(kind: FilmFilterKind) -> Self {
        match kind {
            FilmFilterKind::Box => Self::Box,
            FilmFilterKind::Triangle => Self::Tent,
            FilmFilterKind::Gaussian => Self::Gaussian,
            FilmFilterKind::Mitchell => Self::Mitchell,
            FilmFilterKind::Lanczos => Self::Lanczos,
        }
    }

    fn radius(self) -> f64 {
        match self {
            Self::Box => 0.5,
            Self::Tent | Self::Mitchell => 2.0,
            Self::Gaussian => 1.5,
            Self::Lanczos => 4.0,
        }
    }

    /// The largest `|f|`, at `x = 0`.
    fn peak(self) -> f64 {
        self.profile(0.0).abs()
    }

    /// The 1D profile `f(x)`, zero for `|x| > r`.
    fn profile(self, x: f64) -> f64 {
        let t = x.abs();
        if t > self.radius() {
            return 0.0;
        }
        match self {
            Self::Box => 1.0,
            Self::Tent => 2.0 - t,
            Self::Gaussian => {
                let sigma = 0.5f64;
                let g = |x: f64| {
                    (-(x * x) / (2.0 * sigma * sigma)).exp() / (2.0 * PI * sigma * sigma).sqrt()
                };
                (g(t) - g(1.5)).max(0.0)
            }
            Self::Mitchell => {
                // Mitchell & Netravali (1988), eq. 8, with B = C = 1/3 substituted (the
                // argument 2x / r is x itself for r = 2).
                if t < 1.0 {
                    (7.0 * t.powi(3) - 12.0 * t.powi(2) + 16.0 / 3.0) / 6.0
                } else if t < 2.0 {
                    (-7.0 / 3.0 * t.powi(3) + 12.0 * t.powi(2) - 20.0 * t + 32.0 / 3.0) / 6.0
                } else {
                    0.0
                }
            }
            Self::Lanczos => {
                let sinc = |x: f64| {
                    if x == 0.0 {
                        1.0
                    } else {
                        (PI * x).sin() / (PI * x)
                    }
                };
                sinc(x) * sinc(x / 3.0)
            }
        }
    }
}

/// What the oracle found for one pixel.
struct Pixel {
    /// Value per channel.
    values: Vec<f64>,
    /// Allowed difference per channel.
    tolerance: Vec<f64>,
    /// The pixel averaged with `|w|`.
    cancelled: bool,
    /// The pixel had no sample within the radius.
    empty: bool,
    /// `|D|` within rounding of the cancellation threshold: either branch is right.
    ambiguous: bool,
}

/// The naive weighted average of pixel `(px, py)`: every sample visited.
fn naive_pixel(formula: Formula, samples: &ImageSamples, px: usize, py: usize) -> Pixel {
    let (xs, ys, values) = (samples.xs(), samples.ys(), samples.values());
    let eps = f64::EPSILON;
    let channels = values.len();
    let r = formula.radius();
    let (cx, cy) = (px as f64 + 0.5, py as f64 + 0.5);
    let mut num = vec![0.0; channels];
    let mut num_abs = vec![0.0; channels];
    // sum |w_i f_i| and sum |f_i|, for the rounding bound
    let mut sum_wf = vec![0.0; channels];
    let mut sum_f = vec![0.0; channels];
    let (mut den, mut den_abs, mut n) = (0.0, 0.0, 0usize);
    for i in 0..xs.len() {
        let (dx, dy) = (xs[i] - cx, ys[i] - cy);
        if dx.abs() > r || dy.abs() > r {
            continue;
        }
        let w = formula.profile(dx) * formula.profile(dy);
        n += 1;
        den += w;
        den_abs += w.abs();
        for c in 0..channels {
            let f = values[c][i];
            num[c] += w * f;
            num_abs[c] += w.abs() * f;
            sum_wf[c] += (w * f).abs();
            sum_f[c] += f.abs();
        }
    }
    if den_abs == 0.0 {
        let (values, tolerance) = ring_mean(samples, px, py);
        return Pixel {
            values,
            tolerance,
            cancelled: false,
            empty: true,
            ambiguous: false,
        };
    }
    let nf = n as f64;
    let w_max = formula.peak() * formula.peak();
    let err_den = eps * (nf * den_abs + 16.0 * nf * w_max);
    let threshold = 1e-3 * den_abs;
    let ambiguous = (den.abs() - threshold).abs() <= 2.0 * err_den;
    let cancelled = den.abs() <= threshold;
    let (numerator, d) = if cancelled {
        (&num_abs, den_abs)
    } else {
        (&num, den)
    };
    let values_out: Vec<f64> = numerator.iter().map(|v| v / d).collect();
    let tolerance = (0..channels)
        .map(|c| {
            let err_num = eps * (nf * sum_wf[c] + 16.0 * w_max * sum_f[c]);
            2.0 * (err_num + values_out[c].abs() * err_den) / d.abs()
        })
        .collect();
    Pixel {
        values: values_out,
        tolerance,
        cancelled,
        empty: false,
        ambiguous,
    }
}

/// Mean of the samples whose pixel is nearest to `(px, py)` in Chebyshev distance (all of
/// them at that distance), and its rounding bound `2 n eps max |f|` (a sum of `n` terms in
/// another order).
fn ring_mean(samples: &ImageSamples, px: usize, py: usize) -> (Vec<f64>, Vec<f64>) {
    let (plane, xs, ys) = (samples.plane(), samples.xs(), samples.ys());
    let distance = |i: usize| {
        let qx = (xs[i].floor() as usize).min(plane.width() - 1);
        let qy = (ys[i].floor() as usize).min(plane.height() - 1);
        qx.abs_diff(px).max(qy.abs_diff(py))
    };
    let nearest = (0..xs.len()).map(distance).min().expect("some sample");
    let ring: Vec<usize> = (0..xs.len()).filter(|&i| distance(i) == nearest).collect();
    let n = ring.len() as f64;
    samples
        .values()
        .iter()
        .map(|v| {
            let mean = ring.iter().map(|&i| v[i]).sum::<f64>() / n;
            let largest = ring.iter().map(|&i| v[i].abs()).fold(0.0, f64::max);
            (mean, 2.0 * n * f64::EPSILON * largest)
        })
        .unzip()
}

/// Random samples: `count` uniform positions on the image, plus positions on pixel edges and
/// corners and on the image's border (the closed-interval conventions); values the straight
/// edge (scaled onto the image) and uniform noise in `[0, 1)`.
fn random_samples(plane: ImagePlane, count: usize, seed: u64) -> ImageSamples {
    let (w, h) = (plane.width() as f64, plane.height() as f64);
    let mut rng = Pcg64::seed_from_u64(seed);
    let (mut xs, mut ys): (Vec<f64>, Vec<f64>) = (0..count)
        .map(|_| (w * rng.random::<f64>(), h * rng.random::<f64>()))
        .unzip();
    // on vertical pixel edges, then on horizontal edges and half-way between them
    for _ in 0..count / 10 {
        xs.push(rng.random_range(0..=plane.width()) as f64);
        ys.push(h * rng.random::<f64>());
        xs.push(w * rng.random::<f64>());
        ys.push(0.5 * rng.random_range(0..=2 * plane.height()) as f64);
    }
    xs.extend([0.0, w, 0.0, w]);
    ys.extend([0.0, h, h, 0.0]);
    let scale = 48.0 / w;
    let edge = xs
        .iter()
        .zip(&ys)
        .map(|(&x, &y)| straight_edge(scale * x, scale * y))
        .collect();
    let noise = xs.iter().map(|_| rng.random::<f64>()).collect();
    ImageSamples::new(plane, xs, ys, vec![edge, noise]).unwrap()
}

/// Every filter, three sample sets (4 samples per pixel, 1/3 of a sample per pixel with holes
/// and cancelling lobes, 1/40 with large holes): every pixel of the library's splat within the
/// per-pixel bound of the naive average, and the library's counts of cancelled and empty
/// pixels equal the oracle's.
#[test]
fn every_film_filter_splats_as_the_naive_weighted_average() {
    let cases = [
        (ImagePlane::new(16, 12).unwrap(), 4 * 16 * 12, 31),
        (ImagePlane::new(20, 20).unwrap(), 20 * 20 / 3, 32),
        (ImagePlane::new(24, 16).unwrap(), 24 * 16 / 40, 33),
    ];
    for (plane, count, seed) in cases {
        let samples = random_samples(plane, count, seed);
        for kind in FilmFilterKind::ALL {
            let formula = Formula::of(kind);
            let filter = kind.build();
            assert_eq!(filter.radius(), formula.radius(), "{kind}");
            let (image, report) = splat(&samples, filter.as_ref());
            let (mut cancelled, mut empty, mut ambiguous) = (0, 0, 0);
            let mut worst: f64 = 0.0;
            for py in 0..plane.height() {
                for px in 0..plane.width() {
                    let pixel = naive_pixel(formula, &samples, px, py);
                    cancelled += pixel.cancelled as usize;
                    empty += pixel.empty as usize;
                    if pixel.ambiguous {
                        ambiguous += 1;
                        continue;
                    }
                    for (c, (&want, &tol)) in pixel.values.iter().zip(&pixel.tolerance).enumerate()
                    {
                        let got = image.channels[c][py * plane.width() + px];
                        let diff = (got - want).abs();
                        assert!(
                            diff <= tol,
                            "{kind} on {plane}, seed {seed}, pixel ({px}, {py}), channel {c}: \
                             {got} against the naive {want} (difference {diff:e} > {tol:e})"
                        );
                        if tol > 0.0 {
                            worst = worst.max(diff / tol);
                        }
                    }
                }
            }
            println!(
                "{kind} on {plane} ({} samples): {cancelled} cancelled, {empty} empty, \
                 {ambiguous} ambiguous, worst difference {worst:.2} of the bound",
                samples.len()
            );
            assert_eq!(ambiguous, 0, "{kind}: pixels at the cancellation threshold");
            assert_eq!(report.cancelled_pixels, cancelled, "{kind} on {plane}");
            assert_eq!(report.empty_pixels, empty, "{kind} on {plane}");
        }
    }
}

/// The lowest point `b` of the negative lobe of `formula` and a point `a` in the
/// positive main lobe with `f(a) = -f(b)`: two samples there, on either side of a pixel
/// centre on one row, cancel (`sum w = 0` to rounding). Bisection on the oracle's formula.
fn cancelling_offsets(formula: Formula) -> (f64, f64) {
    let r = formula.radius();
    let grid: Vec<f64> = (1..=4000).map(|i| r * i as f64 / 4000.0).collect();
    // the main lobe ends at the first zero
    let zero = grid
        .iter()
        .copied()
        .find(|&x| formula.profile(x) <= 0.0)
        .expect("a negative lobe");
    let b = grid
        .iter()
        .copied()
        .filter(|&x| x > zero)
        .min_by(|x, y| formula.profile(*x).total_cmp(&formula.profile(*y)))
        .unwrap();
    let target = -formula.profile(b);
    assert!(target > 0.0, "{formula:?} has a negative lobe");
    // the main lobe falls from f(0) > target to f(zero) <= 0 < target
    let (mut lo, mut hi) = (0.0, zero);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if formula.profile(mid) > target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    (0.5 * (lo + hi), b)
}

/// The near-zero-denominator rule, which random samples seldom reach: for the filters with
/// negative lobes (Mitchell, Lanczos), two samples whose weights cancel for one pixel make
/// the library use absolute weights there as the oracle does; the whole image still agrees.
#[test]
fn cancelling_weights_fall_back_to_absolute_weights() {
    let plane = ImagePlane::new(9, 9).unwrap();
    for kind in [FilmFilterKind::Mitchell, FilmFilterKind::Lanczos] {
        let formula = Formula::of(kind);
        let (a, b) = cancelling_offsets(formula);
        let xs = vec![4.5 + a, 4.5 - b, 0.3, 8.7];
        // the pair's row 4.4: no pixel centre at the radius 4 from it, where the Lanczos
        // weights are rounding-level and either branch is right
        let ys = vec![4.4, 4.4, 0.4, 8.9];
        let values = vec![vec![0.25, 0.75, 0.5, 0.1]];
        let samples = ImageSamples::new(plane, xs, ys, values).unwrap();
        let (image, report) = splat(&samples, kind.build().as_ref());
        let mut cancelled = 0;
        for py in 0..plane.height() {
            for px in 0..plane.width() {
                let pixel = naive_pixel(formula, &samples, px, py);
                assert!(!pixel.ambiguous, "{kind}: pixel ({px}, {py})");
                cancelled += pixel.cancelled as usize;
                let got = image.channels[0][py * plane.width() + px];
                assert!(
                    (got - pixel.values[0]).abs() <= pixel.tolerance[0],
                    "{kind}, pixel ({px}, {py}): {got} against {}",
                    pixel.values[0]
                );
            }
        }
        let centre = naive_pixel(formula, &samples, 4, 4);
        assert!(centre.cancelled, "{kind}: the centre pixel cancels");
        assert_eq!(report.cancelled_pixels, cancelled, "{kind}");
    }
}
