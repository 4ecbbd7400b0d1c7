//! The normal matrix of the direct tree solve, `G = K_T^T K_T`, assembled in parallel and
//! deterministically, and carried from round to round ([`TreeGram`]).
//!
//! **Assembly** (Gustavson by rows of the upper triangle): row `a` of the upper triangle is
//!
//! ```text
//! G[a, b] = sum_{j in supp(a), ascending} K[j, a] K[j, b],      b >= a,
//! ```
//!
//! accumulated in a dense accumulator over the samples `j` where function `a` lives (row `a`
//! of `K^T`), each sample's row of `K` read from `a` on. Every entry is a sum in ascending
//! sample order starting from `0.0`, whatever the thread count and the work split: the result
//! is the same bits for the same `K` (and the same as `sprs`'s `K^T K`, which sums in the same
//! order). The lower triangle is the mirror image (the solver takes both triangles).
//!
//! **Update between rounds.** A round adds samples (appended: indices `m_old..m`) and functions
//! (the tree only grows). With the previous round's upper triangle `G_old` (over the old
//! functions, old samples):
//!
//! ```text
//! G[a, b] = G_old[a, b] + sum_{j >= m_old, ascending} K[j, a] K[j, b]     a, b old,
//! G[a, b] = sum_{all j, ascending} K[j, a] K[j, b]                         a or b new.
//! ```
//!
//! `G_old[a, b]` is the running sum after sample `m_old - 1`, so continuing it with the new
//! samples in ascending order is the full assembly's sum operation for operation: the updated
//! `G` equals the rebuilt one bit for bit, and a plan resumed from files (which rebuilds) fits
//! exactly as the in-process loop (which updates). The update reads, for an old function `a`,
//! only the new samples' rows and the old samples' entries on new functions, so its cost is
//! that of what changed: `sum_{j new} r_j^2 / 2 + sum_{a} |supp(a)| r_new`, against
//! `sum_j r_j^2 / 2` for a rebuild (`r_j` the nonzeros of row `j`).

use sprs::CsMat;

use crate::image::adaptive::oracle::mix64;
use crate::solve::{csr_by_rows, csr_raw as raw};

/// The upper triangle of `G = K_T^T K_T` of the last fit, kept for the next round's update.
#[derive(Clone)]
pub struct TreeGram {
    /// The tree's functions (ascending Mallat indices): the columns of `upper`.
    functions: Vec<usize>,
    /// The samples the matrix was summed over (the next call's samples must start with them).
    xs: Vec<f64>,
    ys: Vec<f64>,
    /// Upper triangle (`b >= a` in row `a`), CSR, sorted.
    upper: CsMat<f64>,
}

impl TreeGram {
    /// Stored entries of the full `G` it holds (both triangles) and its functions.
    pub(crate) fn size(&self) -> (usize, usize) {
        (
            (2 * self.upper.nnz()).saturating_sub(self.functions.len()),
            self.functions.len(),
        )
    }
}

/// The first bytes of [`TreeGram::to_bytes`]: the layout's name and version.
const GRAM_MAGIC: &[u8; 8] = b"RKWGRAM1";

/// Why bytes are not a carried state (a normal matrix, PCG's start) for the caller's plan
/// (the caller starts afresh).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum GramBytesError {
    /// Not this layout or version.
    #[error("not a {what} of this build's layout (its first bytes are not `{magic}`)")]
    Layout {
        /// What the file should hold.
        what: &'static str,
        /// The layout's first bytes.
        magic: &'static str,
    },
    /// Written for another plan (its tag differs).
    #[error("written for another plan (tag {found:016x}, this plan's {expected:016x})")]
    OtherPlan {
        /// This plan's tag.
        expected: u64,
        /// The tag in the bytes.
        found: u64,
    },
    /// Cut short, or a checksum or size that does not add up.
    #[error("damaged: {0}")]
    Damaged(&'static str),
}

/// Checksum of 8-byte words: `sum_t mix(w_t + t)`, order-dependent, so a moved, cut or
/// flipped word changes it.
fn checksum(words: &[u8]) -> u64 {
    words.chunks_exact(8).enumerate().fold(0u64, |acc, (t, c)| {
        let w = u64::from_le_bytes(c.try_into().expect("8 bytes"));
        acc.wrapping_add(mix64(w.wrapping_add(t as u64)))
    })
}

/// The layout of a carried file: `magic`, then little-endian 64-bit words (the plan's `tag`
/// first, then the words `fill` writes, `words` of them), then a checksum of the words.
pub(crate) fn seal(
    magic: &[u8; 8],
    tag: u64,
    words: usize,
    fill: impl FnOnce(&mut dyn FnMut(u64)),
) -> Vec<u8> {
    let mut out = Vec::with_capacity(8 * (words + 2) + magic.len());
    out.extend_from_slice(magic);
    out.extend_from_slice(&tag.to_le_bytes());
    fill(&mut |v: u64| out.extend_from_slice(&v.to_le_bytes()));
    let sum = checksum(&out[magic.len()..]);
    out.extend_from_slice(&sum.to_le_bytes());
    out
}

/// The words of a [`seal`]ed file after its tag, read in order.
pub(crate) struct Words<'a>(std::slice::ChunksExact<'a, u8>);

impl Words<'_> {
    /// The next word.
    pub(crate) fn next(&mut self) -> Result<u64, GramBytesError> {
        self.0
            .next()
            .map(|c| u64::from_le_bytes(c.try_into().expect("8 bytes")))
            .ok_or(GramBytesError::Damaged("cut short"))
    }
    /// The next `n` words.
    pub(crate) fn take(&mut self, n: usize) -> Result<Vec<u64>, GramBytesError> {
        if self.0.len() < n {
            return Err(GramBytesError::Damaged("cut short"));
        }
        (0..n).map(|_| self.next()).collect()
    }
    /// Words left.
    pub(crate) fn left(&self) -> usize {
        self.0.len()
    }
}

/// The words of `bytes` sealed by [`seal`] with `magic` (a file holding a `what`), if they
/// are whole (checksum) and carry `tag`.
pub(crate) fn unseal<'a>(
    bytes: &'a [u8],
    magic: &'static [u8; 8],
    what: &'static str,
    tag: u64,
) -> Result<Words<'a>, GramBytesError> {
    let body = bytes.strip_prefix(magic).ok_or(GramBytesError::Layout {
        what,
        magic: std::str::from_utf8(magic).unwrap_or("?"),
    })?;
    if body.len() % 8 != 0 || body.len() < 16 {
        return Err(GramBytesError::Damaged("not a whole number of words"));
    }
    let (payload, sum) = body.split_at(body.len() - 8);
    if checksum(payload) != u64::from_le_bytes(sum.try_into().expect("8 bytes")) {
        return Err(GramBytesError::Damaged("the checksum does not match"));
    }
    let mut words = Words(payload.chunks_exact(8));
    let found = words.next()?;
    if found != tag {
        return Err(GramBytesError::OtherPlan {
            expected: tag,
            found,
        });
    }
    Ok(words)
}

impl TreeGram {
    /// The matrix as bytes (`seal`: `GRAM_MAGIC`, the caller's `tag` naming the plan it
    /// belongs to, then the sizes, the functions, the samples' positions, the upper
    /// triangle's CSR arrays, and a checksum of all that).
    pub fn to_bytes(&self, tag: u64) -> Vec<u8> {
        let (indptr, indices, data) = raw(&self.upper);
        let words = 3 + self.functions.len() + 2 * self.xs.len() + indptr.len() + 2 * data.len();
        seal(GRAM_MAGIC, tag, words, |word| {
            word(self.functions.len() as u64);
            word(self.xs.len() as u64);
            word(self.upper.nnz() as u64);
            self.functions.iter().for_each(|&f| word(f as u64));
            self.xs
                .iter()
                .chain(&self.ys)
                .for_each(|v| word(v.to_bits()));
            indptr.iter().chain(indices).for_each(|&i| word(i as u64));
            data.iter().for_each(|v| word(v.to_bits()));
        })
    }

    /// The matrix of [`TreeGram::to_bytes`], if the bytes are whole and carry `tag`. The
    /// structure is checked as well (ascending functions, a CSR of the upper triangle), so
    /// that what is read is a valid start for `assemble`, which then checks that its
    /// samples and functions fit the fit's.
    pub fn from_bytes(bytes: &[u8], tag: u64) -> Result<Self, GramBytesError> {
        let mut words = unseal(bytes, GRAM_MAGIC, "normal matrix", tag)?;
        let (p, m, nnz) = (
            words.next()? as usize,
            words.next()? as usize,
            words.next()? as usize,
        );
        let expected = 2 * (p as u128) + 1 + 2 * (m as u128) + 2 * (nnz as u128);
        if words.left() as u128 != expected {
            return Err(GramBytesError::Damaged("the sizes do not add up"));
        }
        let functions: Vec<usize> = words.take(p)?.into_iter().map(|v| v as usize).collect();
        let xs: Vec<f64> = words.take(m)?.into_iter().map(f64::from_bits).collect();
        let ys: Vec<f64> = words.take(m)?.into_iter().map(f64::from_bits).collect();
        let indptr: Vec<usize> = words.take(p + 1)?.into_iter().map(|v| v as usize).collect();
        let indices: Vec<usize> = words.take(nnz)?.into_iter().map(|v| v as usize).collect();
        let data: Vec<f64> = words.take(nnz)?.into_iter().map(f64::from_bits).collect();
        let ascending = functions.windows(2).all(|w| w[0] < w[1]);
        let upper_csr = indptr[0] == 0
            && indptr[p] == nnz
            && indptr.windows(2).all(|w| w[0] <= w[1])
            && (0..p).all(|a| {
                let row = &indices[indptr[a]..indptr[a + 1]];
                row.first().is_none_or(|&b| b >= a)
                    && row.windows(2).all(|w| w[0] < w[1])
                    && row.last().is_none_or(|&b| b < p)
            });
        if !ascending || !upper_csr {
            return Err(GramBytesError::Damaged("not an upper triangle in CSR"));
        }
        Ok(Self {
            functions,
            xs,
            ys,
            upper: CsMat::new((p, p), indptr, indices, data),
        })
    }

    /// Samples the matrix was summed over.
    pub fn samples(&self) -> usize {
        self.xs.len()
    }
}

/// The normal matrix a plan carries from one call to the next (the file protocol's
/// `gram.bin`), and why the one read was set aside. Solver state only: two plan states that
/// differ in it are equal.
#[derive(Clone, Debug, Default)]
pub struct CarriedGram {
    /// The matrix (`None`: the next fit assembles afresh).
    pub gram: Option<TreeGram>,
    /// Why the matrix read from the file was set aside (`None`: it was used, or there was
    /// none).
    pub note: Option<String>,
}

impl PartialEq for CarriedGram {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl PartialEq for TreeGram {
    /// The same functions, samples (by bits) and upper triangle (by bits).
    fn eq(&self, other: &Self) -> bool {
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        self.functions == other.functions
            && bits(&self.xs) == bits(&other.xs)
            && bits(&self.ys) == bits(&other.ys)
            && self.upper.indptr() == other.upper.indptr()
            && self.upper.indices() == other.upper.indices()
            && bits(self.upper.data()) == bits(other.upper.data())
    }
}

impl std::fmt::Debug for TreeGram {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TreeGram")
            .field("functions", &self.functions.len())
            .field("samples", &self.xs.len())
            .field("upper_nnz", &self.upper.nnz())
            .finish()
    }
}

/// How the normal matrix of one fit was obtained.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct GramUpdate {
    /// Functions carried over from the previous matrix (0: assembled from scratch).
    pub kept_functions: usize,
    /// Samples carried over from the previous matrix.
    pub kept_samples: usize,
}

/// Rows of the upper triangle computed per parallel work item at least (the result does not
/// depend on the split: each row is summed on its own).
const MIN_ROWS_PER_TASK: usize = 256;

/// `G = K^T K` (both triangles, CSR, sorted) from `K` (`m x P` CSR, sorted rows), `K^T`
/// (`P x m` CSR, sorted rows) and the positions of `K^T`'s entries in `K`'s rows
/// ([`crate::solve::transpose_with_positions`]: row `j` is read from column `a` on without a
/// search), updating `previous` when it applies (its functions a subset of
/// `functions`, its samples a prefix of `(xs, ys)`), and the upper triangle to keep.
pub(crate) fn assemble(
    k: &CsMat<f64>,
    kt: &CsMat<f64>,
    positions_in_rows: &[usize],
    functions: &[usize],
    xs: &[f64],
    ys: &[f64],
    previous: Option<&TreeGram>,
) -> (CsMat<f64>, TreeGram, GramUpdate) {
    let p = functions.len();
    let m = xs.len();
    // Old column -> new column, if the previous matrix can be continued.
    let carried = previous.and_then(|prev| {
        let mo = prev.xs.len();
        if mo > m || prev.xs[..] != xs[..mo] || prev.ys[..] != ys[..mo] {
            return None;
        }
        let mut map = Vec::with_capacity(prev.functions.len());
        let mut q = 0;
        for &f in &prev.functions {
            while q < p && functions[q] < f {
                q += 1;
            }
            if q == p || functions[q] != f {
                return None;
            }
            map.push(q);
        }
        Some((prev, map, mo))
    });
    let (kp, ki, kd) = raw(k);
    let (tp, ti, td) = raw(kt);
    // Old-sample rows restricted to the new functions (only those rows are read).
    let (is_old, newk) = match &carried {
        Some((_, map, mo)) => {
            let mut is_old = vec![false; p];
            for &q in map {
                is_old[q] = true;
            }
            let mut ptr = Vec::with_capacity(mo + 1);
            ptr.push(0usize);
            let (mut idx, mut val) = (Vec::new(), Vec::new());
            for j in 0..*mo {
                for s in kp[j]..kp[j + 1] {
                    if !is_old[ki[s]] {
                        idx.push(ki[s]);
                        val.push(kd[s]);
                    }
                }
                ptr.push(idx.len());
            }
            (is_old, Some((ptr, idx, val)))
        }
        None => (Vec::new(), None),
    };
    let old_index: Vec<usize> = match &carried {
        Some((_, map, _)) => {
            let mut inv = vec![usize::MAX; p];
            for (o, &q) in map.iter().enumerate() {
                inv[q] = o;
            }
            inv
        }
        None => Vec::new(),
    };
    let threads = rayon::current_num_threads().max(1);
    let rows_per_task = p.div_ceil(threads * 16).max(MIN_ROWS_PER_TASK);
    let upper = csr_by_rows((p, p), rows_per_task, |a, acc| match (&carried, &newk) {
        (Some((prev, map, mo)), Some((np, ni, nd))) if is_old[a] => {
            // The old sums first (over old samples), continued below.
            let (up, ui, ud) = raw(&prev.upper);
            let o = old_index[a];
            for t in up[o]..up[o + 1] {
                acc.add(map[ui[t]], ud[t]);
            }
            for t in tp[a]..tp[a + 1] {
                let (j, kja) = (ti[t], td[t]);
                if j < *mo {
                    // Old sample: only its entries on new functions are new.
                    let row = &ni[np[j]..np[j + 1]];
                    let from = np[j] + row.partition_point(|&b| b < a);
                    acc.add_scaled(kja, &ni[from..np[j + 1]], &nd[from..np[j + 1]]);
                } else {
                    let s = positions_in_rows[t];
                    acc.add_scaled(kja, &ki[s..kp[j + 1]], &kd[s..kp[j + 1]]);
                }
            }
        }
        _ => {
            for t in tp[a]..tp[a + 1] {
                let (j, s) = (ti[t], positions_in_rows[t]);
                acc.add_scaled(td[t], &ki[s..kp[j + 1]], &kd[s..kp[j + 1]]);
            }
        }
    });
    let full = mirror(&upper);
    let update = carried
        .as_ref()
        .map_or(GramUpdate::default(), |(prev, _, mo)| GramUpdate {
            kept_functions: prev.functions.len(),
            kept_samples: *mo,
        });
    let kept = TreeGram {
        functions: functions.to_vec(),
        xs: xs.to_vec(),
        ys: ys.to_vec(),
        upper,
    };
    (full, kept, update)
}

/// Both triangles from the upper one: row `a` is `(b, G[b, a])` for `b < a` (the upper rows'
/// entries in column `a`, by ascending `b`), then the upper row.
fn mirror(upper: &CsMat<f64>) -> CsMat<f64> {
    let p = upper.rows();
    let (up, ui, ud) = raw(upper);
    let mut lower_len = vec![0usize; p];
    for b in 0..p {
        for &a in &ui[up[b]..up[b + 1]] {
            if a > b {
                lower_len[a] += 1;
            }
        }
    }
    let mut indptr = Vec::with_capacity(p + 1);
    indptr.push(0usize);
    for a in 0..p {
        indptr.push(indptr[a] + lower_len[a] + (up[a + 1] - up[a]));
    }
    let nnz = indptr[p];
    let mut indices = vec![0usize; nnz];
    let mut data = vec![0.0f64; nnz];
    // Lower parts: scatter by ascending b; next free slot per row.
    let mut next: Vec<usize> = indptr[..p].to_vec();
    for b in 0..p {
        for t in up[b]..up[b + 1] {
            let a = ui[t];
            if a > b {
                indices[next[a]] = b;
                data[next[a]] = ud[t];
                next[a] += 1;
            }
        }
    }
    for a in 0..p {
        let (from, to) = (up[a], up[a + 1]);
        let at = next[a];
        indices[at..at + (to - from)].copy_from_slice(&ui[from..to]);
        data[at..at + (to - from)].copy_from_slice(&ud[from..to]);
    }
    CsMat::new((p, p), indptr, indices, data)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::transpose_with_positions;

    /// A random sparse `m x p` matrix with sorted rows.
    fn random(m: usize, p: usize, seed: u64) -> CsMat<f64> {
        let mut s = seed;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut tri = sprs::TriMat::new((m, p));
        for j in 0..m {
            for a in 0..p {
                if next() < 0.2 {
                    tri.add_triplet(j, a, next() - 0.5);
                }
            }
        }
        tri.to_csr()
    }

    /// The assembly equals sprs's `K^T K` entry for entry (same summation order, so exactly).
    #[test]
    fn equals_sprs_product() {
        let k = random(300, 40, 7);
        let (kt, at) = transpose_with_positions(&k);
        let by_sprs: CsMat<f64> = k.transpose_view().to_csr();
        assert_eq!(kt, by_sprs);
        let reference: CsMat<f64> = &kt * &k;
        let xs: Vec<f64> = (0..300).map(|i| i as f64).collect();
        let functions: Vec<usize> = (0..40).collect();
        let (g, _, update) = assemble(&k, &kt, &at, &functions, &xs, &xs, None);
        assert_eq!(update, GramUpdate::default());
        assert_eq!(g.indptr(), reference.indptr());
        assert_eq!(g.indices(), reference.indices());
        assert_eq!(g.data(), reference.data());
    }

    /// The bytes give back the same matrix; a flipped bit, a cut, another layout or another
    /// plan's tag are each refused with their reason.
    #[test]
    fn bytes_round_trip_and_damage() {
        let k = random(120, 30, 5);
        let (kt, at) = transpose_with_positions(&k);
        let xs: Vec<f64> = (0..120).map(|i| i as f64 * 0.3).collect();
        let functions: Vec<usize> = (0..30).map(|a| 2 * a).collect();
        let (_, gram, _) = assemble(&k, &kt, &at, &functions, &xs, &xs, None);
        let bytes = gram.to_bytes(42);
        assert_eq!(TreeGram::from_bytes(&bytes, 42), Ok(gram.clone()));
        assert_eq!(
            TreeGram::from_bytes(&bytes, 43),
            Err(GramBytesError::OtherPlan {
                expected: 43,
                found: 42
            })
        );
        let mut flipped = bytes.clone();
        flipped[100] ^= 1;
        assert!(matches!(
            TreeGram::from_bytes(&flipped, 42),
            Err(GramBytesError::Damaged(_))
        ));
        assert!(matches!(
            TreeGram::from_bytes(&bytes[..bytes.len() - 8], 42),
            Err(GramBytesError::Damaged(_))
        ));
        assert!(matches!(
            TreeGram::from_bytes(b"RKWGRAM0", 42),
            Err(GramBytesError::Layout { .. })
        ));
    }

    /// Updating with appended samples and inserted functions equals rebuilding, bit for bit.
    #[test]
    fn update_equals_rebuild() {
        let (m, p) = (400, 50);
        let k = random(m, p, 11);
        let xs: Vec<f64> = (0..m).map(|i| i as f64 * 0.5).collect();
        let ys: Vec<f64> = (0..m).map(|i| i as f64 * 0.25).collect();
        let functions: Vec<usize> = (0..p).map(|a| 3 * a + 1).collect();
        // The previous round: the first 250 samples, every function but a few.
        let kept: Vec<usize> = (0..p).filter(|a| a % 7 != 3).collect();
        let mo = 250;
        let k_old = {
            let mut tri = sprs::TriMat::new((mo, kept.len()));
            for (o, &a) in kept.iter().enumerate() {
                for j in 0..mo {
                    if let Some(&v) = k.get(j, a) {
                        tri.add_triplet(j, o, v);
                    }
                }
            }
            tri.to_csr::<usize>()
        };
        let (kt_old, at_old) = transpose_with_positions(&k_old);
        let old_functions: Vec<usize> = kept.iter().map(|&a| functions[a]).collect();
        let (_, previous, _) = assemble(
            &k_old,
            &kt_old,
            &at_old,
            &old_functions,
            &xs[..mo],
            &ys[..mo],
            None,
        );
        let (kt, at) = transpose_with_positions(&k);
        let (rebuilt, _, _) = assemble(&k, &kt, &at, &functions, &xs, &ys, None);
        let (updated, _, update) = assemble(&k, &kt, &at, &functions, &xs, &ys, Some(&previous));
        assert_eq!(update.kept_functions, kept.len());
        assert_eq!(update.kept_samples, mo);
        assert_eq!(updated.indptr(), rebuilt.indptr());
        assert_eq!(updated.indices(), rebuilt.indices());
        assert_eq!(updated.data(), rebuilt.data());
        // Other samples: not continued.
        let mut moved = xs.clone();
        moved[3] += 1.0;
        let (_, _, update) = assemble(&k, &kt, &at, &functions, &moved, &ys, Some(&previous));
        assert_eq!(update, GramUpdate::default());
    }
}
