//! The local-inversion preconditioner `M = K~ K~^T` of the 2D normal equations.
//!
//! `K[i, ky nx + kx] = phi_{Jx,kx}(x_i) phi_{Jy,ky}(y_i)` is built as a CSR matrix (one row
//! per sample, `(2p - 1)^2` entries inside the image) and handed to the generic
//! [`crate::solve::local_inversion`] (rings 0, Cholesky blocks): `K~ ≈ K^+`, so
//! `K~ K~^T ≈ K^+ K^{+T} = (K^T K)^{-1}`.

use rayon::prelude::*;
use sprs::CsMat;

use crate::basis::tensor::TensorBasis;
use crate::image::fit::error::ImageFitError;
use crate::solve::{local_inversion, LocalInversionParams, Solver};

/// The 2D single-scale kernel matrix `K` (`m x nx ny`, CSR); positions must lie in the image.
pub fn kernel_matrix_2d(
    basis: &TensorBasis,
    xs: &[f64],
    ys: &[f64],
) -> Result<CsMat<f64>, ImageFitError> {
    let rows: Vec<Vec<(usize, f64)>> = xs
        .par_chunks(4096)
        .zip(ys.par_chunks(4096))
        .map(|(cx, cy)| {
            let mut ev = basis.evaluator();
            let mut row = Vec::new();
            cx.iter()
                .zip(cy)
                .map(|(&x, &y)| {
                    ev.eval_into(x, y, &mut row)?;
                    Ok(row.iter().map(|v| (v.index, v.value)).collect())
                })
                .collect::<Result<Vec<_>, ImageFitError>>()
        })
        .collect::<Result<Vec<_>, _>>()?
        .into_iter()
        .flatten()
        .collect();
    let mut indptr = Vec::with_capacity(rows.len() + 1);
    indptr.push(0);
    let mut indices = Vec::new();
    let mut data = Vec::new();
    for r in &rows {
        for &(j, v) in r {
            indices.push(j);
            data.push(v);
        }
        indptr.push(indices.len());
    }
    Ok(CsMat::new((rows.len(), basis.len()), indptr, indices, data))
}

/// `K~` (CSC, `P x m`) and its CSR copy, for [`super::system::NormalSystem::solve_cg`].
pub fn local_preconditioner(
    basis: &TensorBasis,
    xs: &[f64],
    ys: &[f64],
) -> Result<(CsMat<f64>, CsMat<f64>), ImageFitError> {
    let k = kernel_matrix_2d(basis, xs, ys)?;
    let params = LocalInversionParams {
        rings: 0,
        solver: Solver::Cholesky,
        ..LocalInversionParams::default()
    };
    let li = local_inversion(&k, &params)?;
    let csr = li.pinv.to_csr();
    Ok((li.pinv, csr))
}
