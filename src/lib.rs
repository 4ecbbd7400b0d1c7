//! # rkwave
//!
//! Least-squares reconstruction of functions from scattered point samples in sparse, adaptive
//! CDV interval wavelet bases: given samples `f_i = f(lambda_i)` at arbitrary positions
//! `lambda_i` of an interval `[a, b]`, the coefficients `c = K^+ f` of
//! `f~(x) = sum_a c_a Psi_a(x)`, `K[i, a] = Psi_a(lambda_i)`, and `f~` anywhere.
//!
//! ## Fit samples in five lines
//!
//! ```
//! use rkwave::reconstruct::{fit, FitParams};
//! use rkwave::sampling::Domain;
//!
//! // 2000 scattered samples of a smooth signal on [0, 1] (a deterministic scatter here).
//! let xs: Vec<f64> = (0..2000).map(|i| (i as f64 * 0.618_033_988_75).fract()).collect();
//! let ys: Vec<f64> = xs.iter().map(|x| (6.0 * x).sin()).collect();
//!
//! let f = fit(&xs, &[&ys], Domain::UNIT, &FitParams::default())?; // p = 3, automatic levels
//! let grid: Vec<f64> = (0..=100).map(|i| i as f64 / 100.0).collect();
//! let values = f.evaluate(&grid)?; // one Vec per channel
//!
//! // Cell width h = 2^-(N+1) ~ 1/256 here: the p = 3 error ~ h^3 max|f'''| ~ 1e-5
//! // (checked with a margin).
//! let err = grid.iter().zip(&values[0]).map(|(x, v)| (v - (6.0 * x).sin()).abs());
//! assert!(err.fold(0.0, f64::max) < 1e-3);
//! assert!(f.fallbacks.is_empty()); // nothing had to be lowered or replaced
//! # Ok::<(), rkwave::reconstruct::ReconstructError>(())
//! ```
//!
//! [`reconstruct::FitParams`] chooses the vanishing moments `p` (the filter family follows
//! CDV's rule unless given), the levels and the solver; [`reconstruct::Fit`] carries the
//! coefficients, the levels used, the solver's report and every fallback taken.
//!
//! ## Samples on the image plane to pixels, through the front door
//!
//! ```
//! use rkwave::image::job::{ImageParams, UniformJob};
//! use rkwave::image::{ImagePlane, ImageSamples};
//!
//! // 4 samples a pixel of a smooth image on a 32 x 24 plane (positions in pixel units).
//! let plane = ImagePlane::new(32, 24)?;
//! let m = 4 * plane.pixels();
//! let xs: Vec<f64> = (0..m).map(|i| 32.0 * (i as f64 * 0.618_034).fract()).collect();
//! let ys: Vec<f64> = (0..m).map(|i| 24.0 * (i as f64 * 0.754_878).fract()).collect();
//! let f: Vec<f64> = xs.iter().zip(&ys).map(|(x, y)| 0.5 + 0.01 * x - 0.02 * y).collect();
//! let samples = ImageSamples::new(plane, xs, ys, vec![f])?;
//!
//! // Validates, decides the pixel estimate (by default a film per pixel chosen by SURE),
//! // checks the memory from the sizes, then reconstructs: what `rkwave reconstruct --dim 2`
//! // and Python's `reconstruct_image` call.
//! let job = UniformJob::new(plane, &ImageParams::default())?;
//! job.check_memory(samples.channels(), samples.len())?; // before reading, from sizes alone
//! let out = job.run(&samples)?;
//! assert_eq!(out.reconstruction.image.channels[0].len(), plane.pixels());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! [`image::job::ImageParams`] groups what a user sets: the method, the fit's options
//! ([`image::job::FitOptions`]: `p`, `rho`, the ridge, the smoothing), the pixel estimate and its
//! shrinkage; a refusal is an [`image::job::JobError`] naming the parameter at fault.
//!
//! ## The pipeline, one module a stage
//!
//! - [`domain`]: the interval `[a, b]` and its map to `[0, 1]` (shared by every stage);
//! - [`sampling`]: sample layouts and built-in test signals (the input);
//! - [`basis`]: Daubechies filters, the CDV edge construction, exact evaluation of every
//!   function of `Psi(n, N)` at any position, and the interval FWT;
//! - [`kernel`]: active basis sets, automatic levels and the sparse kernel matrix
//!   `K[i, a] = Psi_a(lambda_i)`;
//! - [`solve`]: `c = K^+ f` by local inversion, sparse global least squares or the dense
//!   pseudo-inverse;
//! - [`reconstruct`]: samples to coefficients to values ([`reconstruct::fit`]), by default
//!   through the single-scale normal equations of `V_{N+1}`; dual and reproducing kernels;
//! - [`adaptive`]: the adaptive core both dimensions share: the dyadic trees (1D, and 2D
//!   with four children per cell), Dörfler marking, the budget, the stop reasons;
//! - [`refine`]: the adaptive refiner: a wavelet tree and its samples grown together where
//!   the signal needs them ([`refine::refine`]);
//! - [`image`]: the image plane `[0, W] x [0, H]`, scattered samples on it, scenes, film
//!   filters and image-plane reconstruction ([`image::reconstruct`]: samples to pixels);
//! - [`report`]: the local-vs-global comparison of docs/design.md §5 as typed data;
//! - [`io`] (at the edge): reading and writing samples (CSV, NumPy `.npy`) and images;
//! - [`error`]: the kinds every error is classified by and the typed fixes (a leaf: each
//!   error enum's `kind()` sits beside its definition);
//! - `plot` (at the edge, feature `plot`): the figures;
//! - `lab` (feature `plot`): the experiments that measure the library, their tables and
//!   figures; the production path never calls it.
//!
//! Without default features (`cargo build --lib --no-default-features`) the engine builds with
//! no command-line, plotting or image crates in its tree.
//!
//! ## Errors and panics
//!
//! - **Errors.** Everything a caller can get wrong is a typed error (`thiserror`), never a
//!   panic, a NaN or a silent cut: parameters out of range, positions outside the domain or
//!   not finite, non-finite values, too few samples, unreadable files, a solve that does not
//!   converge. Each variant names the value at fault in its fields and its message says what
//!   to pass instead.
//! - **Every public error enum** is `#[non_exhaustive]`, derives `Debug` and `Error` (and
//!   `Clone` and `PartialEq` unless it carries an operating-system, image or nested error
//!   that does not), and has a `kind()` returning one shared [`error::ErrorKind`]
//!   (`InvalidInput`, `Undetermined`, `ResourceLimit`, `NotConverged`, `Numerical`,
//!   `Unreadable`, `OutputRefused`, `WriteFailed`, `Internal`; [`error`] gives each its
//!   meaning). Callers decide by kind, never by message text. The complete list:
//!   - the engine: [`basis::BasisError`], [`basis::tensor::TensorError`],
//!     [`domain::DomainError`], [`kernel::KernelError`], [`solve::SolveError`],
//!     [`reconstruct::ReconstructError`], [`refine::RefineError`],
//!     [`resources::ResourceError`];
//!   - the image plane: [`image::job::JobError`], [`image::ImageError`], [`image::ImageFitError`],
//!     [`image::pixels::PixelError`], [`image::WaveletError`],
//!     [`image::scene::SceneError`], [`image::adaptive::AdaptiveError`],
//!     [`image::plan::ProtocolError`];
//!   - input and output: [`io::IoError`], [`io::output::OutputError`],
//!     [`io::image_file::ImageFileError`];
//!   - reports and the lab: [`report::scaling::ScalingError`]; with feature `plot`,
//!     `plot::PlotError`, `lab::experiment::ImageRunError` and
//!     `lab::adaptive::AdaptiveRunError`.
//!
//!   A parse error of a name (`ParseMethodError`, `ParseSamplerError`, ...) is a struct
//!   holding the name given; its kind is always `InvalidInput`.
//! - **Parameters out of range** are `InvalidParameter { name, value, fix }` with the value
//!   as given (`String`); too few samples is `Undersampled { samples, functions, .. }` (the
//!   reconstruction adds the fix that can work).
//! - **Messages speak of parameters**, in the library's terms (`p`, the domain, the max depth,
//!   `cutoff`), never of command-line flags: the command line maps them to its flags.
//! - **The command line** maps kinds to exit codes: 2 when the caller can fix the request
//!   (every kind but `WriteFailed` and `Internal`), 1 when the machine failed.
//! - **Panics** are only for broken internal contracts (an index the library computed itself
//!   out of range, a factorization of a matrix the library built to be definite): a panic is
//!   a bug to report, never a way to signal bad input.
//! - **Fallbacks are reported.** A departure from what was asked (a lowered level, another
//!   solver, a cut-off) is recorded in the result ([`reconstruct::Fallback`],
//!   [`solve::LocalStats`]) and printed by the command line in text and JSON. A warning that
//!   lists places (gaps, pinned regions) gives their count and the few largest, never a line
//!   of hundreds of characters.
//!
//! ## Evaluating the basis itself
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

pub mod adaptive;
pub mod basis;
pub mod domain;
pub mod error;
pub mod image;
pub mod io;
pub mod kernel;
#[cfg(feature = "plot")]
pub mod lab;
pub mod norms;
#[cfg(feature = "plot")]
pub mod plot;
pub mod reconstruct;
pub mod refine;
pub mod report;
pub mod resources;
pub mod sampling;
pub mod solve;

/// The README's Rust examples, compiled and run as doctests (its shell blocks are not Rust).
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
