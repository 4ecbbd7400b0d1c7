//! Banded QR of the single-scale observation matrix by Givens rotations (FITPACK's way):
//! `K_J = Q R`, `R` upper triangular with `R[j, k] = 0` for `k - j >= w`, and `z = Q^T f`,
//! built one sample row at a time without storing `K_J` or `Q`. The least-squares solution is
//! `R v = z` (back substitution), at the accuracy of `cond(K_J)`, where the normal equations
//! reach only that of `cond(K_J)^2`.
//!
//! A row `(first, values)` is rotated into the triangle column by column: at column `j` the
//! Givens rotation `[c s; -s c]`, `c = R_jj / h`, `s = x_j / h`, `h = sqrt(R_jj^2 + x_j^2)`,
//! zeroes the row's entry and updates `R`'s row `j`, `z_j` and the row's right-hand sides (every
//! channel). If `R`'s row `j` is still empty the row is stored there and the work ends. With the
//! rows in ascending cell order, each row ends where the previous rows end or later, so a row
//! costs `O(w^2)` and never fills in past its own last column; in any order the result is
//! correct, only slower. Two triangles of consecutive sample chunks merge by rotating the
//! rows of the second into the first (QR of the stacked triangles).

/// A remnant row below this fraction of its original size is dropped instead of stored.
const NEGLIGIBLE: f64 = 1e-20;

/// Upper-triangular band `R` and `z = Q^T f` over the columns `c0 .. c0 + n`.
#[derive(Clone)]
pub(crate) struct GivensTriangle {
    c0: usize,
    n: usize,
    w: usize,
    channels: usize,
    /// `r[(j - c0) * w + d] = R[j, j + d]`.
    r: Vec<f64>,
    /// Stored entries of each row of `R` (0: an empty row).
    len: Vec<u16>,
    /// `z[(j - c0) * channels + c]`.
    z: Vec<f64>,
    /// `||K e_j||^2`: squared column norms of the rows added (the scale of the pivots).
    colsq: Vec<f64>,
    /// Per channel, the sum of squares of the right-hand sides rotated out of the triangle:
    /// `||f - K v||^2` of the least-squares solution `v` where `R` has full rank
    /// ([`GivensTriangle::residual_squares`] adds what rank-deficient rows leave).
    rss: Vec<f64>,
    buf: Vec<f64>,
    y: Vec<f64>,
}

/// Back substitution result: single-scale coefficients per channel and the pivot facts.
pub(crate) struct TriangleSolution {
    /// `v` per channel.
    pub coefficients: Vec<Vec<f64>>,
    /// Columns with no sample.
    pub unsampled: usize,
    /// Columns with `R_jj^2 / ||K e_j||^2 <= tolerance` (unsampled included), set to 0.
    pub deficient: usize,
    /// Smallest `R_jj^2 / ||K e_j||^2` over the determined columns.
    pub min_pivot: f64,
    /// Per column: deficient (its component set to 0).
    pub deficient_rows: Vec<bool>,
}

impl GivensTriangle {
    /// An empty triangle over columns `c0 .. c0 + n` with band width `w`.
    pub fn new(c0: usize, n: usize, w: usize, channels: usize) -> Self {
        assert!(w <= u16::MAX as usize, "band width {w} fits a u16");
        Self {
            c0,
            n,
            w,
            channels,
            r: vec![0.0; n * w],
            len: vec![0; n],
            z: vec![0.0; n * channels],
            colsq: vec![0.0; n],
            rss: vec![0.0; channels],
            buf: Vec::with_capacity(4 * w),
            y: Vec::with_capacity(channels),
        }
    }

    /// First column and one past the last column of the triangle.
    pub fn columns(&self) -> std::ops::Range<usize> {
        self.c0..self.c0 + self.n
    }

    /// Widens the triangle to cover the columns `c0 .. end` as well (new rows empty): the
    /// rotations do not depend on the columns covered, so a triangle grown row by row computes
    /// what one allocated at its final size computes.
    pub fn cover(&mut self, c0: usize, end: usize) {
        let (lo, hi) = (c0.min(self.c0), end.max(self.c0 + self.n));
        let (front, n) = (self.c0 - lo, hi - lo);
        if n == self.n {
            return;
        }
        let (w, ch) = (self.w, self.channels);
        let widen = |v: &mut Vec<f64>, per: usize| {
            if front > 0 {
                v.splice(0..0, std::iter::repeat_n(0.0, front * per));
            }
            v.resize(n * per, 0.0);
        };
        widen(&mut self.r, w);
        widen(&mut self.z, ch);
        widen(&mut self.colsq, 1);
        if front > 0 {
            self.len.splice(0..0, std::iter::repeat_n(0, front));
        }
        self.len.resize(n, 0);
        self.c0 = lo;
        self.n = n;
    }

    /// The triangle's state as plain numbers: `[c0, n, w, channels]` and the arrays `r`,
    /// `len`, `z`, `colsq`, `rss` (see [`GivensTriangle::from_parts`]).
    pub fn parts(&self) -> ([usize; 4], [&[f64]; 4], &[u16]) {
        (
            [self.c0, self.n, self.w, self.channels],
            [&self.r, &self.z, &self.colsq, &self.rss],
            &self.len,
        )
    }

    /// The triangle of [`GivensTriangle::parts`]; `None` when the array lengths do not match
    /// the sizes or a stored row is longer than the band or runs past the last column.
    pub fn from_parts(sizes: [usize; 4], arrays: [Vec<f64>; 4], len: Vec<u16>) -> Option<Self> {
        let [c0, n, w, channels] = sizes;
        let [r, z, colsq, rss] = arrays;
        let fits = r.len() == n.checked_mul(w)?
            && z.len() == n.checked_mul(channels)?
            && colsq.len() == n
            && rss.len() == channels
            && len.len() == n
            && len
                .iter()
                .enumerate()
                .all(|(j, &l)| (l as usize) <= w && j + l as usize <= n);
        fits.then(|| Self {
            c0,
            n,
            w,
            channels,
            r,
            len,
            z,
            colsq,
            rss,
            buf: Vec::with_capacity(4 * w),
            y: Vec::with_capacity(channels),
        })
    }

    /// Adds the observation row `K[i, first + k] = values[k]` with right-hand sides `f[c]`.
    #[inline]
    pub fn add_row(&mut self, first: usize, values: &[f64], f: &[f64]) {
        let o = first - self.c0;
        for (s, v) in self.colsq[o..o + values.len()].iter_mut().zip(values) {
            *s += v * v;
        }
        let done = match values.len() {
            1 => self.rotate_in_fixed::<1>(first, values, f),
            3 => self.rotate_in_fixed::<3>(first, values, f),
            5 => self.rotate_in_fixed::<5>(first, values, f),
            7 => self.rotate_in_fixed::<7>(first, values, f),
            9 => self.rotate_in_fixed::<9>(first, values, f),
            11 => self.rotate_in_fixed::<11>(first, values, f),
            13 => self.rotate_in_fixed::<13>(first, values, f),
            15 => self.rotate_in_fixed::<15>(first, values, f),
            17 => self.rotate_in_fixed::<17>(first, values, f),
            19 => self.rotate_in_fixed::<19>(first, values, f),
            _ => false,
        };
        if !done {
            self.rotate_in(first, values, f);
        }
    }

    /// [`GivensTriangle::rotate_in`] for the common case of a streamed interior row: `W`
    /// values (`W = 2p - 1`, known at compile time so the rotations unroll) against rows of
    /// `R` that end no later than the row does (`len[first + k] <= W - k` up to the first
    /// empty row of `R`, which ascending cell order guarantees). The same rotations in the
    /// same order as the general path; returns `false`, having changed nothing, when the
    /// rows of `R` do not fit that shape (the caller then takes the general path).
    #[inline]
    fn rotate_in_fixed<const W: usize>(&mut self, first: usize, values: &[f64], f: &[f64]) -> bool {
        let w = self.w;
        let ch = self.channels;
        let o = first - self.c0;
        if W > w || o + W > self.n {
            return false;
        }
        for (k, &l) in self.len[o..o + W].iter().enumerate() {
            if l == 0 {
                break;
            }
            if l as usize > W - k {
                return false;
            }
        }
        let mut x = [0.0f64; W];
        x.copy_from_slice(values);
        self.y.clear();
        self.y.extend_from_slice(f);
        for k in 0..W {
            let jj = o + k;
            let xk = x[k];
            if xk == 0.0 {
                continue;
            }
            let row = &mut self.r[jj * w..jj * w + (W - k)];
            if self.len[jj] == 0 {
                let size = values.iter().fold(0.0f64, |a, v| a.max(v.abs()));
                let left = x[k..].iter().fold(0.0f64, |a, v| a.max(v.abs()));
                if left <= NEGLIGIBLE * size {
                    self.rotated_out();
                    return true;
                }
                row.copy_from_slice(&x[k..]);
                self.len[jj] = (W - k) as u16;
                self.z[jj * ch..(jj + 1) * ch].copy_from_slice(&self.y);
                return true;
            }
            let d = row[0];
            let h = (d * d + xk * xk).sqrt();
            let (c, s) = (d / h, xk / h);
            row[0] = h;
            for (a, b) in row[1..].iter_mut().zip(&mut x[k + 1..]) {
                let (ra, rb) = (*a, *b);
                *a = c * ra + s * rb;
                *b = c * rb - s * ra;
            }
            self.len[jj] = (W - k) as u16;
            for (a, b) in self.z[jj * ch..(jj + 1) * ch].iter_mut().zip(&mut self.y) {
                let (za, yb) = (*a, *b);
                *a = c * za + s * yb;
                *b = c * yb - s * za;
            }
        }
        self.rotated_out();
        true
    }

    /// Rotates a row into the triangle (column norms untouched).
    fn rotate_in(&mut self, first: usize, values: &[f64], f: &[f64]) {
        let w = self.w;
        let ch = self.channels;
        self.buf.clear();
        self.buf.extend_from_slice(values);
        self.y.clear();
        self.y.extend_from_slice(f);
        let mut end = values.len();
        let size = values.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let mut k = 0;
        while k < end {
            let x = self.buf[k];
            if x == 0.0 {
                k += 1;
                continue;
            }
            let jj = first + k - self.c0;
            debug_assert!(jj < self.n, "row reaches column {} past the triangle", jj);
            let row = &mut self.r[jj * w..(jj + 1) * w];
            let stored = self.len[jj] as usize;
            if stored == 0 {
                let l = end - k;
                // What is left of a row after rotations against a triangle of full rows (a
                // merge) shrinks from round-off size towards underflow, one row further each
                // time; below NEGLIGIBLE of the row's own size it is dropped (a change of `K`
                // far below its rounding) rather than carried on.
                let left = self.buf[k..end].iter().fold(0.0f64, |a, v| a.max(v.abs()));
                if left <= NEGLIGIBLE * size {
                    self.rotated_out();
                    return;
                }
                row[..l].copy_from_slice(&self.buf[k..end]);
                self.len[jj] = l as u16;
                self.z[jj * ch..(jj + 1) * ch].copy_from_slice(&self.y);
                return;
            }
            let d = row[0];
            let h = (d * d + x * x).sqrt();
            let (c, s) = (d / h, x / h);
            row[0] = h;
            let m = stored.max(end - k);
            debug_assert!(m <= w, "rotated rows stay within the band");
            if self.buf.len() < k + m {
                self.buf.resize(k + m, 0.0);
            }
            let tail = &mut self.buf[k + 1..k + m];
            for (a, b) in row[1..m].iter_mut().zip(tail) {
                let (ra, rb) = (*a, *b);
                *a = c * ra + s * rb;
                *b = c * rb - s * ra;
            }
            self.len[jj] = m as u16;
            end = k + m;
            for (a, b) in self.z[jj * ch..(jj + 1) * ch].iter_mut().zip(&mut self.y) {
                let (za, yb) = (*a, *b);
                *a = c * za + s * yb;
                *b = c * yb - s * za;
            }
            k += 1;
        }
        self.rotated_out();
    }

    /// The row being rotated in has been zeroed (or dropped as negligible): what is left of
    /// its right-hand sides is residual.
    fn rotated_out(&mut self) {
        for (r, y) in self.rss.iter_mut().zip(&self.y) {
            *r += y * y;
        }
    }

    /// Merges `other` (a triangle over columns inside this one's) into this one: QR of the
    /// stacked triangles, its rows rotated in in ascending order.
    pub fn absorb(&mut self, other: &GivensTriangle) {
        debug_assert!(other.c0 >= self.c0 && other.c0 + other.n <= self.c0 + self.n);
        debug_assert_eq!((other.w, other.channels), (self.w, self.channels));
        let o = other.c0 - self.c0;
        for (s, t) in self.colsq[o..o + other.n].iter_mut().zip(&other.colsq) {
            *s += t;
        }
        for (s, t) in self.rss.iter_mut().zip(&other.rss) {
            *s += t;
        }
        let (w, ch) = (other.w, other.channels);
        for jj in 0..other.n {
            let l = other.len[jj] as usize;
            if l > 0 {
                self.rotate_in(
                    other.c0 + jj,
                    &other.r[jj * w..jj * w + l],
                    &other.z[jj * ch..(jj + 1) * ch],
                );
            }
        }
    }

    /// Adds the ridge rows `sqrt(ridge ||K e_j||^2) e_j^T` (right-hand side 0): the least
    /// squares of `[K; sqrt(ridge) D^{1/2}]`, the QR form of the equilibrated shift
    /// `A + ridge I`.
    pub fn add_ridge(&mut self, ridge: f64) {
        if ridge <= 0.0 {
            return;
        }
        let zeros = vec![0.0; self.channels];
        for jj in 0..self.n {
            let v = (ridge * self.colsq[jj]).sqrt();
            if v > 0.0 {
                self.rotate_in(self.c0 + jj, &[v], &zeros);
            }
        }
    }

    /// `||f - K v||^2` per channel for the solution `v` of [`GivensTriangle::solve`] (without
    /// ridge rows): the right-hand sides rotated out, plus `(z_j - (R v)_j)^2` for the rows
    /// whose pivot was declared deficient (their equation is not solved). `K = Q R` with `Q`
    /// orthogonal makes this the residual of the samples themselves, found without
    /// evaluating the fit again.
    pub fn residual_squares(&self, solution: &TriangleSolution) -> Vec<f64> {
        let (w, ch) = (self.w, self.channels);
        let mut rss = self.rss.clone();
        for (j, &deficient) in solution.deficient_rows.iter().enumerate() {
            let l = self.len[j] as usize;
            if !deficient || l == 0 {
                continue;
            }
            let row = &self.r[j * w..j * w + l];
            for (c, (r, v)) in rss.iter_mut().zip(&solution.coefficients).enumerate() {
                let rv: f64 = row.iter().enumerate().map(|(d, rd)| rd * v[j + d]).sum();
                *r += (self.z[j * ch + c] - rv).powi(2);
            }
        }
        rss
    }

    /// Back substitution `R v = z`; a column whose pivot `R_jj^2 / ||K e_j||^2` is at most
    /// `tolerance` (or that has no sample) is a direction the samples do not determine: its
    /// component is set to 0.
    pub fn solve(&self, tolerance: f64) -> TriangleSolution {
        let (n, w, ch) = (self.n, self.w, self.channels);
        let mut min_pivot = f64::INFINITY;
        let mut unsampled = 0;
        let deficient: Vec<bool> = (0..n)
            .map(|j| {
                if self.colsq[j] == 0.0 {
                    unsampled += 1;
                    return true;
                }
                let rjj = if self.len[j] > 0 { self.r[j * w] } else { 0.0 };
                let pivot = rjj * rjj / self.colsq[j];
                if pivot > tolerance {
                    min_pivot = min_pivot.min(pivot);
                }
                pivot <= tolerance
            })
            .collect();
        let mut v = vec![vec![0.0; n]; ch];
        for j in (0..n).rev() {
            if deficient[j] {
                continue;
            }
            let l = self.len[j] as usize;
            let row = &self.r[j * w..j * w + l];
            for (c, vc) in v.iter_mut().enumerate() {
                let mut t = self.z[j * ch + c];
                for (d, rd) in row.iter().enumerate().skip(1) {
                    t -= rd * vc[j + d];
                }
                vc[j] = t / row[0];
            }
        }
        TriangleSolution {
            coefficients: v,
            unsampled,
            deficient: deficient.iter().filter(|&&d| d).count(),
            min_pivot,
            deficient_rows: deficient,
        }
    }
}

/// The order that sorts the samples by their cell `floor(2^J t)` (a counting sort, `O(m + 2^J)`),
/// or `None` when they are sorted already.
pub(crate) fn cell_order(ts: &[f64], level: u32) -> Option<Vec<usize>> {
    let cells = 1usize << level;
    let size = cells as f64;
    let cell = |t: f64| ((t * size) as usize).min(cells - 1);
    if ts.windows(2).all(|p| cell(p[0]) <= cell(p[1])) {
        return None;
    }
    let mut start = vec![0usize; cells + 1];
    for &t in ts {
        start[cell(t) + 1] += 1;
    }
    for c in 0..cells {
        start[c + 1] += start[c];
    }
    let mut order = vec![0usize; ts.len()];
    for (i, &t) in ts.iter().enumerate() {
        let c = cell(t);
        order[start[c]] = i;
        start[c] += 1;
    }
    Some(order)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `R^T R = K^T K` and `R^T z = K^T f` for a small dense `K` fed in scrambled order and
    /// in two merged halves: the rotations are orthogonal.
    #[test]
    fn triangle_reproduces_the_normal_equations() {
        // Rows of the band's width in scrambled order (the general path), and rows of odd
        // width 3 in ascending order (the fixed-width path) or scrambled (fixed-width rows
        // that meet longer rows of R: the general path again).
        for (len, ascending) in [(4, false), (3, true), (3, false)] {
            check_triangle(len, ascending);
        }
    }

    fn check_triangle(len: usize, ascending: bool) {
        let n = 12;
        let w = 4;
        let mut rows = Vec::new();
        let mut s = 0.37f64;
        let mut next = || {
            s = (s * 9301.0 + 0.49297).fract();
            s - 0.5
        };
        for i in 0..40 {
            let first = if ascending {
                i * (n - len + 1) / 40
            } else {
                (i * 7) % (n - len + 1)
            };
            let vals: Vec<f64> = (0..len).map(|_| next()).collect();
            rows.push((first, vals, vec![next(), next()]));
        }
        let mut whole = GivensTriangle::new(0, n, w, 2);
        let mut a = GivensTriangle::new(0, n, w, 2);
        let mut b = GivensTriangle::new(0, n, w, 2);
        for (i, (first, vals, f)) in rows.iter().enumerate() {
            whole.add_row(*first, vals, f);
            if i % 2 == 0 { &mut a } else { &mut b }.add_row(*first, vals, f);
        }
        a.absorb(&b);
        for t in [&whole, &a] {
            for j in 0..n {
                for k in 0..n {
                    let ktk: f64 = rows
                        .iter()
                        .map(|(f0, v, _)| {
                            let at = |c: usize| c.checked_sub(*f0).and_then(|d| v.get(d));
                            at(j).zip(at(k)).map_or(0.0, |(x, y)| x * y)
                        })
                        .sum();
                    let rtr: f64 = (0..n)
                        .map(|i| {
                            let at = |c: usize| {
                                let l = t.len[i] as usize;
                                if c >= i && c - i < l {
                                    t.r[i * w + c - i]
                                } else {
                                    0.0
                                }
                            };
                            at(j) * at(k)
                        })
                        .sum();
                    assert!((ktk - rtr).abs() < 1e-13, "({j}, {k}): {ktk} vs {rtr}");
                }
                for c in 0..2 {
                    let ktf: f64 = rows
                        .iter()
                        .map(|(f0, v, f)| {
                            j.checked_sub(*f0)
                                .and_then(|d| v.get(d))
                                .map_or(0.0, |x| x * f[c])
                        })
                        .sum();
                    let rtz: f64 = (0..n)
                        .map(|i| {
                            let l = t.len[i] as usize;
                            let r = (j >= i && j - i < l).then(|| t.r[i * w + j - i]);
                            r.unwrap_or(0.0) * t.z[i * 2 + c]
                        })
                        .sum();
                    assert!(
                        (ktf - rtz).abs() < 1e-13,
                        "K^T f [{j}, {c}]: {ktf} vs {rtz}"
                    );
                }
            }
        }
    }

    #[test]
    fn cell_order_sorts_by_cell() {
        let ts = [0.9, 0.1, 0.5, 0.12, 1.0, 0.0];
        let order = cell_order(&ts, 3).expect("unsorted");
        let cells: Vec<usize> = order
            .iter()
            .map(|&i| ((ts[i] * 8.0) as usize).min(7))
            .collect();
        assert!(cells.windows(2).all(|p| p[0] <= p[1]), "{cells:?}");
        assert!(cell_order(&[0.0, 0.2, 0.2, 0.9, 1.0], 3).is_none());
    }
}
