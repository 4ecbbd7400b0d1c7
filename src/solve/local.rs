//! Local inversion: `K~[:, i] = (K[jdx, idx])^+ e_i` placed at rows `idx`, an approximate
//! `K^+` built one small pseudo-inverse per neighbourhood (docs/design.md §4).
//!
//! For pivot row `i`: `idx` = the column pattern of row `i`; `jdx` = the rows where any
//! column of `idx` is nonzero; each ring sets `idx` = all columns nonzero on `jdx`, then
//! recomputes `jdx`. `K1 = K[jdx, idx]`, `S1 = pinv(K1)`, and column `i` of `K~` is the
//! column of `S1` for row `i`, at rows `idx`.
//!
//! Speed: `idx` (hence `jdx` and `K1`) depends only on the pattern of row `i`, so pivots are
//! grouped by their pattern (hashed index slice), and after the rings grow them, by the
//! grown `idx` again; each group factors `K1` once and reads off the columns of all its
//! pivots. Groups run in parallel on the rayon pool, each factorization sequential
//! (see `kernel.rs`). Generic: any CSR matrix; structural nonzeros define the patterns.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use faer::Mat;
use rayon::prelude::*;
use serde::Serialize;
use sprs::CsMat;

use super::block::{cholesky_columns, qr_columns, svd_columns, BlockOut};
use super::params::{LocalInversionParams, Solver};
use super::sparse::{check_values, ldexp, normal_matrix, prepare, raw, Prepared};
use super::SolveError;

/// Statistics of one group (one factorized block `K1`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GroupStats {
    /// Rows of `K1` (`|jdx|`, samples in the neighbourhood).
    pub rows: usize,
    /// Columns of `K1` (`|idx|`, basis functions in the neighbourhood).
    pub cols: usize,
    /// Pivots (columns of `K~`) served by this factorization.
    pub pivots: usize,
    /// `s_max / s_min` of `K1` (exact for SVD; `|R_00|/|R_nn|` for QR; `max L_ii / min L_ii`
    /// of the equilibrated Cholesky factor, a lower bound, for Cholesky). Infinite when `K1`
    /// has a null space (`rows < cols`, exact zero singular value, or a shifted Cholesky).
    pub condition: f64,
    /// Directions dropped by the cut-off (`cols - numerical rank`); always 0 for Cholesky.
    pub cut: usize,
    /// Relative diagonal shift the Cholesky needed (0 = none).
    pub shift: f64,
    /// The SVD did not converge and QR was used.
    pub svd_fallback: bool,
    /// The chosen solver's block was ill-conditioned (Cholesky: estimated `cond(K1)` above
    /// [`CHOLESKY_MAX_CONDITION`] or a shift was needed; QR: kept `|R_00 / R_kk|` above
    /// [`WEAK_CONDITION`]) and the block was solved again by SVD.
    pub solver_fallback: bool,
    /// `s_max / s_kept` on the directions kept by the cut-off: how much the block amplifies
    /// data errors into the answer.
    pub kept_condition: f64,
}

/// Largest estimated `cond(K1)` a Cholesky block may have: the normal equations lose
/// `cond(K1)^2 eps` relative accuracy, so a Cholesky block stays within
/// `1e8 * eps ≈ 2.2e-8` (relative to the block's answer) of the SVD one; above it the block
/// is solved by SVD (reported as a solver fallback).
pub const CHOLESKY_MAX_CONDITION: f64 = 1e4;

/// Kept condition `s_max / s_kept` above which a block's answer is reported as weakly
/// supported by the data: data errors (and round-off, `eps` relative) are amplified by up
/// to that factor, about 1e-6 relative already from round-off alone.
pub const WEAK_CONDITION: f64 = 1e10;

/// min / median / max / mean of a per-group quantity.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Summary {
    /// Smallest value.
    pub min: f64,
    /// Median (upper median for an even count).
    pub median: f64,
    /// Largest value.
    pub max: f64,
    /// Arithmetic mean (infinite if any value is).
    pub mean: f64,
}

impl Summary {
    /// Summary of `values` (`NaN`s count as `+inf`); all zero for an empty list.
    pub fn of(values: impl IntoIterator<Item = f64>) -> Self {
        let mut v: Vec<f64> = values
            .into_iter()
            .map(|x| if x.is_nan() { f64::INFINITY } else { x })
            .collect();
        if v.is_empty() {
            return Self {
                min: 0.0,
                median: 0.0,
                max: 0.0,
                mean: 0.0,
            };
        }
        v.sort_by(f64::total_cmp);
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        Self {
            min: v[0],
            median: v[v.len() / 2],
            max: v[v.len() - 1],
            mean,
        }
    }
}

/// What the local inversion did, for reports.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LocalStats {
    /// Solver used.
    pub solver: Solver,
    /// Rings used.
    pub rings: usize,
    /// One entry per factorization.
    pub groups: Vec<GroupStats>,
    /// Number of factorizations (`groups.len()`).
    pub n_groups: usize,
    /// Distinct row patterns (before merging groups whose grown `idx` coincide).
    pub n_patterns: usize,
    /// Rows of `K` with no nonzero: their column of `K~` is zero.
    pub empty_rows: usize,
    /// Groups where the cut-off dropped at least one direction.
    pub cut_groups: usize,
    /// Directions dropped, summed over groups.
    pub cut_total: usize,
    /// Groups whose Cholesky needed a diagonal shift (fallback 1).
    pub cholesky_shifted: usize,
    /// Largest Cholesky shift used.
    pub max_shift: f64,
    /// Groups whose SVD did not converge and used QR (fallback 2).
    pub svd_fallbacks: usize,
    /// Groups re-solved by SVD because the chosen solver's block was ill-conditioned.
    pub solver_fallbacks: usize,
    /// Groups whose kept condition exceeds [`WEAK_CONDITION`]: their coefficients are not
    /// well supported by the samples.
    pub weak_groups: usize,
    /// Largest kept condition over groups.
    pub max_kept_condition: f64,
    /// The relative cut-off used.
    pub cutoff: f64,
    /// Whether `condition` is exact (SVD) or an estimate (QR, Cholesky).
    pub condition_is_estimate: bool,
    /// `K` was scaled by `2^-scale_exponent` internally (exact; undone in the results).
    pub scale_exponent: i32,
}

impl LocalStats {
    /// Every decision a reader must know about, one sentence each: directions cut,
    /// solver fallbacks, Cholesky shifts, weakly supported blocks.
    pub fn warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        if self.cut_groups > 0 {
            w.push(format!(
                "local inversion: {} of {} blocks had {} directions below the relative cut-off \
                 {:e}: the samples do not determine them (set to zero)",
                self.cut_groups, self.n_groups, self.cut_total, self.cutoff
            ));
        }
        if self.solver_fallbacks > 0 {
            w.push(format!(
                "local inversion: {} of {} blocks were too ill-conditioned for {:?} and were \
                 solved by SVD",
                self.solver_fallbacks, self.n_groups, self.solver
            ));
        }
        if self.svd_fallbacks > 0 {
            w.push(format!(
                "local inversion: the SVD of {} blocks did not converge; QR was used",
                self.svd_fallbacks
            ));
        }
        if self.weak_groups > 0 {
            w.push(format!(
                "local inversion: {} of {} blocks have a kept condition up to {:.1e} \
                 (above {:e}): the answer there is not supported by the data; give samples \
                 where they are sparse, fewer levels, or a larger cut-off",
                self.weak_groups, self.n_groups, self.max_kept_condition, WEAK_CONDITION
            ));
        }
        w
    }
    /// Block rows (`|jdx|`) over groups.
    pub fn rows_summary(&self) -> Summary {
        Summary::of(self.groups.iter().map(|g| g.rows as f64))
    }
    /// Block columns (`|idx|`) over groups.
    pub fn cols_summary(&self) -> Summary {
        Summary::of(self.groups.iter().map(|g| g.cols as f64))
    }
    /// Condition numbers over groups.
    pub fn condition_summary(&self) -> Summary {
        Summary::of(self.groups.iter().map(|g| g.condition))
    }
    /// Pivots per group.
    pub fn pivots_summary(&self) -> Summary {
        Summary::of(self.groups.iter().map(|g| g.pivots as f64))
    }
}

/// The approximate pseudo-inverse `K~ ≈ K^+` and how it was made.
#[derive(Debug, Clone)]
pub struct LocalInversion {
    /// `K~`, `P x m`, stored **CSC**: column `i` (pivot `i`) is produced whole by one group,
    /// its rows `idx` already sorted, so the matrix is assembled by appending with no sort
    /// or transpose; `K~ f = sum_i f_i K~[:, i]` streams it, and `pinv.transpose_view()` is
    /// the CSR matrix of the dual kernels (row `i` = coefficients of `k~_i`).
    pub pinv: CsMat<f64>,
    /// Statistics.
    pub stats: LocalStats,
}

/// Coefficients from [`apply_local`].
#[derive(Debug, Clone)]
pub struct LocalApply {
    /// `c[ch] = K~ f[ch]`, `P` values per channel.
    pub coefficients: Vec<Vec<f64>>,
    /// Statistics.
    pub stats: LocalStats,
}

/// FxHash-style hasher for index slices: the SipHash default costs more than the grouping.
#[derive(Default)]
struct FxHasher(u64);

impl Hasher for FxHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(b as u64);
        }
    }
    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    fn write_usize(&mut self, v: usize) {
        self.write_u64(v as u64);
    }
}

type FxMap<K, V> = HashMap<K, V, BuildHasherDefault<FxHasher>>;

/// One block: its columns, rows and the pivots it serves (all sorted ascending).
struct Group {
    idx: Vec<usize>,
    jdx: Vec<usize>,
    pivots: Vec<usize>,
}

/// Sorted union of the index lists `outer` of the given rows of a CSR matrix.
fn union_of(indptr: &[usize], indices: &[usize], outer: &[usize]) -> Vec<usize> {
    let mut out = Vec::new();
    for &o in outer {
        out.extend_from_slice(&indices[indptr[o]..indptr[o + 1]]);
    }
    out.sort_unstable();
    out.dedup();
    // The concatenation is ~10x longer than the union: without this, every group keeps that
    // capacity (tens of GB at 1e6 samples: docs/measurements/basis.md, "Solver per block,
    // parallelism and memory").
    out.shrink_to_fit();
    out
}

fn hash_slice(v: &[usize]) -> u64 {
    let mut h = FxHasher::default();
    for &x in v {
        h.write_usize(x);
    }
    h.write_usize(v.len());
    h.finish()
}

/// Classes of equal slices: `class[i]` = index of the first `i' <= i` with
/// `key(i') == key(i)`, hashed in parallel, compared exactly (no false merge on a hash
/// collision).
fn classes<'a>(n: usize, key: impl Fn(usize) -> &'a [usize] + Sync) -> Vec<usize> {
    let hashes: Vec<u64> = (0..n).into_par_iter().map(|i| hash_slice(key(i))).collect();
    let mut first: FxMap<u64, Vec<usize>> = FxMap::default();
    let mut class = Vec::with_capacity(n);
    for (i, &h) in hashes.iter().enumerate() {
        // consecutive equal keys (sorted samples) skip the map
        if i > 0 && hashes[i - 1] == h && key(i - 1) == key(i) {
            let c = class[i - 1];
            class.push(c);
            continue;
        }
        let bucket = first.entry(h).or_default();
        match bucket.iter().find(|&&j| key(j) == key(i)) {
            Some(&j) => class.push(j),
            None => {
                bucket.push(i);
                class.push(i);
            }
        }
    }
    class
}

/// Groups the rows of `K` by pattern, grows neighbourhoods, merges equal `idx`.
fn build_groups(prep: &Prepared, rings: usize) -> (Vec<Group>, usize, usize) {
    let (kp, ki, _) = raw(&prep.k);
    let (tp, ti, _) = raw(&prep.kt);
    let m = prep.k.rows();
    let class = classes(m, |i| &ki[kp[i]..kp[i + 1]]);
    // representative row -> group number, in order of first appearance
    let mut number = vec![usize::MAX; m];
    let mut patterns: Vec<(usize, Vec<usize>)> = Vec::new();
    let mut empty = 0;
    for i in 0..m {
        if kp[i] == kp[i + 1] {
            empty += 1;
            continue;
        }
        let c = class[i];
        if number[c] == usize::MAX {
            number[c] = patterns.len();
            patterns.push((c, Vec::new()));
        }
        patterns[number[c]].1.push(i);
    }
    drop(number);
    let n_patterns = patterns.len();
    let grown: Vec<Group> = patterns
        .into_par_iter()
        .map(|(rep, pivots)| {
            let mut idx = ki[kp[rep]..kp[rep + 1]].to_vec();
            let mut jdx = union_of(tp, ti, &idx);
            for _ in 0..rings {
                let grown = union_of(kp, ki, &jdx);
                // A closed neighbourhood grows no further: more rings cost nothing.
                if grown.len() == idx.len() {
                    break;
                }
                idx = grown;
                jdx = union_of(tp, ti, &idx);
            }
            Group { idx, jdx, pivots }
        })
        .collect();
    if rings == 0 {
        return (grown, n_patterns, empty);
    }
    // Different patterns can grow into the same neighbourhood: one factorization each.
    let class = classes(grown.len(), |g| grown[g].idx.as_slice());
    if class.iter().enumerate().all(|(g, &c)| g == c) {
        return (grown, n_patterns, empty);
    }
    let mut extra: Vec<Vec<usize>> = vec![Vec::new(); grown.len()];
    for (g, &c) in class.iter().enumerate() {
        if c != g {
            extra[c].extend_from_slice(&grown[g].pivots);
        }
    }
    let mut merged: Vec<Group> = grown
        .into_iter()
        .zip(extra)
        .enumerate()
        .filter(|(g, _)| class[*g] == *g)
        .map(|(_, (mut grp, more))| {
            grp.pivots.extend(more);
            grp
        })
        .collect();
    merged.par_iter_mut().for_each(|g| g.pivots.sort_unstable());
    (merged, n_patterns, empty)
}

/// Everything the block solves need, prepared once.
struct Context {
    prep: Prepared,
    normal: Option<CsMat<f64>>,
    params: LocalInversionParams,
}

/// Factors one group: `X = S1[:, pivots]`, `|idx| x |pivots|`, in units of the scaled `K_s`.
fn solve_group(ctx: &Context, g: &Group) -> Result<(BlockOut, GroupStats), SolveError> {
    let (kp, ki, kd) = raw(&ctx.prep.k);
    let (n, r) = (g.idx.len(), g.jdx.len());
    // One block per thread at a time.
    crate::resources::check(
        || {
            format!(
                "a local inversion block of {r} x {n} (times {} threads)",
                rayon::current_num_threads()
            )
        },
        crate::resources::dense_block_bytes(r, n, g.pivots.len())
            * rayon::current_num_threads() as f64,
        || {
            "spread the samples (clusters make large blocks), use fewer rings, or a global method"
                .into()
        },
    )?;
    let dense_block = || {
        let mut k1 = Mat::<f64>::zeros(r, n);
        for (ri, &j) in g.jdx.iter().enumerate() {
            for t in kp[j]..kp[j + 1] {
                if let Ok(ci) = g.idx.binary_search(&ki[t]) {
                    k1[(ri, ci)] += kd[t];
                }
            }
        }
        let piv: Vec<usize> = g
            .pivots
            .iter()
            .map(|p| g.jdx.binary_search(p).unwrap_or(0))
            .collect();
        (k1, piv)
    };
    let mut solver_fallback = false;
    let out = match ctx.params.solver {
        Solver::Svd | Solver::Qr => {
            let (k1, piv) = dense_block();
            if ctx.params.solver == Solver::Svd {
                svd_columns(k1.as_ref(), &piv, ctx.params.cutoff)
            } else {
                let out = qr_columns(k1.as_ref(), &piv, ctx.params.cutoff);
                if out.kept > WEAK_CONDITION {
                    solver_fallback = true;
                    svd_columns(k1.as_ref(), &piv, ctx.params.cutoff)
                } else {
                    out
                }
            }
        }
        Solver::Cholesky => {
            let normal = ctx
                .normal
                .as_ref()
                .ok_or_else(|| SolveError::Factorization {
                    what: "internal: normal matrix missing for the Cholesky solver".into(),
                })?;
            let (gp, gi, gd) = raw(normal);
            let mut gm = Mat::<f64>::zeros(n, n);
            for (ai, &a) in g.idx.iter().enumerate() {
                for t in gp[a]..gp[a + 1] {
                    if let Ok(bi) = g.idx.binary_search(&gi[t]) {
                        gm[(ai, bi)] = gd[t];
                    }
                }
            }
            let mut b = Mat::<f64>::zeros(n, g.pivots.len());
            for (t, &p) in g.pivots.iter().enumerate() {
                for s in kp[p]..kp[p + 1] {
                    if let Ok(ci) = g.idx.binary_search(&ki[s]) {
                        b[(ci, t)] += kd[s];
                    }
                }
            }
            match cholesky_columns(gm, b, ctx.params.cholesky_shift) {
                Some(out) if out.shift == 0.0 && out.kept <= CHOLESKY_MAX_CONDITION => out,
                // Shifted, failed, or too ill-conditioned for the normal equations.
                _ => {
                    solver_fallback = true;
                    let (k1, piv) = dense_block();
                    svd_columns(k1.as_ref(), &piv, ctx.params.cutoff)
                }
            }
        }
    };
    let stats = GroupStats {
        rows: r,
        cols: n,
        pivots: g.pivots.len(),
        condition: out.condition,
        cut: out.cut,
        shift: out.shift,
        svd_fallback: out.fallback,
        solver_fallback,
        kept_condition: out.kept,
    };
    Ok((out, stats))
}

/// Validation, scaling, grouping, and the parallel factorizations, shared by both entry
/// points; `each` turns a group's block result into what the caller keeps.
fn run<T: Send>(
    k: &CsMat<f64>,
    params: &LocalInversionParams,
    each: impl Fn(&Group, Mat<f64>) -> Result<T, SolveError> + Sync,
) -> Result<(Vec<Group>, Vec<T>, LocalStats), SolveError> {
    params.validate()?;
    let prep = prepare(k)?;
    let normal = (params.solver == Solver::Cholesky).then(|| normal_matrix(&prep.k, &prep.kt));
    let (groups, n_patterns, empty_rows) = build_groups(&prep, params.rings);
    let exponent = prep.exponent;
    let ctx = Context {
        prep,
        normal,
        params: *params,
    };
    let results: Vec<(T, GroupStats)> = groups
        .par_iter()
        .map(|g| {
            let (out, st) = solve_group(&ctx, g)?;
            let mut x = out.x;
            if exponent != 0 {
                for j in 0..x.ncols() {
                    for i in 0..x.nrows() {
                        x[(i, j)] = ldexp(x[(i, j)], -exponent);
                    }
                }
            }
            for j in 0..x.ncols() {
                for i in 0..x.nrows() {
                    if !x[(i, j)].is_finite() {
                        return Err(SolveError::NonFiniteOutput {
                            what: format!(
                                "local pseudo-inverse column of row {} ({} x {} block, \
                                 condition {:.3e})",
                                g.pivots[j], st.rows, st.cols, st.condition
                            ),
                        });
                    }
                }
            }
            Ok((each(g, x)?, st))
        })
        .collect::<Result<_, _>>()?;
    let (kept, group_stats): (Vec<T>, Vec<GroupStats>) = results.into_iter().unzip();
    let stats = LocalStats {
        solver: params.solver,
        rings: params.rings,
        n_groups: group_stats.len(),
        n_patterns,
        empty_rows,
        cut_groups: group_stats.iter().filter(|g| g.cut > 0).count(),
        cut_total: group_stats.iter().map(|g| g.cut).sum(),
        cholesky_shifted: group_stats.iter().filter(|g| g.shift > 0.0).count(),
        max_shift: group_stats.iter().map(|g| g.shift).fold(0.0, f64::max),
        svd_fallbacks: group_stats.iter().filter(|g| g.svd_fallback).count(),
        solver_fallbacks: group_stats.iter().filter(|g| g.solver_fallback).count(),
        weak_groups: group_stats
            .iter()
            .filter(|g| g.kept_condition > WEAK_CONDITION)
            .count(),
        max_kept_condition: group_stats
            .iter()
            .map(|g| g.kept_condition)
            .fold(0.0, f64::max),
        cutoff: params.cutoff,
        condition_is_estimate: params.solver != Solver::Svd,
        scale_exponent: exponent,
        groups: group_stats,
    };
    Ok((groups, kept, stats))
}

/// The approximate pseudo-inverse `K~` (`P x m`, CSC) of a CSR (or CSC, converted) `K`.
///
/// Cost: one factorization per group (see [`LocalStats::n_groups`]); memory: the
/// `sum over pivots of |idx|` stored entries of `K~` plus the same again transiently.
pub fn local_inversion(
    k: &CsMat<f64>,
    params: &LocalInversionParams,
) -> Result<LocalInversion, SolveError> {
    let (m, p) = k.shape();
    let (groups, blocks, stats) = run(k, params, |_, x| Ok(x))?;
    // owner[i] = (group, column in its block)
    let mut owner = vec![(usize::MAX, 0usize); m];
    for (gi, g) in groups.iter().enumerate() {
        for (t, &i) in g.pivots.iter().enumerate() {
            owner[i] = (gi, t);
        }
    }
    let mut indptr = Vec::with_capacity(m + 1);
    indptr.push(0usize);
    let mut nnz = 0;
    for &(gi, _) in &owner {
        if gi != usize::MAX {
            nnz += groups[gi].idx.len();
        }
        indptr.push(nnz);
    }
    let mut indices = vec![0usize; nnz];
    let mut data = vec![0.0f64; nnz];
    // one disjoint (indices, data) slice per column, filled in parallel
    let mut cols: Vec<(&mut [usize], &mut [f64])> = Vec::with_capacity(m);
    let (mut ri, mut rd) = (indices.as_mut_slice(), data.as_mut_slice());
    for w in indptr.windows(2) {
        let len = w[1] - w[0];
        let (ci, ti) = std::mem::take(&mut ri).split_at_mut(len);
        let (cd, td) = std::mem::take(&mut rd).split_at_mut(len);
        cols.push((ci, cd));
        ri = ti;
        rd = td;
    }
    cols.into_par_iter()
        .zip(owner.par_iter())
        .for_each(|((ci, cd), &(gi, t))| {
            if gi != usize::MAX {
                ci.copy_from_slice(&groups[gi].idx);
                let x = &blocks[gi];
                for (a, v) in cd.iter_mut().enumerate() {
                    *v = x[(a, t)];
                }
            }
        });
    let pinv = CsMat::new_csc((p, m), indptr, indices, data);
    Ok(LocalInversion { pinv, stats })
}

/// `c[ch] = K~ f[ch]` for every channel without storing `K~`: each group is factored once
/// and its block applied to all channels (`values[ch].len() == rows of K`).
pub fn apply_local(
    k: &CsMat<f64>,
    values: &[&[f64]],
    params: &LocalInversionParams,
) -> Result<LocalApply, SolveError> {
    let (m, p) = k.shape();
    check_values(values, m)?;
    let nch = values.len();
    let (groups, contribs, stats) = run(k, params, |g, x| {
        // contribution (|idx| x channels) = X (|idx| x g) * F (g x channels)
        let f = Mat::<f64>::from_fn(g.pivots.len(), nch, |t, c| values[c][g.pivots[t]]);
        let mut y = Mat::<f64>::zeros(x.nrows(), nch);
        faer::linalg::matmul::matmul(
            y.as_mut(),
            faer::Accum::Replace,
            x.as_ref(),
            f.as_ref(),
            1.0,
            faer::Par::Seq,
        );
        Ok(y)
    })?;
    let mut coefficients = vec![vec![0.0; p]; nch];
    for (g, y) in groups.iter().zip(&contribs) {
        for (c, out) in coefficients.iter_mut().enumerate() {
            for (ai, &a) in g.idx.iter().enumerate() {
                out[a] += y[(ai, c)];
            }
        }
    }
    for (c, out) in coefficients.iter().enumerate() {
        super::sparse::check_finite_output(out, &format!("apply_local channel {c}"))?;
    }
    Ok(LocalApply {
        coefficients,
        stats,
    })
}
