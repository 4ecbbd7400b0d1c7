//! Least squares on the tree: `c = argmin ||K_T c - f_ch||` per channel, `K_T[i, a] =
//! Psi_a(x_i, y_i)` over the active functions `a` of a [`QuadTree`] (the non-standard
//! multilevel basis restricted to the tree).
//!
//! Two solvers ([`TreeSolver`]):
//!
//! - **PCG** (opt-in for `image --adaptive`, measured slower there; the default of a
//!   renderer's plan, see [`super::pcg`]): matrix-free preconditioned
//!   conjugate gradients on the normal equations ([`super::pcg`]), `K_T = E S P_T` applied
//!   through the single-scale rows and the 2D FWT, every channel's conjugate gradients in
//!   lockstep so that one pass over the rows serves all of them (the crate's one CG,
//!   [`crate::solve::cg::pcg`], through [`super::pcg::pcg_many`]), optionally warm-started;
//!   its iterations, relative residual and condition estimate are reported. If it does not reach its tolerance the direct solve
//!   takes over on trees of at most [`super::pcg::DIRECT_FALLBACK_MAX`] functions; either way
//!   the report says so.
//! - **Direct** (the reference and the default): `K_T` row by row from the multilevel evaluator (in parallel),
//!   `G = K_T^T K_T` by a parallel, deterministic assembly that a round continues from the
//!   previous round's matrix ([`super::gram`]: bit for bit the rebuilt one), and [`crate::solve::normal_ls`]: the equilibrated
//!   sparse Cholesky of the 1D refiner, one factorization for every channel, with
//!   [`RankPolicy::Regularize`](crate::solve::RankPolicy): a direction the samples do not
//!   determine (a function without samples, a rank-deficient patch) gets a relative ridge,
//!   reported, never NaN. Its cost grows with `G`'s ~300 entries per column (rows mix every
//!   level).
//!
//! Pixels are exact: the tree's coefficients, zero off the tree, are one 2D synthesis away from
//! the single-scale coefficients of `V_Jx (x) V_Jy` (`TensorBasis::synthesis`), whose box
//! pixel integrals are exact ([`crate::image::pixels`]).

use rayon::prelude::*;
use serde::Serialize;
use sprs::CsMat;

use super::gram::{assemble, TreeGram};
use super::pcg::{
    pcg_many_to, DiagonalSums, SingleScaleRows, TreeNormalOperator, TreeSolver, DIRECT_FALLBACK_MAX,
};
use super::schwarz::{schwarz_pcg, Schwarz, SchwarzReport};
use super::AdaptiveError;
use crate::adaptive::tree::quad::QuadTree;
use crate::basis::tensor::TensorValue;
use crate::image::fit::ImageFitError;
use crate::image::pixels::{filter_image, PixelIntegrals};
use crate::solve::cg::{CgReport, IterationLimit};
use crate::solve::transpose_with_positions;
use crate::solve::{normal_ls, GlobalLsParams, RankPolicy};

/// What the tree solve did.
#[derive(Clone, Debug, Default, Serialize)]
pub struct TreeFitReport {
    /// Active functions `P`.
    pub functions: usize,
    /// Samples `m`.
    pub samples: usize,
    /// Active functions without any sample in their support (pinned near 0 by the ridge).
    pub unsampled: usize,
    /// Ridge added to the equilibrated normal matrix (0: none was needed).
    pub ridge: f64,
    /// Smallest pivot of the equilibrated Cholesky factor.
    pub min_pivot: f64,
    /// Stored entries of `G`.
    pub normal_nnz: usize,
    /// Stored entries of the Cholesky factor.
    pub factor_nnz: usize,
    /// Seconds: kernel rows, `G`, factor and solve.
    pub kernel_s: f64,
    /// Seconds: the normal matrix (assembly or update) and the right-hand sides.
    pub normal_s: f64,
    /// Functions whose normal-matrix entries were carried over from the previous round's
    /// matrix (0: assembled from scratch; see [`super::gram`]).
    pub normal_kept_functions: usize,
    /// Samples whose contributions to the normal matrix were carried over.
    pub normal_kept_samples: usize,
    /// Seconds: factorization and solves.
    pub solve_s: f64,
    /// The solver that produced the coefficients: `"direct"`, `"pcg"`, or `"pcg->direct"`
    /// (PCG missed its tolerance and the direct solve took over).
    pub solver: String,
    /// PCG iterations (most over the channels; 0 for the direct solve).
    pub iterations: usize,
    /// PCG's final relative residual of the normal equations (largest over the channels).
    pub relative_residual: f64,
    /// PCG's condition estimate of the preconditioned `G` (largest over the channels).
    pub condition: f64,
    /// Whether PCG reached its tolerance on every channel (true for the direct solve).
    pub converged: bool,
    /// The Schwarz preconditioner's blocks ([`TreeSolver::Schwarz`] only).
    pub schwarz: Option<SchwarzReport>,
    /// Seconds of `solve_s` spent building and factoring the Schwarz blocks.
    pub schwarz_setup_s: f64,
    /// What the fit does at PCG's iteration limit, named at the call (`None`: the direct
    /// solve, which has none): [`IterationLimit::FallBack`] to the direct solve up to
    /// `DIRECT_FALLBACK_MAX` functions (taken: `solver` `"pcg->direct"`),
    /// [`IterationLimit::Accept`] above and for the Schwarz PCG (taken: `converged` false).
    pub on_limit: Option<IterationLimit>,
    /// PCG per channel (the image's, then the noise test's probes): what each asked and
    /// reached (empty for the direct and Schwarz solves).
    pub channels: Vec<ChannelSolve>,
}

/// One channel of a PCG fit.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ChannelSolve {
    /// The relative residual asked, `||K_T^T (f - K_T c)|| <= tolerance ||K_T^T f||`.
    pub tolerance: f64,
    /// The start's relative residual (1 from zero; the carried start's quality).
    pub start_residual: f64,
    /// The relative residual reached (the recurred `||r|| / ||b||`).
    pub residual: f64,
    /// Iterations taken.
    pub iterations: usize,
}

impl ChannelSolve {
    /// Per channel of a PCG `report` asked for `tolerances`.
    fn of(report: &CgReport, tolerances: &[f64]) -> Vec<Self> {
        (0..report.iterations.len())
            .map(|c| Self {
                tolerance: tolerances[c],
                start_residual: report.start_residual.get(c).copied().unwrap_or(1.0),
                residual: report.relative_residual[c],
                iterations: report.iterations[c],
            })
            .collect()
    }
}

/// What a fit leaves for the next round's fit (more samples after the same ones, a tree that
/// only grew): the direct solve's normal matrix ([`super::gram`]), PCG's exact diagonal
/// ([`DiagonalSums`]) and single-scale rows ([`SingleScaleRows::continued`]; the noise test's
/// residuals use them too). Solver state only: with a fresh state a fit computes the same
/// coefficients (the direct solve bit for bit; PCG up to the rounding of its preconditioner).
#[derive(Clone, Debug, Default)]
pub struct FitState {
    /// The direct solve's normal matrix.
    pub gram: Option<TreeGram>,
    /// PCG's diagonal of `G`.
    pub diagonal: Option<DiagonalSums>,
    /// The single-scale rows of the samples so far.
    pub rows: Option<SingleScaleRows>,
}

/// A fit on a tree: coefficients in the full Mallat layout (zero off the tree).
#[derive(Clone, Debug)]
pub struct TreeFit {
    /// Per channel, `nx ny` multilevel coefficients, Mallat layout of the tree's basis.
    pub coefficients: Vec<Vec<f64>>,
    /// What the solve did.
    pub report: TreeFitReport,
}

/// Positions evaluated per parallel work item.
const CHUNK: usize = 2048;

/// Checks the sample arrays: equal lengths, positions in the image, finite values (the
/// uniform engine's checks, on the tree's image).
pub(crate) fn check_samples(
    tree: &QuadTree,
    xs: &[f64],
    ys: &[f64],
    values: &[&[f64]],
) -> Result<(), ImageFitError> {
    let b = tree.basis();
    crate::image::fit::check_input(b.width(), b.height(), xs, ys, values)
}

/// The kernel matrix `K_T` (`m x P` CSR) over the tree's functions `functions` (ascending
/// Mallat indices): rows from the multilevel evaluator, restricted to the tree.
pub fn tree_kernel(tree: &QuadTree, functions: &[usize], xs: &[f64], ys: &[f64]) -> CsMat<f64> {
    let basis = tree.basis();
    let mut column = vec![u32::MAX; basis.len()];
    for (a, &f) in functions.iter().enumerate() {
        column[f] = a as u32;
    }
    let blocks: Vec<(Vec<usize>, Vec<usize>, Vec<f64>)> = xs
        .par_chunks(CHUNK)
        .zip(ys.par_chunks(CHUNK))
        .map(|(cx, cy)| {
            let mut ev = basis.multilevel_evaluator();
            let mut row: Vec<TensorValue> = Vec::new();
            let mut counts = Vec::with_capacity(cx.len());
            let mut idx = Vec::new();
            let mut val = Vec::new();
            for (&x, &y) in cx.iter().zip(cy) {
                ev.eval_into(x, y, &mut row)
                    .expect("positions are checked before the kernel is built");
                let before = idx.len();
                for v in &row {
                    let c = column[v.index];
                    if c != u32::MAX {
                        idx.push(c as usize);
                        val.push(v.value);
                    }
                }
                counts.push(idx.len() - before);
            }
            (counts, idx, val)
        })
        .collect();
    let mut indptr = Vec::with_capacity(xs.len() + 1);
    indptr.push(0usize);
    let (mut indices, mut data) = (Vec::new(), Vec::new());
    for (counts, idx, val) in blocks {
        for c in counts {
            indptr.push(indptr.last().unwrap() + c);
        }
        indices.extend(idx);
        data.extend(val);
    }
    CsMat::new((xs.len(), functions.len()), indptr, indices, data)
}

/// Samples whose kernel rows estimate the size of `K` before it is built.
const SIZE_PROBE: usize = 4096;

/// Refuses a direct fit whose kernel and normal matrix cannot fit in memory, before either is
/// allocated. `K` and `K^T` hold `32 nnz(K)` bytes (value and index, twice), `nnz(K)`
/// estimated as `m` times the mean row of every `ceil(m / 4096)`-th sample (exact up to
/// sampling; the rows of a tree vary by its local depth); `G` and its kept upper triangle
/// about `24 nnz(G)` bytes, `nnz(G)` scaled from the previous round's matrix by the growth of
/// the functions (0 on a first fit, whose size the factor's own check bounds).
fn check_direct_memory(
    tree: &QuadTree,
    functions: &[usize],
    xs: &[f64],
    ys: &[f64],
    gram: Option<&TreeGram>,
) -> Result<(), AdaptiveError> {
    let m = xs.len();
    if m == 0 {
        return Ok(());
    }
    let step = m.div_ceil(SIZE_PROBE);
    let px: Vec<f64> = xs.iter().step_by(step).copied().collect();
    let py: Vec<f64> = ys.iter().step_by(step).copied().collect();
    let per_row = tree_kernel(tree, functions, &px, &py).nnz() as f64 / px.len() as f64;
    let kernel = 32.0 * per_row * m as f64;
    let normal = gram.map_or(0.0, |g| {
        let (nnz, p) = g.size();
        24.0 * nnz as f64 * functions.len() as f64 / p.max(1) as f64
    });
    crate::resources::check(
        || {
            format!(
                "the tree fit of {m} samples on {} functions (kernel rows of about {per_row:.0} \
                 entries each, and the normal matrix)",
                functions.len()
            )
        },
        kernel + normal,
        || {
            format!(
                "a smaller budget or depth limit, or the matrix-free PCG solve (`{}`)",
                crate::error::Fix::SolverPcg
            )
        },
    )?;
    Ok(())
}

/// Fits every channel on the tree from samples `(xs[i], ys[i])` with values `values[c][i]`,
/// by the direct solve (the reference, [`TreeSolver::Direct`]).
pub fn fit_tree(
    tree: &QuadTree,
    xs: &[f64],
    ys: &[f64],
    values: &[&[f64]],
) -> Result<TreeFit, AdaptiveError> {
    fit_tree_with(tree, xs, ys, values, TreeSolver::Direct, None)
}

/// Fits every channel on the tree by `solver`; PCG starts from `start` (per channel, Mallat
/// layout, e.g. the previous round's coefficients: new functions start at 0) or from 0.
pub fn fit_tree_with(
    tree: &QuadTree,
    xs: &[f64],
    ys: &[f64],
    values: &[&[f64]],
    solver: TreeSolver,
    start: Option<&[Vec<f64>]>,
) -> Result<TreeFit, AdaptiveError> {
    fit_tree_updating(
        tree,
        xs,
        ys,
        values,
        solver,
        start,
        &mut FitState::default(),
    )
}

/// [`fit_tree_with`] continuing the state of an earlier fit (same first samples, a tree that
/// only grew; otherwise built afresh) and leaving this fit's there: the direct solve's normal
/// matrix (the coefficients are those of [`fit_tree_with`] bit for bit, [`super::gram`]),
/// PCG's exact diagonal of `G` (the same up to rounding).
pub fn fit_tree_updating(
    tree: &QuadTree,
    xs: &[f64],
    ys: &[f64],
    values: &[&[f64]],
    solver: TreeSolver,
    start: Option<&[Vec<f64>]>,
    state: &mut FitState,
) -> Result<TreeFit, AdaptiveError> {
    fit_tree_channels(tree, xs, ys, values, solver, None, start, state)
}

/// [`fit_tree_updating`] with, under PCG, channel `c` stopping at its own relative residual
/// `tolerances[c]` (`None`: the solver's tolerance for every channel; ignored by the direct
/// and Schwarz solves). The fallback to the direct solve is taken when a channel misses its
/// own tolerance at the iteration limit.
#[allow(clippy::too_many_arguments)]
pub fn fit_tree_channels(
    tree: &QuadTree,
    xs: &[f64],
    ys: &[f64],
    values: &[&[f64]],
    solver: TreeSolver,
    tolerances: Option<&[f64]>,
    start: Option<&[Vec<f64>]>,
    state: &mut FitState,
) -> Result<TreeFit, AdaptiveError> {
    check_samples(tree, xs, ys, values)?;
    match solver {
        TreeSolver::Direct | TreeSolver::Schwarz { .. } => {
            fit_direct(tree, xs, ys, values, &mut state.gram, solver)
        }
        TreeSolver::Pcg {
            tolerance,
            max_iterations,
        } => {
            let t = std::time::Instant::now();
            let rows = SingleScaleRows::continued(state.rows.take(), tree.basis(), xs, ys);
            let diagonal = DiagonalSums::new(tree, xs, ys, state.diagonal.as_ref());
            let op = TreeNormalOperator::with_diagonal(tree, &rows, xs, ys, &diagonal);
            state.diagonal = Some(diagonal);
            let kernel_s = t.elapsed().as_secs_f64();
            let t = std::time::Instant::now();
            let tolerances = match tolerances {
                Some(t) if t.len() == values.len() => t.to_vec(),
                _ => vec![tolerance; values.len()],
            };
            let solved = pcg_many_to(&op, values, start, &tolerances, max_iterations);
            let solve_s = t.elapsed().as_secs_f64();
            let unsampled = op.unsampled();
            drop(op);
            state.rows = Some(rows);
            let (coefficients, report) = solved;
            let converged = report.all_converged();
            // The tree system's policy at PCG's iteration limit: the direct solve while it is
            // small enough, the iterate (reported as not converged) above.
            let on_limit = if tree.len() <= DIRECT_FALLBACK_MAX {
                IterationLimit::FallBack
            } else {
                IterationLimit::Accept
            };
            if !converged && on_limit == IterationLimit::FallBack {
                let mut fit = fit_direct(tree, xs, ys, values, &mut None, TreeSolver::Direct)?;
                let worst = (0..report.iterations.len())
                    .max_by(|&a, &b| {
                        report.relative_residual[a].total_cmp(&report.relative_residual[b])
                    })
                    .expect("at least one channel");
                fit.report.solver = "pcg->direct".into();
                fit.report.iterations = report.iterations[worst];
                fit.report.relative_residual = report.relative_residual[worst];
                fit.report.condition = condition(&report)[worst];
                fit.report.converged = false;
                fit.report.on_limit = Some(on_limit);
                return Ok(fit);
            }
            Ok(TreeFit {
                report: TreeFitReport {
                    functions: tree.len(),
                    samples: xs.len(),
                    unsampled,
                    kernel_s,
                    solve_s,
                    solver: "pcg".into(),
                    iterations: report.iterations.iter().copied().max().unwrap_or(0),
                    relative_residual: largest(&report.relative_residual),
                    condition: largest(condition(&report)),
                    converged,
                    on_limit: Some(on_limit),
                    channels: ChannelSolve::of(&report, &tolerances),
                    ..TreeFitReport::default()
                },
                coefficients,
            })
        }
    }
}

/// The reference: assembled (or updated) `G`, equilibrated sparse Cholesky; or, for
/// [`TreeSolver::Schwarz`], conjugate gradients on the same `G` preconditioned by
/// [`Schwarz`] blocks.
fn fit_direct(
    tree: &QuadTree,
    xs: &[f64],
    ys: &[f64],
    values: &[&[f64]],
    gram: &mut Option<TreeGram>,
    solver: TreeSolver,
) -> Result<TreeFit, AdaptiveError> {
    let functions = tree.functions();
    let t = std::time::Instant::now();
    check_direct_memory(tree, &functions, xs, ys, gram.as_ref())?;
    let k = tree_kernel(tree, &functions, xs, ys);
    let kernel_s = t.elapsed().as_secs_f64();
    let t = std::time::Instant::now();
    let (kt, positions_in_rows) = transpose_with_positions(&k);
    let (g, kept, update) = assemble(
        &k,
        &kt,
        &positions_in_rows,
        &functions,
        xs,
        ys,
        gram.as_ref(),
    );
    drop(positions_in_rows);
    *gram = Some(kept);
    let rhs: Vec<Vec<f64>> = values
        .iter()
        .map(|f| {
            kt.outer_iterator()
                .map(|r| r.iter().map(|(i, v)| v * f[i]).sum())
                .collect()
        })
        .collect();
    let column_samples: Vec<usize> = kt.outer_iterator().map(|r| r.nnz()).collect();
    // `K` and `K^T` are not needed by the solve: freed before the factor is allocated.
    drop((k, kt));
    let normal_s = t.elapsed().as_secs_f64();
    let t = std::time::Instant::now();
    if let TreeSolver::Schwarz {
        tolerance,
        max_iterations,
        tile,
        halo,
    } = solver
    {
        let pre = Schwarz::new(tree, &functions, &g, tile, halo);
        let setup_s = t.elapsed().as_secs_f64();
        let (solved, cg) = schwarz_pcg(&g, &rhs, &pre, tolerance, max_iterations);
        let n = tree.basis().len();
        return Ok(TreeFit {
            report: TreeFitReport {
                functions: functions.len(),
                samples: xs.len(),
                unsampled: column_samples.iter().filter(|&&c| c == 0).count(),
                normal_nnz: g.nnz(),
                kernel_s,
                normal_s,
                normal_kept_functions: update.kept_functions,
                normal_kept_samples: update.kept_samples,
                solve_s: t.elapsed().as_secs_f64(),
                solver: "schwarz".into(),
                iterations: cg.iterations.iter().copied().max().unwrap_or(0),
                relative_residual: largest(&cg.relative_residual),
                // At the iteration limit: IterationLimit::Accept, reported here.
                converged: cg.all_converged(),
                schwarz: Some(pre.report()),
                schwarz_setup_s: setup_s,
                on_limit: Some(IterationLimit::Accept),
                ..TreeFitReport::default()
            },
            coefficients: solved
                .into_iter()
                .map(|c| {
                    let mut full = vec![0.0; n];
                    for (&f, &v) in functions.iter().zip(&c) {
                        full[f] = v;
                    }
                    full
                })
                .collect(),
        });
    }
    let params = GlobalLsParams {
        rank_policy: RankPolicy::Regularize,
        ..GlobalLsParams::default()
    };
    let rhs_ref: Vec<&[f64]> = rhs.iter().map(|r| r.as_slice()).collect();
    let solved = normal_ls(&g, &rhs_ref, xs.len(), &column_samples, None, &params)?;
    let solve_s = t.elapsed().as_secs_f64();
    let n = tree.basis().len();
    let coefficients = solved
        .coefficients
        .iter()
        .map(|c| {
            let mut full = vec![0.0; n];
            for (&f, &v) in functions.iter().zip(c) {
                full[f] = v;
            }
            full
        })
        .collect();
    Ok(TreeFit {
        coefficients,
        report: TreeFitReport {
            functions: functions.len(),
            samples: xs.len(),
            unsampled: column_samples.iter().filter(|&&c| c == 0).count(),
            ridge: solved.report.ridge,
            min_pivot: solved.report.min_pivot,
            normal_nnz: solved.report.normal_nnz,
            factor_nnz: solved.report.factor_nnz,
            kernel_s,
            normal_s,
            normal_kept_functions: update.kept_functions,
            normal_kept_samples: update.kept_samples,
            solve_s,
            solver: "direct".into(),
            converged: true,
            ..TreeFitReport::default()
        },
    })
}

/// The largest of `values`, 0 if none (the report's fold over channels).
fn largest(values: &[f64]) -> f64 {
    values.iter().copied().fold(0.0, f64::max)
}

/// The per-channel condition estimates of a report that asked for them.
fn condition(report: &CgReport) -> &[f64] {
    report.condition.as_deref().unwrap_or_default()
}

impl TreeFit {
    /// Single-scale coefficients of `V_Jx (x) V_Jy` per channel (2D synthesis).
    pub fn single_scale(&self, tree: &QuadTree) -> Vec<Vec<f64>> {
        self.coefficients
            .iter()
            .map(|c| tree.basis().synthesis(c))
            .collect()
    }

    /// The reconstruction at `(x, y)`, one value per channel.
    pub fn evaluate(&self, tree: &QuadTree, x: f64, y: f64) -> Result<Vec<f64>, AdaptiveError> {
        let mut ev = tree.basis().multilevel_evaluator();
        let mut row = Vec::new();
        ev.eval_into(x, y, &mut row)?;
        Ok(self
            .coefficients
            .iter()
            .map(|c| row.iter().map(|v| c[v.index] * v.value).sum())
            .collect())
    }

    /// Box pixel values, exact: `I = B_y C B_x^T` of the single-scale coefficients, one
    /// `H x W` row-major image per channel.
    pub fn box_pixels(&self, tree: &QuadTree) -> Result<Vec<Vec<f64>>, AdaptiveError> {
        let b = tree.basis();
        let bx = PixelIntegrals::new(b.scale_x(), b.width())?;
        let by = PixelIntegrals::new(b.scale_y(), b.height())?;
        self.single_scale(tree)
            .iter()
            .map(|c| Ok(filter_image(&by, &bx, c)?))
            .collect()
    }
}
