//! Numbering of `Psi(n, N)`: scaling functions of level `n` take global indices
//! `0..2^n`, wavelets of level `j` take `2^j + k`, `k < 2^j`. Within a level, the `p` left edge
//! functions come first (`k < p`), then interior translates (`k = m`), then the right edge
//! functions (`k = 2^j - 1 - r` for right edge function `r`).

use serde::Serialize;

/// Scaling function or wavelet.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum FunctionKind {
    /// `phi_{n,k}`.
    Scaling,
    /// `psi_{j,k}`.
    Wavelet,
}

/// Where on the interval a function sits.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Side {
    /// A left edge function.
    Left,
    /// An interior translate.
    Interior,
    /// A right edge function.
    Right,
}

/// The identity of one function of `Psi(n, N)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub struct FunctionId {
    /// Scaling or wavelet.
    pub kind: FunctionKind,
    /// Left edge, interior or right edge.
    pub side: Side,
    /// Level `j`.
    pub level: u32,
    /// Index within the level, `0..2^j`.
    pub index: usize,
}

impl FunctionId {
    /// Global index in `Psi(n, N)`.
    pub fn global(&self) -> usize {
        match self.kind {
            FunctionKind::Scaling => self.index,
            FunctionKind::Wavelet => (1usize << self.level) + self.index,
        }
    }

    /// Decodes a global index given the coarse level and the number of edge functions per side.
    pub fn from_index(a: usize, coarse: u32, edge_count: usize) -> Self {
        let (kind, level, index) = if a < (1usize << coarse) {
            (FunctionKind::Scaling, coarse, a)
        } else {
            let level = usize::BITS - 1 - a.leading_zeros();
            (FunctionKind::Wavelet, level, a - (1usize << level))
        };
        let size = 1usize << level;
        let side = if index < edge_count {
            Side::Left
        } else if index >= size - edge_count {
            Side::Right
        } else {
            Side::Interior
        };
        Self {
            kind,
            side,
            level,
            index,
        }
    }
}

/// Structural support of function `index` of a level with `2^level` functions: the inclusive
/// range of level-`level` cells on which it is (structurally) nonzero, for `p` vanishing
/// moments (`p` edge functions per side, none for Haar).
pub fn support_cells(p: usize, level: u32, index: usize) -> (u64, u64) {
    let size = 1u64 << level;
    let k = index as u64;
    let p64 = p as u64;
    let edges = if p >= 2 { p64 } else { 0 };
    if k < edges {
        (0, p64 + k - 1)
    } else if k + edges >= size {
        let r = size - 1 - k;
        (size - p64 - r, size - 1)
    } else {
        (k.saturating_sub(p64 - 1), (k + p64 - 1).min(size - 1))
    }
}

/// The level-`level` cell holding `t` in `[0, 1]`: `floor(2^level t)`, with `t = 1` in the last
/// cell (the evaluator's convention).
pub fn cell_of(t: f64, level: u32) -> u64 {
    let size = 1u64 << level;
    if t.is_nan() || t <= 0.0 {
        return 0;
    }
    if t >= 1.0 {
        return size - 1;
    }
    ((t * size as f64).floor() as u64).min(size - 1)
}
