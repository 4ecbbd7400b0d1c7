//! Matrix-free preconditioned conjugate gradients for the tree fit.
//!
//! The tree's functions are a subset `T` of the orthonormal non-standard basis, and every one
//! of them is a combination of the single-scale functions of `V_Jx (x) V_Jy` through the 2D
//! synthesis `S` (`TensorBasis::synthesis`, orthogonal: `S^T` is the analysis). So the tree
//! kernel factors as
//!
//! ```text
//! K_T = E S P_T,        E[i, k] = Phi_k(x_i, y_i)   (single-scale rows, (2p - 1)^2 entries),
//! ```
//!
//! with `P_T` the injection of the tree's coefficients into the Mallat layout. One product
//! `G v = K_T^T K_T v = P_T^T S^T E^T E S P_T v` costs two 2D FWTs and two passes over `E`:
//! `O(nx ny + m (2p - 1)^2)`, against the `~300 P` entries of an assembled `G` whose rows mix
//! every level. `E` does not depend on the tree (a round's fit builds it afresh for all
//! samples; [`SingleScaleRows::append`] could continue it).
//!
//! The normal equations `G c = K_T^T f` are solved by conjugate gradients preconditioned by
//! `diag G`, `G_aa = sum_i Psi_a(x_i, y_i)^2`, from one pass of the multilevel evaluator over
//! the samples (it removes the `4^depth` spread of the sample density between deep and
//! shallow regions, and conditions better than the count estimate `G_aa ~ n_a / |supp_a|`,
//! `n_a` the samples in the `(2p - 1)^2` cells around the function's own, which is kept for
//! reporting unsampled functions). A function with no sample in its support has a zero column in `K_T`: its
//! residual is always 0, so it keeps its start value (0 for a new function), as the direct
//! solve's ridge pins it near 0.
//!
//! *Limit.* At `rho = 2` samples per slot the least-squares problem itself is not well
//! conditioned (jittered pairs of samples leave local near-null directions), so Jacobi-PCG
//! takes hundreds of iterations to a tight residual, more work than the direct solve at small
//! sizes (docs/measurements/plan-speed.md, "The iterative solvers"). So PCG is opt-in for the
//! in-process engine; a stronger (local / Schwarz, or previous-factor) preconditioner is what it
//! lacks. With the rounds' fits loose and warm-started it is the renderer plan's solver
//! ([`TreeSolver::plan_pcg`], [`CarriedPcg`]: docs/measurements/plan-speed.md, "The renderer loop
//! on PCG").
//!
//! Stopping: the relative residual of the normal equations `||K_T^T (f - K_T c)|| / ||K_T^T
//! f|| <= tol`. Then the coefficient error is at most `kappa(G) tol` relative, `kappa`
//! estimated from the Lanczos tridiagonal of the iteration (its extreme eigenvalues are
//! those of the preconditioned `G` from inside).
//!
//! The conjugate gradient itself is the crate's one ([`crate::solve::cg::pcg`], with
//! [`Jacobi`] on the exact diagonal and the Lanczos estimate); the pieces it runs on live
//! beside this file: the solver choice ([`TreeSolver`]), the single-scale rows
//! ([`SingleScaleRows`], [`SingleScaleColumns`]), the operator ([`TreeNormalOperator`]) and
//! the diagonal ([`DiagonalSums`]).

pub(crate) use super::diagonal::positions_hash;
pub use super::diagonal::DiagonalSums;
pub use super::operator::TreeNormalOperator;
pub(crate) use super::single_scale::multilevel_values;
pub use super::single_scale::{SingleScaleColumns, SingleScaleRows};
pub use super::solver::{TreeSolver, DIRECT_FALLBACK_MAX};

use super::gram::{seal, unseal, GramBytesError};
use crate::solve::cg::{self, CgParams, CgReport, ConditionEstimate, Jacobi, ResidualReport};
use crate::solve::vectors::interleave;

/// Solves `G c = K_T^T f` by PCG from `start` (zero off the tree; `None`: zero).
pub fn pcg(
    op: &TreeNormalOperator<'_>,
    f: &[f64],
    start: Option<&[f64]>,
    tolerance: f64,
    max_iterations: usize,
) -> (Vec<f64>, CgReport) {
    let starts = start.map(|s| vec![s.to_vec()]);
    let (mut x, report) = pcg_many(op, &[f], starts.as_deref(), tolerance, max_iterations);
    (x.pop().expect("one channel"), report)
}

/// Solves `G c_c = K_T^T f_c` for every channel `c` by PCG from `starts` (per channel, zero
/// off the tree; `None`: zero): independent conjugate-gradient runs in lockstep, whose
/// products `G p_c` share one pass over the rows per iteration
/// ([`TreeNormalOperator::apply_many`]), preconditioned by the exact Jacobi diagonal. A
/// channel stops at its own tolerance; the others go on. The report's residuals are the
/// recurred `||K_T^T (f - K_T c)|| / ||K_T^T f||` (equal to the recomputed one up to
/// rounding), with the Lanczos condition estimate.
pub fn pcg_many(
    op: &TreeNormalOperator<'_>,
    fs: &[&[f64]],
    starts: Option<&[Vec<f64>]>,
    tolerance: f64,
    max_iterations: usize,
) -> (Vec<Vec<f64>>, CgReport) {
    pcg_many_to(op, fs, starts, &vec![tolerance; fs.len()], max_iterations)
}

/// [`pcg_many`] with channel `c` stopping at its own relative residual `tolerances[c]`
/// ([`cg::pcg_to`]).
pub fn pcg_many_to(
    op: &TreeNormalOperator<'_>,
    fs: &[&[f64]],
    starts: Option<&[Vec<f64>]>,
    tolerances: &[f64],
    max_iterations: usize,
) -> (Vec<Vec<f64>>, CgReport) {
    let k = fs.len();
    let tolerance = tolerances.iter().copied().fold(0.0, f64::max);
    let b = op.rhs_many(&interleave(fs), k);
    let n = op.basis().len();
    let xs: Vec<Vec<f64>> = (0..k)
        .map(|c| match starts.and_then(|s| s.get(c)) {
            Some(s) => {
                let mut x = s.clone();
                op.restrict(&mut x);
                x
            }
            None => vec![0.0; n],
        })
        .collect();
    let params = CgParams {
        tolerance,
        max_iterations,
        // the recurred residual: recomputing it cost one more product a fit (of the 5-10 a
        // round's fit takes) for a figure that only reports
        residual: ResidualReport::Recurred,
        condition: ConditionEstimate::Lanczos,
        forward_error: None,
    };
    let b: Vec<&[f64]> = b.iter().map(|b| b.as_slice()).collect();
    cg::pcg_to(
        op,
        &Jacobi::new(op.inverse_diagonal()),
        &b,
        Some(xs),
        &params,
        tolerances,
        true,
    )
}

/// The first bytes of [`CarriedPcg::to_bytes`]: the layout's name and version.
const PCG_MAGIC: &[u8; 8] = b"RKWPCG01";

/// PCG's state a plan carries from one call to the next (the file protocol's `pcg.bin`,
/// beside `gram.bin`): the last round's coefficients, per image channel then per probe
/// channel (the next round's start), and the exact diagonal `G_aa` with the samples it was
/// summed over ([`DiagonalSums`], continued by the next round). Solver state only: a round
/// without it starts from zero and sums the diagonal afresh, reaching the same tolerance.
#[derive(Clone, Debug, Default)]
pub struct CarriedPcg {
    /// The start of the next fit (full Mallat layout, zero off the last tree).
    pub start: Option<Vec<Vec<f64>>>,
    /// The last fit's exact diagonal.
    pub diagonal: Option<DiagonalSums>,
    /// Why the state read from the file was set aside, or its diagonal not continued
    /// (`None`: used, or there was none).
    pub note: Option<String>,
}

impl PartialEq for CarriedPcg {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl CarriedPcg {
    /// The state as bytes ([`super::gram`]'s sealed layout: `PCG_MAGIC`, the plan's `tag`,
    /// the basis size `n`, the vectors `k`, the samples and their positions' hash, the last
    /// tree as a bit mask, then on the tree's functions the diagonal and each start vector;
    /// a checksum); `None` unless both the start and the diagonal are there.
    pub fn to_bytes(&self, tag: u64) -> Option<Vec<u8>> {
        let (start, d) = (self.start.as_ref()?, self.diagonal.as_ref()?);
        let n = d.mask.len();
        if start.iter().any(|s| s.len() != n) {
            return None;
        }
        let on: Vec<usize> = (0..n).filter(|&f| d.mask[f]).collect();
        let words = 4 + n.div_ceil(64) + on.len() * (1 + start.len());
        Some(seal(PCG_MAGIC, tag, words, |word| {
            word(n as u64);
            word(start.len() as u64);
            word(d.samples as u64);
            word(d.positions);
            for block in d.mask.chunks(64) {
                word(
                    block
                        .iter()
                        .rev()
                        .fold(0u64, |w, &b| (w << 1) | u64::from(b)),
                );
            }
            on.iter().for_each(|&f| word(d.sums[f].to_bits()));
            for s in start {
                on.iter().for_each(|&f| word(s[f].to_bits()));
            }
        }))
    }

    /// The state of [`CarriedPcg::to_bytes`], if the bytes are whole, carry `tag` and hold
    /// vectors of `n` entries (the plan's basis).
    pub fn from_bytes(bytes: &[u8], tag: u64, n: usize) -> Result<Self, GramBytesError> {
        let mut words = unseal(bytes, PCG_MAGIC, "PCG start", tag)?;
        let (len, k, samples, positions) = (
            words.next()? as usize,
            words.next()? as usize,
            words.next()? as usize,
            words.next()?,
        );
        if len != n || words.left() < n.div_ceil(64) {
            return Err(GramBytesError::Damaged("the basis size does not match"));
        }
        let mut mask = Vec::with_capacity(n);
        for w in words.take(n.div_ceil(64))? {
            mask.extend((0..64).map(|b| (w >> b) & 1 == 1));
        }
        mask.truncate(n);
        let on: Vec<usize> = (0..n).filter(|&f| mask[f]).collect();
        if words.left() as u128 != on.len() as u128 * (1 + k as u128) {
            return Err(GramBytesError::Damaged("the sizes do not add up"));
        }
        let spread = |words: &mut super::gram::Words<'_>| -> Result<Vec<f64>, _> {
            let mut v = vec![0.0; n];
            for (&f, w) in on.iter().zip(words.take(on.len())?) {
                v[f] = f64::from_bits(w);
            }
            Ok(v)
        };
        let sums = spread(&mut words)?;
        let start = (0..k)
            .map(|_| spread(&mut words))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            start: Some(start),
            diagonal: Some(DiagonalSums {
                samples,
                positions,
                mask,
                sums,
            }),
            note: None,
        })
    }

    /// The start and the diagonal for a fit of the samples `(xs, ys)` (the diagonal only when
    /// its samples are their first, in order, [`DiagonalSums::continues`]), and the note of
    /// what was set aside.
    #[allow(clippy::type_complexity)]
    pub fn offer(
        &self,
        xs: &[f64],
        ys: &[f64],
    ) -> (Option<Vec<Vec<f64>>>, Option<DiagonalSums>, Option<String>) {
        let mut note = self.note.clone();
        let diagonal = self.diagonal.clone().filter(|d| {
            let continues = d.continues(xs, ys);
            if !continues {
                note.get_or_insert(format!(
                    "the carried PCG diagonal ({} samples) was not continued: the samples do \
                     not start with its samples in the same order; summed afresh",
                    d.samples()
                ));
            }
            continues
        });
        (self.start.clone(), diagonal, note)
    }
}
