//! The refinement loop: fit, indicate, mark, deepen, sample, repeat (module docs of
//! [`crate::refine`]); each round's decision (stop, mark within the budget, deepen) is the
//! rounds driver's ([`crate::adaptive::rounds`]) over the interval tree's adapter
//! (`IntervalRound`).

use std::time::Instant;

use rand::SeedableRng;
use rand_pcg::Pcg64;
use sprs::CsMat;

use super::indicator::{coefficient_indication, residual_indication, Indication};
use super::measure::ErrorFigures;
use super::normal::{NormalEquations, TrackedPoints};
use super::refinement::{tree_fit, Refinement, RoundLog, RoundTimes};
use super::samples::{fill_leaves, probe_points, shortfall, SampleStore};
use super::{Indicator, RefineError, RefineParams, Sample, SampleOracle};
use crate::adaptive::rounds::{self, RoundFacts};
use crate::adaptive::tree::interval::{Leaf, WaveletTree};
use crate::adaptive::StopReason;

use crate::basis::{CdvBasis, FilterBank};
use crate::kernel::ActiveSet;
use crate::reconstruct::Fit;
use crate::solve::{global_ls, GlobalMethod, SolveError};

/// Ulps a sampling stratum of a new leaf must span (jittered points in the middle 80 % of
/// the stratum stay distinct and inside their leaf after the domain map).
const RESOLUTION_ULPS: f64 = 16.0;

/// The fit of the current round and how it was made.
#[derive(Clone, Debug)]
struct Current {
    /// The fit on the tree (one channel).
    fit: Fit,
    /// Rows of `K` in this fit.
    samples: usize,
    error: Option<ErrorFigures>,
    new_samples: usize,
    times: RoundTimes,
}

/// The indicator of one fit and the probe samples it took.
struct Probed {
    /// `None` when no indicator could be computed (residual probes over budget).
    indication: Option<Indication>,
    probes: usize,
}

/// An accepted marking: the deepened tree, its leaves and the samples they still need.
struct Marks {
    marked: usize,
    tree: WaveletTree,
    leaves: Vec<Leaf>,
    shortfall: usize,
}

/// What [`Refiner::refine_once`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// The tree was deepened, sampled and refitted.
    Refined,
    /// Nothing more to do.
    Stopped(StopReason),
}

/// The refiner, one round at a time: [`Refiner::new`] samples the base and fits it,
/// [`Refiner::refine_once`] runs one round; every intermediate state is inspectable.
pub struct Refiner<'o, O: SampleOracle + ?Sized> {
    oracle: &'o O,
    params: RefineParams,
    full: CdvBasis,
    tree: WaveletTree,
    store: SampleStore,
    rng: Pcg64,
    round: usize,
    current: Current,
    rounds: Vec<RoundLog>,
    stop: Option<StopReason>,
    /// The normal equations, updated round by round.
    normal: NormalEquations,
    /// The diagnostic reference grid (its kernel, kept up to date) and the truth there.
    reference: Option<(TrackedPoints, Vec<f64>)>,
    base_depth: u32,
}

/// Refines until a stop: [`Refiner::new`], [`Refiner::refine_once`] until it stops.
///
/// ```
/// use rkwave::refine::{refine, RefineParams};
///
/// // A kink at x = 1/3: the tree deepens there and stays coarse elsewhere.
/// let kink = |x: f64| (x - 1.0 / 3.0).abs();
/// let mut params = RefineParams::default();
/// params.stop.tolerance = 1e-3;
/// params.stop.budget = 4000;
/// let r = refine(&kink, &params)?;
/// assert!(r.samples.len() <= 4000);
/// let v = r.evaluate(&[0.8])?;
/// assert!((v[0] - (0.8 - 1.0 / 3.0)).abs() < 1e-2); // the smooth side, well within
/// # Ok::<(), rkwave::refine::RefineError>(())
/// ```
pub fn refine<O: SampleOracle + ?Sized>(
    oracle: &O,
    params: &RefineParams,
) -> Result<Refinement, RefineError> {
    let mut refiner = Refiner::new(oracle, params)?;
    while refiner.refine_once()? == Step::Refined {}
    Ok(refiner.into_result())
}

impl<'o, O: SampleOracle + ?Sized> Refiner<'o, O> {
    /// Validates `params`, samples the base layout, tops up the leaves of the base tree that
    /// hold fewer than `ceil(rho)` samples, and fits (round 0).
    pub fn new(oracle: &'o O, params: &RefineParams) -> Result<Self, RefineError> {
        params.validate()?;
        let domain = params.domain;
        let bank = FilterBank::shared(params.tree.p, params.family())?;
        let coarse = params.coarse();
        let base_depth = params.base_depth();
        let full = CdvBasis::with_bank(bank.clone(), coarse, params.interval.max_depth, domain)?;
        let tree = WaveletTree::uniform(
            bank,
            coarse,
            base_depth as i32,
            params.interval.max_depth,
            domain,
        )?;
        let mut rng = Pcg64::seed_from_u64(params.sampling.seed ^ 0x5EED_0FAD_A971);
        let t0 = Instant::now();
        let mut xs = params.sampling.base_layout.generate(
            params.sampling.base_samples,
            domain,
            params.sampling.seed,
        );
        // Top-ups for the base leaves the layout left short.
        let mut sorted: Vec<f64> = xs.iter().map(|&x| domain.to_unit(x)).collect();
        sorted.sort_by(f64::total_cmp);
        let top_up = fill_leaves(&sorted, &tree.leaves(), params.per_leaf(), domain, &mut rng)?;
        xs.extend(top_up);
        let mut store = SampleStore::new();
        if xs.len() > params.stop.budget {
            return Err(RefineError::BudgetBelowBase {
                budget: params.stop.budget,
                required: xs.len() as u64,
                fix: format!("raise the budget to at least {}", xs.len()),
            });
        }
        store.add(&xs, oracle, &full, 0)?;
        let sample_s = t0.elapsed().as_secs_f64();
        let mut reference = (params.reference_grid > 0).then(|| {
            let g = domain.uniform_grid(params.reference_grid);
            let truth = g.iter().map(|&x| oracle.sample(x)).collect();
            let ts = g.iter().map(|&x| domain.to_unit(x)).collect();
            (TrackedPoints::new(&full, ts), truth)
        });
        let mut normal = NormalEquations::default();
        let current = fit_round(
            &tree,
            &store,
            &mut normal,
            &mut reference,
            params,
            xs.len(),
            sample_s,
        )?;
        Ok(Self {
            oracle,
            params: *params,
            full,
            tree,
            store,
            rng,
            round: 0,
            current,
            rounds: Vec::new(),
            stop: None,
            normal,
            reference,
            base_depth,
        })
    }

    /// The current tree.
    pub fn tree(&self) -> &WaveletTree {
        &self.tree
    }
    /// Every sample so far (rows of [`Refiner::kernel`] once refitted).
    pub fn samples(&self) -> &[Sample] {
        &self.store.samples
    }
    /// The current columns (active global indices, ascending).
    pub fn columns(&self) -> &[usize] {
        self.current.fit.active.indices()
    }
    /// The current coefficients, one per column.
    pub fn coefficients(&self) -> &[f64] {
        &self.current.fit.coefficients[0]
    }
    /// The current fit (the library's [`Fit`] on the tree's active set).
    pub fn fit(&self) -> &Fit {
        &self.current.fit
    }
    /// The current reconstruction at domain positions `xs` ([`Fit::evaluate`]).
    pub fn evaluate(&self, xs: &[f64]) -> Result<Vec<f64>, RefineError> {
        Ok(self.current.fit.evaluate(xs)?.swap_remove(0))
    }
    /// The current kernel matrix (filtered from the cached evaluation rows on each call,
    /// [`crate::kernel::EvaluationRows::kernel`]).
    pub fn kernel(&self) -> CsMat<f64> {
        self.store.rows.kernel(&self.current.fit.active)
    }
    /// The normal equations as kept between rounds (tests).
    #[cfg(test)]
    pub(crate) fn normal(&self) -> &NormalEquations {
        &self.normal
    }
    /// The rounds logged so far.
    pub fn rounds(&self) -> &[RoundLog] {
        &self.rounds
    }
    /// Why the refiner stopped, once it has.
    pub fn stop(&self) -> Option<StopReason> {
        self.stop
    }
    /// The parameters.
    pub fn params(&self) -> &RefineParams {
        &self.params
    }
    /// Current round number (0 = base fit).
    pub fn round(&self) -> usize {
        self.round
    }

    /// One round: indicate on the current fit, stop or mark, deepen, sample the new leaves,
    /// refit. Logs the current round either way.
    ///
    /// Cost, for `P` active functions, `dP` new ones, `ds` new samples (`ds <= ceil(rho)` per
    /// new leaf, about `2 ceil(rho) dP`), `r` active functions per sample (about `(2p - 1)`
    /// per level of the local depth) and `D - n` levels in the cached rows:
    ///
    /// ```text
    /// indicate, leaves, mark, Fit:  O(P log P)               (tree walks, column lookups)
    /// sample:                       O(ds (D - n) p^2)         (oracle + cached rows, once)
    /// normal equations update:      O(sum_{new a} s_a r + ds r^2)   (module `normal`)
    /// solve:                        O(nnz G) hand-over + symbolic + numeric Cholesky of G
    /// ```
    ///
    /// All but the solve are linear in what changed (`dP`, `ds`) up to the `O(P log P)` tree
    /// walks; the sparse Cholesky is still redone on the whole `G` each round (finest level
    /// first: `nnz(L)` about `0.6 nnz(G)` on `jumps`), so a round costs
    /// `O(dP rho r^2 + P log P) + C_chol(P)` and the factorization dominates.
    pub fn refine_once(&mut self) -> Result<Step, RefineError> {
        if let Some(reason) = self.stop {
            return Ok(Step::Stopped(reason));
        }
        let t_ind = Instant::now();
        let leaves = self.tree.leaves();
        let min_leaf = self.min_leaf_samples(&leaves);
        let probed = self.indicate(&leaves)?;
        let indicate_s = t_ind.elapsed().as_secs_f64();
        let stop = self.params.stop;
        let mut round = IntervalRound {
            refiner: self,
            probed,
            leaves: leaves.len(),
            min_leaf,
            indicate_s,
            t_mark: Instant::now(),
            resolvable: Vec::new(),
            wanted: 0,
        };
        rounds::round(&mut round, &stop)
    }

    /// The indicator of the current fit; residual probes are sampled (and kept) here.
    fn indicate(&mut self, leaves: &[Leaf]) -> Result<Probed, RefineError> {
        let params = self.params;
        let mut out = Probed {
            indication: None,
            probes: 0,
        };
        if matches!(
            params.indicator,
            Indicator::Coefficients | Indicator::Both { .. }
        ) {
            out.indication = Some(coefficient_indication(&self.tree, &self.current.fit));
        }
        if let Indicator::Residual { probes } | Indicator::Both { probes } = params.indicator {
            let markable: Vec<Leaf> = leaves
                .iter()
                .copied()
                .filter(|l| l.level <= self.tree.max_level())
                .collect();
            let points = probe_points(&markable, probes, params.domain, &mut self.rng);
            // Without budget for the probes, Both goes on with the coefficients alone.
            if self.store.len() + points.len() <= params.stop.budget {
                let xs: Vec<f64> = points.iter().map(|p| p.1).collect();
                let fitted = self.evaluate(&xs)?;
                let before = self.store.len();
                self.store
                    .add(&xs, self.oracle, &self.full, self.round + 1)?;
                out.probes = xs.len();
                let residuals: Vec<(usize, f64)> = points
                    .iter()
                    .zip(&self.store.samples[before..])
                    .zip(&fitted)
                    .map(|((&(i, _), s), f)| (i, s.value - f))
                    .collect();
                let r =
                    residual_indication(&self.tree, &markable, &residuals, params.domain.length());
                out.indication = Some(match out.indication.take() {
                    Some(c) => c.merge(r),
                    None => r,
                });
            }
        }
        Ok(out)
    }

    /// Whether the leaves that wavelet `a` (level `j`) creates, cells of level `j + 1`, can
    /// hold `ceil(rho)` samples in distinct strata: a stratum `2^-(j+1) / ceil(rho)` wide must
    /// span at least [`RESOLUTION_ULPS`] ulps of the positions there, in unit coordinates and
    /// in the domain.
    fn resolvable(&self, a: usize) -> bool {
        let (level, _, _) = self.tree.support(a);
        let (lo, hi) = self.tree.support_unit(a);
        let domain = self.params.domain;
        let stratum = (-(level as f64 + 1.0)).exp2() / self.params.per_leaf() as f64;
        let ulp = |v: f64| v.abs().max(f64::MIN_POSITIVE) * f64::EPSILON;
        let unit_ulp = ulp(lo).max(ulp(hi.min(1.0)));
        let domain_ulp = ulp(domain.from_unit(lo)).max(ulp(domain.from_unit(hi.min(1.0))));
        stratum >= RESOLUTION_ULPS * unit_ulp
            && stratum * domain.length() >= RESOLUTION_ULPS * domain_ulp
    }

    /// Brings every leaf to `ceil(rho)` samples and refits (the next round).
    fn sample_and_refit(&mut self, leaves: &[Leaf], probes: usize) -> Result<(), RefineError> {
        let t0 = Instant::now();
        let xs = fill_leaves(
            self.store.sorted(),
            leaves,
            self.params.per_leaf(),
            self.params.domain,
            &mut self.rng,
        )?;
        self.round += 1;
        self.store.add(&xs, self.oracle, &self.full, self.round)?;
        let sample_s = t0.elapsed().as_secs_f64();
        self.current = fit_round(
            &self.tree,
            &self.store,
            &mut self.normal,
            &mut self.reference,
            &self.params,
            xs.len() + probes,
            sample_s,
        )?;
        Ok(())
    }

    fn min_leaf_samples(&self, leaves: &[Leaf]) -> usize {
        leaves
            .iter()
            .map(|l| self.store.count_in(l))
            .min()
            .unwrap_or(0)
    }

    #[allow(clippy::too_many_arguments)]
    fn log(
        &self,
        leaves: usize,
        min_leaf_samples: usize,
        indicator_max: Option<f64>,
        estimated_error: Option<f64>,
        marked: usize,
        added_functions: usize,
        indicate_s: f64,
        mark_s: f64,
    ) -> RoundLog {
        let c = &self.current;
        let mut times = c.times;
        times.indicate_s = indicate_s;
        times.mark_s = mark_s;
        times.total_s = times.sample_s + times.kernel_s + times.solve_s + indicate_s + mark_s;
        RoundLog {
            round: self.round,
            samples: c.samples,
            new_samples: c.new_samples,
            basis_size: c.fit.active.len(),
            depth: self.tree.depth(),
            leaves,
            min_leaf_samples,
            indicator_max,
            estimated_error,
            error: c.error,
            marked,
            added_functions,
            times,
        }
    }

    /// The result (runs no further round).
    pub fn into_result(self) -> Refinement {
        let kernel = self.kernel();
        Refinement {
            tree: self.tree,
            samples: self.store.samples,
            fit: self.current.fit,
            kernel,
            rounds: self.rounds,
            stop: self.stop.unwrap_or(StopReason::MaxRounds),
            base_depth: self.base_depth,
            params: self.params,
        }
    }
}

/// One round of the 1D refiner after its indicator, the interval tree's side of the rounds
/// driver ([`rounds::round`]): the stop test's facts, Dörfler's set of the resolvable units
/// cut to the budget by the leaves of trial trees, deepening, sampling and the refit.
struct IntervalRound<'r, 'o, O: SampleOracle + ?Sized> {
    refiner: &'r mut Refiner<'o, O>,
    probed: Probed,
    /// Leaves of the tree the round indicated on, and the fewest samples one of them holds.
    leaves: usize,
    min_leaf: usize,
    indicate_s: f64,
    t_mark: Instant,
    /// Whether each unit's new leaves can be sampled in `f64` ([`Refiner::resolvable`]).
    resolvable: Vec<bool>,
    /// The resolvable units of Dörfler's set.
    wanted: usize,
}

impl<O: SampleOracle + ?Sized> IntervalRound<'_, '_, O> {
    /// Logs the round as it was decided: `marked` units, `added` functions.
    fn log(&mut self, marked: usize, added: usize) {
        let mark_s = self.t_mark.elapsed().as_secs_f64();
        let r = &*self.refiner;
        let estimate = self
            .probed
            .indication
            .as_ref()
            .map(|i| (i.total_sq / r.params.domain.length()).sqrt());
        let log = r.log(
            self.leaves,
            self.min_leaf,
            self.probed.indication.as_ref().map(|i| i.max),
            estimate,
            marked,
            added,
            self.indicate_s,
            mark_s,
        );
        self.refiner.rounds.push(log);
    }
}

impl<O: SampleOracle + ?Sized> rounds::RoundAdapter for IntervalRound<'_, '_, O> {
    type Marks = Marks;
    type Outcome = Step;
    type Error = RefineError;

    /// The estimate `sqrt(sum eta^2 / |Omega|)`; markable: a unit left whose part of the
    /// estimate is above the tolerance; resolvable: a unit of Dörfler's set whose new leaves
    /// `f64` can sample; the round counted with the base fit (`round + 1`).
    fn facts(&mut self) -> RoundFacts {
        let r = &*self.refiner;
        let params = &r.params;
        let length = params.domain.length();
        let Some(indication) = &self.probed.indication else {
            return RoundFacts {
                estimate: None,
                markable: false,
                deepenable: false,
                resolvable: false,
                spent: false,
                rounds: r.round + 1,
            };
        };
        // A NaN estimate never satisfies a stop test (`NaN <= t` is false; kept explicit).
        let below = |sq: f64| {
            let e = (sq / length).sqrt();
            e.is_finite() && e <= params.stop.tolerance
        };
        let markable = !(indication.units.is_empty() || below(indication.markable_sq));
        // Dörfler's set on every markable unit; of it, the marks whose new leaves f64 cannot
        // sample are dropped. If none is left, what is left of the error (a fraction `theta`
        // of it at least) sits below the resolution of f64: refinement stops there.
        let dorfler = indication.dorfler(params.marking.theta);
        self.resolvable = indication
            .units
            .iter()
            .map(|u| u.wavelets.iter().all(|&a| r.resolvable(a)))
            .collect();
        self.wanted = self.resolvable[..dorfler].iter().filter(|&&r| r).count();
        RoundFacts {
            estimate: Some((indication.total_sq / length).sqrt()),
            markable,
            deepenable: markable,
            resolvable: self.wanted > 0,
            spent: false,
            rounds: r.round + 1,
        }
    }

    /// Logs the round; the residual probes, samples, go into a last fit.
    fn stop(&mut self, reason: StopReason) -> Result<Step, RefineError> {
        self.log(0, 0);
        let r = &mut *self.refiner;
        r.stop = Some(reason);
        if self.probed.probes > 0 {
            // The probes are samples: the final fit uses them.
            r.round += 1;
            r.current = fit_round(
                &r.tree,
                &r.store,
                &mut r.normal,
                &mut r.reference,
                &r.params,
                self.probed.probes,
                0.0,
            )?;
            let leaves = r.tree.leaves();
            let min_leaf = r.min_leaf_samples(&leaves);
            let log = r.log(leaves.len(), min_leaf, None, None, 0, 0, 0.0, 0.0);
            r.rounds.push(log);
        }
        Ok(Step::Stopped(reason))
    }

    /// The resolvable units of Dörfler's set, cut ([`rounds::cut`]) to the largest prefix
    /// whose deepened tree's leaves the rest of the budget can top up to `ceil(rho)` (the
    /// shortfall grows with the prefix); `None` when not even one unit fits.
    fn mark(&mut self) -> Result<Option<Marks>, RefineError> {
        let r = &*self.refiner;
        let params = &r.params;
        let indication = self
            .probed
            .indication
            .as_ref()
            .expect("the stop test stops a round without an indicator");
        let units: Vec<&super::indicator::Unit> = indication
            .units
            .iter()
            .zip(&self.resolvable)
            .filter(|(_, &ok)| ok)
            .map(|(u, _)| u)
            .collect();
        let need = params.per_leaf();
        let remaining = params.stop.budget.saturating_sub(r.store.len());
        let trial = |k: usize| -> Marks {
            let mut tree = r.tree.clone();
            tree.extend(units[..k].iter().flat_map(|u| u.wavelets.iter().copied()));
            let leaves = tree.leaves();
            let shortfall = shortfall(&r.store, &leaves, need);
            Marks {
                marked: k,
                tree,
                leaves,
                shortfall,
            }
        };
        // the fitting trial of the largest prefix so far is the cut's answer
        let mut best: Option<Marks> = None;
        let k = rounds::cut(self.wanted, remaining, |k| {
            let t = trial(k);
            let cost = t.shortfall;
            if cost <= remaining && best.as_ref().is_none_or(|b| b.marked < k) {
                best = Some(t);
            }
            cost
        });
        if k == 0 {
            return Ok(None);
        }
        Ok(Some(match best {
            Some(b) if b.marked == k => b,
            _ => trial(k),
        }))
    }

    /// Logs the round, deepens the tree, tops every leaf up to `ceil(rho)` and refits.
    fn deepen(&mut self, marks: Marks) -> Result<Step, RefineError> {
        let added = marks.tree.len() - self.refiner.tree.len();
        self.log(marks.marked, added);
        let r = &mut *self.refiner;
        r.tree = marks.tree;
        r.sample_and_refit(&marks.leaves, self.probed.probes)?;
        Ok(Step::Refined)
    }

    /// Never called: the 1D refiner's units are all deepenable (a round that cannot mark
    /// stops at the budget).
    fn densify(&mut self) -> Result<Option<Step>, RefineError> {
        Ok(None)
    }
}

/// Brings the normal equations to the current tree and samples and solves them (or, for
/// CGLS, solves from `K` filtered from the cached rows); the reference error if asked.
fn fit_round(
    tree: &WaveletTree,
    store: &SampleStore,
    normal: &mut NormalEquations,
    reference: &mut Option<(TrackedPoints, Vec<f64>)>,
    params: &RefineParams,
    new_samples: usize,
    sample_s: f64,
) -> Result<Current, RefineError> {
    let t0 = Instant::now();
    let active = ActiveSet::from_sorted(tree.basis()?, tree.columns());
    let columns = active.indices();
    normal.update(&store.rows, &store.samples, columns, |a| {
        tree.support_unit(a)
    });
    let kernel_s = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let (coefficients, solve) = if params.solve.method == GlobalMethod::Cholesky {
        let mut solved = normal
            .solve(&store.samples, &params.solve)
            .map_err(|e| match e {
                RefineError::Solve(SolveError::RankDeficient {
                    column,
                    pivot,
                    column_samples,
                    ..
                }) => RefineError::RankDeficient {
                    column,
                    pivot,
                    column_samples,
                    per_leaf: params.per_leaf(),
                    p: params.tree.p,
                },
                e => e,
            })?;
        let by_slot = solved.coefficients.swap_remove(0);
        let coefficients = columns
            .iter()
            .map(|&a| by_slot[normal.slot(a).expect("every column is active")])
            .collect();
        (coefficients, solved.report)
    } else {
        let kernel = store.rows.kernel(&active);
        let values = store.values();
        let mut solved = global_ls(&kernel, &[&values], &params.solve)?;
        (solved.coefficients.swap_remove(0), solved.report)
    };
    let solve_s = t1.elapsed().as_secs_f64();
    let error = reference.as_mut().map(|(points, truth)| {
        let by_slot = normal.by_slot(columns, &coefficients);
        ErrorFigures::between(&points.values(normal, &by_slot), truth)
    });
    let fit = tree_fit(active, coefficients, solve, store.len());
    Ok(Current {
        fit,
        samples: store.len(),
        error,
        new_samples,
        times: RoundTimes {
            sample_s,
            kernel_s,
            solve_s,
            ..RoundTimes::default()
        },
    })
}
