//! Image-plane samplers: where a renderer traces its camera rays.
//!
//! For `s` samples per pixel on a `W x H` plane (`m = s W H` positions in `[0, W] x [0, H]`):
//!
//! * [`Sampler::Uniform`]: `m` independent uniform positions over the whole plane;
//! * [`Sampler::Stratified`]: per pixel, a jittered `sx x sy` grid (`sx sy = s`, `sx` the
//!   largest divisor of `s` not above `sqrt(s)`, so 4 spp is 2 x 2), one uniform point per
//!   stratum;
//! * [`Sampler::Sobol`]: the first two dimensions of the Sobol sequence (van der Corput in
//!   base 2 and its Pascal-matrix companion, a (0, 2)-sequence) over the unit square, each
//!   dimension Owen-scrambled with the hash-based nested uniform scramble of Burley (2020,
//!   "Practical hash-based Owen scrambling"), then stretched to `[0, W] x [0, H]`.
//!
//! All three are seeded (PCG-64 from `rand_pcg`) and reproducible bit for bit.

use std::fmt;
use std::str::FromStr;

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::ImagePlane;

/// The image-plane sampler.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Sampler {
    /// Independent uniform positions.
    Uniform,
    /// Jittered strata per pixel.
    Stratified,
    /// Owen-scrambled Sobol (0, 2)-sequence.
    Sobol,
}

impl Sampler {
    /// Every sampler.
    pub const ALL: [Sampler; 3] = [Sampler::Uniform, Sampler::Stratified, Sampler::Sobol];

    /// The lowercase name.
    pub fn name(self) -> &'static str {
        match self {
            Sampler::Uniform => "uniform",
            Sampler::Stratified => "stratified",
            Sampler::Sobol => "sobol",
        }
    }

    /// `s` samples per pixel over `plane`, seeded: the positions `(xs, ys)`.
    pub fn positions(self, plane: ImagePlane, spp: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
        let (w, h) = (plane.width() as f64, plane.height() as f64);
        let m = spp * plane.pixels();
        let mut rng = Pcg64::seed_from_u64(seed);
        let mut xs = Vec::with_capacity(m);
        let mut ys = Vec::with_capacity(m);
        match self {
            Sampler::Uniform => {
                for _ in 0..m {
                    xs.push(rng.random::<f64>() * w);
                    ys.push(rng.random::<f64>() * h);
                }
            }
            Sampler::Stratified => {
                let (sx, sy) = strata(spp);
                for py in 0..plane.height() {
                    for px in 0..plane.width() {
                        for j in 0..sy {
                            for i in 0..sx {
                                let u: f64 = rng.random();
                                let v: f64 = rng.random();
                                xs.push(px as f64 + (i as f64 + u) / sx as f64);
                                ys.push(py as f64 + (j as f64 + v) / sy as f64);
                            }
                        }
                    }
                }
            }
            Sampler::Sobol => {
                let seeds: [u32; 3] = [rng.random(), rng.random(), rng.random()];
                for k in 0..m as u32 {
                    // Shuffle the index (Burley's index scrambling) so prefixes stay random.
                    let i = nested_uniform_scramble(k, seeds[0]);
                    let (u, v) = owen_sobol_02(i, [seeds[1], seeds[2]]);
                    xs.push(u * w);
                    ys.push(v * h);
                }
            }
        }
        (xs, ys)
    }
}

/// `sx x sy = spp` strata per pixel, `sx` the largest divisor of `spp` with `sx^2 <= spp`
/// (`sx <= sy`).
pub fn strata(spp: usize) -> (usize, usize) {
    let mut sx = (spp as f64).sqrt().floor() as usize;
    while sx > 1 && spp % sx != 0 {
        sx -= 1;
    }
    let sx = sx.max(1);
    (sx, spp / sx)
}

/// Point `i` of the Sobol (0, 2)-sequence in the unit square (van der Corput and its
/// Pascal-matrix companion), each coordinate Owen-scrambled (nested uniform scramble) with
/// its own seed of `seeds`. Every aligned block `[a 2^m, (a + 1) 2^m)` of indices is a
/// `(0, m, 2)`-net: one point in each elementary interval `2^-j x 2^-(m - j)`, and Owen
/// scrambling keeps nets.
pub fn owen_sobol_02(i: u32, seeds: [u32; 2]) -> (f64, f64) {
    (
        to_unit(nested_uniform_scramble(i.reverse_bits(), seeds[0])),
        to_unit(nested_uniform_scramble(sobol_second(i), seeds[1])),
    )
}

/// A 32-bit fraction `a / 2^32` as a float in `[0, 1)`.
fn to_unit(a: u32) -> f64 {
    a as f64 / 4_294_967_296.0
}

/// Second Sobol dimension (generator matrix the upper-triangular Pascal matrix mod 2), as a
/// 32-bit fraction.
fn sobol_second(mut i: u32) -> u32 {
    let mut v: u32 = 1 << 31;
    let mut r = 0;
    while i != 0 {
        if i & 1 == 1 {
            r ^= v;
        }
        i >>= 1;
        v ^= v >> 1;
    }
    r
}

/// Laine–Karras style hash permutation (Burley 2020, listing 1): an invertible map on `u32`
/// in which each bit depends only on lower bits.
fn laine_karras(mut x: u32, seed: u32) -> u32 {
    x = x.wrapping_add(seed);
    x ^= x.wrapping_mul(0x6c50_b47c);
    x ^= x.wrapping_mul(0xb82f_1e52);
    x ^= x.wrapping_mul(0xc7af_e638);
    x ^= x.wrapping_mul(0x8d22_f6e6);
    x
}

/// Nested uniform (Owen) scramble of a 32-bit fraction: reverse bits, permute so each bit
/// depends on the higher ones, reverse back.
fn nested_uniform_scramble(x: u32, seed: u32) -> u32 {
    laine_karras(x.reverse_bits(), seed).reverse_bits()
}

impl fmt::Display for Sampler {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A sampler name that is not `uniform`, `stratified` or `sobol`.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("unknown sampler `{name}`: expected one of uniform, stratified, sobol")]
pub struct ParseSamplerError {
    /// The name as given.
    pub name: String,
}

impl FromStr for Sampler {
    type Err = ParseSamplerError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Sampler::ALL
            .into_iter()
            .find(|k| k.name().eq_ignore_ascii_case(s.trim()))
            .ok_or_else(|| ParseSamplerError {
                name: s.to_string(),
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stratified_puts_one_sample_in_each_stratum() {
        let plane = ImagePlane::new(3, 2).unwrap();
        let (xs, ys) = Sampler::Stratified.positions(plane, 6, 7);
        assert_eq!(strata(6), (2, 3));
        assert_eq!(xs.len(), 36);
        // Each (pixel, stratum) cell of size 1/2 x 1/3 holds exactly one sample.
        let mut seen = std::collections::HashSet::new();
        for (x, y) in xs.iter().zip(&ys) {
            assert!(seen.insert(((x * 2.0).floor() as i64, (y * 3.0).floor() as i64)));
        }
        assert_eq!(seen.len(), 36);
    }

    #[test]
    fn sobol_is_stratified_in_elementary_intervals_and_seeded() {
        let plane = ImagePlane::new(16, 16).unwrap();
        // 256 points of a scrambled (0, 2)-sequence. The index shuffle maps indices 0..256 onto
        // one aligned block of 256 indices (its bits >= 8 depend only on input bits >= 8),
        // and any such block of a (0, 2)-sequence is a (0, 8, 2)-net; Owen scrambling keeps
        // nets. So every 1/16 x 1/16 box of the unit square holds exactly one point, and so
        // does every 1/256 x 1 box.
        let (xs, ys) = Sampler::Sobol.positions(plane, 1, 3);
        let mut boxes = std::collections::HashSet::new();
        let mut cols = std::collections::HashSet::new();
        for (x, y) in xs.iter().zip(&ys) {
            boxes.insert((x.floor() as i64, y.floor() as i64));
            cols.insert((x * 16.0).floor() as i64);
        }
        assert_eq!((boxes.len(), cols.len()), (256, 256));
        assert_eq!(Sampler::Sobol.positions(plane, 1, 3), (xs, ys));
        assert_ne!(
            Sampler::Sobol.positions(plane, 1, 4).0,
            Sampler::Sobol.positions(plane, 1, 3).0
        );
        let (ux, uy) = Sampler::Uniform.positions(plane, 2, 1);
        assert!(ux.iter().zip(&uy).all(|(x, y)| plane.contains(*x, *y)));
    }
}
