//! The 2D least-squares reconstruction on the image plane (docs/design.md §7; the 1D single-scale
//! solve of [`crate::reconstruct::single_scale_ls`] with a second axis).
//!
//! `min_z ||K z - f_c||^2` over the single-scale space `V_Jx (x) V_Jy` of a
//! [`TensorBasis`], per channel `c`, through the normal equations `G z = b_c`
//! (`G = K^T K`, `b_c = K^T f_c`, accumulated sample by sample, see [`normal`]) solved by
//! sparse Cholesky or preconditioned CG ([`system`]). The result is a function:
//! `f_c(x, y) = sum_{ky,kx} z_c[ky nx + kx] phi_{Jx,kx}(x) phi_{Jy,ky}(y)`
//! ([`ImageFit::evaluate`]); the multilevel coefficients are one 2D FWT away
//! ([`TensorBasis::analysis`]).

pub(crate) mod error;

use std::sync::Arc;
use std::time::Instant;

use serde::Serialize;

use crate::basis::tensor::{TensorBasis, TensorError, TensorLevelParams, TensorValue};
use crate::basis::{CdvBasis, FilterFamily};
use crate::solve::cg::IterationLimit;
use crate::solve::stencil::precondition;

pub use crate::solve::stencil::precondition::kernel_matrix_2d;
/// The stencil system (the normal equations' assembly and their solves) lives in the solver
/// layer, [`crate::solve::stencil`]; its modules keep their paths here.
pub use crate::solve::stencil::{normal, system};
pub use error::ImageFitError;
pub use normal::{NormalEquations2d, StencilPattern};
pub use system::{
    FactorReport, FillOrdering, NormalSolver, NormalSystem, StencilCgReport, StencilPreconditioner,
    CG_MAX_ITERATIONS, CG_TOLERANCE, CHOLESKY_MAX_FUNCTIONS,
};

/// How the levels are chosen per axis.
#[derive(Clone, Copy, Debug, Serialize)]
pub enum ImageLevels {
    /// From the resolution and the samples ([`crate::basis::tensor::auto_level`]).
    Auto(TensorLevelParams),
    /// Single-scale levels `(Jx, Jy)`.
    Fixed(u32, u32),
}

/// Parameters of an image fit.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct ImageFitParams {
    /// Vanishing moments `p`: 2 costs `(2p - 1)^4 / 2 = 41` updates per sample, 3 costs 313
    /// and reproduces quadratics.
    pub p: usize,
    /// Interior filter family; `None` is CDV's choice for `p`
    /// ([`FilterFamily::cdv_default`]: extremal phase for `p <= 3`, least asymmetric above),
    /// resolved by [`ImageFitParams::family`] as [`crate::reconstruct::FitParams::family`]
    /// does in 1D.
    #[serde(skip)]
    pub family: Option<FilterFamily>,
    /// Levels per axis.
    pub levels: ImageLevels,
    /// The solver of the normal equations: by default chosen by size, Jacobi PCG (with the
    /// Cholesky where it does not converge) above `64²` functions ([`NormalSolver::Auto`]).
    pub solver: NormalSolver,
    /// Fill-reducing ordering of the Cholesky solver (and of CG's fallback).
    pub ordering: FillOrdering,
    /// Relative ridge `lambda` on the equilibrated normal matrix: bounds the amplification
    /// of directions the samples barely determine (`~ 1 / (2 sqrt(lambda))`) at a bias of
    /// about `lambda / sigma^2` on well-determined ones; 0 for the exact least squares.
    pub ridge: f64,
    /// Weight `mu` of a first-difference penalty on the single-scale coefficients,
    /// `mu gbar sum (z_k - z_k')^2` over horizontally and vertically adjacent functions
    /// (`gbar` the mean diagonal of `G`, so `mu` is relative): `G + mu gbar L` with `L` the
    /// grid Laplacian of the coefficients. 0 (the default) is the least-squares fit; `> 0`
    /// damps oscillation between neighbours (ringing at edges, noise) and fills unsampled
    /// functions from their neighbours instead of pinning them to 0. Needs `p >= 2`
    /// (neighbouring functions must overlap).
    pub smoothing: f64,
}

impl ImageFitParams {
    /// The interior filter family: the given one, or CDV's choice for `p`.
    pub fn family(&self) -> FilterFamily {
        self.family
            .unwrap_or_else(|| FilterFamily::cdv_default(self.p))
    }
}

impl Default for ImageFitParams {
    fn default() -> Self {
        Self {
            p: 2,
            family: None,
            levels: ImageLevels::Auto(TensorLevelParams::default()),
            solver: NormalSolver::Auto,
            ordering: FillOrdering::default(),
            ridge: 1e-9,
            smoothing: 0.0,
        }
    }
}

/// Seconds per stage.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct ImageTimings {
    /// Stencil pattern (symbolic, once per basis).
    pub pattern_s: f64,
    /// Accumulating `G` and `b` over the samples.
    pub accumulate_s: f64,
    /// Cholesky (symbolic + numeric) or preconditioner setup.
    pub factor_s: f64,
    /// Triangular solves or CG iterations, all channels.
    pub solve_s: f64,
}

/// What the image solve did.
#[derive(Clone, Debug, Serialize)]
pub struct ImageSolveReport {
    /// Single-scale levels `(Jx, Jy)`.
    pub levels: (u32, u32),
    /// Functions per axis `(nx, ny)`.
    pub dims: (usize, usize),
    /// Unknowns `nx ny`.
    pub functions: usize,
    /// Samples `m`.
    pub samples: usize,
    /// `m / (nx ny)`.
    pub oversampling: f64,
    /// Stored entries of `G` (lower triangle).
    pub normal_nnz: usize,
    /// Solver used (never [`NormalSolver::Auto`]: the one it resolved to).
    pub solver: NormalSolver,
    /// Relative ridge used.
    pub ridge: f64,
    /// Relative weight of the first-difference penalty (0: none).
    pub smoothing: f64,
    /// Functions with no sample in their support (coefficient pinned to 0).
    pub unsampled: usize,
    /// Where the pinned functions are (`None` when every function has a sample).
    pub pinned: Option<PinnedRegion>,
    /// Functions with fewer than `(2p - 1)^2` samples (fewer than their own neighbours).
    pub undersampled: usize,
    /// Cholesky facts (Cholesky solver).
    pub factor: Option<FactorReport>,
    /// CG facts (CG solver).
    pub cg: Option<StencilCgReport>,
    /// Local inversion statistics (local solver).
    pub local: Option<crate::solve::LocalStats>,
    /// Stage times.
    pub timings: ImageTimings,
}

/// Where the unsampled (pinned) functions lie. Single-scale function `(kx, ky)` is placed at
/// its cell `[kx W / nx, (kx + 1) W / nx] x [ky H / ny, (ky + 1) H / ny]` (pixel units; its
/// support is `2p - 1` cells wide around it); the reconstruction is 0 there (not a coarser
/// fit) unless a smoothing penalty fills them from their neighbours
/// ([`ImageFitParams::smoothing`]).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct PinnedRegion {
    /// Total area of the pinned functions' cells, in pixels.
    pub area_px: f64,
    /// That area over the image's `W H`.
    pub fraction: f64,
    /// Bounding box of the pinned cells, `[x0, x1]` (pixels).
    pub x: (f64, f64),
    /// Bounding box of the pinned cells, `[y0, y1]` (pixels).
    pub y: (f64, f64),
}

impl PinnedRegion {
    /// The region of the functions with `support_samples[ky nx + kx] == 0`, or `None`.
    pub fn of(
        support_samples: &[u32],
        dims: (usize, usize),
        width: usize,
        height: usize,
    ) -> Option<Self> {
        let (nx, ny) = dims;
        let (cw, ch) = (width as f64 / nx as f64, height as f64 / ny as f64);
        let mut count = 0usize;
        let (mut x0, mut x1, mut y0, mut y1) = (usize::MAX, 0, usize::MAX, 0);
        for (k, _) in support_samples.iter().enumerate().filter(|(_, &c)| c == 0) {
            let (kx, ky) = (k % nx, k / nx);
            count += 1;
            x0 = x0.min(kx);
            x1 = x1.max(kx);
            y0 = y0.min(ky);
            y1 = y1.max(ky);
        }
        (count > 0).then(|| Self {
            area_px: count as f64 * cw * ch,
            fraction: count as f64 / (nx * ny) as f64,
            x: (x0 as f64 * cw, (x1 + 1) as f64 * cw),
            y: (y0 as f64 * ch, (y1 + 1) as f64 * ch),
        })
    }
}

/// A fitted image: the reconstruction as a function on `[0, W] x [0, H]`.
#[derive(Clone, Debug)]
pub struct ImageFit {
    basis: TensorBasis,
    /// Single-scale coefficients per channel, `nx ny` each, index `ky * nx + kx`.
    pub coefficients: Vec<Vec<f64>>,
    /// What the solve did.
    pub report: ImageSolveReport,
    system: Arc<NormalSystem>,
    params: ImageFitParams,
}

/// Checks the sample arrays of a `width x height` image: samples and channels present, equal
/// lengths, finite values, positions in `[0, width] x [0, height]`.
pub(crate) fn check_input(
    width: usize,
    height: usize,
    xs: &[f64],
    ys: &[f64],
    values: &[&[f64]],
) -> Result<(), ImageFitError> {
    if xs.is_empty() {
        return Err(ImageFitError::Empty { what: "samples" });
    }
    if values.is_empty() {
        return Err(ImageFitError::Empty { what: "channels" });
    }
    if ys.len() != xs.len() {
        return Err(ImageFitError::LengthMismatch {
            what: "ys".into(),
            expected: xs.len(),
            found: ys.len(),
        });
    }
    for (c, v) in values.iter().enumerate() {
        if v.len() != xs.len() {
            return Err(ImageFitError::LengthMismatch {
                what: format!("channel {c}"),
                expected: xs.len(),
                found: v.len(),
            });
        }
        if let Some((index, &value)) = v.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(ImageFitError::NonFiniteValue {
                index,
                channel: c,
                value,
            });
        }
    }
    let (w, h) = (width as f64, height as f64);
    if let Some(index) =
        (0..xs.len()).find(|&i| !(0.0..=w).contains(&xs[i]) || !(0.0..=h).contains(&ys[i]))
    {
        return Err(ImageFitError::SampleOutside {
            index,
            x: xs[index],
            y: ys[index],
            width,
            height,
        });
    }
    Ok(())
}

/// Fits every channel on a `width x height` image from samples `(xs[i], ys[i])` (pixel
/// units) with values `values[c][i]`.
pub fn fit_image(
    width: usize,
    height: usize,
    xs: &[f64],
    ys: &[f64],
    values: &[&[f64]],
    params: &ImageFitParams,
) -> Result<ImageFit, ImageFitError> {
    if width == 0 || height == 0 {
        let (axis, value) = if width == 0 {
            ("width", width)
        } else {
            ("height", height)
        };
        return Err(TensorError::ZeroResolution { axis, value }.into());
    }
    check_input(width, height, xs, ys, values)?;
    let basis = match params.levels {
        ImageLevels::Auto(lp) => {
            TensorBasis::auto(params.p, params.family(), width, height, xs.len(), lp)?
        }
        ImageLevels::Fixed(jx, jy) => {
            TensorBasis::new(params.p, params.family(), width, height, (jx, jy))?
        }
    };
    let mut timings = ImageTimings::default();
    let t = Instant::now();
    let pattern = StencilPattern::new(&basis);
    timings.pattern_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let mut ne = normal::accumulate(&basis, &pattern, xs, ys, values);
    if params.smoothing != 0.0 {
        if !(params.smoothing.is_finite() && params.smoothing > 0.0) || params.p < 2 {
            return Err(ImageFitError::Smoothing {
                smoothing: params.smoothing,
                p: params.p,
            });
        }
        add_difference_penalty(&pattern, &mut ne.values, basis.dims(), params.smoothing);
    }
    timings.accumulate_s = t.elapsed().as_secs_f64();
    let full = (2 * params.p - 1).pow(2) as u32;
    let unsampled = ne.support_samples.iter().filter(|&&c| c == 0).count();
    let pinned = PinnedRegion::of(&ne.support_samples, basis.dims(), width, height);
    let undersampled = ne.support_samples.iter().filter(|&&c| c < full).count();
    let normal_nnz = pattern.nnz();
    let mut system = NormalSystem::new(pattern, ne.values, params.ridge);
    let rhs: Vec<&[f64]> = ne.rhs.iter().map(|r| r.as_slice()).collect();
    let mut local_stats = None;
    let solver = params.solver.resolve(basis.len());
    let (coefficients, factor, cg) = match solver {
        // `resolve` never returns `Auto`
        NormalSolver::Cholesky | NormalSolver::Auto => {
            let t = Instant::now();
            let f = system.factor(params.ordering)?;
            timings.factor_s = t.elapsed().as_secs_f64();
            let t = Instant::now();
            let z = system.solve_factored(&rhs);
            timings.solve_s = t.elapsed().as_secs_f64();
            (z, Some(f), None)
        }
        NormalSolver::Local(local) => {
            let t = Instant::now();
            let k = kernel_matrix_2d(&basis, xs, ys)?;
            let applied = crate::solve::apply_local(&k, values, &local)?;
            timings.factor_s = t.elapsed().as_secs_f64();
            local_stats = Some(applied.stats);
            (applied.coefficients, None, None)
        }
        NormalSolver::Cg {
            preconditioner,
            tolerance,
            forward_error,
            max_iterations,
        } => {
            let t = Instant::now();
            let local = match preconditioner {
                StencilPreconditioner::Local => {
                    Some(precondition::local_preconditioner(&basis, xs, ys)?)
                }
                _ => None,
            };
            let setup_s = t.elapsed().as_secs_f64();
            timings.factor_s = setup_s;
            // The stencil system's policy at CG's iteration limit: the sparse Cholesky.
            const ON_LIMIT: IterationLimit = IterationLimit::FallBack;
            let t = Instant::now();
            let mut report = StencilCgReport {
                preconditioner,
                iterations: Vec::new(),
                residual: Vec::new(),
                forward_error: forward_error.map(|_| Vec::new()),
                converged: true,
                setup_s,
                fallback: None,
                on_limit: ON_LIMIT,
            };
            let mut z = Vec::with_capacity(rhs.len());
            for (zc, it, res, bound) in system.solve_cg(
                &rhs,
                preconditioner,
                local.as_ref(),
                tolerance,
                forward_error,
                max_iterations,
            ) {
                report.iterations.push(it);
                report.residual.push(res);
                report.converged &= res <= tolerance;
                if let (Some(eps), Some(bound)) = (forward_error, bound) {
                    report.converged &= bound <= eps;
                    if let Some(bounds) = report.forward_error.as_mut() {
                        bounds.push(bound);
                    }
                }
                z.push(zc);
            }
            timings.solve_s = t.elapsed().as_secs_f64();
            if report.converged || ON_LIMIT != IterationLimit::FallBack {
                (z, None, Some(report))
            } else {
                // short of the tolerance (the cap, or a breakdown): the direct solve instead
                let list = |v: &[f64]| {
                    v.iter()
                        .map(|r| format!("{r:.1e}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                };
                let error = match (&report.forward_error, forward_error) {
                    (Some(bounds), Some(eps)) => format!(
                        " and estimated coefficient errors {} (forward-error tolerance {eps:e})",
                        list(bounds)
                    ),
                    _ => String::new(),
                };
                report.fallback = Some(format!(
                    "CG stopped at relative residuals {}{error} after {:?} iterations \
                     (tolerance {tolerance:e}, at most {max_iterations}): solved by the sparse \
                     Cholesky instead",
                    list(&report.residual),
                    report.iterations,
                ));
                let t = Instant::now();
                let f = system.factor(params.ordering)?;
                let z = system.solve_factored(&rhs);
                timings.factor_s += t.elapsed().as_secs_f64();
                (z, Some(f), Some(report))
            }
        }
    };
    if let Some((c, _)) = coefficients
        .iter()
        .enumerate()
        .find(|(_, z)| z.iter().any(|v: &f64| !v.is_finite()))
    {
        return Err(ImageFitError::NonFiniteCoefficients { channel: c });
    }
    let (nx, ny) = basis.dims();
    let report = ImageSolveReport {
        levels: basis.levels(),
        dims: (nx, ny),
        functions: nx * ny,
        samples: xs.len(),
        oversampling: xs.len() as f64 / (nx * ny) as f64,
        normal_nnz,
        solver,
        ridge: system.ridge(),
        smoothing: params.smoothing,
        unsampled,
        pinned,
        undersampled,
        factor,
        cg,
        local: local_stats,
        timings,
    };
    Ok(ImageFit {
        basis,
        coefficients,
        report,
        system: Arc::new(system),
        params: *params,
    })
}

/// Adds `mu gbar L` to `G` on its pattern (`L` the Laplacian of the `nx x ny` coefficient
/// grid: `c^T L c = sum (c_k - c_k')^2` over adjacent pairs; `gbar` the mean diagonal of `G`).
fn add_difference_penalty(pattern: &StencilPattern, g: &mut [f64], dims: (usize, usize), mu: f64) {
    let (nx, ny) = dims;
    let n = nx * ny;
    let gbar = (0..n).map(|j| g[pattern.col_ptr[j]]).sum::<f64>() / n as f64;
    let s = mu * gbar;
    let mut pair = |ky: usize, kx: usize, ky2: usize, kx2: usize| {
        g[pattern.offset(ky, kx, ky, kx)] += s;
        g[pattern.offset(ky2, kx2, ky2, kx2)] += s;
        g[pattern.offset(ky, kx, ky2, kx2)] -= s;
    };
    for ky in 0..ny {
        for kx in 0..nx {
            if kx + 1 < nx {
                pair(ky, kx, ky, kx + 1);
            }
            if ky + 1 < ny {
                pair(ky, kx, ky + 1, kx);
            }
        }
    }
}

/// [`fit_image`] on validated [`super::ImageSamples`].
pub fn fit_samples(
    samples: &super::ImageSamples,
    params: &ImageFitParams,
) -> Result<ImageFit, ImageFitError> {
    let plane = samples.plane();
    let values: Vec<&[f64]> = samples.values().iter().map(|v| v.as_slice()).collect();
    fit_image(
        plane.width(),
        plane.height(),
        samples.xs(),
        samples.ys(),
        &values,
        params,
    )
}

/// Positions evaluated per parallel work item.
const CHUNK: usize = 4096;

impl ImageFit {
    /// The tensor basis.
    pub fn basis(&self) -> &TensorBasis {
        &self.basis
    }
    /// The x axis single-scale basis `Psi(Jx, Jx)` on `[0, W]` (scaling part `V_Jx`).
    pub fn scale_x(&self) -> &CdvBasis {
        self.basis.scale_x()
    }
    /// The y axis single-scale basis `Psi(Jy, Jy)` on `[0, H]`.
    pub fn scale_y(&self) -> &CdvBasis {
        self.basis.scale_y()
    }
    /// `(nx, ny)`.
    pub fn dims(&self) -> (usize, usize) {
        self.basis.dims()
    }
    /// Number of channels.
    pub fn channels(&self) -> usize {
        self.coefficients.len()
    }
    /// The parameters of the fit.
    pub fn params(&self) -> &ImageFitParams {
        &self.params
    }
    /// The assembled normal system (and its factor, for the Cholesky solver).
    pub fn system(&self) -> &NormalSystem {
        &self.system
    }

    /// The reconstruction at `(x, y)`, one value per channel.
    pub fn evaluate(&self, x: f64, y: f64) -> Result<Vec<f64>, ImageFitError> {
        let mut ev = self.basis.evaluator();
        let mut row = Vec::new();
        ev.eval_into(x, y, &mut row)?;
        Ok(self.combine(&row))
    }

    fn combine(&self, row: &[TensorValue]) -> Vec<f64> {
        self.coefficients
            .iter()
            .map(|z| row.iter().map(|v| z[v.index] * v.value).sum())
            .collect()
    }

    /// The reconstruction at many points (in parallel), one vector per channel.
    pub fn evaluate_many(&self, xs: &[f64], ys: &[f64]) -> Result<Vec<Vec<f64>>, ImageFitError> {
        use rayon::prelude::*;
        if xs.len() != ys.len() {
            return Err(ImageFitError::LengthMismatch {
                what: "ys".into(),
                expected: xs.len(),
                found: ys.len(),
            });
        }
        let blocks: Vec<Vec<Vec<f64>>> = xs
            .par_chunks(CHUNK)
            .zip(ys.par_chunks(CHUNK))
            .map(|(cx, cy)| {
                let mut ev = self.basis.evaluator();
                let mut row = Vec::new();
                cx.iter()
                    .zip(cy)
                    .map(|(&x, &y)| {
                        ev.eval_into(x, y, &mut row)?;
                        Ok(self.combine(&row))
                    })
                    .collect::<Result<Vec<_>, ImageFitError>>()
            })
            .collect::<Result<_, _>>()?;
        let mut out = vec![Vec::with_capacity(xs.len()); self.channels()];
        for point in blocks.into_iter().flatten() {
            for (c, v) in point.into_iter().enumerate() {
                out[c].push(v);
            }
        }
        Ok(out)
    }

    /// The sample row `K_i`: every nonzero single-scale function at `(x, y)` (index
    /// `ky * nx + kx`) and its value.
    pub fn sample_row(&self, x: f64, y: f64) -> Result<Vec<TensorValue>, ImageFitError> {
        let mut row = Vec::new();
        self.basis.evaluator().eval_into(x, y, &mut row)?;
        Ok(row)
    }

    /// Solves `(G + lambda D^{-2}) z = b` with the fit's factor (Cholesky solver), or by
    /// Jacobi PCG to a relative residual of `1e-12` (CG solver): `z` such that
    /// `K_i . z` is the weight of sample `i` in the functional `b . coefficients`.
    pub fn solve_normal(&self, b: &[f64]) -> Result<Vec<f64>, ImageFitError> {
        let n = self.basis.len();
        if b.len() != n {
            return Err(ImageFitError::LengthMismatch {
                what: "b".into(),
                expected: n,
                found: b.len(),
            });
        }
        if self.system.is_factored() {
            Ok(self.system.solve_factored(&[b]).remove(0))
        } else {
            Ok(self
                .system
                .solve_cg(
                    &[b],
                    StencilPreconditioner::Jacobi,
                    None,
                    1e-12,
                    None,
                    100 * n.max(10),
                )
                .remove(0)
                .0)
        }
    }

    /// The multilevel (non-standard) coefficients of channel `c` (2D FWT analysis).
    pub fn multilevel_coefficients(&self, c: usize) -> Vec<f64> {
        self.basis.analysis(&self.coefficients[c])
    }
}
