//! Dense block solves of local inversion (kernel *matrices* are [`crate::kernel`]):
//! `X = K1^+ E_R`, the columns of the pseudo-inverse of one local block `K1` (`r x n`) for
//! the pivot rows `R` (`E_R` = identity columns), by SVD, column-pivoted QR or Cholesky of the
//! normal matrix.
//!
//! All faer calls here take `Par::Seq` explicitly: the blocks are small (tens to a few
//! hundred rows) and thousands of them run concurrently on the rayon pool, so faer's own
//! parallelism would only add synchronisation (a small thin SVD is about three times slower
//! with `Par::rayon(0)`; docs/measurements/basis.md has the figure). Passing `Par` per call instead
//! of `faer::set_global_parallelism(Par::Seq)` leaves the global setting alone for the one
//! large factorization of the global reference, which runs at the same time in a report.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::{cholesky_in_place, cholesky_in_place_scratch};
use faer::linalg::householder::{
    apply_block_householder_sequence_on_the_left_in_place_scratch,
    apply_block_householder_sequence_on_the_left_in_place_with_conj,
    apply_block_householder_sequence_transpose_on_the_left_in_place_scratch,
    apply_block_householder_sequence_transpose_on_the_left_in_place_with_conj,
};
use faer::linalg::qr::col_pivoting::factor::{qr_in_place, qr_in_place_scratch};
use faer::linalg::qr::no_pivoting::factor::{
    qr_in_place as qr_plain, qr_in_place_scratch as qr_plain_scratch, recommended_block_size,
};
use faer::linalg::svd::{svd, svd_scratch, ComputeSvdVectors};
use faer::linalg::triangular_solve::solve_upper_triangular_in_place;
use faer::{Accum, Conj, Mat, MatRef, Par};

/// Result of one block.
pub(crate) struct BlockOut {
    /// `n x g`: column `t` is the pseudo-inverse column of pivot `t`.
    pub x: Mat<f64>,
    /// `s_max / s_min` of `K1` (SVD), or an estimate (QR, Cholesky); infinite when `K1`
    /// has a null space (`r < n` or a dropped direction / failed Cholesky).
    pub condition: f64,
    /// Directions dropped: `n - numerical rank` (SVD, QR); 0 for Cholesky.
    pub cut: usize,
    /// Relative diagonal shift that made the Cholesky succeed (0 when none was needed).
    pub shift: f64,
    /// The SVD did not converge and QR was used instead.
    pub fallback: bool,
    /// `s_max / s_kept`: the condition of the block on the directions kept by the cut-off
    /// (the amplification of data errors into the answer); Cholesky: its estimate of
    /// `cond(K1)` (infinite when shifted).
    pub kept: f64,
}

impl BlockOut {
    /// The answer for a block with no rows (or no columns): every one of its `n` directions is
    /// undetermined, so all are cut and the `n x g` pseudo-inverse columns are zero.
    fn without_rows(n: usize, g: usize) -> Self {
        BlockOut {
            x: Mat::zeros(n, g),
            condition: f64::INFINITY,
            cut: n,
            shift: 0.0,
            fallback: false,
            kept: f64::INFINITY,
        }
    }
}

thread_local! {
    /// Per-thread faer workspace, grown on demand and reused by every block on that thread
    /// (a block's scratch can exceed the allocator's mmap threshold, ~0.5 MB at 300 x 90).
    static WORK: std::cell::RefCell<(usize, Option<MemBuffer>)> =
        const { std::cell::RefCell::new((0, None)) };
}

/// Runs `f` with a workspace of at least `req`; not re-entrant (callers keep each faer
/// call inside its own `with_stack`).
fn with_stack<R>(req: StackReq, f: impl FnOnce(&mut MemStack) -> R) -> R {
    WORK.with(|w| {
        let mut w = w.borrow_mut();
        let need = req.unaligned_bytes_required();
        if w.1.is_none() || w.0 < need {
            let cap = need.max(1 << 14);
            *w = (cap, Some(MemBuffer::new(StackReq::new::<u8>(cap))));
        }
        let buf = w.1.as_mut().expect("workspace allocated above");
        f(MemStack::new(buf))
    })
}

/// `K1^+ E_R` by thin SVD with relative cut-off; falls back to QR if the SVD does not
/// converge (reported in [`BlockOut::fallback`]).
///
/// Tall blocks (`r > n`, the usual case) are first reduced by Householder QR,
/// `K1 = Q R`, so that `K1^+ E_R = R^+ (Q^T E_R)`: the SVD runs on the `n x n` factor and
/// `Q` is applied to the `g` pivot columns only, never formed (`U` of `K1` would cost
/// `~4 r n^2` flops more).
pub(crate) fn svd_columns(k1: MatRef<'_, f64>, piv: &[usize], cutoff: f64) -> BlockOut {
    let (r, n) = k1.shape();
    let g = piv.len();
    let size = r.min(n);
    if size == 0 {
        return BlockOut::without_rows(n, g);
    }
    // (matrix to decompose, right-hand side block it acts on: E_R or Q^T E_R)
    let (core, rhs) = if r > n {
        let mut a = k1.to_owned();
        let bs = qr_block_size(r, n);
        let mut coeff = Mat::<f64>::zeros(bs, n);
        // Few pivots: Q^T applied to the identity columns E_R (r x g). Many pivots (up to
        // every row, e.g. one block holding all samples of a cluster): E_R would be r x r,
        // so the thin Q (r x n) is formed instead and its rows R read off.
        let few = g <= n;
        let mut e = Mat::<f64>::zeros(if few { r } else { 0 }, g);
        if few {
            for (t, &p) in piv.iter().enumerate() {
                e[(p, t)] = 1.0;
            }
        }
        with_stack(
            StackReq::any_of(&[
                qr_plain_scratch::<f64>(r, n, bs, Par::Seq, Default::default()),
                apply_block_householder_sequence_transpose_on_the_left_in_place_scratch::<f64>(
                    r, bs, g,
                ),
            ]),
            |stack| {
                qr_plain(
                    a.as_mut(),
                    coeff.as_mut(),
                    Par::Seq,
                    stack,
                    Default::default(),
                );
                if few {
                    apply_block_householder_sequence_transpose_on_the_left_in_place_with_conj(
                        a.as_ref(),
                        coeff.as_ref(),
                        Conj::No,
                        e.as_mut(),
                        Par::Seq,
                        stack,
                    );
                }
            },
        );
        let rhs = if few {
            e.get(..n, ..).to_owned()
        } else {
            q_rows_transposed(a.as_ref(), coeff.as_ref(), n, piv)
        };
        let rr = Mat::<f64>::from_fn(n, n, |i, j| if i <= j { a[(i, j)] } else { 0.0 });
        (rr, rhs)
    } else {
        let mut e = Mat::<f64>::zeros(r, g);
        for (t, &p) in piv.iter().enumerate() {
            e[(p, t)] = 1.0;
        }
        (k1.to_owned(), e)
    };
    let (cr, cn) = core.shape();
    let csize = cr.min(cn);
    let mut s = faer::diag::Diag::<f64>::zeros(csize);
    let mut u = Mat::<f64>::zeros(cr, csize);
    let mut v = Mat::<f64>::zeros(cn, csize);
    let ok = with_stack(
        svd_scratch::<f64>(
            cr,
            cn,
            ComputeSvdVectors::Thin,
            ComputeSvdVectors::Thin,
            Par::Seq,
            Default::default(),
        ),
        |stack| {
            svd(
                core.as_ref(),
                s.as_mut(),
                Some(u.as_mut()),
                Some(v.as_mut()),
                Par::Seq,
                stack,
                Default::default(),
            )
        },
    );
    if ok.is_err() {
        let mut out = qr_columns(k1, piv, cutoff);
        out.fallback = true;
        return out;
    }
    let s = s.column_vector();
    let smax = s[0];
    let tol = cutoff * smax;
    let rank = (0..csize).take_while(|&k| s[k] > tol && s[k] > 0.0).count();
    // W = diag(1/s) U[:, :rank]^T rhs : rank x g
    let mut w = Mat::<f64>::zeros(rank, g);
    faer::linalg::matmul::matmul(
        w.as_mut(),
        Accum::Replace,
        u.get(.., ..rank).transpose(),
        rhs.as_ref(),
        1.0,
        Par::Seq,
    );
    for k in 0..rank {
        let inv = 1.0 / s[k];
        for t in 0..g {
            w[(k, t)] *= inv;
        }
    }
    let mut x = Mat::<f64>::zeros(n, g);
    faer::linalg::matmul::matmul(
        x.as_mut(),
        Accum::Replace,
        v.get(.., ..rank),
        w.as_ref(),
        1.0,
        Par::Seq,
    );
    let smin = if r >= n { s[n - 1] } else { 0.0 };
    BlockOut {
        x,
        condition: if smin > 0.0 {
            smax / smin
        } else {
            f64::INFINITY
        },
        cut: n - rank,
        shift: 0.0,
        fallback: false,
        kept: if rank > 0 {
            smax / s[rank - 1]
        } else {
            f64::INFINITY
        },
    }
}

/// `Q[R, :]^T` (`size x g`) for the thin `Q` (`r x size`) of a Householder QR held in
/// `(a, coeff)`: equal to the first `size` rows of `Q^T E_R`, at `r x size` memory instead of
/// `r x g`.
fn q_rows_transposed(
    a: MatRef<'_, f64>,
    coeff: MatRef<'_, f64>,
    size: usize,
    piv: &[usize],
) -> Mat<f64> {
    let r = a.nrows();
    let mut q = Mat::<f64>::zeros(r, size);
    for k in 0..size {
        q[(k, k)] = 1.0;
    }
    with_stack(
        apply_block_householder_sequence_on_the_left_in_place_scratch::<f64>(
            r,
            coeff.nrows(),
            size,
        ),
        |stack| {
            apply_block_householder_sequence_on_the_left_in_place_with_conj(
                a.get(.., ..size),
                coeff,
                Conj::No,
                q.as_mut(),
                Par::Seq,
                stack,
            )
        },
    );
    Mat::from_fn(size, piv.len(), |k, t| q[(piv[t], k)])
}

fn qr_block_size(r: usize, n: usize) -> usize {
    recommended_block_size::<f64>(r, n).max(1)
}

/// `K1^+ E_R` by column-pivoted QR: basic least-squares solution on the leading columns
/// with `|R_kk| > cutoff |R_00|`.
pub(crate) fn qr_columns(k1: MatRef<'_, f64>, piv: &[usize], cutoff: f64) -> BlockOut {
    let (r, n) = k1.shape();
    let g = piv.len();
    let size = r.min(n);
    if size == 0 {
        return BlockOut::without_rows(n, g);
    }
    let mut a = k1.to_owned();
    let bs = qr_block_size(r, n);
    let mut coeff = Mat::<f64>::zeros(bs, size);
    let mut fwd = vec![0usize; n];
    let mut inv = vec![0usize; n];
    // E_R, then Q^T E_R (many pivots: rows of the thin Q instead, see `svd_columns`)
    let few = g <= size;
    let mut e = Mat::<f64>::zeros(if few { r } else { 0 }, g);
    if few {
        for (t, &p) in piv.iter().enumerate() {
            e[(p, t)] = 1.0;
        }
    }
    let perm_fwd: Vec<usize> = with_stack(
        StackReq::any_of(&[
            qr_in_place_scratch::<usize, f64>(r, n, bs, Par::Seq, Default::default()),
            apply_block_householder_sequence_transpose_on_the_left_in_place_scratch::<f64>(
                r, bs, g,
            ),
        ]),
        |stack| {
            let (_, perm) = qr_in_place(
                a.as_mut(),
                coeff.as_mut(),
                &mut fwd,
                &mut inv,
                Par::Seq,
                stack,
                Default::default(),
            );
            let perm_fwd = perm.arrays().0.to_vec();
            if few {
                apply_block_householder_sequence_transpose_on_the_left_in_place_with_conj(
                    a.get(.., ..size),
                    coeff.as_ref(),
                    Conj::No,
                    e.as_mut(),
                    Par::Seq,
                    stack,
                );
            }
            perm_fwd
        },
    );
    if !few {
        e = q_rows_transposed(a.as_ref(), coeff.as_ref(), size, piv);
    }
    let r00 = a[(0, 0)].abs();
    let tol = cutoff * r00;
    let rank = (0..size)
        .take_while(|&k| a[(k, k)].abs() > tol && a[(k, k)] != 0.0)
        .count();
    let mut y = e.get(..rank, ..).to_owned();
    solve_upper_triangular_in_place(a.get(..rank, ..rank), y.as_mut(), Par::Seq);
    let mut x = Mat::<f64>::zeros(n, g);
    for k in 0..rank {
        for t in 0..g {
            x[(perm_fwd[k], t)] = y[(k, t)];
        }
    }
    let rnn = if r >= n { a[(n - 1, n - 1)].abs() } else { 0.0 };
    BlockOut {
        x,
        condition: if rnn > 0.0 { r00 / rnn } else { f64::INFINITY },
        cut: n - rank,
        shift: 0.0,
        fallback: false,
        kept: if rank > 0 {
            r00 / a[(rank - 1, rank - 1)].abs()
        } else {
            f64::INFINITY
        },
    }
}

/// `G^{-1} B` for the normal matrix `G = K1^T K1` (`n x n`, full symmetric) and
/// `B = K1[R, :]^T` (`n x g`), by Cholesky after symmetric diagonal equilibration.
///
/// A failed factorization, or one with a pivot below `16 n eps` (numerically singular),
/// is retried with `G + delta I` (equilibrated), `delta = shift0 * 10^t`, `t = 0..8`.
/// Returns `None` if even the largest shift fails (only possible for non-finite input).
pub(crate) fn cholesky_columns(mut gm: Mat<f64>, mut b: Mat<f64>, shift0: f64) -> Option<BlockOut> {
    let n = gm.nrows();
    let g = b.ncols();
    if n == 0 {
        return Some(BlockOut {
            x: Mat::zeros(0, g),
            condition: f64::INFINITY,
            cut: 0,
            shift: 0.0,
            fallback: false,
            kept: 1.0,
        });
    }
    let d: Vec<f64> = (0..n)
        .map(|i| {
            let v = gm[(i, i)];
            if v > 0.0 {
                1.0 / v.sqrt()
            } else {
                1.0
            }
        })
        .collect();
    for j in 0..n {
        for i in 0..n {
            gm[(i, j)] *= d[i] * d[j];
        }
    }
    for t in 0..g {
        for i in 0..n {
            b[(i, t)] *= d[i];
        }
    }
    let thresh = 16.0 * n as f64 * f64::EPSILON;
    let req = cholesky_in_place_scratch::<f64>(n, Par::Seq, Default::default());
    let mut shift = 0.0;
    for attempt in 0..=9 {
        if attempt > 0 {
            shift = shift0 * 10f64.powi(attempt - 1);
        }
        let mut l = gm.clone();
        for i in 0..n {
            l[(i, i)] += shift;
        }
        let ok = with_stack(req, |stack| {
            cholesky_in_place(
                l.as_mut(),
                Default::default(),
                Par::Seq,
                stack,
                Default::default(),
            )
        });
        if ok.is_err() {
            continue;
        }
        let diag: Vec<f64> = (0..n).map(|i| l[(i, i)]).collect();
        let lmin = diag.iter().cloned().fold(f64::INFINITY, f64::min);
        let lmax = diag.iter().cloned().fold(0.0, f64::max);
        if lmin.is_nan() || lmin * lmin < thresh {
            continue;
        }
        let solve = |rhs: faer::MatMut<'_, f64>| {
            with_stack(StackReq::EMPTY, |stack| {
                faer::linalg::cholesky::llt::solve::solve_in_place(l.as_ref(), rhs, Par::Seq, stack)
            })
        };
        // cond(K1) estimate = sqrt(lambda_max / lambda_min) of the equilibrated G:
        // lambda_max <= the largest absolute row sum (Gershgorin), lambda_min by five steps
        // of inverse iteration with the factor (an upper bound on lambda_min, so the
        // estimate errs low by the iteration's convergence only), O(n^2) each.
        let row_max = (0..n)
            .map(|i| (0..n).map(|j| gm[(i, j)].abs()).sum::<f64>())
            .fold(0.0, f64::max);
        let mut v = Mat::<f64>::from_fn(n, 1, |i, _| 1.0 + (i as f64 * 0.618_034).fract());
        let mut lam_min = f64::INFINITY;
        for _ in 0..5 {
            let norm = v.norm_l2();
            if !(norm > 0.0 && norm.is_finite()) {
                break;
            }
            for i in 0..n {
                v[(i, 0)] /= norm;
            }
            solve(v.as_mut());
            lam_min = 1.0 / v.norm_l2();
        }
        let estimate = if shift > 0.0 {
            f64::INFINITY
        } else {
            (row_max / lam_min).sqrt().max(lmax / lmin)
        };
        solve(b.as_mut());
        for t in 0..g {
            for i in 0..n {
                b[(i, t)] *= d[i];
            }
        }
        return Some(BlockOut {
            x: b,
            condition: if shift > 0.0 {
                f64::INFINITY
            } else {
                lmax / lmin
            },
            cut: 0,
            shift,
            fallback: false,
            kept: if estimate.is_nan() {
                f64::INFINITY
            } else {
                estimate
            },
        });
    }
    None
}
