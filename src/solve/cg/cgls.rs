//! Conjugate gradients in the least-squares form (CGLS, Björck 1996, 7.4): `A^T A y = A^T f`
//! for `A = K D` (`D` the column scaling) without forming `A^T A`. Per channel, from `y = 0`,
//! `r = f`, `s = A^T r`, `p = s`, `gamma = s . s`:
//!
//! ```text
//! q = A p,  alpha = gamma / (q . q)
//! y += alpha p,  r -= alpha q          (r = f - A y, in the sample space)
//! s = A^T r,  gamma' = s . s,  beta = gamma' / gamma,  p = s + beta p
//! ```
//!
//! This is [`super::pcg`] on `A^T A` with `M = I` in exact arithmetic; the residual is
//! updated in the sample space and `p . A^T A p` is summed as `||A p||^2`, which keeps the
//! accuracy of `A` rather than of `A^T A`. Stopping rule: `||s|| <= tol ||s_0||` (the
//! relative normal-equation residual), or `A p = 0` (then `s = 0` to rounding: counted as
//! converged). Past [`super::CgParams::max_iterations`] the still-iterating channels report
//! `converged` false.
//!
//! Vectors are interleaved (`v[a ch + c]`), every product and update runs in parallel over
//! rows for all channels, and the dot products are summed per block of 1024 rows and then
//! across blocks.

use rayon::prelude::*;
use sprs::CsMat;

use super::{CgParams, CgReport};
use crate::solve::sparse::spmm;

/// CGLS for `A = K diag(d)` and the channels of `f` (interleaved, `m x ch`), `kt = K^T`
/// (CSR). Returns `y` (interleaved, `P x ch`; the coefficients are `c = D y`) and the report
/// (residuals: the recurred `||A^T r|| / ||A^T f||`; no condition estimate).
pub fn cgls(
    k: &CsMat<f64>,
    kt: &CsMat<f64>,
    d: &[f64],
    f: &[f64],
    ch: usize,
    params: &CgParams,
) -> (Vec<f64>, CgReport) {
    let (m, p) = k.shape();
    let dot_cols = |x: &[f64], y: &[f64]| -> Vec<f64> {
        x.par_chunks(ch * 1024)
            .zip(y.par_chunks(ch * 1024))
            .map(|(xb, yb)| {
                let mut acc = vec![0.0; ch];
                for (t, (a, b)) in xb.iter().zip(yb).enumerate() {
                    acc[t % ch] += a * b;
                }
                acc
            })
            .reduce(
                || vec![0.0; ch],
                |a, b| a.iter().zip(&b).map(|(x, y)| x + y).collect(),
            )
    };
    // s = D K^T r
    let at = |r: &[f64], s: &mut [f64]| {
        spmm(kt, r, s, ch);
        s.par_chunks_mut(ch)
            .zip(d.par_iter())
            .for_each(|(row, &da)| row.iter_mut().for_each(|v| *v *= da));
    };
    let mut y = vec![0.0; p * ch];
    let mut r = f.to_vec();
    let mut s = vec![0.0; p * ch];
    at(&r, &mut s);
    let mut pdir = s.clone();
    let mut gamma = dot_cols(&s, &s);
    let norm0: Vec<f64> = gamma.iter().map(|g| g.sqrt()).collect();
    let mut residual: Vec<f64> = (0..ch)
        .map(|c| {
            if norm0[c] > 0.0 {
                gamma[c].sqrt() / norm0[c]
            } else {
                0.0
            }
        })
        .collect();
    let mut active: Vec<bool> = norm0.iter().map(|&n| n > 0.0).collect();
    let mut iterations = vec![0usize; ch];
    let mut q = vec![0.0; m * ch];
    let mut dp = vec![0.0; p * ch];
    let mut it = 0;
    while active.iter().any(|&a| a) && it < params.max_iterations {
        it += 1;
        dp.par_chunks_mut(ch)
            .zip(pdir.par_chunks(ch))
            .zip(d.par_iter())
            .for_each(|((o, i), &da)| o.iter_mut().zip(i).for_each(|(o, i)| *o = da * i));
        spmm(k, &dp, &mut q, ch);
        let qq = dot_cols(&q, &q);
        let alpha: Vec<f64> = (0..ch)
            .map(|c| {
                if active[c] && qq[c] > 0.0 {
                    gamma[c] / qq[c]
                } else {
                    0.0
                }
            })
            .collect();
        y.par_chunks_mut(ch)
            .zip(pdir.par_chunks(ch))
            .for_each(|(yr, pr)| (0..ch).for_each(|c| yr[c] += alpha[c] * pr[c]));
        r.par_chunks_mut(ch)
            .zip(q.par_chunks(ch))
            .for_each(|(rr, qr)| (0..ch).for_each(|c| rr[c] -= alpha[c] * qr[c]));
        at(&r, &mut s);
        let gnew = dot_cols(&s, &s);
        let mut beta = vec![0.0; ch];
        for c in 0..ch {
            if !active[c] {
                continue;
            }
            iterations[c] = it;
            residual[c] = gnew[c].sqrt() / norm0[c];
            if gnew[c].sqrt() <= params.tolerance * norm0[c] || qq[c] == 0.0 {
                active[c] = false;
            } else {
                beta[c] = gnew[c] / gamma[c];
                gamma[c] = gnew[c];
            }
        }
        pdir.par_chunks_mut(ch)
            .zip(s.par_chunks(ch))
            .for_each(|(pr, sr)| (0..ch).for_each(|c| pr[c] = sr[c] + beta[c] * pr[c]));
    }
    let report = CgReport {
        iterations,
        relative_residual: residual,
        converged: active.iter().map(|&a| !a).collect(),
        condition: None,
        forward_error: None,
        start_residual: Vec::new(),
    };
    (y, report)
}
