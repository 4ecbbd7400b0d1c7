//! Vectors of several channels: the dot product `a . b = sum_j a_j b_j` summed in index
//! order, and the interleaved layout `v[j k + c] = v_c[j]` of `k` channels (one pass over a
//! sparse operator's rows then serves every channel).
//!
//! Interleaving and its inverse are pure copies: the bits are the inputs'.

use rayon::prelude::*;

/// `a . b = sum_j a_j b_j`, summed in index order (the bits do not depend on threads).
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Entries per parallel work item of [`interleave`] and [`deinterleave`].
pub(crate) const SHUFFLE_BLOCK: usize = 1 << 14;

/// `k` vectors of equal length interleaved: `out[j k + c] = vs[c][j]` (in parallel over
/// blocks of `j`, each block's rows written in order: a pure copy, so the bits are the
/// inputs'; the serial channel-by-channel copy was a visible share of the image PCG's
/// operator products).
pub fn interleave<V: AsRef<[f64]> + Sync>(vs: &[V]) -> Vec<f64> {
    let k = vs.len();
    let n = vs.first().map_or(0, |v| v.as_ref().len());
    let mut out = vec![0.0; n * k];
    if k == 0 {
        return out;
    }
    out.par_chunks_mut(SHUFFLE_BLOCK * k)
        .enumerate()
        .for_each(|(b, block)| {
            let j0 = b * SHUFFLE_BLOCK;
            for (jj, row) in block.chunks_exact_mut(k).enumerate() {
                for (c, v) in row.iter_mut().enumerate() {
                    *v = vs[c].as_ref()[j0 + jj];
                }
            }
        });
    out
}

/// The inverse of [`interleave`] for `k` vectors (in parallel over blocks of `j`).
pub fn deinterleave(v: &[f64], k: usize) -> Vec<Vec<f64>> {
    if k == 0 {
        return Vec::new();
    }
    let n = v.len() / k;
    let mut outs = vec![vec![0.0; n]; k];
    // per block of `j`, the block's slice of every channel
    let mut blocks: Vec<Vec<&mut [f64]>> = (0..n.div_ceil(SHUFFLE_BLOCK))
        .map(|_| Vec::with_capacity(k))
        .collect();
    for out in outs.iter_mut() {
        for (b, part) in out.chunks_mut(SHUFFLE_BLOCK).enumerate() {
            blocks[b].push(part);
        }
    }
    blocks
        .into_par_iter()
        .enumerate()
        .for_each(|(b, mut parts)| {
            let rows = &v[b * SHUFFLE_BLOCK * k..];
            for (c, part) in parts.iter_mut().enumerate() {
                for (jj, x) in part.iter_mut().enumerate() {
                    *x = rows[jj * k + c];
                }
            }
        });
    outs
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `interleave` is `out[j k + c] = vs[c][j]` and `deinterleave` its inverse, bit for bit,
    /// for every channel count and lengths around the parallel block.
    #[test]
    fn interleave_and_deinterleave_are_inverse_copies() {
        for k in 1..=8 {
            for n in [0, 1, 7, SHUFFLE_BLOCK, 2 * SHUFFLE_BLOCK + 5] {
                let vs: Vec<Vec<f64>> = (0..k)
                    .map(|c| (0..n).map(|j| (j * 31 + c) as f64 * 0.5 - 3.0).collect())
                    .collect();
                let v = interleave(&vs);
                assert_eq!(v.len(), n * k);
                for (c, vc) in vs.iter().enumerate() {
                    for (j, &x) in vc.iter().enumerate() {
                        assert_eq!(v[j * k + c].to_bits(), x.to_bits());
                    }
                }
                assert_eq!(deinterleave(&v, k), vs);
            }
        }
    }
}
