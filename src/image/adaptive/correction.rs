//! The fit as a control variate: box pixels of the tree fit plus the mean residual of the
//! samples in each pixel.
//!
//! For a pixel `P` with samples `i in P`, `f~` the tree fit, the estimate
//!
//! `I_P = int_P f~ + (|P| / n_P) sum_{i in P} (f_i - f~(x_i))`
//!
//! is the box filter's estimate of `int_P f` with the fit as a control variate: where the fit
//! resolves the scene the residuals vanish and `I_P` is the fit's pixel; where it cannot
//! (detail below the depth limit: a sub-pixel line, an edge inside a finest cell fitted by two
//! samples, where least squares nearly interpolates and rings) the residual mean of the
//! stratified samples restores it as a box filter would, with the variance of the residual
//! instead of that of `f`. Under noise of deviation `sigma` the mean adds noise
//! `sigma / sqrt(n_P)`, undoing the least-squares smoothing: the correction is applied only
//! where it is significant, `|mean r| > z sigma / sqrt(n_P)` (norm over the channels against
//! `z sqrt(ch)`), with `sigma` the noise test's estimate from the same residuals.

use super::fit::TreeFit;
use super::significance::residuals;
use super::tree::QuadTree;
use super::AdaptiveError;

/// Box pixels of `fit` on `tree` plus the significant mean residual of the samples in each
/// pixel (`z` standard errors of the residual mean at noise `sigma`; `sigma = 0` or `z = 0`:
/// every pixel with a sample is corrected). Returns the channels and the pixels corrected.
pub fn residual_corrected_pixels(
    tree: &QuadTree,
    fit: &TreeFit,
    xs: &[f64],
    ys: &[f64],
    values: &[Vec<f64>],
    sigma: f64,
    z: f64,
) -> Result<(Vec<Vec<f64>>, usize), AdaptiveError> {
    let mut pixels = fit.box_pixels(tree)?;
    let coef: Vec<&[f64]> = fit.coefficients.iter().map(|c| c.as_slice()).collect();
    let vals: Vec<&[f64]> = values.iter().map(|v| v.as_slice()).collect();
    let r = residuals(tree, &coef, xs, ys, &vals);
    let (w, h) = (tree.basis().width(), tree.basis().height());
    let ch = r.len();
    let mut sum = vec![0.0; w * h * ch];
    let mut count = vec![0usize; w * h];
    for (i, (&x, &y)) in xs.iter().zip(ys).enumerate() {
        let px = (x.floor() as usize).min(w - 1);
        let py = (y.floor() as usize).min(h - 1);
        let p = py * w + px;
        count[p] += 1;
        for (c, rc) in r.iter().enumerate() {
            sum[p * ch + c] += rc[i];
        }
    }
    let mut corrected = 0;
    for (p, &n) in count.iter().enumerate() {
        if n == 0 {
            continue;
        }
        let mean: Vec<f64> = (0..ch).map(|c| sum[p * ch + c] / n as f64).collect();
        let norm = mean.iter().map(|m| m * m).sum::<f64>().sqrt();
        if norm > z * sigma * (ch as f64 / n as f64).sqrt() {
            for (c, m) in mean.iter().enumerate() {
                pixels[c][p] += m;
            }
            corrected += 1;
        }
    }
    Ok((pixels, corrected))
}
