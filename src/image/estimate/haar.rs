//! The orthonormal (unbalanced) Haar transform of an image of any size, its dyadic partition
//! shifted by an offset per axis.
//!
//! **One axis.** Element `i` of a line of `n` belongs at level `j` to the block
//! `k = floor((i + o) / 2^j)` (offset `o >= 0`); the blocks of level `j + 1` merge the blocks
//! `2k` and `2k + 1` of level `j`. A block's scaling coefficient is `sum / sqrt(size)` of the
//! values in it; merging blocks `a` and `b` of sizes `n_a`, `n_b` is the rotation
//!
//! `s = c_a x_a + c_b x_b`,  `d = c_b x_a - c_a x_b`,
//! `c_a = sqrt(n_a / (n_a + n_b))`, `c_b = sqrt(n_b / (n_a + n_b))`,
//!
//! orthonormal (`c_a² + c_b² = 1`), and `d = 0` on a constant line. At the borders the first
//! and last blocks are truncated to the image (no wrap-around, no padding): a block with no
//! partner at some level passes to the next unchanged. So the transform is orthonormal for
//! every `n` and every offset, and for `n = 2^J`, `o = 0` it is the plain orthonormal Haar
//! transform (`c_a = c_b = 1 / sqrt 2`).
//!
//! **Two axes.** Mallat's pyramid (the non-standard decomposition, as PyWavelets' `wavedec2`):
//! at each level one merge step along x on every row of the approximation, then one along y on
//! both halves, leaving the approximation `LL` and three detail bands `LH`, `HL`, `HH`; repeated
//! on `LL` until one block remains per axis. An axis that is already one block passes its
//! steps through.

/// One block of the next level: two blocks merged, or one passed through.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Merge {
    /// Blocks `a` and `a + 1` merged with weights `(c_a, c_b)`.
    Pair { a: usize, ca: f64, cb: f64 },
    /// Block `a` passed through.
    Single { a: usize },
}

/// The merge steps of one axis, level by level, until one block remains.
fn axis_steps(n: usize, offset: usize) -> Vec<Vec<Merge>> {
    let mut blocks: Vec<(usize, usize)> = (0..n).map(|i| (i + offset, 1)).collect();
    let mut steps = vec![];
    while blocks.len() > 1 {
        let (mut step, mut next) = (vec![], vec![]);
        let mut a = 0;
        while a < blocks.len() {
            let (id, size) = blocks[a];
            if a + 1 < blocks.len() && blocks[a + 1].0 >> 1 == id >> 1 {
                let other = blocks[a + 1].1;
                let total = (size + other) as f64;
                step.push(Merge::Pair {
                    a,
                    ca: (size as f64 / total).sqrt(),
                    cb: (other as f64 / total).sqrt(),
                });
                next.push((id >> 1, size + other));
                a += 2;
            } else {
                step.push(Merge::Single { a });
                next.push((id >> 1, size));
                a += 1;
            }
        }
        steps.push(step);
        blocks = next;
    }
    steps
}

/// The weights of one merge: `(c_a, c_b)`, or their squares `(c_a², c_b²)` for the transform
/// of variances ([`Haar2d::forward_squared`]).
#[inline]
fn weights(ca: f64, cb: f64, squared: bool) -> (f64, f64, f64) {
    if squared {
        // s = ca² x_a + cb² x_b, d = cb² x_a + ca² x_b: the sign of d's second weight squares away
        (ca * ca, cb * cb, 1.0)
    } else {
        (ca, cb, -1.0)
    }
}

/// One merge step on every row (`lines` rows of `n`): the low half (`lines` rows of the step's
/// length) and the details (`lines` rows of the number of pairs); with the squared weights
/// where `squared`.
fn forward_rows_with(
    data: &[f64],
    n: usize,
    lines: usize,
    step: &[Merge],
    squared: bool,
) -> (Vec<f64>, Vec<f64>) {
    let pairs = step
        .iter()
        .filter(|m| matches!(m, Merge::Pair { .. }))
        .count();
    let (mut low, mut high) = (
        Vec::with_capacity(lines * step.len()),
        Vec::with_capacity(lines * pairs),
    );
    for row in data.chunks_exact(n).take(lines) {
        for m in step {
            match *m {
                Merge::Pair { a, ca, cb } => {
                    let (ca, cb, sign) = weights(ca, cb, squared);
                    low.push(ca * row[a] + cb * row[a + 1]);
                    high.push(cb * row[a] + sign * ca * row[a + 1]);
                }
                Merge::Single { a } => low.push(row[a]),
            }
        }
    }
    (low, high)
}

/// The inverse of [`forward_rows_with`]: rows of `n` from the low half and the details; with
/// the squared weights where `squared` (the transpose of the squared forward step, which is
/// symmetric).
fn inverse_rows_with(
    low: &[f64],
    high: &[f64],
    n: usize,
    lines: usize,
    step: &[Merge],
    squared: bool,
) -> Vec<f64> {
    let pairs = high.len() / lines.max(1);
    let mut out = vec![0.0; n * lines];
    for line in 0..lines {
        let (row, l, mut h) = (
            &mut out[line * n..(line + 1) * n],
            &low[line * step.len()..(line + 1) * step.len()],
            high[line * pairs..(line + 1) * pairs].iter(),
        );
        for (m, &s) in step.iter().zip(l) {
            match *m {
                Merge::Pair { a, ca, cb } => {
                    let (ca, cb, sign) = weights(ca, cb, squared);
                    let d = *h.next().expect("one detail per pair");
                    row[a] = ca * s + cb * d;
                    row[a + 1] = cb * s + sign * ca * d;
                }
                Merge::Single { a } => row[a] = s,
            }
        }
    }
    out
}

/// `rows x cols` row-major to `cols x rows` row-major.
fn transpose(data: &[f64], cols: usize, rows: usize) -> Vec<f64> {
    let mut out = vec![0.0; data.len()];
    for r in 0..rows {
        for c in 0..cols {
            out[c * rows + r] = data[r * cols + c];
        }
    }
    out
}

/// The detail bands of one level (each in its own layout; only their values matter).
#[derive(Debug, Clone, PartialEq)]
pub struct DetailBands {
    /// Low along x, high along y.
    pub lh: Vec<f64>,
    /// High along x, low along y.
    pub hl: Vec<f64>,
    /// High along both.
    pub hh: Vec<f64>,
}

impl DetailBands {
    /// Every detail coefficient of the level, mutably.
    pub fn values_mut(&mut self) -> impl Iterator<Item = &mut f64> {
        self.lh
            .iter_mut()
            .chain(self.hl.iter_mut())
            .chain(self.hh.iter_mut())
    }

    /// Every detail coefficient of the level.
    pub fn values(&self) -> impl Iterator<Item = &f64> {
        self.lh.iter().chain(&self.hl).chain(&self.hh)
    }
}

/// The Haar coefficients of a `width x height` image: the last approximation (one value) and
/// the detail bands, finest level first.
#[derive(Debug, Clone, PartialEq)]
pub struct HaarCoefficients {
    /// The coarsest scaling coefficient(s): `sum / sqrt(W H)` of the image.
    pub approximation: Vec<f64>,
    /// Detail bands, finest first.
    pub levels: Vec<DetailBands>,
}

/// The 2D unbalanced Haar transform of one size and one pair of offsets.
#[derive(Debug, Clone, PartialEq)]
pub struct Haar2d {
    width: usize,
    height: usize,
    x_steps: Vec<Vec<Merge>>,
    y_steps: Vec<Vec<Merge>>,
}

impl Haar2d {
    /// The transform of `width x height` images (both at least 1) with the dyadic partition
    /// shifted by `(offset_x, offset_y)` pixels.
    pub fn new(width: usize, height: usize, offset_x: usize, offset_y: usize) -> Self {
        let mut x_steps = axis_steps(width, offset_x);
        let mut y_steps = axis_steps(height, offset_y);
        // The shorter axis passes through its single block while the longer one goes on.
        let levels = x_steps.len().max(y_steps.len());
        x_steps.resize(levels, vec![Merge::Single { a: 0 }]);
        y_steps.resize(levels, vec![Merge::Single { a: 0 }]);
        Self {
            width,
            height,
            x_steps,
            y_steps,
        }
    }

    /// The coefficients of `image` (`width x height`, row-major).
    pub fn forward(&self, image: &[f64]) -> HaarCoefficients {
        self.forward_with(image, false)
    }

    /// The variances of the coefficients of an image of independent pixels with variances
    /// `variance` (`width x height`, row-major): `Var d_k = sum_P W_{kP}² v_P`, `W` the
    /// transform's matrix. Each pixel reaches each coefficient along one path of merges (the
    /// partition is a tree), so `W_{kP}` is the product of the merge weights along it and
    /// `W_{kP}²` the product of their squares: the same pyramid with `(c_a², c_b²)` in place of
    /// `(c_a, c_b)` and no sign.
    pub fn forward_squared(&self, variance: &[f64]) -> HaarCoefficients {
        self.forward_with(variance, true)
    }

    /// `sum_k W_{kP}² g_k` for every pixel `P` (`g` per coefficient, in the layout of
    /// [`Haar2d::forward`]): the transpose of [`Haar2d::forward_squared`]. With `g_k = 1` for
    /// the coefficients a shrinkage keeps and 0 for those it kills, the derivative
    /// `d x^_P / d y_P` of the hard-kept / soft-shrunk image at pixel `P` (the divergence SURE
    /// needs).
    pub fn inverse_squared(&self, g: &HaarCoefficients) -> Vec<f64> {
        self.inverse_with(g, true)
    }

    fn forward_with(&self, image: &[f64], squared: bool) -> HaarCoefficients {
        assert_eq!(image.len(), self.width * self.height, "image size");
        let (mut a, mut nx, mut ny) = (image.to_vec(), self.width, self.height);
        let mut levels = vec![];
        for (sx, sy) in self.x_steps.iter().zip(&self.y_steps) {
            let (l, h) = forward_rows_with(&a, nx, ny, sx, squared);
            let (nxl, nxh) = (sx.len(), h.len() / ny);
            let (llt, lh) = forward_rows_with(&transpose(&l, nxl, ny), ny, nxl, sy, squared);
            let (hl, hh) = forward_rows_with(&transpose(&h, nxh, ny), ny, nxh, sy, squared);
            a = transpose(&llt, sy.len(), nxl);
            (nx, ny) = (nxl, sy.len());
            levels.push(DetailBands { lh, hl, hh });
        }
        HaarCoefficients {
            approximation: a,
            levels,
        }
    }

    /// The image of `coefficients` (the inverse of [`Haar2d::forward`]).
    pub fn inverse(&self, coefficients: &HaarCoefficients) -> Vec<f64> {
        self.inverse_with(coefficients, false)
    }

    fn inverse_with(&self, coefficients: &HaarCoefficients, squared: bool) -> Vec<f64> {
        // The approximation sizes per level, finest first.
        let mut sizes = vec![(self.width, self.height)];
        for (sx, sy) in self.x_steps.iter().zip(&self.y_steps) {
            sizes.push((sx.len(), sy.len()));
        }
        let mut a = coefficients.approximation.clone();
        for (j, bands) in coefficients.levels.iter().enumerate().rev() {
            let ((nx, ny), (nxl, nyl)) = (sizes[j], sizes[j + 1]);
            let (sx, sy) = (&self.x_steps[j], &self.y_steps[j]);
            let nxh = bands.hl.len() / nyl.max(1);
            let lt = inverse_rows_with(&transpose(&a, nxl, nyl), &bands.lh, ny, nxl, sy, squared);
            let ht = inverse_rows_with(&bands.hl, &bands.hh, ny, nxh, sy, squared);
            let (l, h) = (transpose(&lt, ny, nxl), transpose(&ht, ny, nxh));
            a = inverse_rows_with(&l, &h, nx, ny, sx, squared);
        }
        a
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn power_of_two_without_offset_is_the_plain_haar_transform() {
        // [1, 3] -> s = 4 / sqrt 2, d = -2 / sqrt 2.
        let t = Haar2d::new(2, 1, 0, 0);
        let c = t.forward(&[1.0, 3.0]);
        let r = std::f64::consts::FRAC_1_SQRT_2;
        assert!((c.approximation[0] - 4.0 * r).abs() <= 4.0 * f64::EPSILON);
        assert!((c.levels[0].hl[0] + 2.0 * r).abs() <= 4.0 * f64::EPSILON);
    }

    #[test]
    fn a_line_of_three_with_offset_one_merges_as_the_partition_says() {
        // Offset 1: ids 1, 2, 3 -> level 1 blocks {0}, {1, 2}; level 2 {0, 1, 2}.
        let steps = axis_steps(3, 1);
        assert_eq!(steps.len(), 2);
        assert!(matches!(steps[0][0], Merge::Single { a: 0 }));
        assert!(matches!(steps[0][1], Merge::Pair { a: 1, .. }));
        assert!(matches!(steps[1][0], Merge::Pair { a: 0, .. }));
    }
}
