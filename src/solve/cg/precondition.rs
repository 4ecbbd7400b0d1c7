//! Preconditioners `M^{-1}` of [`super::pcg`]:
//!
//! * [`Identity`]: `M = I` (plain conjugate gradients);
//! * [`Jacobi`]: `M = diag(A)`, given as its inverse: `z_i = r_i / A_ii` as `r_i d_i`,
//!   `d_i = 1 / A_ii` (0 pins a component the operator does not see);
//! * [`LocalInverse`]: `M^{-1} = K~ K~^T` with `K~ ≈ K^+` the local inversion of the kernel
//!   matrix ([`crate::solve::local_inversion`]): `K^+ K^{+T} = (K^T K)^{-1}`, so it
//!   approximates the inverse of the normal matrix `A = K^T K`;
//! * additive Schwarz, [`super::AdditiveSchwarz`].

use rayon::prelude::*;
use sprs::CsMat;

use super::Preconditioner;

/// `M = I`.
#[derive(Clone, Copy, Debug, Default)]
pub struct Identity;

impl Preconditioner for Identity {
    fn apply(&self, r: &[&[f64]], z: &mut [Vec<f64>]) {
        for (z, r) in z.iter_mut().zip(r) {
            z.copy_from_slice(r);
        }
    }
}

/// `M^{-1} = diag(d)`, `d_i = 1 / A_ii` (or 0).
#[derive(Clone, Copy, Debug)]
pub struct Jacobi<'a> {
    inverse_diagonal: &'a [f64],
}

impl<'a> Jacobi<'a> {
    /// The preconditioner `z_i = r_i d_i` of the inverse diagonal `d`.
    pub fn new(inverse_diagonal: &'a [f64]) -> Self {
        Self { inverse_diagonal }
    }
}

impl Preconditioner for Jacobi<'_> {
    fn apply(&self, r: &[&[f64]], z: &mut [Vec<f64>]) {
        z.par_iter_mut().zip(r).for_each(|(z, r)| {
            for ((z, r), d) in z.iter_mut().zip(*r).zip(self.inverse_diagonal) {
                *z = r * d;
            }
        });
    }
}

/// `M^{-1} = K~ K~^T` from the local inversion `K~` (`P x m`), held as CSC and CSR.
#[derive(Clone, Copy, Debug)]
pub struct LocalInverse<'a> {
    csc: &'a CsMat<f64>,
    csr: &'a CsMat<f64>,
}

impl<'a> LocalInverse<'a> {
    /// The preconditioner of `K~` given twice: CSC (`P x m`) and the same matrix as CSR.
    pub fn new(csc: &'a CsMat<f64>, csr: &'a CsMat<f64>) -> Self {
        Self { csc, csr }
    }

    /// `z = K~ (K~^T r)`: `u = K~^T r` (one dot product per sample, from the CSC columns),
    /// then `z = K~ u` (gathered from the CSR rows), each sum in index order.
    fn apply_one(&self, r: &[f64], z: &mut [f64]) {
        let (csc, csr) = (self.csc, self.csr);
        let m = csc.cols();
        let (ip, ix, dv) = (csc.indptr(), csc.indices(), csc.data());
        let ip = ip.raw_storage();
        let u: Vec<f64> = (0..m)
            .into_par_iter()
            .map(|i| (ip[i]..ip[i + 1]).map(|t| dv[t] * r[ix[t]]).sum())
            .collect();
        let (rp, rx, rv) = (csr.indptr(), csr.indices(), csr.data());
        let rp = rp.raw_storage();
        z.par_iter_mut().enumerate().for_each(|(a, za)| {
            *za = (rp[a]..rp[a + 1]).map(|t| rv[t] * u[rx[t]]).sum();
        });
    }
}

impl Preconditioner for LocalInverse<'_> {
    fn apply(&self, r: &[&[f64]], z: &mut [Vec<f64>]) {
        for (z, r) in z.iter_mut().zip(r) {
            self.apply_one(r, z);
        }
    }
}
