//! The film filter chosen per pixel by Stein's unbiased risk estimate (SURE).
//!
//! **Model.** Sample `i` of pixel `Q` has value `v_i` with mean depending on the scene and
//! variance `s²_Q` (Monte Carlo noise and the stratified position's jitter; [`super::noise`]
//! estimates it). The box estimate `m_P = (1 / n_P) sum_{i in P} v_i` has mean `mu_P` (the
//! pixel integral) and variance `sigma²_P = s²_P / n_P`. A film filter `w` is linear in the
//! values:
//!
//! `F_P = sum_i a_{P,i} v_i`, `a_{P,i} = w(x_i - c_P) / sum_j w(x_j - c_P)`
//!
//! ([`crate::image::splat`], the weights fixed by the positions).
//!
//! **SURE.** With `m_P` as the noisy observation of `mu_P`,
//! `E (F_P - mu_P)² = E (F_P - m_P)² - sigma²_P + 2 Cov(F_P, m_P)`, and the covariance comes
//! from the pixel's own samples only: `Cov(F_P, m_P) = sum_{i in P} a_{P,i} s²_P / n_P =
//! A_P sigma²_P`, with `A_P = sum_{i in P} a_{P,i}` the filter weight of the pixel's own
//! samples (the divergence `d F_P / d m_P` of the linear film). So
//!
//! `SURE_P = (F_P - m_P)² + sigma²_P (2 A_P - 1)`
//!
//! is an unbiased estimate of the film's risk at `P` (summed over channels). One pixel's SURE is
//! noisy; the risk of a film over the `(2h + 1)²` window around `P` is the sum of the SUREs in
//! it, and each pixel takes the film of least window risk. The box film (`F = m`, `A = 1`) has
//! `SURE = sigma²_P`: a smoother film is chosen where its bias `(F - m)²` costs less than the
//! noise it removes, `sigma² (1 - 2A)`.
//!
//! The output's noise, `Var F_P = sum_i a²_{P,i} s²_{Q(i)}`, is kept for the shrinkage after
//! the choice ([`super::shrink`], by the median of that variance per channel).
//!
//! Filters with negative lobes can nearly cancel their weights (`|sum w| <= 1e-3 sum |w|`); such
//! a pixel is averaged with `|w|` as [`crate::image::splat`] does, and its `A_P` is the `|w|`
//! share of its own samples.

use serde::Serialize;

use super::noise::PixelNoise;
use crate::image::film_weights::map_rows;
use crate::image::filters::FilmFilterKind;
use crate::image::splat::{PixelBins, CANCELLATION_RATIO};
use crate::image::{ImageSamples, PixelImage};

/// One film's image with what SURE needs.
#[derive(Debug, Clone)]
pub struct FilmCandidate {
    /// The film.
    pub film: FilmFilterKind,
    /// `F_P` per channel.
    pub image: PixelImage,
    /// `A_P`: the weight of the pixel's own samples.
    pub own_weight: Vec<f64>,
    /// `Var F_P` per channel.
    pub variance: Vec<Vec<f64>>,
}

/// The film `film` of `samples` (binned by `bins`) with its own weights and output variance
/// under `noise`.
pub fn film_candidate(
    samples: &ImageSamples,
    bins: &PixelBins,
    noise: &PixelNoise,
    film: FilmFilterKind,
) -> FilmCandidate {
    let filter = film.build();
    let reach = crate::image::film_weights::reach(filter.radius());
    let plane = samples.plane();
    let w = plane.width();
    let channels = samples.channels();
    // `s²_{Q,c}` per pixel `Q` (interleaved by channel): looked up once per pixel, not once per
    // sample and neighbour.
    let sample_variance: Vec<f64> = (0..plane.pixels())
        .flat_map(|q| (0..channels).map(move |c| noise.sample_variance(c, q)))
        .collect();
    // Per row: interleaved (value, variance) per pixel and channel, and A per pixel; the
    // weights from the cached 1D factors, in the direct gather's order (`film_weights`).
    let rows: Vec<(Vec<f64>, Vec<f64>, Vec<f64>)> =
        map_rows(samples, bins, filter.as_ref(), |weights| {
            let row = weights.row() * w;
            // The values of the samples this row reaches (pixel rows `Y - R..=Y + R`) in bin
            // order, interleaved by channel (`binned[(pos - first) * ch + c]` =
            // `v_{c, order[pos]}`): the gather reads them in that order, contiguously, not
            // scattered over the channels' arrays; the same numbers, so the same sums. One
            // row's copy at a time, `(2 R + 1)` rows of samples.
            let (r0, r1) = (
                weights.row().saturating_sub(reach),
                (weights.row() + reach + 1).min(plane.height()),
            );
            let first = bins.start[r0 * w];
            let binned: Vec<f64> = bins.order[first..bins.start[r1 * w]]
                .iter()
                .flat_map(|&i| samples.values().iter().map(move |v| v[i]))
                .collect();
            let values_at = |pos: usize| &binned[(pos - first) * channels..][..channels];
            let mut values = vec![0.0; w * channels];
            let mut variances = vec![0.0; w * channels];
            let mut own = vec![0.0; w];
            let mut acc = Accumulator::new(channels);
            for px in 0..w {
                acc.clear();
                weights.pixel_slots(px, |pos, _, q, wt| {
                    let s2 = &sample_variance[q * channels..(q + 1) * channels];
                    acc.add(wt, q == row + px, values_at(pos), s2);
                });
                if acc.cancels() {
                    // The signed weights cancel: the sums again with `|w|`, in the same order.
                    acc.clear_sums();
                    weights.pixel_slots(px, |pos, _, q, wt| {
                        let s2 = &sample_variance[q * channels..(q + 1) * channels];
                        acc.add_sums(wt.abs(), values_at(pos), s2);
                    });
                }
                own[px] = acc.finish(
                    &mut values[px * channels..(px + 1) * channels],
                    &mut variances[px * channels..(px + 1) * channels],
                );
            }
            (values, variances, own)
        });
    let mut image = PixelImage::zeros(plane, channels);
    let mut variance = vec![vec![0.0; plane.pixels()]; channels];
    let mut own_weight = vec![0.0; plane.pixels()];
    for (py, (vals, vars, own)) in rows.into_iter().enumerate() {
        for px in 0..w {
            own_weight[py * w + px] = own[px];
            for c in 0..channels {
                image.channels[c][py * w + px] = vals[px * channels + c];
                variance[c][py * w + px] = vars[px * channels + c];
            }
        }
    }
    FilmCandidate {
        film,
        image,
        own_weight,
        variance,
    }
}

/// Sums of one pixel's weighted samples: the weights' sums with signed and with absolute
/// weights, the values' and variances' sums with one of them (the signed weights, or `|w|`
/// after [`Accumulator::clear_sums`] where [`Accumulator::cancels`]).
///
/// The sums with `|w|` are needed only where the signed weights cancel, so they are formed
/// only there, by a second pass over the pixel's samples in the same order: every sum is the
/// one a single pass forming both would give, bit for bit.
struct Accumulator {
    den: [f64; 2],
    own: [f64; 2],
    num: Vec<f64>,
    var: Vec<f64>,
    /// Whether `num` and `var` hold the `|w|` sums.
    absolute: bool,
}

impl Accumulator {
    fn new(channels: usize) -> Self {
        Self {
            den: [0.0; 2],
            own: [0.0; 2],
            num: vec![0.0; channels],
            var: vec![0.0; channels],
            absolute: false,
        }
    }

    fn clear(&mut self) {
        self.den = [0.0; 2];
        self.own = [0.0; 2];
        self.absolute = false;
        self.clear_sums();
    }

    /// Empties the values' and variances' sums for a pass with `|w|`.
    fn clear_sums(&mut self) {
        self.num.iter_mut().for_each(|v| *v = 0.0);
        self.var.iter_mut().for_each(|v| *v = 0.0);
        self.absolute = true;
    }

    /// Adds a sample with weight `wt` and values `values` (per channel); `mine` when it lies
    /// in the pixel itself, `s2` the variance `s²_{Q,c}` per channel of one sample of its
    /// pixel `Q`.
    #[inline]
    fn add(&mut self, wt: f64, mine: bool, values: &[f64], s2: &[f64]) {
        for (k, wk) in [wt, wt.abs()].into_iter().enumerate() {
            self.den[k] += wk;
            if mine {
                self.own[k] += wk;
            }
        }
        self.add_sums(wt, values, s2);
    }

    /// Adds a sample with weight `wk` to the values' and variances' sums alone.
    #[inline]
    fn add_sums(&mut self, wk: f64, values: &[f64], s2: &[f64]) {
        let w2 = wk * wk;
        for (((n, v), value), s) in self
            .num
            .iter_mut()
            .zip(self.var.iter_mut())
            .zip(values)
            .zip(s2)
        {
            *n += wk * value;
            *v += w2 * s;
        }
    }

    /// Whether the signed weights cancel, `|sum w| <= CANCELLATION_RATIO sum |w|`, so that
    /// the pixel is averaged with `|w|`.
    fn cancels(&self) -> bool {
        self.den[0].abs() <= CANCELLATION_RATIO * self.den[1]
    }

    /// Writes `F_P` and `Var F_P` per channel into `value` and `variance`, and returns
    /// `A_P`, with `|w|` where the signed weights cancel.
    fn finish(&self, value: &mut [f64], variance: &mut [f64]) -> f64 {
        let k = usize::from(self.cancels());
        debug_assert_eq!(k == 1, self.absolute, "the sums' weights match the choice");
        let den = self.den[k];
        for ((out, var), (n, v)) in value
            .iter_mut()
            .zip(variance.iter_mut())
            .zip(self.num.iter().zip(&self.var))
        {
            *out = n / den;
            *var = v / (den * den);
        }
        self.own[k] / den
    }
}

/// `SURE_P = sum_c (F_{P,c} - m_{P,c})² + sigma²_{P,c} (2 A_P - 1)` of one candidate, with the
/// box pixels `mean` (per channel).
pub fn sure(candidate: &FilmCandidate, mean: &[Vec<f64>], noise: &PixelNoise) -> Vec<f64> {
    let pixels = candidate.own_weight.len();
    (0..pixels)
        .map(|p| {
            let a = candidate.own_weight[p];
            (0..mean.len())
                .map(|c| {
                    let d = candidate.image.channels[c][p] - mean[c][p];
                    d * d + noise.pixel_variance(c, p) * (2.0 * a - 1.0)
                })
                .sum()
        })
        .collect()
}

/// The means of `values` (`width x height`, row-major) over the `(2 half + 1)²` window around
/// each pixel, clipped at the borders: [`window_sum`] over the window's pixel count.
pub fn window_mean(values: &[f64], width: usize, height: usize, half: usize) -> Vec<f64> {
    let area = window_sum(&vec![1.0; values.len()], width, height, half);
    window_sum(values, width, height, half)
        .iter()
        .zip(&area)
        .map(|(s, a)| s / a)
        .collect()
}

/// The sums of `values` (`width x height`, row-major) over the `(2 half + 1)²` window around each
/// pixel, clipped at the borders (a summed-area table).
pub fn window_sum(values: &[f64], width: usize, height: usize, half: usize) -> Vec<f64> {
    let mut table = vec![0.0; (width + 1) * (height + 1)];
    for y in 0..height {
        let mut row = 0.0;
        for x in 0..width {
            row += values[y * width + x];
            table[(y + 1) * (width + 1) + x + 1] = table[y * (width + 1) + x + 1] + row;
        }
    }
    let at = |x: usize, y: usize| table[y * (width + 1) + x];
    let mut out = vec![0.0; width * height];
    for y in 0..height {
        let (y0, y1) = (y.saturating_sub(half), (y + half + 1).min(height));
        for x in 0..width {
            let (x0, x1) = (x.saturating_sub(half), (x + half + 1).min(width));
            out[y * width + x] = at(x1, y1) - at(x0, y1) - at(x1, y0) + at(x0, y0);
        }
    }
    out
}

/// The films chosen per pixel and the image they make.
#[derive(Debug, Clone)]
pub struct FilmChoice {
    /// The pixels, each from its chosen film.
    pub image: PixelImage,
    /// The index into `films` of each pixel's film.
    pub choice: Vec<usize>,
    /// The candidate films.
    pub films: Vec<FilmFilterKind>,
    /// `Var` of each output pixel per channel (the chosen film's).
    pub variance: Vec<Vec<f64>>,
    /// `A_P` of each pixel's chosen film: the weight of the pixel's own samples, the
    /// derivative of the output pixel in the pixel's own mean.
    pub own_weight: Vec<f64>,
    /// The estimated risk (window-averaged SURE per pixel, summed over channels) of the choice
    /// and of each film alone, per pixel averaged over the image.
    pub risk: FilmRisks,
    /// The chosen film's SURE over each pixel's window, per pixel of the window: the window
    /// sum of `SURE_Q` (summed over channels) divided by the pixels `Q` in the window (fewer
    /// at the borders). An estimate of the chosen pixels' mean squared error near `P`.
    pub window_risk: Vec<f64>,
}

/// The mean estimated risk per pixel of the choice and of each film alone.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FilmRisks {
    /// The choice.
    pub chosen: f64,
    /// Each film alone, in the order of the films.
    pub films: Vec<(FilmFilterKind, f64)>,
}

impl FilmChoice {
    /// Pixels per film, in the order of `films`.
    pub fn counts(&self) -> Vec<(FilmFilterKind, usize)> {
        self.films
            .iter()
            .enumerate()
            .map(|(k, &f)| (f, self.choice.iter().filter(|&&c| c == k).count()))
            .collect()
    }
}

/// Each pixel's film among `films` by the least SURE over its `(2 half + 1)²` window; `mean`
/// is the box pixels per channel (every pixel with a sample).
pub fn choose_films(
    samples: &ImageSamples,
    bins: &PixelBins,
    noise: &PixelNoise,
    mean: &[Vec<f64>],
    films: &[FilmFilterKind],
    half: usize,
) -> FilmChoice {
    let plane = samples.plane();
    let (w, h) = (plane.width(), plane.height());
    let candidates: Vec<FilmCandidate> = films
        .iter()
        .map(|&f| film_candidate(samples, bins, noise, f))
        .collect();
    let sures: Vec<Vec<f64>> = candidates.iter().map(|c| sure(c, mean, noise)).collect();
    let windows: Vec<Vec<f64>> = sures.iter().map(|s| window_sum(s, w, h, half)).collect();
    let choice: Vec<usize> = (0..plane.pixels())
        .map(|p| {
            (0..films.len())
                .min_by(|&a, &b| windows[a][p].total_cmp(&windows[b][p]))
                .unwrap_or(0)
        })
        .collect();
    let area = window_sum(&vec![1.0; plane.pixels()], w, h, half);
    let window_risk: Vec<f64> = choice
        .iter()
        .enumerate()
        .map(|(p, &k)| windows[k][p] / area[p])
        .collect();
    let channels = samples.channels();
    let mut image = PixelImage::zeros(plane, channels);
    let mut variance = vec![vec![0.0; plane.pixels()]; channels];
    let mut own_weight = vec![0.0; plane.pixels()];
    for (p, &k) in choice.iter().enumerate() {
        let chosen = &candidates[k];
        own_weight[p] = chosen.own_weight[p];
        for (c, (out, var)) in image.channels.iter_mut().zip(&mut variance).enumerate() {
            out[p] = chosen.image.channels[c][p];
            var[p] = chosen.variance[c][p];
        }
    }
    let n = plane.pixels() as f64;
    let chosen = choice
        .iter()
        .enumerate()
        .map(|(p, &k)| sures[k][p])
        .sum::<f64>()
        / n;
    let risk = FilmRisks {
        chosen,
        films: films
            .iter()
            .zip(&sures)
            .map(|(&f, s)| (f, s.iter().sum::<f64>() / n))
            .collect(),
    };
    FilmChoice {
        image,
        choice,
        films: films.to_vec(),
        variance,
        own_weight,
        risk,
        window_risk,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The candidates from the cached 1D factors equal, bit for bit, the same sums over the
    /// direct gather (`eval_2d` per sample and pixel, naive loops): `F_P`, `A_P` and
    /// `Var F_P` of every pixel for all five films, on random positions with border samples,
    /// a plane taller than one band; the reference forms the signed and the `|w|` sums in one
    /// pass and keeps the `|w|` ones where the signed weights cancel. Compared by their bits
    /// (`0 / 0` where the box has no sample, the same NaN both ways).
    #[test]
    fn candidates_equal_the_direct_gather_bit_for_bit() {
        use crate::image::film_weights::test_support::{direct_pixel, random_samples};
        let (w, h) = (23, 41);
        let samples = random_samples(w, h, 4 * w * h, 7);
        let bins = PixelBins::new(&samples);
        let noise = PixelNoise::new(&samples, &bins).unwrap();
        for film in FilmFilterKind::ALL {
            let candidate = film_candidate(&samples, &bins, &noise, film);
            let filter = film.build();
            for py in 0..h {
                for px in 0..w {
                    let p = py * w + px;
                    let mut visits = vec![];
                    direct_pixel(&samples, &bins, filter.as_ref(), (px, py), |i, q, wt| {
                        visits.push((i, q, wt))
                    });
                    // One pass forming the signed and the `|w|` sums, in visit order.
                    let mut den = [0.0; 2];
                    let mut own = [0.0; 2];
                    let mut num = [vec![0.0; samples.channels()], vec![0.0; samples.channels()]];
                    let mut var = num.clone();
                    for &(i, q, wt) in &visits {
                        for (k, wk) in [wt, wt.abs()].into_iter().enumerate() {
                            den[k] += wk;
                            if q == p {
                                own[k] += wk;
                            }
                            for c in 0..samples.channels() {
                                num[k][c] += wk * samples.values()[c][i];
                                var[k][c] += wk * wk * noise.sample_variance(c, q);
                            }
                        }
                    }
                    let k = usize::from(den[0].abs() <= CANCELLATION_RATIO * den[1]);
                    // The bits (a pixel without samples in reach is 0 / 0 both ways).
                    let same = |x: f64, y: f64| {
                        assert_eq!(x.to_bits(), y.to_bits(), "{film} ({px}, {py}): {x} {y}")
                    };
                    same(candidate.own_weight[p], own[k] / den[k]);
                    for c in 0..samples.channels() {
                        same(candidate.image.channels[c][p], num[k][c] / den[k]);
                        same(candidate.variance[c][p], var[k][c] / (den[k] * den[k]));
                    }
                }
            }
        }
    }

    #[test]
    fn window_sums_match_the_direct_sum() {
        let (w, h) = (7, 5);
        let v: Vec<f64> = (0..w * h).map(|i| ((i * 37) % 11) as f64 - 3.0).collect();
        let s = window_sum(&v, w, h, 2);
        for y in 0..h {
            for x in 0..w {
                let mut direct = 0.0;
                for yy in y.saturating_sub(2)..(y + 3).min(h) {
                    for xx in x.saturating_sub(2)..(x + 3).min(w) {
                        direct += v[yy * w + xx];
                    }
                }
                // Sums of small integers: exact.
                assert_eq!(s[y * w + x], direct);
            }
        }
    }
}
