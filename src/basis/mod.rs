//! The CDV interval wavelet basis: Daubechies filters, the Cohen–Daubechies–Vial edge
//! construction, exact pointwise evaluation and the interval fast wavelet transform.
//!
//! On `[0, 1]`, `V_j` has `2^j` orthonormal scaling functions: `p` left edge functions
//! `phi^L_{j,k}(x) = 2^{j/2} phi^L_k(2^j x)`, the interior translates
//! `phi_{j,m}(x) = 2^{j/2} phi(2^j x - m)`, `m = p..2^j-p-1`, and `p` right edge functions;
//! `W_j` likewise with wavelets. The localized basis of the paper supplement (eq. 11) is
//! `Psi(n, N) = {phi_{n,k}} U {psi_{j,k} : n <= j <= N}`, of dimension `2^{N+1}`.
//! Haar (`p = 1`) needs no edge functions and is usable from level 0.

pub mod bank;
mod byte_tables;
pub mod cdv;
mod digits;
mod error;
pub mod eval;
pub mod facts;
pub mod filters;
pub mod fwt;
mod index;
pub mod integral;
mod localized;
pub mod single_level;
pub mod tensor;

pub use bank::FilterBank;
pub use error::BasisError;
pub use eval::{BasisValue, Evaluator};
pub use filters::{FilterFamily, MAX_VANISHING_MOMENTS};
pub use index::{cell_of, support_cells, FunctionId, FunctionKind, Side};
pub use localized::{minimum_level, CdvBasis, MAX_LEVEL};
pub use single_level::SingleLevelEvaluator;

pub use crate::domain::Domain;
