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
