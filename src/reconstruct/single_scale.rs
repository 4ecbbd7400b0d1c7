//! The global least-squares solution through the single-scale basis (docs/design.md §4, last point).
//!
//! `Psi(n, N)` spans `V_{N+1}`, so `argmin_c ||K c - f||` equals the FWT analysis of
//! `argmin_v ||K_J v - f||`, `K_J[i, k] = phi_{J,k}(lambda_i)`, `J = N + 1`. Each row of `K_J`
//! has at most `2p - 1` interior (plus edge) nonzeros with column indices within `3p - 3` of
//! each other, so the normal matrix `K_J^T K_J` is banded with half-bandwidth `b = 3p - 3`
//! (`b = 0` for Haar) and is accumulated sample by sample without storing `K_J`. It is
//! equilibrated, `A = D^{-1/2} K_J^T K_J D^{-1/2}` with `D = diag`, shifted by a tiny relative
//! ridge `epsilon I` (default 0), and factored by a banded Cholesky `A = L L^T` in `O(P b^2)`; a
//! pivot below [`PIVOT_TOLERANCE`] (an undetermined direction, e.g. a function without
//! samples) is counted in the report and the caller falls back: automatic levels drop the
//! finest level, fixed levels use local inversion's truncated pseudo-inverses.

#![allow(clippy::needless_range_loop)] // banded triangular solves read clearest as index loops

use rayon::prelude::*;
use serde::Serialize;

use crate::basis::{fwt, CdvBasis};

use crate::solve::band::{cell_order, GivensTriangle};

/// Samples per parallel work item.
const CHUNK: usize = 16_384;

/// Pivots of the equilibrated factor below this mark directions the samples do not determine
/// (`cond(K) >~ 1e5` along them).
pub const PIVOT_TOLERANCE: f64 = 1e-10;

/// What the single-scale solve did.
#[derive(Clone, Debug, Serialize)]
pub struct SingleScaleReport {
    /// The factorization used.
    pub solver: SingleScaleSolver,
    /// Half-bandwidth of the normal matrix.
    pub bandwidth: usize,
    /// Relative ridge added to the equilibrated diagonal.
    pub ridge: f64,
    /// Single-scale functions without any sample in their support (coefficient set to 0).
    pub unsampled: usize,
    /// Pivots below the tolerance: directions the samples do not determine, unsampled
    /// functions included. When nonzero the solution is not trustworthy (near-deficient
    /// directions amplify rounding): callers fall back (see `reconstruct::fit`).
    pub deficient: usize,
    /// Smallest pivot `L_jj^2` of the equilibrated factor: near `1 / cond(K)^2`, small values
    /// flag locally undersampled regions.
    pub min_pivot: f64,
    /// RMS residual at the samples `sqrt(||f - K v||^2 / m)` per channel, when the solve
    /// found it on the way (the QR: the right-hand sides rotated out; not with a ridge, whose
    /// rows would count too, nor when a sum of squares overflows): the fit need not be
    /// evaluated at the samples again.
    pub residual_rms: Option<Vec<f64>>,
}

/// Banded symmetric matrix: `band[i * (b + 1) + d] = A[i, i - d]`, `d <= b`.
struct Band {
    n: usize,
    b: usize,
    data: Vec<f64>,
}

impl Band {
    fn zeros(n: usize, b: usize) -> Self {
        Self {
            n,
            b,
            data: vec![0.0; n * (b + 1)],
        }
    }
    #[inline]
    fn at(&mut self, i: usize, d: usize) -> &mut f64 {
        &mut self.data[i * (self.b + 1) + d]
    }
    fn add(&mut self, other: &Band) {
        self.data
            .iter_mut()
            .zip(&other.data)
            .for_each(|(a, b)| *a += b);
    }
}

/// Accumulates `K_J^T K_J` and `K_J^T f` over the samples.
fn normal_equations(
    scale: &CdvBasis,
    positions: &[f64],
    values: &[&[f64]],
    b: usize,
) -> (Band, Vec<Vec<f64>>) {
    let n = scale.dimension() / 2; // V_J has 2^J functions; Psi(J, J) has 2^{J+1}
    let domain = scale.domain();
    let channels = values.len();
    // One accumulator per thread (not per work item: a band is O(P) memory); small problems
    // run on the calling thread (no thread pool is started for them).
    let per = if positions.len() < 2 * CHUNK {
        CHUNK.max(positions.len())
    } else {
        positions
            .len()
            .div_ceil(rayon::current_num_threads().max(1))
            .max(CHUNK)
    };
    let chunks: Vec<(usize, &[f64])> = positions
        .chunks(per)
        .enumerate()
        .map(|(c, x)| (c * per, x))
        .collect();
    let work = |&(start, xs): &(usize, &[f64])| {
        let mut band = Band::zeros(n, b);
        let mut rhs = vec![vec![0.0; n]; channels];
        {
            let mut ev = scale.single_level_evaluator();
            let bw = b + 1;
            for (off, &x) in xs.iter().enumerate() {
                let (first, row) = ev.row_unit(domain.to_unit(x));
                for (k, &vk) in row.iter().enumerate() {
                    let i = first + k;
                    let dst = &mut band.data[i * bw..i * bw + k + 1];
                    // A[i, i - d] += v_k v_{k - d}, d = 0..=k.
                    for (a, &vl) in dst.iter_mut().zip(row[..=k].iter().rev()) {
                        *a += vk * vl;
                    }
                    for (c, f) in values.iter().enumerate() {
                        rhs[c][i] += vk * f[start + off];
                    }
                }
            }
        }
        (band, rhs)
    };
    if chunks.len() == 1 {
        return work(&chunks[0]);
    }
    chunks
        .par_iter()
        .map(work)
        .reduce_with(|(mut a, mut ra), (bb, rb)| {
            a.add(&bb);
            for (x, y) in ra.iter_mut().zip(rb) {
                x.iter_mut().zip(y).for_each(|(p, q)| *p += q);
            }
            (a, ra)
        })
        .unwrap_or_else(|| (Band::zeros(n, b), vec![vec![0.0; n]; channels]))
}

/// The normal equations `K_J^T K_J v = K_J^T f` of the single-scale basis `V_J` (banded,
/// not equilibrated), one right-hand side per channel.
pub struct NormalEquations {
    band: Band,
    rhs: Vec<Vec<f64>>,
    level: u32,
}

impl NormalEquations {
    /// Accumulates the normal equations of `V_{N+1}` for `basis = Psi(n, N)`.
    pub fn accumulate(
        basis: &CdvBasis,
        positions: &[f64],
        values: &[&[f64]],
    ) -> Result<Self, crate::basis::BasisError> {
        let top = basis.fine() + 1;
        let scale = CdvBasis::with_bank(basis.bank().clone(), top, top, basis.domain())?;
        let (band, rhs) = normal_equations(&scale, positions, values, bandwidth(basis));
        Ok(Self {
            band,
            rhs,
            level: top,
        })
    }

    /// The single-scale level `J`.
    pub fn level(&self) -> u32 {
        self.level
    }

    /// The same least-squares problem restricted to `V_{J-1} ⊂ V_J`: with `H` the low-pass
    /// half of the FWT step (`phi_{J-1,c} = sum_i H_ci phi_{J,i}`), `A' = H A H^T`,
    /// `r' = H r`; `O(P b p)`, no pass over the samples. `A'` keeps the half-bandwidth
    /// `b = 3p - 3` (coarse functions `b + 1` apart share no fine function's band).
    pub fn coarsen(&self, bank: &crate::basis::FilterBank) -> Self {
        let coarse_level = self.level - 1;
        let n = self.band.n / 2;
        let b = self.band.b;
        let mut rows: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
        fwt::analysis_entries(bank, coarse_level, false, |c, i, w| rows[c].push((i, w)));
        let fine = &self.band;
        let a_sym = |i: usize, j: usize| -> f64 {
            let (hi, lo) = if i >= j { (i, j) } else { (j, i) };
            if hi - lo <= b {
                fine.data[hi * (b + 1) + (hi - lo)]
            } else {
                0.0
            }
        };
        // B = H A, row c on the window [lo_c, hi_c] of fine indices.
        let windows: Vec<(usize, Vec<f64>)> = rows
            .par_iter()
            .map(|row| {
                let lo = row.iter().map(|e| e.0).min().unwrap_or(0).saturating_sub(b);
                let hi = (row.iter().map(|e| e.0).max().unwrap_or(0) + b).min(fine.n - 1);
                let vals = (lo..=hi)
                    .map(|i| row.iter().map(|&(i1, w1)| w1 * a_sym(i1, i)).sum())
                    .collect();
                (lo, vals)
            })
            .collect();
        let mut band = Band::zeros(n, b);
        band.data
            .par_chunks_mut(b + 1)
            .enumerate()
            .for_each(|(c1, out)| {
                let (lo, ref vals) = windows[c1];
                for (d, o) in out.iter_mut().enumerate().take(b.min(c1) + 1) {
                    *o = rows[c1 - d]
                        .iter()
                        .filter_map(|&(i2, w2)| {
                            i2.checked_sub(lo).and_then(|k| vals.get(k)).map(|v| w2 * v)
                        })
                        .sum();
                }
            });
        let rhs = self
            .rhs
            .iter()
            .map(|r| {
                rows.iter()
                    .map(|row| row.iter().map(|&(i, w)| w * r[i]).sum())
                    .collect()
            })
            .collect();
        Self {
            band,
            rhs,
            level: coarse_level,
        }
    }

    /// Solves for the `Psi(n, N)` coefficients (`basis.fine() + 1` must equal the level).
    pub fn solve(&self, basis: &CdvBasis, ridge: f64) -> (Vec<Vec<f64>>, SingleScaleReport) {
        debug_assert_eq!(basis.fine() + 1, self.level);
        factor_and_solve(
            basis,
            Band {
                n: self.band.n,
                b: self.band.b,
                data: self.band.data.clone(),
            },
            self.rhs.clone(),
            ridge,
        )
    }
}

fn bandwidth(basis: &CdvBasis) -> usize {
    if basis.bank().edge_count() == 0 {
        0
    } else {
        3 * basis.p() - 3
    }
}

/// Global least squares for every channel through `V_{N+1}`; returns the `Psi(n, N)`
/// coefficients per channel.
pub fn single_scale_ls(
    basis: &CdvBasis,
    positions: &[f64],
    values: &[&[f64]],
    ridge: f64,
) -> Result<(Vec<Vec<f64>>, SingleScaleReport), crate::basis::BasisError> {
    let ne = NormalEquations::accumulate(basis, positions, values)?;
    Ok(factor_and_solve(basis, ne.band, ne.rhs, ridge))
}

fn factor_and_solve(
    basis: &CdvBasis,
    mut a: Band,
    mut rhs: Vec<Vec<f64>>,
    ridge: f64,
) -> (Vec<Vec<f64>>, SingleScaleReport) {
    let b = a.b;
    let n = a.n;
    // Equilibrate.
    let d: Vec<f64> = (0..n)
        .map(|i| {
            let v = *a.at(i, 0);
            if v > 0.0 {
                1.0 / v.sqrt()
            } else {
                0.0
            }
        })
        .collect();
    let unsampled = d.iter().filter(|&&x| x == 0.0).count();
    for i in 0..n {
        for dd in 0..=b.min(i) {
            *a.at(i, dd) *= d[i] * d[i - dd];
        }
        *a.at(i, 0) += ridge;
    }
    // Banded Cholesky in place: A = L L^T. A pivot below PIVOT_TOLERANCE marks a direction
    // the samples do not determine: its column of L is zeroed and its component set to 0.
    let w = b + 1;
    let mut min_pivot = f64::INFINITY;
    let mut deficient = vec![false; n];
    for j in 0..n {
        let lo = j.saturating_sub(b);
        let mut s = a.data[j * w];
        for k in lo..j {
            let l = a.data[j * w + (j - k)];
            s -= l * l;
        }
        if s <= PIVOT_TOLERANCE {
            // An undetermined direction: fixed at 0 so the factorization stays finite; the
            // caller decides what to do (fewer levels, or local inversion).
            deficient[j] = true;
            a.data[j * w] = 1.0;
            for i in (j + 1)..n.min(j + b + 1) {
                a.data[i * w + (i - j)] = 0.0;
            }
            continue;
        }
        min_pivot = min_pivot.min(s);
        let ljj = s.sqrt();
        a.data[j * w] = ljj;
        for i in (j + 1)..n.min(j + b + 1) {
            let lo_i = i.saturating_sub(b);
            let mut t = a.data[i * w + (i - j)];
            for k in lo_i.max(lo)..j {
                t -= a.data[i * w + (i - k)] * a.data[j * w + (j - k)];
            }
            a.data[i * w + (i - j)] = t / ljj;
        }
    }
    let coefficients = rhs
        .iter_mut()
        .map(|r| {
            // Scale, forward and back substitution, unscale.
            for i in 0..n {
                r[i] *= d[i];
            }
            for i in 0..n {
                let mut t = r[i];
                for k in i.saturating_sub(b)..i {
                    t -= a.data[i * w + (i - k)] * r[k];
                }
                r[i] = if deficient[i] { 0.0 } else { t / a.data[i * w] };
            }
            for i in (0..n).rev() {
                let mut t = r[i];
                for k in (i + 1)..n.min(i + b + 1) {
                    t -= a.data[k * w + (k - i)] * r[k];
                }
                r[i] = if deficient[i] { 0.0 } else { t / a.data[i * w] };
            }
            for i in 0..n {
                r[i] *= d[i];
            }
            fwt::analysis(basis.bank(), basis.coarse(), basis.fine(), r)
        })
        .collect();
    (
        coefficients,
        SingleScaleReport {
            solver: SingleScaleSolver::NormalEquations,
            bandwidth: b,
            ridge,
            unsampled,
            deficient: deficient.iter().filter(|&&x| x).count(),
            min_pivot,
            residual_rms: None,
        },
    )
}

/// How the single-scale least-squares problem `min ||K_J v - f||` is solved.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub enum SingleScaleSolver {
    /// Banded QR of `K_J` by Givens rotations, streamed in cell order (no `K_J` stored): the
    /// accuracy of `cond(K_J)`; the default in 1D.
    #[default]
    Qr,
    /// Banded normal equations `K_J^T K_J v = K_J^T f` and a banded Cholesky: the accuracy of
    /// `cond(K_J)^2`, about half the work per sample, no sorting of the samples, and lowering
    /// the finest level coarsens the equations without another pass over the samples.
    NormalEquations,
}

/// Global least squares for every channel through `V_{N+1}` by a banded QR of `K_J`
/// ([`SingleScaleSolver::Qr`]); returns the `Psi(n, N)` coefficients per channel.
///
/// The samples are put in ascending cell order at level `J` (a counting sort, skipped when
/// they are already in that order), split into one contiguous chunk per thread, each chunk
/// rotated into its own triangle, and the triangles merged in order. The ridge adds the rows
/// `sqrt(ridge ||K_J e_j||^2) e_j^T`, the same shift as the normal equations' equilibrated
/// `A + ridge I`; a pivot `R_jj^2 / ||K_J e_j||^2` below [`PIVOT_TOLERANCE`] (the pivot of the
/// equilibrated Cholesky factor in exact arithmetic) counts as undetermined.
pub fn single_scale_qr(
    basis: &CdvBasis,
    positions: &[f64],
    values: &[&[f64]],
    ridge: f64,
) -> Result<(Vec<Vec<f64>>, SingleScaleReport), crate::basis::BasisError> {
    let top = basis.fine() + 1;
    let scale = CdvBasis::with_bank(basis.bank().clone(), top, top, basis.domain())?;
    let n = scale.dimension() / 2;
    let b = bandwidth(basis);
    let w = b + 1;
    let domain = basis.domain();
    let channels = values.len();
    let m = positions.len();
    let ts: Vec<f64> = positions.iter().map(|&x| domain.to_unit(x)).collect();
    let order = cell_order(&ts, top);
    let at = |i: usize| order.as_ref().map_or(i, |o| o[i]);
    let fill = |tri: &mut GivensTriangle, range: std::ops::Range<usize>| {
        let mut ev = scale.single_level_evaluator();
        let mut f = vec![0.0; channels];
        for i in range {
            let s = at(i);
            for (fc, vc) in f.iter_mut().zip(values) {
                *fc = vc[s];
            }
            let (first, row) = ev.row_unit(ts[s]);
            tri.add_row(first, row, &f);
        }
    };
    let mut tri = GivensTriangle::new(0, n, w, channels);
    let ranges = qr_parts(m);
    if ranges.len() == 1 {
        fill(&mut tri, 0..m);
    } else {
        let parts: Vec<GivensTriangle> = ranges
            .into_par_iter()
            .map(|range| {
                // Columns of the chunk: from the first row's first to the last row's last.
                let mut ev = scale.single_level_evaluator();
                let c0 = ev.row_unit(ts[at(range.start)]).0;
                let (last, row) = ev.row_unit(ts[at(range.end - 1)]);
                let mut part = GivensTriangle::new(c0, last + row.len() - c0, w, channels);
                fill(&mut part, range);
                part
            })
            .collect();
        for part in &parts {
            tri.absorb(part);
        }
    }
    Ok(solve_triangle(basis, tri, ridge, m))
}

/// The consecutive sample ranges the QR rotates into triangles of their own (one per
/// thread, at least [`CHUNK`] samples each; a single range for small inputs or one thread)
/// and then merges in order: the rounding of the result depends on them.
pub(crate) fn qr_parts(m: usize) -> Vec<std::ops::Range<usize>> {
    let threads = rayon::current_num_threads().max(1);
    if m < 2 * CHUNK || threads == 1 {
        return std::iter::once(0..m).collect();
    }
    let per = m.div_ceil(threads).max(CHUNK);
    (0..m).step_by(per).map(|s| s..(s + per).min(m)).collect()
}

/// The `Psi(n, N)` coefficients from the triangle of all `m` samples over the columns of
/// `V_{N+1}`: the ridge rows, back substitution, the residual the rotations left, the FWT.
pub(crate) fn solve_triangle(
    basis: &CdvBasis,
    mut tri: GivensTriangle,
    ridge: f64,
    m: usize,
) -> (Vec<Vec<f64>>, SingleScaleReport) {
    let b = bandwidth(basis);
    tri.add_ridge(ridge);
    let sol = tri.solve(PIVOT_TOLERANCE);
    let residual_rms = if ridge == 0.0 && m > 0 {
        let rss = tri.residual_squares(&sol);
        rss.iter()
            .all(|r| r.is_finite())
            .then(|| rss.iter().map(|r| (r / m as f64).sqrt()).collect())
    } else {
        None
    };
    let coefficients = sol
        .coefficients
        .into_iter()
        .map(|v| fwt::analysis(basis.bank(), basis.coarse(), basis.fine(), &v))
        .collect();
    (
        coefficients,
        SingleScaleReport {
            solver: SingleScaleSolver::Qr,
            bandwidth: b,
            ridge,
            unsampled: sol.unsampled,
            deficient: sol.deficient,
            min_pivot: sol.min_pivot,
            residual_rms,
        },
    )
}

/// The single-scale problem at one level, ready to solve and to lower by one level: the
/// automatic-level search of `reconstruct::fit` solves, and while directions stay
/// undetermined, coarsens. The normal equations coarsen in `O(P b p)` (`A' = H A H^T`); the
/// QR path solves afresh at the coarser level (one more pass over the samples).
pub enum SingleScaleProblem<'a> {
    /// Accumulated normal equations.
    Normal(NormalEquations),
    /// The samples, for the banded QR at `level`.
    Qr {
        /// The single-scale level `J`.
        level: u32,
        /// Sample positions.
        positions: &'a [f64],
        /// Values per channel.
        values: &'a [&'a [f64]],
    },
}

impl<'a> SingleScaleProblem<'a> {
    /// The problem of `V_{N+1}` for `basis = Psi(n, N)` with the chosen solver.
    pub fn new(
        basis: &CdvBasis,
        positions: &'a [f64],
        values: &'a [&'a [f64]],
        solver: SingleScaleSolver,
    ) -> Result<Self, crate::basis::BasisError> {
        Ok(match solver {
            SingleScaleSolver::NormalEquations => {
                Self::Normal(NormalEquations::accumulate(basis, positions, values)?)
            }
            SingleScaleSolver::Qr => Self::Qr {
                level: basis.fine() + 1,
                positions,
                values,
            },
        })
    }

    /// Solves for the `Psi(n, N)` coefficients (`basis.fine() + 1` must equal the level).
    pub fn solve(
        &self,
        basis: &CdvBasis,
        ridge: f64,
    ) -> Result<(Vec<Vec<f64>>, SingleScaleReport), crate::basis::BasisError> {
        match self {
            Self::Normal(ne) => Ok(ne.solve(basis, ridge)),
            Self::Qr {
                level,
                positions,
                values,
            } => {
                debug_assert_eq!(basis.fine() + 1, *level);
                single_scale_qr(basis, positions, values, ridge)
            }
        }
    }

    /// The same problem one level coarser.
    pub fn coarsen(self, bank: &crate::basis::FilterBank) -> Self {
        match self {
            Self::Normal(ne) => Self::Normal(ne.coarsen(bank)),
            Self::Qr {
                level,
                positions,
                values,
            } => Self::Qr {
                level: level - 1,
                positions,
                values,
            },
        }
    }
}
