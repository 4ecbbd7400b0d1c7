//! The equivalent reconstruction filter of a pixel: the weight each sample receives in that
//! pixel's value.
//!
//! The least-squares fit `c = G^{-1} K^T f` (`G = K^T K`, `K_i` the row of single-scale tensor
//! values at sample `i`) gives pixel `(X, Y)` the value `b^T c` with
//! `b = B_y[Y, :] (x) B_x[X, :]` (index `ky * nx + kx`, [`super::pixels`]). Hence
//!
//! `value(X, Y) = sum_i w_i f_i`,  `w_i = K_i . z`,  `G z = b`:
//!
//! one solve with the fit's factorization, then one sparse dot product per sample. `sum_i w_i = 1`
//! when constants are reproduced (the pixel has area 1), and `sum_i w_i (x_i, y_i)` is the pixel
//! centre when linear functions are (`p >= 2`): the filter rkwave applied, to set beside the
//! film filters.

use serde::Serialize;

use super::fit::ImageFit;
use super::pixels::{PixelError, PixelIntegrals};

/// The normal equations of a least-squares fit in a single-scale tensor space: what the
/// equivalent filter needs from a solver.
pub trait NormalEquations {
    /// Number of unknowns `nx * ny`.
    fn unknowns(&self) -> usize;
    /// Number of samples `m`.
    fn samples(&self) -> usize;
    /// `z` with `G z = b` (`G = K^T K`).
    fn solve_normal(&self, b: &[f64]) -> Vec<f64>;
    /// `K z`: for every sample `i`, `K_i . z` (`K_i` the tensor single-scale values at sample
    /// `i`, index `ky * nx + kx`).
    fn apply_rows(&self, z: &[f64]) -> Vec<f64>;
}

/// The weight one sample receives in one pixel's value.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SampleWeight {
    /// Sample index.
    pub index: usize,
    /// Its x position.
    pub x: f64,
    /// Its y position.
    pub y: f64,
    /// Its weight `w_i` (`I(X, Y) = sum_i w_i f_i`).
    pub weight: f64,
}

/// The weights of every sample in one pixel's value.
#[derive(Clone, Debug, Serialize)]
pub struct EquivalentFilter {
    /// Pixel column `X`.
    pub x: usize,
    /// Pixel row `Y`.
    pub y: usize,
    /// `w_i` per sample, in sample order.
    pub weights: Vec<f64>,
    /// `sum_i w_i` (1 when constants are reproduced).
    pub total: f64,
}

/// `w = K z`, `G z = B_y[Y, :] (x) B_x[X, :]` (module docs).
pub fn equivalent_filter(
    normal: &dyn NormalEquations,
    by: &PixelIntegrals,
    bx: &PixelIntegrals,
    x: usize,
    y: usize,
) -> Result<EquivalentFilter, PixelError> {
    let (nx, ny) = (bx.functions(), by.functions());
    if normal.unknowns() != nx * ny {
        return Err(PixelError::CoefficientLength {
            got: normal.unknowns(),
            expected: nx * ny,
            ny,
            nx,
        });
    }
    if x >= bx.pixels() || y >= by.pixels() {
        return Err(PixelError::PixelOutside {
            x,
            y,
            width: bx.pixels(),
            height: by.pixels(),
        });
    }
    let b = pixel_functional(by, bx, x, y);
    let z = normal.solve_normal(&b);
    let weights = normal.apply_rows(&z);
    let total = weights.iter().sum();
    Ok(EquivalentFilter {
        x,
        y,
        weights,
        total,
    })
}

/// `b = B_y[Y, :] (x) B_x[X, :]` as a dense vector of length `ny * nx`, index `ky * nx + kx`:
/// the pixel value of single-scale coefficients `c` is `b . c`.
pub fn pixel_functional(by: &PixelIntegrals, bx: &PixelIntegrals, x: usize, y: usize) -> Vec<f64> {
    let nx = bx.functions();
    let mut b = vec![0.0; nx * by.functions()];
    let rx = bx.matrix().outer_view(x).expect("pixel column checked");
    let ry = by.matrix().outer_view(y).expect("pixel row checked");
    for (ky, vy) in ry.iter() {
        for (kx, vx) in rx.iter() {
            b[ky * nx + kx] = vy * vx;
        }
    }
    b
}

/// An [`ImageFit`] together with the samples it was fitted to: its normal equations for the
/// equivalent filter (`G` solved with the fit's own factor or CG, rows `K_i` evaluated from the
/// tensor basis).
pub struct FitNormalEquations<'a> {
    fit: &'a ImageFit,
    xs: &'a [f64],
    ys: &'a [f64],
}

impl<'a> FitNormalEquations<'a> {
    /// The fit and its sample positions (pixel units; the same samples, in the same order, as
    /// the fit used).
    pub fn new(fit: &'a ImageFit, xs: &'a [f64], ys: &'a [f64]) -> Result<Self, PixelError> {
        let basis = fit.basis();
        if xs.len() != ys.len() {
            return Err(PixelError::SampleLengths {
                xs: xs.len(),
                ys: ys.len(),
            });
        }
        if let Some(i) = (0..xs.len()).find(|&i| basis.check(xs[i], ys[i]).is_err()) {
            return Err(PixelError::SampleOutside {
                index: i,
                x: xs[i],
                y: ys[i],
            });
        }
        Ok(Self { fit, xs, ys })
    }
}

impl NormalEquations for FitNormalEquations<'_> {
    fn unknowns(&self) -> usize {
        self.fit.basis().len()
    }
    fn samples(&self) -> usize {
        self.xs.len()
    }
    fn solve_normal(&self, b: &[f64]) -> Vec<f64> {
        self.fit
            .solve_normal(b)
            .expect("b has nx * ny entries: checked by equivalent_filter")
    }
    fn apply_rows(&self, z: &[f64]) -> Vec<f64> {
        use rayon::prelude::*;
        let basis = self.fit.basis();
        self.xs
            .par_chunks(4096)
            .zip(self.ys.par_chunks(4096))
            .flat_map_iter(|(cx, cy)| {
                let mut ev = basis.evaluator();
                let mut row = Vec::new();
                cx.iter()
                    .zip(cy)
                    .map(|(&x, &y)| {
                        ev.eval_into(x, y, &mut row)
                            .expect("positions checked in FitNormalEquations::new");
                        row.iter().map(|v| v.value * z[v.index]).sum::<f64>()
                    })
                    .collect::<Vec<f64>>()
            })
            .collect()
    }
}
