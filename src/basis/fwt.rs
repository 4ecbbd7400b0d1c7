//! The interval fast wavelet transform between `V_{N+1}` coefficients and `Psi(n, N)`
//! coefficients.
//!
//! One analysis step maps fine coefficients `f` (length `2^{j+1}`) to `s` (`V_j`) and `d` (`W_j`):
//! - left edge `k < p`: `s_k = sum_l H_kl f_l + sum_{m=p}^{3p-2} h_{k,m} f_m` (and `d_k` with `G, g`);
//! - interior `m`: `s_m = sum_i hc_i f_{2m+i}`, `d_m = sum_i gc_i f_{2m+i}`, `i = -p+1..p`;
//! - right edge `k`: `s_{2^j-1-k} = sum_l HR_kl f_{2^{j+1}-1-l} + sum_m hR_{k,m} f_{2^{j+1}-1-m}`.
//!
//! The step is orthogonal, so synthesis is its transpose. Coefficients of `Psi(n, N)` are laid out
//! by global index: `[s_n | d_n | d_{n+1} | ... | d_N]`.

use nalgebra::DMatrix;

use super::bank::FilterBank;
use super::cdv::EdgeFilters;

/// The low-pass (`H`, `h`) or high-pass (`G`, `g`) refinement matrices of one edge.
fn halves(edge: &EdgeFilters, high: bool) -> (&DMatrix<f64>, &DMatrix<f64>) {
    if high {
        (&edge.g_edge, &edge.g_interior)
    } else {
        (&edge.h_edge, &edge.h_interior)
    }
}

/// Coarse index, fine index and weight of every nonzero entry of one analysis step, for the
/// low-pass (`false`) or high-pass (`true`) half.
pub(crate) fn analysis_entries(
    bank: &FilterBank,
    level: u32,
    high: bool,
    mut f: impl FnMut(usize, usize, f64),
) {
    let p = bank.p();
    let e = bank.edge_count();
    let size = 1usize << level;
    let fine = 2 * size;
    let int = &bank.interior;
    let pick = |edge| halves(edge, high);
    if let (Some(left), Some(right)) = (bank.left.as_ref(), bank.right.as_ref()) {
        let (le, li) = pick(left);
        let (re, ri) = pick(right);
        for k in 0..e {
            for l in 0..e {
                f(k, l, le[(k, l)]);
                f(size - 1 - k, fine - 1 - l, re[(k, l)]);
            }
            for q in 0..li.ncols() {
                f(k, p + q, li[(k, q)]);
                f(size - 1 - k, fine - 1 - (p + q), ri[(k, q)]);
            }
        }
    }
    for m in e..size - e {
        for i in (-(p as i64) + 1)..=(p as i64) {
            let w = if high { int.gc(i) } else { int.hc(i) };
            f(m, (2 * m as i64 + i) as usize, w);
        }
    }
}

/// One analysis step `f (2^{j+1}) -> (s, d)` at level `level = j`, written into
/// `out[..2^j]` and `out[2^j..2^{j+1}]`.
pub fn analysis_step(bank: &FilterBank, level: u32, f: &[f64], out: &mut [f64]) {
    let size = 1usize << level;
    out[..2 * size].iter_mut().for_each(|x| *x = 0.0);
    let (s, d) = out.split_at_mut(size);
    analysis_entries(bank, level, false, |c, i, w| s[c] += w * f[i]);
    analysis_entries(bank, level, true, |c, i, w| d[c] += w * f[i]);
}

/// One synthesis step (the transpose): `(s, d)` at level `j` to `f (2^{j+1})`.
pub fn synthesis_step(bank: &FilterBank, level: u32, sd: &[f64], f: &mut [f64]) {
    let size = 1usize << level;
    f[..2 * size].iter_mut().for_each(|x| *x = 0.0);
    let (s, d) = sd.split_at(size);
    analysis_entries(bank, level, false, |c, i, w| f[i] += w * s[c]);
    analysis_entries(bank, level, true, |c, i, w| f[i] += w * d[c]);
}

/// One step (analysis or synthesis) at one level as a sparse matrix stored by output: for
/// output `o`, the inputs and weights `ptr[o]..ptr[o + 1]` in the order [`analysis_step`] and
/// [`synthesis_step`] sum them, so that `out[o] = sum w f[in]` from 0 in that order gives their
/// bits exactly (a stable sort of [`analysis_entries`] by output).
#[derive(Clone, Debug)]
pub(crate) struct StepMatrix {
    ptr: Vec<usize>,
    input: Vec<usize>,
    weight: Vec<f64>,
}

impl StepMatrix {
    /// The analysis (`f -> [s | d]`) or synthesis (`[s | d] -> f`) step of level `level`.
    pub(crate) fn new(bank: &FilterBank, level: u32, analysis: bool) -> Self {
        let size = 1usize << level;
        let mut triples: Vec<(usize, usize, f64)> = Vec::new();
        for high in [false, true] {
            let shift = if high { size } else { 0 };
            analysis_entries(bank, level, high, |c, i, w| {
                if analysis {
                    triples.push((shift + c, i, w));
                } else {
                    triples.push((i, shift + c, w));
                }
            });
        }
        let mut ptr = vec![0usize; 2 * size + 1];
        for &(o, _, _) in &triples {
            ptr[o + 1] += 1;
        }
        for o in 0..2 * size {
            ptr[o + 1] += ptr[o];
        }
        let mut next = ptr.clone();
        let mut input = vec![0usize; triples.len()];
        let mut weight = vec![0.0; triples.len()];
        for (o, i, w) in triples {
            input[next[o]] = i;
            weight[next[o]] = w;
            next[o] += 1;
        }
        Self { ptr, input, weight }
    }

    /// Outputs (and inputs): `2^{level+1}`.
    pub(crate) fn len(&self) -> usize {
        self.ptr.len() - 1
    }

    /// Inputs and weights of output `o`.
    pub(crate) fn entries(&self, o: usize) -> (&[usize], &[f64]) {
        let (a, b) = (self.ptr[o], self.ptr[o + 1]);
        (&self.input[a..b], &self.weight[a..b])
    }

    /// `out_r = A f_r` for `R` vectors at once, `f_r = f[r stride..r stride + len]` and
    /// `out_r = out[r len..(r + 1) len]`: each output the same sum in the same order as
    /// [`Self::apply`] (the same bits), the `R` independent sums interleaved so that they
    /// do not wait on one another and each entry's input and weight are read once.
    pub(crate) fn apply_rows<const R: usize>(&self, f: &[f64], stride: usize, out: &mut [f64]) {
        let len = self.len();
        for o in 0..len {
            let (input, weight) = self.entries(o);
            let mut acc = [0.0; R];
            for (&i, &w) in input.iter().zip(weight) {
                for (r, a) in acc.iter_mut().enumerate() {
                    *a += w * f[r * stride + i];
                }
            }
            for (r, &a) in acc.iter().enumerate() {
                out[r * len + o] = a;
            }
        }
    }

    /// `out = A f` for one vector.
    pub(crate) fn apply(&self, f: &[f64], out: &mut [f64]) {
        for (o, v) in out[..self.len()].iter_mut().enumerate() {
            let (input, weight) = self.entries(o);
            let mut acc = 0.0;
            for (&i, &w) in input.iter().zip(weight) {
                acc += w * f[i];
            }
            *v = acc;
        }
    }
}

/// Full analysis: `V_{N+1}` coefficients (length `2^{N+1}`) to `Psi(n, N)` coefficients.
pub fn analysis(bank: &FilterBank, coarse: u32, fine: u32, data: &[f64]) -> Vec<f64> {
    let mut x = data.to_vec();
    let mut buf = vec![0.0; data.len()];
    for j in (coarse..=fine).rev() {
        let len = 2usize << j;
        analysis_step(bank, j, &x[..len], &mut buf[..len]);
        x[..len].copy_from_slice(&buf[..len]);
    }
    x
}

/// Full synthesis: `Psi(n, N)` coefficients to `V_{N+1}` coefficients.
pub fn synthesis(bank: &FilterBank, coarse: u32, fine: u32, coefficients: &[f64]) -> Vec<f64> {
    let mut x = coefficients.to_vec();
    let mut buf = vec![0.0; coefficients.len()];
    for j in coarse..=fine {
        let len = 2usize << j;
        synthesis_step(bank, j, &x[..len], &mut buf[..len]);
        x[..len].copy_from_slice(&buf[..len]);
    }
    x
}

/// The synthesis step of level `j` as a sparse matrix (`2^{j+1}` square, columns `[s | d]`).
pub fn synthesis_matrix(bank: &FilterBank, level: u32, total: usize) -> sprs::CsMat<f64> {
    let size = 1usize << level;
    let mut tri = sprs::TriMat::new((total, total));
    analysis_entries(bank, level, false, |c, i, w| tri.add_triplet(i, c, w));
    analysis_entries(bank, level, true, |c, i, w| tri.add_triplet(i, size + c, w));
    for i in 2 * size..total {
        tri.add_triplet(i, i, 1.0);
    }
    tri.to_csr()
}
