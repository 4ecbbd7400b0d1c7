//! Pixels of a reconstruction: a reconstruction `f(x, y) = sum C[ky, kx] phi_ky(y) phi_kx(x)` in
//! `V_Jx (x) V_Jy` is a function, and a pixel value is its integral against a pixel filter.
//!
//! Per axis, for `W` pixels of width 1 on `[0, W]` (pixel `X` is `[X, X + 1]`, centre
//! `X + 1/2`), the sparse `W x 2^J` matrix
//!
//! `B[X, k] = int phi_{J,k}(x) w(x - X - 1/2) dx / int w(x - X - 1/2) dx`,
//!
//! both integrals over `[0, W]` (a filter reaching past the image border is renormalized over
//! the part inside, as weighted splatting does). For the box filter (the default, the
//! anti-aliased image) `B[X, k] = int_X^{X+1} phi_{J,k}`, exact to rounding
//! ([`crate::basis::integral`]). A separable filter gives the image
//!
//! `I = B_y C B_x^T`  (per channel; `C` is `ny x nx`, index `ky * nx + kx`).
//!
//! Film filters: the filter is split at its own breakpoints and, if it is not a polynomial of
//! degree `<= 3` between them, into sub-cells of width `h` ([`FilterQuadrature::sub_cell`]); on
//! each piece it is replaced by its cubic interpolant at the four Chebyshev nodes, which is
//! integrated against `phi_{J,k}` exactly (moments of degree 3). Box, triangle and Mitchell are
//! cubic on their pieces, so their rows are exact to rounding; for the Gaussian and Lanczos the
//! error of a row is at most `max |w - P w| int |phi_{J,k}| / int w`, and `max |w - P w|` is
//! measured on every sub-cell and reported ([`PixelIntegrals::weight_error`]). The same
//! interpolant gives the normalization, so constants stay exact.

use std::collections::HashMap;

use serde::Serialize;
use sprs::CsMat;
use thiserror::Error;

use super::filters::FilmFilter;
use crate::basis::integral::{Antiderivative, ScalingIntegrals};
use crate::basis::{BasisError, CdvBasis};

/// Why pixel integrals could not be formed.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum PixelError {
    /// The basis lives on another interval than `[0, W]`.
    #[error(
        "the basis domain [{a}, {b}] is not the pixel axis [0, {pixels}]: build the axis basis \
         on [0, W] with W = {pixels} pixels"
    )]
    DomainMismatch {
        /// Left end of the basis domain.
        a: f64,
        /// Right end of the basis domain.
        b: f64,
        /// Number of pixels on the axis.
        pixels: usize,
    },
    /// No pixels.
    #[error("an axis of 0 pixels has no pixel integrals: give at least one pixel")]
    NoPixels,
    /// The coefficient array does not have `ny * nx` entries.
    #[error(
        "{got} single-scale coefficients given for a {ny} x {nx} tensor space: give ny * nx = \
         {expected} coefficients, index ky * nx + kx"
    )]
    CoefficientLength {
        /// Entries given.
        got: usize,
        /// `ny * nx`.
        expected: usize,
        /// Functions on the y axis.
        ny: usize,
        /// Functions on the x axis.
        nx: usize,
    },
    /// The filter weight inside the image vanishes for a pixel (negative lobes cancel).
    #[error(
        "the film filter's weight inside the image is {weight:e} for pixel {pixel}: use a \
         filter without cancelling lobes near the border or a larger image"
    )]
    VanishingWeight {
        /// The pixel index on the axis.
        pixel: usize,
        /// `int w` over the part of the support inside the image.
        weight: f64,
    },
    /// A sub-cell width that is not positive or not finite, or above one pixel.
    #[error("sub-cell width {h} is not in (0, 1]: choose a width such as 1/32 pixel")]
    SubCell {
        /// The width given.
        h: f64,
    },
    /// A pixel outside the image.
    #[error(
        "pixel ({x}, {y}) is outside the {width} x {height} image: give 0 <= X < W, 0 <= Y < H"
    )]
    PixelOutside {
        /// Column given.
        x: usize,
        /// Row given.
        y: usize,
        /// Image width.
        width: usize,
        /// Image height.
        height: usize,
    },
    /// Sample position arrays of different lengths.
    #[error("{xs} x positions but {ys} y positions: give one (x, y) per sample")]
    SampleLengths {
        /// Length of `xs`.
        xs: usize,
        /// Length of `ys`.
        ys: usize,
    },
    /// A sample outside the image.
    #[error(
        "sample {index} at ({x}, {y}) is outside the image: give positions within [0, W] x [0, H]"
    )]
    SampleOutside {
        /// Sample index.
        index: usize,
        /// Its x.
        x: f64,
        /// Its y.
        y: f64,
    },
    /// The basis could not be built or a position was outside it.
    #[error(transparent)]
    Basis(#[from] BasisError),
}

/// How film-filter rows are integrated (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FilterQuadrature {
    /// Width `h` of the sub-cells on which a non-polynomial filter is replaced by its cubic
    /// interpolant, in pixels: the interpolation error falls like `h^4`, the cost grows like
    /// `1 / h`. Default `1/32`.
    pub sub_cell: f64,
}

impl Default for FilterQuadrature {
    fn default() -> Self {
        Self {
            sub_cell: 1.0 / 32.0,
        }
    }
}

/// The sparse `W x 2^J` matrix `B` of one axis (module docs).
#[derive(Clone, Debug)]
pub struct PixelIntegrals {
    matrix: CsMat<f64>,
    weight_error: f64,
}

impl PixelIntegrals {
    /// Box filter: `B[X, k] = int_X^{X+1} phi_{J,k}`, `J = basis.coarse()`, exact to rounding.
    /// The basis must live on `[0, pixels]`.
    pub fn new(basis: &CdvBasis, pixels: usize) -> Result<Self, PixelError> {
        check_axis(basis, pixels)?;
        let ints = ScalingIntegrals::new(basis, 0)?;
        let xs: Vec<f64> = (0..=pixels).map(|i| i as f64).collect();
        let f = ints.antiderivatives(&xs)?;
        let rows: Vec<Vec<(usize, f64)>> = (0..pixels)
            .map(|i| {
                ints.integrals_between(&f[i], &f[i + 1])
                    .into_iter()
                    .map(|v| (v.index, v.value))
                    .collect()
            })
            .collect();
        Ok(Self {
            matrix: csr(&rows, ints.size()),
            weight_error: 0.0,
        })
    }

    /// A film filter centred on each pixel: `B[X, k] = int phi_{J,k}(x) w(x - X - 1/2) dx /
    /// int w`, both over `[0, W]` (module docs for the quadrature and its error).
    pub fn filtered(
        basis: &CdvBasis,
        pixels: usize,
        filter: &dyn FilmFilter,
        quadrature: FilterQuadrature,
    ) -> Result<Self, PixelError> {
        check_axis(basis, pixels)?;
        let h = quadrature.sub_cell;
        if !(h > 0.0 && h <= 1.0) {
            return Err(PixelError::SubCell { h });
        }
        let ints = ScalingIntegrals::new(basis, 3)?;
        let r = filter.radius();
        // Breakpoints relative to the centre.
        let mut breaks: Vec<f64> = match filter.cubic_pieces() {
            Some(b) => b.into_iter().filter(|x| x.abs() < r).collect(),
            None => {
                let n = (2.0 * r / h).ceil() as usize;
                (1..n)
                    .map(|i| -r + i as f64 * (2.0 * r / n as f64))
                    .collect()
            }
        };
        breaks.insert(0, -r);
        breaks.push(r);
        breaks.sort_by(f64::total_cmp);
        breaks.dedup();
        let mut cache: HashMap<u64, Antiderivative> = HashMap::new();
        let width = pixels as f64;
        let mut weight_error: f64 = 0.0;
        let mut rows = Vec::with_capacity(pixels);
        for pixel in 0..pixels {
            let centre = pixel as f64 + 0.5;
            let mut row: HashMap<usize, f64> = HashMap::new();
            let mut norm = 0.0;
            for piece in breaks.windows(2) {
                let a = (centre + piece[0]).clamp(0.0, width);
                let b = (centre + piece[1]).clamp(0.0, width);
                if b <= a {
                    continue;
                }
                let (coef, err) = cubic_interpolant(|x| filter.eval(x - centre), a, b);
                weight_error = weight_error.max(err);
                norm += (b - a) * (0..4).map(|d| coef[d] / (d + 1) as f64).sum::<f64>();
                for x in [a, b] {
                    if let std::collections::hash_map::Entry::Vacant(e) = cache.entry(x.to_bits()) {
                        e.insert(ints.antiderivatives(&[x])?.remove(0));
                    }
                }
                let fa = &cache[&a.to_bits()];
                let fb = &cache[&b.to_bits()];
                for (k, m) in ints.moments_between(a, b, fa, fb) {
                    let v: f64 = (0..4).map(|d| coef[d] * m[d]).sum();
                    *row.entry(k).or_insert(0.0) += v;
                }
            }
            if norm.abs() < 1e-12 * r {
                return Err(PixelError::VanishingWeight {
                    pixel,
                    weight: norm,
                });
            }
            let mut row: Vec<(usize, f64)> = row.into_iter().map(|(k, v)| (k, v / norm)).collect();
            row.sort_by_key(|e| e.0);
            rows.push(row);
        }
        Ok(Self {
            matrix: csr(&rows, ints.size()),
            weight_error,
        })
    }

    /// The sparse matrix `B` (CSR, `W x 2^J`).
    pub fn matrix(&self) -> &CsMat<f64> {
        &self.matrix
    }
    /// Number of pixels `W`.
    pub fn pixels(&self) -> usize {
        self.matrix.rows()
    }
    /// Number of functions `2^J`.
    pub fn functions(&self) -> usize {
        self.matrix.cols()
    }
    /// `max |w - P w|` over the pieces (the filter against its cubic interpolants, measured at
    /// 33 points per piece): `0` up to rounding for the box and for piecewise-cubic filters.
    pub fn weight_error(&self) -> f64 {
        self.weight_error
    }

    /// The pixel values of one axis from 1D single-scale coefficients: `B c`.
    pub fn apply(&self, c: &[f64]) -> Vec<f64> {
        self.matrix
            .outer_iterator()
            .map(|row| row.iter().map(|(k, v)| v * c[k]).sum())
            .collect()
    }
}

/// The image `I = B_y C B_x^T` of single-scale tensor coefficients `C` (`ny x nx`, index
/// `ky * nx + kx`), row-major `H x W` (index `Y * W + X`).
pub fn filter_image(
    by: &PixelIntegrals,
    bx: &PixelIntegrals,
    coefficients: &[f64],
) -> Result<Vec<f64>, PixelError> {
    let (nx, ny) = (bx.functions(), by.functions());
    if coefficients.len() != nx * ny {
        return Err(PixelError::CoefficientLength {
            got: coefficients.len(),
            expected: nx * ny,
            ny,
            nx,
        });
    }
    let w = bx.pixels();
    // T = C B_x^T (ny x W), then I = B_y T.
    let mut t = vec![0.0; ny * w];
    for ky in 0..ny {
        let c = &coefficients[ky * nx..(ky + 1) * nx];
        let out = &mut t[ky * w..(ky + 1) * w];
        for (x, row) in bx.matrix.outer_iterator().enumerate() {
            out[x] = row.iter().map(|(k, v)| v * c[k]).sum();
        }
    }
    let mut image = vec![0.0; by.pixels() * w];
    for (y, row) in by.matrix.outer_iterator().enumerate() {
        let out = &mut image[y * w..(y + 1) * w];
        for (ky, v) in row.iter() {
            let src = &t[ky * w..(ky + 1) * w];
            for (o, s) in out.iter_mut().zip(src) {
                *o += v * s;
            }
        }
    }
    Ok(image)
}

/// The pixel filter applied to a reconstruction.
#[derive(Clone, Copy)]
pub enum PixelFilter<'a> {
    /// The box over each pixel (the anti-aliased image), exact to rounding.
    Box,
    /// A separable film filter on both axes (module docs for its accuracy).
    Film(&'a dyn FilmFilter, FilterQuadrature),
}

/// The pixels of a fitted image, one `H x W` row-major image per channel (index `Y * W + X`).
pub fn fit_pixels(
    fit: &super::fit::ImageFit,
    filter: PixelFilter<'_>,
) -> Result<Vec<Vec<f64>>, PixelError> {
    let basis = fit.basis();
    let (w, h) = (basis.width(), basis.height());
    let (bx, by) = match filter {
        PixelFilter::Box => (
            PixelIntegrals::new(fit.scale_x(), w)?,
            PixelIntegrals::new(fit.scale_y(), h)?,
        ),
        PixelFilter::Film(f, q) => (
            PixelIntegrals::filtered(fit.scale_x(), w, f, q)?,
            PixelIntegrals::filtered(fit.scale_y(), h, f, q)?,
        ),
    };
    fit.coefficients
        .iter()
        .map(|c| filter_image(&by, &bx, c))
        .collect()
}

fn check_axis(basis: &CdvBasis, pixels: usize) -> Result<(), PixelError> {
    if pixels == 0 {
        return Err(PixelError::NoPixels);
    }
    let d = basis.domain();
    if d.a() != 0.0 || d.b() != pixels as f64 {
        return Err(PixelError::DomainMismatch {
            a: d.a(),
            b: d.b(),
            pixels,
        });
    }
    Ok(())
}

fn csr(rows: &[Vec<(usize, f64)>], cols: usize) -> CsMat<f64> {
    let mut indptr = Vec::with_capacity(rows.len() + 1);
    let mut indices = Vec::new();
    let mut data = Vec::new();
    indptr.push(0);
    for row in rows {
        for &(k, v) in row {
            indices.push(k);
            data.push(v);
        }
        indptr.push(indices.len());
    }
    CsMat::new((rows.len(), cols), indptr, indices, data)
}

/// Monomial coefficients (in `u = (x - a)/(b - a)`) of the cubic interpolating `g` at the four
/// Chebyshev nodes of `[a, b]`, and `max |g - P|` measured at 33 equispaced points.
fn cubic_interpolant(g: impl Fn(f64) -> f64, a: f64, b: f64) -> ([f64; 4], f64) {
    let nodes: [f64; 4] = std::array::from_fn(|i| {
        0.5 - 0.5 * ((2 * i + 1) as f64 * std::f64::consts::PI / 8.0).cos()
    });
    let vals: [f64; 4] = std::array::from_fn(|i| g(a + (b - a) * nodes[i]));
    // Newton divided differences, then expansion into monomials.
    let mut dd = vals;
    for level in 1..4 {
        for i in (level..4).rev() {
            dd[i] = (dd[i] - dd[i - 1]) / (nodes[i] - nodes[i - level]);
        }
    }
    let mut coef = [0.0; 4];
    for i in (0..4).rev() {
        // coef <- coef * (u - nodes[i]) + dd[i]
        let mut next = [0.0; 4];
        for d in 0..4 {
            if d + 1 < 4 {
                next[d + 1] += coef[d];
            }
            next[d] -= nodes[i] * coef[d];
        }
        next[0] += dd[i];
        coef = next;
    }
    let err = (0..=32)
        .map(|i| {
            let u = i as f64 / 32.0;
            let p = coef[0] + u * (coef[1] + u * (coef[2] + u * coef[3]));
            (g(a + (b - a) * u) - p).abs()
        })
        .fold(0.0, f64::max);
    (coef, err)
}

impl PixelError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            PixelError::Basis(e) => e.kind(),
            PixelError::DomainMismatch { .. }
            | PixelError::NoPixels
            | PixelError::CoefficientLength { .. }
            | PixelError::VanishingWeight { .. }
            | PixelError::SubCell { .. }
            | PixelError::PixelOutside { .. }
            | PixelError::SampleLengths { .. }
            | PixelError::SampleOutside { .. } => crate::error::ErrorKind::InvalidInput,
        }
    }
}

crate::error::classified!(PixelError);
