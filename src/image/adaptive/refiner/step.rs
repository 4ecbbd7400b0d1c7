//! One round of the plan ([`ImagePlan::step`]) as named steps: fit ([`ImagePlan::fit_round`]),
//! indicate, log, stop ([`ImagePlan::stop_reason`]), tally the slots, then densify when
//! nothing significant is left, or mark, deepen and sample.

use std::time::Instant;

use super::super::fit::{fit_tree_updating, FitState, TreeFit};
use super::super::indicator::{indicate, Indication};
use super::super::pcg::TreeSolver;
use super::super::significance::Significance;
use super::super::AdaptiveError;
use super::{Decision, ImagePlan, ImageRound, RebuildCost, Round};
use crate::adaptive::marking::SpreadRule;
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
        let nothing_significant = ind.markable_sq <= 0.0 || ind.units.is_empty();
        // the coverage rule (module `coverage`): the samples every pixel lacks are held back
        let empty = self.shortfall(xs, ys);
        log.reserved = empty.iter().map(|s| s.1).sum();
        let stop = self.stop_reason(&ind, log.estimate_rms, nothing_significant, round, xs.len());
        if let Some(stop) = stop {
            return Ok(self.fill_or_stop(log, fit, stop, &empty, fit_s, t));
        }
        let tally = self.tally(xs, ys, values, &fit, &ind, log.reserved);
        if nothing_significant {
            let refine_s = t.elapsed().as_secs_f64();
            return Ok(match self.densify(round, xs.len(), &tally, &mut log) {
                None => self.fill_or_stop(log, fit, StopReason::Budget, &empty, fit_s, t),
                Some((next, position_s)) => Round {
                    log,
                    fit,
                    decision: Decision::Sample(next),
                    fit_s,
                    refine_s,
                    position_s,
                },
            });
        }
        let Some(marking) = self.mark(xs, ys, &ind, &tally) else {
            return Ok(self.fill_or_stop(log, fit, StopReason::Budget, &empty, fit_s, t));
        };
        log.marked = marking.k;
        let refine_s = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let next = self.deepen_and_sample(round, xs.len(), &tally, &marking, &mut log);
        Ok(Round {
            log,
            fit,
            decision: Decision::Sample(next),
            fit_s,
            refine_s,
            position_s: t.elapsed().as_secs_f64(),
        })
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

    /// Stop: at the tolerance, when nothing below the depth limit is left to deepen or
    /// densify, when the budget is spent (a round could only deepen the tree without a
    /// sample to give it, and the renderer would get no positions yet no final image), or at
    /// the round limit. Under [`SpreadRule::Uncertainty`] a tree that is deep
    /// everywhere its detail is significant is not a reason to stop while the budget lasts:
    /// the next rounds densify where the slots' means are uncertain.
    fn stop_reason(
        &self,
        ind: &Indication,
        estimate_rms: f64,
        nothing_significant: bool,
        round: usize,
        samples: usize,
    ) -> Option<StopReason> {
        let densify_at_limit = self.params.growth.spread == SpreadRule::Uncertainty
            && samples < self.params.stop.budget;
        if estimate_rms <= self.params.stop.tolerance {
            Some(StopReason::Tolerance)
        } else if nothing_significant && ind.insignificant.is_empty() && !densify_at_limit {
            Some(StopReason::DepthLimit)
        } else if samples >= self.params.stop.budget {
            Some(StopReason::Budget)
        } else if round >= self.params.stop.max_rounds {
            Some(StopReason::MaxRounds)
        } else {
            None
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
