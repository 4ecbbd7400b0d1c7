//! The single-scale rows `E[i, k] = Phi_k(x_i, y_i)` (`m x nx ny`, `(2p - 1)^2` entries a
//! row, stored as their two 1D factors per sample) and their columns: the matrix through
//! which the tree kernel factors as `K_T = E S P_T` (`S` the 2D synthesis, `P_T` the
//! injection of the tree's coefficients), so that `K_T v` and `K_T^T r` cost one 2D FWT and
//! one pass over `E` each.

use rayon::prelude::*;

use super::diagonal::positions_hash;
use super::gram::{seal, unseal};
use crate::basis::tensor::TensorBasis;
use crate::solve::vectors::interleave;

/// Positions evaluated per parallel work item.
const CHUNK: usize = 4096;

/// The single-scale rows `E` (`m x nx ny`), stored as their two 1D factors per sample.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SingleScaleRows {
    nx: usize,
    /// What the rows depend on ([`basis_key`]).
    basis_key: [usize; 7],
    /// The bits of the last row's position (a check that a continued prefix is one).
    last: (u64, u64),
    ptr_x: Vec<u32>,
    ix: Vec<u32>,
    vx: Vec<f64>,
    ptr_y: Vec<u32>,
    iy: Vec<u32>,
    vy: Vec<f64>,
}

/// The single-scale space's order, image size, levels and layout: what [`SingleScaleRows`]
/// depend on besides the filters (a state continued on the same tree's basis has the same
/// ones).
fn basis_key(basis: &TensorBasis) -> [usize; 7] {
    let (jx, jy) = basis.levels();
    let (nx, ny) = basis.dims();
    [
        basis.p(),
        basis.width(),
        basis.height(),
        jx as usize,
        jy as usize,
        nx,
        ny,
    ]
}

impl SingleScaleRows {
    /// Rows of the positions `(xs[i], ys[i])` (checked to lie in the image).
    pub fn new(basis: &TensorBasis, xs: &[f64], ys: &[f64]) -> Self {
        let mut rows = Self {
            nx: basis.dims().0,
            basis_key: basis_key(basis),
            ptr_x: vec![0],
            ptr_y: vec![0],
            ..Self::default()
        };
        rows.append(basis, xs, ys);
        rows
    }

    /// Samples (rows).
    pub fn len(&self) -> usize {
        self.ptr_x.len() - 1
    }
    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The rows of `(xs, ys)` continuing `previous`, the rows of a prefix of them on the
    /// same basis (a round's samples are the previous ones plus new ones): only the new
    /// positions are evaluated. Anything else (`None`, another basis, more rows than
    /// positions, a last row at another position) is evaluated afresh.
    pub fn continued(previous: Option<Self>, basis: &TensorBasis, xs: &[f64], ys: &[f64]) -> Self {
        let usable = previous.filter(|r| {
            let old = r.len();
            r.basis_key == basis_key(basis)
                && old <= xs.len()
                && (old == 0 || r.last == (xs[old - 1].to_bits(), ys[old - 1].to_bits()))
        });
        match usable {
            Some(mut rows) => {
                let old = rows.len();
                rows.append(basis, &xs[old..], &ys[old..]);
                rows
            }
            None => Self::new(basis, xs, ys),
        }
    }

    /// Appends the rows of new positions (a round's new samples).
    pub fn append(&mut self, basis: &TensorBasis, xs: &[f64], ys: &[f64]) {
        type Part = (Vec<u32>, Vec<u32>, Vec<f64>, Vec<u32>, Vec<u32>, Vec<f64>);
        let parts: Vec<Part> = xs
            .par_chunks(CHUNK)
            .zip(ys.par_chunks(CHUNK))
            .map(|(cx, cy)| {
                let mut ev = basis.evaluator();
                let mut part: Part = Default::default();
                for (&x, &y) in cx.iter().zip(cy) {
                    let (fx, fy) = ev.factors_unchecked(x, y);
                    part.0.push(fx.len() as u32);
                    part.1.extend(fx.iter().map(|v| v.index as u32));
                    part.2.extend(fx.iter().map(|v| v.value));
                    part.3.push(fy.len() as u32);
                    part.4.extend(fy.iter().map(|v| v.index as u32));
                    part.5.extend(fy.iter().map(|v| v.value));
                }
                part
            })
            .collect();
        if let (Some(&x), Some(&y)) = (xs.last(), ys.last()) {
            self.last = (x.to_bits(), y.to_bits());
        }
        for (cx, ix, vx, cy, iy, vy) in parts {
            for c in cx {
                self.ptr_x.push(self.ptr_x.last().unwrap() + c);
            }
            for c in cy {
                self.ptr_y.push(self.ptr_y.last().unwrap() + c);
            }
            self.ix.extend(ix);
            self.vx.extend(vx);
            self.iy.extend(iy);
            self.vy.extend(vy);
        }
    }

    fn factors(&self, i: usize) -> (&[u32], &[f64], &[u32], &[f64]) {
        let (a, b) = (self.ptr_x[i] as usize, self.ptr_x[i + 1] as usize);
        let (c, d) = (self.ptr_y[i] as usize, self.ptr_y[i + 1] as usize);
        (
            &self.ix[a..b],
            &self.vx[a..b],
            &self.iy[c..d],
            &self.vy[c..d],
        )
    }

    /// `out = E s` (single-scale coefficients `s` to values at the samples).
    pub fn apply(&self, s: &[f64], out: &mut [f64]) {
        self.apply_many(s, 1, out);
    }

    /// `out = E s` for `k` vectors at once, interleaved: `s[j k + c]` is coefficient `j` of
    /// vector `c`, `out[i k + c]` the value of vector `c` at sample `i` (one pass over the
    /// rows for every vector).
    pub fn apply_many(&self, s: &[f64], k: usize, out: &mut [f64]) {
        // The channel count as a constant for the counts the refiner uses (3 image channels,
        // and 4 probes beside them): the same sums in the same order, unrolled.
        match k {
            1 => self.apply_fixed::<1>(s, out),
            3 => self.apply_fixed::<3>(s, out),
            4 => self.apply_fixed::<4>(s, out),
            7 => self.apply_fixed::<7>(s, out),
            _ => self.apply_dynamic(s, k, out),
        }
    }

    fn apply_fixed<const K: usize>(&self, s: &[f64], out: &mut [f64]) {
        let nx = self.nx;
        out.par_chunks_mut(CHUNK * K)
            .enumerate()
            .for_each(|(chunk, o)| {
                for (j, v) in o.chunks_exact_mut(K).enumerate() {
                    let (ix, vx, iy, vy) = self.factors(chunk * CHUNK + j);
                    let mut acc = [0.0; K];
                    for (&ky, &wy) in iy.iter().zip(vy) {
                        let mut inner = [0.0; K];
                        for (&kx, &wx) in ix.iter().zip(vx) {
                            let at = (ky as usize * nx + kx as usize) * K;
                            let sv: &[f64; K] = s[at..at + K].try_into().expect("K values");
                            for c in 0..K {
                                inner[c] += wx * sv[c];
                            }
                        }
                        for c in 0..K {
                            acc[c] += wy * inner[c];
                        }
                    }
                    v.copy_from_slice(&acc);
                }
            });
    }

    fn apply_dynamic(&self, s: &[f64], k: usize, out: &mut [f64]) {
        let nx = self.nx;
        out.par_chunks_mut(CHUNK * k)
            .enumerate()
            .for_each(|(chunk, o)| {
                let mut acc = vec![0.0; k];
                let mut inner = vec![0.0; k];
                for (j, v) in o.chunks_mut(k).enumerate() {
                    let (ix, vx, iy, vy) = self.factors(chunk * CHUNK + j);
                    acc.iter_mut().for_each(|a| *a = 0.0);
                    for (&ky, &wy) in iy.iter().zip(vy) {
                        inner.iter_mut().for_each(|a| *a = 0.0);
                        for (&kx, &wx) in ix.iter().zip(vx) {
                            let at = (ky as usize * nx + kx as usize) * k;
                            for (a, &sv) in inner.iter_mut().zip(&s[at..at + k]) {
                                *a += wx * sv;
                            }
                        }
                        for (a, &b) in acc.iter_mut().zip(&inner) {
                            *a += wy * b;
                        }
                    }
                    v.copy_from_slice(&acc);
                }
            });
    }

    /// `out = E^T r` (sample residuals to single-scale coefficients), `out` overwritten.
    pub fn apply_transpose(&self, r: &[f64], out: &mut [f64]) {
        let t = self.apply_transpose_many(r, 1, out.len());
        out.copy_from_slice(&t);
    }

    /// `E^T r` for `k` vectors at once, interleaved as in [`Self::apply_many`] (`r[i k + c]`
    /// in, `n k` coefficients out, `n` the single-scale functions), through the columns
    /// ([`SingleScaleColumns`]).
    pub fn apply_transpose_many(&self, r: &[f64], k: usize, n: usize) -> Vec<f64> {
        self.columns(n).apply_many(r, k)
    }

    /// `E` by columns: for each single-scale function, its samples (ascending) and values.
    pub fn columns(&self, n: usize) -> SingleScaleColumns {
        let m = self.len();
        let nx = self.nx;
        let mut ptr = vec![0usize; n + 1];
        for i in 0..m {
            let (ix, _, iy, _) = self.factors(i);
            for &ky in iy {
                for &kx in ix {
                    ptr[ky as usize * nx + kx as usize + 1] += 1;
                }
            }
        }
        for j in 0..n {
            ptr[j + 1] += ptr[j];
        }
        let mut next = ptr.clone();
        let mut sample = vec![0u32; ptr[n]];
        let mut weight = vec![0.0; ptr[n]];
        for i in 0..m {
            let (ix, vx, iy, vy) = self.factors(i);
            for (&ky, &wy) in iy.iter().zip(vy) {
                for (&kx, &wx) in ix.iter().zip(vx) {
                    let j = ky as usize * nx + kx as usize;
                    sample[next[j]] = i as u32;
                    weight[next[j]] = wy * wx;
                    next[j] += 1;
                }
            }
        }
        SingleScaleColumns {
            ptr,
            sample,
            weight,
        }
    }
}

/// `E` stored by columns (CSC): `E^T r` as a gather, in parallel over the functions, each
/// summed over its samples in ascending order (the bits do not depend on the thread count,
/// and no per-thread copy of the output is needed).
#[derive(Clone, Debug, Default)]
pub struct SingleScaleColumns {
    /// Column starts (`n + 1`).
    pub(super) ptr: Vec<usize>,
    sample: Vec<u32>,
    weight: Vec<f64>,
}

impl SingleScaleColumns {
    /// `E^T r` for `k` interleaved vectors (`r[i k + c]`), `n k` interleaved coefficients out.
    pub fn apply_many(&self, r: &[f64], k: usize) -> Vec<f64> {
        match k {
            1 => self.apply_fixed::<1>(r),
            3 => self.apply_fixed::<3>(r),
            4 => self.apply_fixed::<4>(r),
            7 => self.apply_fixed::<7>(r),
            _ => self.apply_dynamic(r, k),
        }
    }

    /// [`Self::apply_many`] for `K` vectors, a constant (the same sums in the same order).
    fn apply_fixed<const K: usize>(&self, r: &[f64]) -> Vec<f64> {
        let n = self.ptr.len() - 1;
        let mut out = vec![0.0; n * K];
        out.par_chunks_mut(CHUNK * K)
            .enumerate()
            .for_each(|(chunk, o)| {
                for (t, v) in o.chunks_exact_mut(K).enumerate() {
                    let j = chunk * CHUNK + t;
                    let mut acc = [0.0; K];
                    for q in self.ptr[j]..self.ptr[j + 1] {
                        let (i, w) = (self.sample[q] as usize, self.weight[q]);
                        let ri: &[f64; K] = r[i * K..(i + 1) * K].try_into().expect("K values");
                        for c in 0..K {
                            acc[c] += w * ri[c];
                        }
                    }
                    v.copy_from_slice(&acc);
                }
            });
        out
    }

    fn apply_dynamic(&self, r: &[f64], k: usize) -> Vec<f64> {
        let n = self.ptr.len() - 1;
        let mut out = vec![0.0; n * k];
        out.par_chunks_mut(CHUNK * k)
            .enumerate()
            .for_each(|(chunk, o)| {
                for (t, v) in o.chunks_mut(k).enumerate() {
                    let j = chunk * CHUNK + t;
                    for q in self.ptr[j]..self.ptr[j + 1] {
                        let (i, w) = (self.sample[q] as usize, self.weight[q]);
                        for (a, &ri) in v.iter_mut().zip(&r[i * k..(i + 1) * k]) {
                            *a += w * ri;
                        }
                    }
                }
            });
        out
    }
}

/// `K v_c = E S v_c` for `k` multilevel vectors `v_c` (full Mallat layout of `basis`) at the
/// samples of `rows`, interleaved (`out[i k + c]`): each synthesized to single scale, then one
/// pass over the rows for all of them.
pub(crate) fn multilevel_values(
    basis: &TensorBasis,
    rows: &SingleScaleRows,
    vs: &[&[f64]],
) -> Vec<f64> {
    let s: Vec<Vec<f64>> = vs.par_iter().map(|v| basis.synthesis(v)).collect();
    let k = vs.len();
    let mut out = vec![0.0; rows.len() * k];
    rows.apply_many(&interleave(&s), k, &mut out);
    out
}

/// The first bytes of a piece of [`SingleScaleRows::piece_bytes`]: the layout's name and
/// version.
const ROWS_MAGIC: &[u8; 8] = b"RKWROW01";

/// Words of a piece before its rows: the basis key (7), the first row, the rows, the
/// positions' hash.
const PIECE_HEAD: usize = 10;

/// The largest first index a row's header holds (24 bits).
const INDEX_LIMIT: u32 = 1 << 24;

impl SingleScaleRows {
    /// The rows `from..` of these rows, the rows of the positions `(xs, ys)`, as one piece of
    /// a file of rows carried between a plan's calls (appended per call, read back by
    /// [`SingleScaleRows::from_pieces`]): the length in bytes, then the sealed layout of the
    /// plan's caches (`RKWROW01`, the plan's `tag`, the basis key, the first row, the rows,
    /// `positions_hash` of their positions; per row one word `ix0 | lx << 24 | iy0 << 32 |
    /// ly << 56` (each factor's indices are consecutive) and the `lx + ly` values' bits; a
    /// checksum). `None` when a row does not fit that header (indices not consecutive, an
    /// index of `2^24` or more, more than 255 values): then nothing is carried.
    pub fn piece_bytes(&self, tag: u64, from: usize, xs: &[f64], ys: &[f64]) -> Option<Vec<u8>> {
        let m = self.len();
        if from > m || xs.len() != m || ys.len() != m {
            return None;
        }
        let consecutive = |ix: &[u32]| {
            ix.len() < 256
                && ix.first().is_none_or(|&i| i < INDEX_LIMIT)
                && ix.windows(2).all(|w| w[1] == w[0] + 1)
        };
        let mut words = PIECE_HEAD;
        for i in from..m {
            let (ix, vx, iy, vy) = self.factors(i);
            if !consecutive(ix) || !consecutive(iy) {
                return None;
            }
            words += 1 + vx.len() + vy.len();
        }
        let sealed = seal(ROWS_MAGIC, tag, words, |word| {
            self.basis_key.iter().for_each(|&k| word(k as u64));
            word(from as u64);
            word((m - from) as u64);
            word(positions_hash(&xs[from..], &ys[from..]));
            for i in from..m {
                let (ix, vx, iy, vy) = self.factors(i);
                let first = |ix: &[u32]| u64::from(ix.first().copied().unwrap_or(0));
                word(
                    first(ix) | (ix.len() as u64) << 24 | first(iy) << 32 | (iy.len() as u64) << 56,
                );
                vx.iter().chain(vy).for_each(|v| word(v.to_bits()));
            }
        });
        let mut out = Vec::with_capacity(8 + sealed.len());
        out.extend_from_slice(&(sealed.len() as u64).to_le_bytes());
        out.extend_from_slice(&sealed);
        Some(out)
    }

    /// The rows kept in `bytes` (pieces of [`SingleScaleRows::piece_bytes`], in order) that
    /// are the rows of a prefix of the positions `(xs, ys)` on `basis`, for the plan `tag`:
    /// the pieces are taken while each continues the rows before it, on the same basis, with
    /// the positions' hash of the positions it claims. Returns the rows (`None`: no piece
    /// taken), the bytes of `bytes` they fill, and why reading stopped before the end
    /// (`None`: every piece taken).
    pub fn from_pieces(
        bytes: &[u8],
        tag: u64,
        basis: &TensorBasis,
        xs: &[f64],
        ys: &[f64],
    ) -> (Option<Self>, u64, Option<String>) {
        let mut rows: Option<Self> = None;
        let mut used = 0usize;
        let key = basis_key(basis);
        while used < bytes.len() {
            let rest = &bytes[used..];
            let Some(len) = rest
                .get(..8)
                .map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes")) as usize)
                .filter(|&len| len <= rest.len() - 8)
            else {
                return (rows, used as u64, Some("damaged: cut short".into()));
            };
            let done = rows.as_ref().map_or(0, Self::len);
            match Self::piece(&rest[8..8 + len], tag, key, done, xs, ys) {
                Ok(piece) => {
                    // the first piece is the rows read (not copied); a later one is appended
                    match rows.as_mut() {
                        None => rows = Some(piece),
                        Some(all) => all.extend(piece),
                    }
                    used += 8 + len;
                }
                Err(why) => return (rows, used as u64, Some(why)),
            }
        }
        if let Some(r) = rows.as_mut().filter(|r| !r.is_empty()) {
            let last = r.len() - 1;
            r.last = (xs[last].to_bits(), ys[last].to_bits());
        }
        (rows, used as u64, None)
    }

    /// One piece's rows (`done` rows before it), if it continues them (see
    /// [`SingleScaleRows::from_pieces`]).
    fn piece(
        sealed: &[u8],
        tag: u64,
        key: [usize; 7],
        done: usize,
        xs: &[f64],
        ys: &[f64],
    ) -> Result<Self, String> {
        let mut words =
            unseal(sealed, ROWS_MAGIC, "file of rows", tag).map_err(|e| e.to_string())?;
        let word = |w: &mut super::gram::Words<'_>| w.next().map_err(|e| e.to_string());
        for k in key {
            if word(&mut words)? != k as u64 {
                return Err("rows of another basis".into());
            }
        }
        let (from, count) = (word(&mut words)? as usize, word(&mut words)? as usize);
        if from != done || count > xs.len().saturating_sub(done) {
            return Err(format!(
                "a piece of rows {from}..{} does not continue the {done} rows read (of {} \
                 samples)",
                from.saturating_add(count),
                xs.len()
            ));
        }
        let end = from + count;
        if word(&mut words)? != positions_hash(&xs[from..end], &ys[from..end]) {
            return Err(format!(
                "the rows {from}..{end} are not those of the samples' positions"
            ));
        }
        let mut rows = Self {
            nx: key[5],
            basis_key: key,
            ptr_x: vec![0],
            ptr_y: vec![0],
            ..Self::default()
        };
        // a head word a row, then its factors' values (x and y about half each)
        let values = words.left().saturating_sub(count) / 2;
        rows.ptr_x.reserve(count);
        rows.ptr_y.reserve(count);
        for v in [&mut rows.ix, &mut rows.iy] {
            v.reserve(values);
        }
        for v in [&mut rows.vx, &mut rows.vy] {
            v.reserve(values);
        }
        for _ in 0..count {
            let head = word(&mut words)?;
            let (ix0, lx) = ((head & 0xFF_FFFF) as u32, ((head >> 24) & 0xFF) as u32);
            let (iy0, ly) = (((head >> 32) & 0xFF_FFFF) as u32, (head >> 56) as u32);
            rows.ptr_x.push(rows.ptr_x.last().unwrap() + lx);
            rows.ptr_y.push(rows.ptr_y.last().unwrap() + ly);
            rows.ix.extend(ix0..ix0 + lx);
            rows.iy.extend(iy0..iy0 + ly);
            for _ in 0..lx {
                rows.vx.push(f64::from_bits(word(&mut words)?));
            }
            for _ in 0..ly {
                rows.vy.push(f64::from_bits(word(&mut words)?));
            }
        }
        if words.left() != 0 {
            return Err("damaged: the sizes do not add up".into());
        }
        Ok(rows)
    }

    /// Appends `later`'s rows (of the same basis) after these.
    fn extend(&mut self, later: Self) {
        let (bx, by) = (*self.ptr_x.last().unwrap(), *self.ptr_y.last().unwrap());
        self.ptr_x.extend(later.ptr_x[1..].iter().map(|p| p + bx));
        self.ptr_y.extend(later.ptr_y[1..].iter().map(|p| p + by));
        self.ix.extend(later.ix);
        self.vx.extend(later.vx);
        self.iy.extend(later.iy);
        self.vy.extend(later.vy);
        self.last = later.last;
    }
}
