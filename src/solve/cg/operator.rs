//! An assembled sparse symmetric matrix as a [`SymmetricOperator`]: `q_c = A p_c` for every
//! vector in one pass over the rows of `A` (CSR, both triangles), each entry of `q` summed
//! over its row in index order.

use rayon::prelude::*;
use sprs::CsMat;

use super::SymmetricOperator;
use crate::solve::sparse::raw;
use crate::solve::vectors::deinterleave;

/// `A` held as CSR (both triangles stored).
#[derive(Clone, Copy, Debug)]
pub struct SparseOperator<'a> {
    a: &'a CsMat<f64>,
}

impl<'a> SparseOperator<'a> {
    /// The operator of the square CSR matrix `a` (both triangles).
    pub fn new(a: &'a CsMat<f64>) -> Self {
        Self { a }
    }
}

impl SymmetricOperator for SparseOperator<'_> {
    fn dim(&self) -> usize {
        self.a.rows()
    }
    fn apply(&self, p: &[&[f64]], q: &mut [Vec<f64>]) {
        let (ap, ai, ad) = raw(self.a);
        let k = p.len();
        let mut rows = vec![0.0; self.a.rows() * k];
        rows.par_chunks_mut(k.max(1))
            .enumerate()
            .for_each(|(a, acc)| {
                for t in ap[a]..ap[a + 1] {
                    let (j, v) = (ai[t], ad[t]);
                    for (s, x) in acc.iter_mut().zip(p) {
                        *s += v * x[j];
                    }
                }
            });
        for (q, out) in q.iter_mut().zip(deinterleave(&rows, k)) {
            *q = out;
        }
    }
}
