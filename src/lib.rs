//! # rkwave
//!
//! Least-squares reconstruction of functions from scattered point samples in sparse, adaptive
//! CDV interval wavelet bases.
//!
//! The modules follow the pipeline:
//! - [`basis`]: Daubechies filters, the CDV edge construction, exact pointwise evaluation of
//!   `Psi(n, N)` ([`basis::CdvBasis`], [`basis::Evaluator`]) and the interval FWT;
//! - [`sampling`]: domains, sample layouts and built-in test signals;
//! - [`refine`]: the adaptive refiner ([`refine::refine`]): a wavelet tree and samples grown
//!   together where the signal needs them;
//! - [`image`]: the image plane `[0, W] x [0, H]`, scattered samples on it, scenes, film
//!   filters and image-plane reconstruction;
//! - [`io`]: reading and writing samples (CSV, NumPy `.npy`);
//! - [`plot`] draws the figures.
//!
//! ```
//! use rkwave::basis::{CdvBasis, FilterFamily};
//! use rkwave::sampling::Domain;
//!
//! let basis = CdvBasis::new(3, FilterFamily::Extremal, 4, 8, Domain::UNIT)?;
//! let values = basis.evaluator().eval(0.3)?; // every nonzero function at x = 0.3
//! assert!(values.len() > 10);
//! # Ok::<(), rkwave::basis::BasisError>(())
//! ```

#![deny(missing_docs)]

pub mod basis;
pub mod image;
pub mod io;
pub mod kernel;
#[cfg(feature = "plot")]
pub mod plot;
pub mod reconstruct;
pub mod refine;
pub mod report;
pub mod sampling;
pub mod solve;
