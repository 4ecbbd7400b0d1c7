//! One round of the plan ([`ImagePlan::step`]) as named steps: fit ([`ImagePlan::fit_round`]),
//! indicate, log, then the rounds driver ([`crate::adaptive::rounds::round`]) over the
//! quadtree's adapter (`PlaneRound`): the stop test (or the coverage rule's fill), tally the
//! slots, then densify when nothing significant is left, or mark, deepen and sample.

use std::time::Instant;

use super::super::fit::{fit_tree_updating, FitState, TreeFit};
use super::super::indicator::{indicate, Indication};
use super::super::pcg::TreeSolver;
use super::super::significance::Significance;
use super::super::AdaptiveError;
use super::deepen::{Marking, Tally};
use super::{Decision, ImagePlan, ImageRound, RebuildCost, Round};
use crate::adaptive::marking::SpreadRule;
use crate::adaptive::rounds::{self, RoundAdapter, RoundFacts};
use crate::adaptive::Cell;
use crate::adaptive::StopReason;

impl ImagePlan {
    /// One round on every sample so far (`values[c][i]` channel `c` at `(xs[i], ys[i])`):
    /// fit on the tree, indicate, then stop or mark, deepen and return the positions that
    /// top the marked slots' children up to `ceil(rho)` samples.
    ///
    /// With `AdaptiveParams::round_tolerance` and an iterative solver the round's fit stops
    /// at the round tolerance; when the round stops the refinement, its fit is continued from
    /// those coefficients to the solver's own tolerance (reported in
    /// [`ImageRound::final_fit`]), so the output is the accurate fit.
    pub fn step(
        &mut self,
        xs: &[f64],
        ys: &[f64],
        values: &[&[f64]],
    ) -> Result<Round, AdaptiveError> {
        let solver = self.params.fit.solver;
        let loose = self
            .params
            .fit
            .round_tolerance
            .and_then(|t| solver.with_tolerance(t))
            .filter(|&s| s != solver);
        let mut round = self.step_with(xs, ys, values, loose.unwrap_or(solver))?;
        round.log.times.fit_s = round.fit_s;
        round.log.times.refine_s = round.refine_s;
        round.log.times.position_s = round.position_s;
        if loose.is_some() && matches!(round.decision, Decision::Stop(_)) {
            // The tree is unchanged by a stopping round: continue the same system.
            let t = Instant::now();
            let last = fit_tree_updating(
                &self.tree,
                xs,
                ys,
                values,
                solver,
                Some(&round.fit.coefficients),
                &mut self.state,
            )?;
            round.log.times.final_fit_s = t.elapsed().as_secs_f64();
            round.fit_s += round.log.times.final_fit_s;
            round.log.final_fit = Some(last.report.clone());
            round.fit = last;
        }
        Ok(round)
    }

    /// [`ImagePlan::step`] with the round's fit by `solver`: the named steps below in order.
    fn step_with(
        &mut self,
        xs: &[f64],
        ys: &[f64],
        values: &[&[f64]],
        solver: TreeSolver,
    ) -> Result<Round, AdaptiveError> {
        let round = self.round();
        let RoundFit {
            fit,
            significance,
            fit_s,
            rebuild,
        } = self.fit_round(xs, ys, values, solver)?;
        let t = Instant::now();
        let ind = self.indicate(&fit, significance.as_ref());
        let indicator_s = t.elapsed().as_secs_f64();
        let mut log = self.round_log(round, xs.len(), &fit, &ind, significance, rebuild);
        log.times.indicator_s = indicator_s;
        // the coverage rule (module `coverage`): the samples every pixel lacks are held back
        let empty = self.shortfall(xs, ys);
        log.reserved = empty.iter().map(|s| s.1).sum();
        let stop = self.params.stop;
        let mut plane_round = PlaneRound {
            plan: self,
            xs,
            ys,
            values,
            round,
            ind,
            log: Some(log),
            fit: Some(fit),
            empty,
            fit_s,
            t,
            tally: None,
        };
        rounds::round(&mut plane_round, &stop)
    }

    /// The round would stop for `stop`: under the coverage rule with pixels short of their
    /// samples (`empty`: pixel, samples it lacks), it tops them up instead (module `coverage`),
    /// and the next round fits on them; otherwise it stops. The note (what was filled, or the pixels left empty) goes in
    /// the round's log.
    fn fill_or_stop(
        &mut self,
        mut log: ImageRound,
        fit: TreeFit,
        stop: StopReason,
        empty: &[(usize, usize)],
        fit_s: f64,
        t: Instant,
    ) -> Round {
        let (next, note) = self.fill(log.round, log.samples, empty);
        log.coverage = note;
        let refine_s = t.elapsed().as_secs_f64();
        match next {
            Some(next) => {
                log.filled = next.len();
                Round {
                    log,
                    fit,
                    decision: Decision::Sample(next),
                    fit_s,
                    refine_s,
                    position_s: 0.0,
                }
            }
            None => stopped(log, fit, stop, fit_s, refine_s),
        }
    }

    /// Fit: the round's fit by `solver`, continuing the plan's solver state (and, under PCG,
    /// starting from the last round's coefficients, then keeping this round's for the next),
    /// with the rebuild from scratch beside it when [`AdaptiveParams::measure_rebuild`] asks.
    fn fit_round(
        &mut self,
        xs: &[f64],
        ys: &[f64],
        values: &[&[f64]],
        solver: TreeSolver,
    ) -> Result<RoundFit, AdaptiveError> {
        let t = Instant::now();
        let mut state = std::mem::take(&mut self.state);
        let start = self.start.take();
        let fitted = self.fit_updating(xs, ys, values, solver, start.as_deref(), &mut state);
        self.state = state;
        let (fit, significance) = fitted?;
        let fit_s = t.elapsed().as_secs_f64();
        let rebuild = if self.params.fit.measure_rebuild {
            let t = Instant::now();
            let (again, _) =
                self.fit_updating(xs, ys, values, solver, None, &mut FitState::default())?;
            let rebuild_s = t.elapsed().as_secs_f64();
            Some(RebuildCost {
                round_s: fit_s,
                rebuild_s,
                ratio: fit_s / rebuild_s,
                fit: again.report,
            })
        } else {
            None
        };
        if matches!(self.params.fit.solver, TreeSolver::Pcg { .. }) {
            // the next round starts from this one's image and probe coefficients
            let mut start = fit.coefficients.clone();
            if let Some(s) = &significance {
                start.extend(s.probe_coefficients().iter().cloned());
            }
            self.start = Some(start);
        }
        Ok(RoundFit {
            fit,
            significance,
            fit_s,
            rebuild,
        })
    }

    /// Indicate: the predicted detail of every slot (`super::super::indicator`), with the
    /// noise test's thresholds when it is on.
    fn indicate(&self, fit: &TreeFit, significance: Option<&Significance>) -> Indication {
        let tree = &self.tree;
        let threshold = significance.map(|s| move |cell: Cell| s.threshold(tree, cell));
        indicate(
            tree,
            &fit.coefficients,
            self.params.indicator.max_ratio,
            threshold.as_ref().map(|f| f as &dyn Fn(Cell) -> f64),
        )
    }

    /// The round's log before its decision (nothing marked, spread or densified yet).
    fn round_log(
        &self,
        round: usize,
        samples: usize,
        fit: &TreeFit,
        ind: &Indication,
        significance: Option<Significance>,
        rebuild: Option<RebuildCost>,
    ) -> ImageRound {
        ImageRound {
            round,
            samples,
            new_samples: samples.saturating_sub(self.progress.samples_fitted),
            functions: fit.report.functions,
            max_depth: self.tree.leaves().iter().map(|c| c.step).max().unwrap_or(0),
            estimate_rms: (ind.total_sq / self.plane.pixels() as f64).sqrt(),
            marked: 0,
            noise: significance.as_ref().map(|s| s.level.clone()),
            insignificant: ind.insignificant.len(),
            densified_to: None,
            spread: 0,
            pixel_spread: 0,
            reserved: 0,
            filled: 0,
            coverage: None,
            fit: fit.report.clone(),
            final_fit: None,
            rebuild,
            times: Default::default(),
        }
    }
}

/// The round's fit and what it cost.
struct RoundFit {
    fit: TreeFit,
    /// The noise test (`None`: off).
    significance: Option<Significance>,
    /// Seconds of the fit.
    fit_s: f64,
    /// The fit against a rebuild from scratch, when measured.
    rebuild: Option<RebuildCost>,
}

/// A round that stops: its fit is the result.
fn stopped(log: ImageRound, fit: TreeFit, stop: StopReason, fit_s: f64, refine_s: f64) -> Round {
    Round {
        log,
        fit,
        decision: Decision::Stop(stop),
        fit_s,
        refine_s,
        position_s: 0.0,
    }
}

/// One round of the image plane after its fit and indicator, the quadtree's side of the
/// rounds driver ([`rounds::round`]): the stop test's facts, the coverage rule's fill before
/// a stop, densifying, marking (Dörfler extended to the least growth, cut to the budget by
/// [`crate::adaptive::marking::within_budget`]), deepening and the positions handed out.
struct PlaneRound<'p, 's> {
    plan: &'p mut ImagePlan,
    xs: &'s [f64],
    ys: &'s [f64],
    values: &'s [&'s [f64]],
    /// The round's number (0: the base fit).
    round: usize,
    ind: Indication,
    /// The round's log and fit, until the round's outcome takes them.
    log: Option<ImageRound>,
    fit: Option<TreeFit>,
    /// The pixels short of their samples (pixel, samples it lacks): the coverage rule.
    empty: Vec<(usize, usize)>,
    fit_s: f64,
    /// When the indicator started (the round's refine seconds count from it).
    t: Instant,
    /// The slots' samples and the round's allowance, once the round goes on.
    tally: Option<Tally>,
}

impl PlaneRound<'_, '_> {
    /// The slots' tally (computed once, after the stop test).
    fn tally(&mut self) -> &Tally {
        if self.tally.is_none() {
            let (log, fit) = (self.log.as_ref(), self.fit.as_ref());
            let (log, fit) = (log.expect("the log"), fit.expect("the fit"));
            let tally =
                self.plan
                    .tally(self.xs, self.ys, self.values, fit, &self.ind, log.reserved);
            self.tally = Some(tally);
        }
        self.tally.as_ref().expect("just computed")
    }

    /// The round's log and fit, taken by its outcome.
    fn take(&mut self) -> (ImageRound, TreeFit) {
        let log = self.log.take().expect("a round ends once");
        (log, self.fit.take().expect("a round ends once"))
    }
}

impl RoundAdapter for PlaneRound<'_, '_> {
    type Marks = Marking;
    type Outcome = Round;
    type Error = AdaptiveError;

    /// The estimate `sqrt(sum eta^2 / (W H))`. Nothing significant left (no markable slot)
    /// densifies rather than deepens; it stops at the depth limit only with no insignificant
    /// slot to densify either, and under [`SpreadRule::Uncertainty`] a tree that is deep
    /// everywhere its detail is significant is not a reason to stop while the budget lasts.
    /// The budget is spent at the budget's samples (a round could only deepen the tree
    /// without a sample to give it, and the renderer would get no positions yet no final
    /// image); the rounds counted are the rounds made.
    fn facts(&mut self) -> RoundFacts {
        let params = &self.plan.params;
        let samples = self.xs.len();
        let ind = &self.ind;
        let nothing_significant = ind.markable_sq <= 0.0 || ind.units.is_empty();
        let densify_at_limit =
            params.growth.spread == SpreadRule::Uncertainty && samples < params.stop.budget;
        RoundFacts {
            estimate: self.log.as_ref().map(|l| l.estimate_rms),
            markable: !(nothing_significant && ind.insignificant.is_empty() && !densify_at_limit),
            deepenable: !nothing_significant,
            resolvable: true,
            spent: samples >= params.stop.budget,
            rounds: self.round,
        }
    }

    /// [`ImagePlan::fill_or_stop`]: the coverage rule's fill round, or the stop.
    fn stop(&mut self, reason: StopReason) -> Result<Round, AdaptiveError> {
        let (log, fit) = self.take();
        let (fit_s, t) = (self.fit_s, self.t);
        Ok(self
            .plan
            .fill_or_stop(log, fit, reason, &self.empty, fit_s, t))
    }

    /// [`ImagePlan::mark`] on the slots' tally.
    fn mark(&mut self) -> Result<Option<Marking>, AdaptiveError> {
        self.tally();
        let tally = self.tally.as_ref().expect("tallied");
        Ok(self.plan.mark(self.xs, self.ys, &self.ind, tally))
    }

    /// [`ImagePlan::deepen_and_sample`]: the marked slots deepened, the positions handed out.
    fn deepen(&mut self, marking: Marking) -> Result<Round, AdaptiveError> {
        let (mut log, fit) = self.take();
        log.marked = marking.k;
        let refine_s = self.t.elapsed().as_secs_f64();
        let t = Instant::now();
        let tally = self.tally.take().expect("marked on the tally");
        let next =
            self.plan
                .deepen_and_sample(self.round, self.xs.len(), &tally, &marking, &mut log);
        Ok(Round {
            log,
            fit,
            decision: Decision::Sample(next),
            fit_s: self.fit_s,
            refine_s,
            position_s: t.elapsed().as_secs_f64(),
        })
    }

    /// [`ImagePlan::densify`]: more samples in the slots as they are; `None` when the budget
    /// is spent.
    fn densify(&mut self) -> Result<Option<Round>, AdaptiveError> {
        self.tally();
        let tally = self.tally.take().expect("tallied");
        let refine_s = self.t.elapsed().as_secs_f64();
        let log = self.log.as_mut().expect("the log");
        let densified = self.plan.densify(self.round, self.xs.len(), &tally, log);
        Ok(densified.map(|(next, position_s)| {
            let (log, fit) = self.take();
            Round {
                log,
                fit,
                decision: Decision::Sample(next),
                fit_s: self.fit_s,
                refine_s,
                position_s,
            }
        }))
    }
}
