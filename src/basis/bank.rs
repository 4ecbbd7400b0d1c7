//! The level-independent part of a CDV basis: interior and edge refinement matrices, their
//! exact facts, and the digit matrices of pointwise evaluation.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

use nalgebra::DMatrix;

use super::cdv::{digit_matrix, EdgeFilters, InteriorFilters, SQRT2};
use super::filters::{daubechies_lowpass, FilterFamily, MAX_VANISHING_MOMENTS};
use super::BasisError;

/// Digit matrices of one interior filter: `v((t+d)/2) = T_d v(t)` and the wavelet values
/// `w((t+d)/2) = U_d v(t)`, `(T_d)_{i,l} = sqrt2 h_{2i+d-l}`, `(U_d)_{i,l} = sqrt2 g_{2i+d-l}`,
/// plus all products of eight digit matrices (one per byte), row-major.
#[derive(Clone, Debug)]
pub struct DigitTables {
    /// `2p - 1`: length of the state `v(t) = (phi(t), ..., phi(t + 2p - 2))`.
    pub width: usize,
    /// `T_0`, `T_1`, row-major `width x width`.
    pub t: [Vec<f64>; 2],
    /// `U_0`, `U_1`.
    pub u: [Vec<f64>; 2],
    /// `P_b = T_{b_7} T_{b_6} ... T_{b_0}` for bytes `b` (`b_7` the most significant digit).
    pub bytes: Vec<f64>,
    /// `v(0)`: values at the integers.
    pub v0: Vec<f64>,
    /// `v(1^-)`: left limits at `1, ..., 2p-1`.
    pub v1: Vec<f64>,
}

impl DigitTables {
    fn new(f: &InteriorFilters) -> Self {
        let w = 2 * f.p - 1;
        let flat = |m: DMatrix<f64>| -> Vec<f64> {
            let mut out = vec![0.0; w * w];
            for i in 0..w {
                for l in 0..w {
                    out[i * w + l] = m[(i, l)];
                }
            }
            out
        };
        let tm = [digit_matrix(&f.h, 0), digit_matrix(&f.h, 1)];
        let um = [digit_matrix(&f.g, 0), digit_matrix(&f.g, 1)];
        // Formed in double-double and rounded once: f64 products were the evaluation's
        // largest rounding (see byte_tables).
        let bytes = super::byte_tables::byte_tables(&f.h);
        Self {
            width: w,
            t: [flat(tm[0].clone()), flat(tm[1].clone())],
            u: [flat(um[0].clone()), flat(um[1].clone())],
            bytes,
            v0: f.values_at_integers.clone(),
            v1: f.left_limits_at_integers.clone(),
        }
    }
}

/// Edge refinement matrices scaled by `sqrt2`, flat row-major, for the evaluation recursion
/// `a_j = sqrt2 H a_{j+1} + sqrt2 h phi_{j+1}`.
#[derive(Clone, Debug)]
pub struct EdgeTables {
    /// Number of edge functions.
    pub count: usize,
    /// `sqrt2 H`, `count x count`.
    pub h_edge: Vec<f64>,
    /// `sqrt2 h`, `count x (2p-1)`.
    pub h_interior: Vec<f64>,
    /// `sqrt2 G`.
    pub g_edge: Vec<f64>,
    /// `sqrt2 g`.
    pub g_interior: Vec<f64>,
    /// `phi_L(c)`, `c = 0..2p-2`, as `[c][k]`.
    pub values_at_integers: Vec<Vec<f64>>,
}

impl EdgeTables {
    fn new(e: &EdgeFilters) -> Self {
        let flat = |m: &DMatrix<f64>| -> Vec<f64> {
            let mut out = Vec::with_capacity(m.nrows() * m.ncols());
            for i in 0..m.nrows() {
                for j in 0..m.ncols() {
                    out.push(SQRT2 * m[(i, j)]);
                }
            }
            out
        };
        Self {
            count: e.count,
            h_edge: flat(&e.h_edge),
            h_interior: flat(&e.h_interior),
            g_edge: flat(&e.g_edge),
            g_interior: flat(&e.g_interior),
            values_at_integers: e.values_at_integers.clone(),
        }
    }
}

/// Everything about a CDV basis that does not depend on the levels or the domain.
#[derive(Clone, Debug)]
pub struct FilterBank {
    family: FilterFamily,
    /// The interior filter and its facts.
    pub interior: InteriorFilters,
    /// The reversed interior filter (whose left edge, reflected, is the right edge).
    pub reversed: InteriorFilters,
    /// Left edge construction (absent for Haar).
    pub left: Option<EdgeFilters>,
    /// Left edge construction of the reversed filter = right edge, reflected.
    pub right: Option<EdgeFilters>,
    /// Digit tables of the interior filter.
    pub digits: DigitTables,
    /// Digit tables of the reversed filter.
    pub reversed_digits: DigitTables,
    /// Evaluation tables of the left edge.
    pub left_tables: Option<EdgeTables>,
    /// Evaluation tables of the right edge (in reflected coordinates).
    pub right_tables: Option<EdgeTables>,
}

impl FilterBank {
    /// Builds the bank for `p` vanishing moments of the given family.
    pub fn new(p: usize, family: FilterFamily) -> Result<Self, BasisError> {
        if p == 0 || p > MAX_VANISHING_MOMENTS {
            return Err(BasisError::UnsupportedOrder {
                p,
                max: MAX_VANISHING_MOMENTS,
            });
        }
        let h = daubechies_lowpass(p, family);
        Self::from_lowpass(&h, family)
    }

    /// Builds the bank from an explicit orthonormal low-pass filter of length `2p`.
    pub fn from_lowpass(h: &[f64], family: FilterFamily) -> Result<Self, BasisError> {
        let interior = InteriorFilters::new(h)?;
        let rev: Vec<f64> = h.iter().rev().copied().collect();
        let reversed = InteriorFilters::new(&rev)?;
        let (left, right) = if interior.p >= 2 {
            (
                Some(EdgeFilters::left(&interior)?),
                Some(EdgeFilters::left(&reversed)?),
            )
        } else {
            (None, None)
        };
        Ok(Self {
            family,
            digits: DigitTables::new(&interior),
            reversed_digits: DigitTables::new(&reversed),
            left_tables: left.as_ref().map(EdgeTables::new),
            right_tables: right.as_ref().map(EdgeTables::new),
            interior,
            reversed,
            left,
            right,
        })
    }

    /// A process-wide shared bank (built once per `(p, family)`).
    pub fn shared(p: usize, family: FilterFamily) -> Result<Arc<Self>, BasisError> {
        type Cache = Mutex<HashMap<(usize, FilterFamily), Arc<FilterBank>>>;
        static CACHE: OnceLock<Cache> = OnceLock::new();
        let cache = CACHE.get_or_init(|| Mutex::new(HashMap::new()));
        if let Some(b) = cache.lock().ok().and_then(|c| c.get(&(p, family)).cloned()) {
            return Ok(b);
        }
        let bank = Arc::new(Self::new(p, family)?);
        if let Ok(mut c) = cache.lock() {
            c.insert((p, family), bank.clone());
        }
        Ok(bank)
    }

    /// Vanishing moments `p`.
    pub fn p(&self) -> usize {
        self.interior.p
    }
    /// The interior filter family.
    pub fn family(&self) -> FilterFamily {
        self.family
    }
    /// Edge functions per side: `p`, or `0` for Haar.
    pub fn edge_count(&self) -> usize {
        if self.interior.p >= 2 {
            self.interior.p
        } else {
            0
        }
    }
    /// Max deviation from orthonormality of the edge scaling functions (exact Gram matrices).
    pub fn edge_gram_error(&self) -> f64 {
        let l = self.left.as_ref().map_or(0.0, |e| e.gram_error);
        let r = self.right.as_ref().map_or(0.0, |e| e.gram_error);
        l.max(r)
    }
}
