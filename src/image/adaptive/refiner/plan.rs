//! The plan between rounds ([`ImagePlan`]): the parameters, the tree and how it grew; its
//! construction from a budget, its resumption from a progress record and the round's fit.

use serde::{Deserialize, Serialize};

use super::super::correction::ResidualCorrection;
use super::super::fit::{fit_tree_updating, FitState, TreeFit};
use super::super::pcg::{SingleScaleRows, TreeSolver};
use super::super::significance::{probe_values, Significance};
use super::super::AdaptiveError;
use super::positions::{round_rng, Placer};
use super::report::{fit_notes, noise_notes};
use super::top_up::top_up;
use super::{AdaptiveParams, AdaptiveReport, AdaptiveTimes, ImageRound, SamplePositions};
use crate::adaptive::StopReason;
use crate::adaptive::{Cell, QuadTree};
use crate::basis::tensor::TensorBasis;
use crate::basis::FilterFamily;
use crate::image::ImagePlane;

/// What the refiner decided after a round's fit.
#[derive(Clone, Debug, PartialEq)]
pub enum Decision {
    /// Sample these positions, then run the next round on every sample so far.
    Sample(SamplePositions),
    /// Stop: the round's fit is the result.
    Stop(StopReason),
}

/// One round of the refiner ([`ImagePlan::step`]): its fit, its log and its decision.
#[derive(Clone, Debug)]
pub struct Round {
    /// What the round saw and did.
    pub log: ImageRound,
    /// The fit on the tree as it was at the start of the round.
    pub fit: TreeFit,
    /// Positions to sample next, or the stop.
    pub decision: Decision,
    /// Seconds: the fit.
    pub fit_s: f64,
    /// Seconds: indicator, marking, deepening.
    pub refine_s: f64,
    /// Seconds: drawing the new positions.
    pub position_s: f64,
}

/// How far a plan has come: enough, with its parameters and plane, to rebuild it
/// ([`ImagePlan::resume`]).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PlanProgress {
    /// The cells marked in rounds `1, 2, ...` (round `r` deepened `marked[r - 1]`), in the
    /// order they were activated: the tree is the base tree plus these cells.
    pub marked: Vec<Vec<Cell>>,
    /// Samples in the last round's fit (0 before the first fit).
    pub samples_fitted: usize,
}

/// The refiner between rounds: parameters, the tree and how it grew.
///
/// One round ([`ImagePlan::step`]) takes every sample so far (which must include the base
/// positions of [`ImagePlan::base_positions`] and the positions of every earlier decision),
/// fits on the tree, and either stops or deepens the tree and returns the positions to sample
/// next. `refine_image` is a loop over it with a scene as the oracle; a renderer outside the
/// process drives the same rounds through files (module `protocol`).
#[derive(Clone, Debug)]
pub struct ImagePlan {
    pub(super) params: AdaptiveParams,
    pub(super) plane: ImagePlane,
    pub(super) tree: QuadTree,
    pub(super) base_steps: u32,
    pub(super) per_slot: usize,
    pub(super) progress: PlanProgress,
    /// The last fit's solver state, continued by the next round's fit ([`FitState`]: the
    /// direct solve's normal matrix, the same bits without it, see `super::super::gram`; PCG's
    /// diagonal; a resumed plan starts without).
    pub(super) state: FitState,
    /// The last fit's coefficients per image channel, then per probe channel of the noise
    /// test (a sample keeps its probe values), PCG's start in the next round (solver
    /// state only, kept for [`TreeSolver::Pcg`]: the tree only grows, so they are a point of
    /// the next tree's space with its new functions at 0; a resumed plan starts from 0).
    pub(super) start: Option<Vec<Vec<f64>>>,
    /// What the coverage rule did to the base level (`None`: nothing), for the notes.
    pub(super) coverage: Option<String>,
    /// The uniform floor's samples a pixel, `floor(f N / (W H))` ([`ImageSampling::
    /// pixel_floor`]), when above the coverage rule's count (else 0): the base positions
    /// already give every pixel this many (module `coverage`, "Floor").
    ///
    /// [`ImageSampling::pixel_floor`]: super::ImageSampling::pixel_floor
    pub(super) floor: usize,
}

impl ImagePlan {
    /// The plan before any sample: validated parameters, the basis at the depth limit and the
    /// base tree (full up to the base step, chosen from the budget unless given).
    pub fn new(plane: ImagePlane, params: &AdaptiveParams) -> Result<Self, AdaptiveError> {
        params.validate()?;
        // A lower bound of what the budget's samples hold at the last fit: the position (16
        // bytes), one value (8) and the finest level's (2p - 1)^2 kernel entries (16 each).
        let per_sample = 24.0 + 16.0 * ((2 * params.tree.p - 1) as f64).powi(2);
        crate::resources::check(
            || format!("a budget of {} samples", params.stop.budget),
            params.stop.budget as f64 * per_sample,
            || {
                format!(
                    "lower the budget to at most {} samples",
                    (crate::resources::memory_limit() as f64 / per_sample) as u64
                )
            },
        )?;
        let (w, h) = (plane.width(), plane.height());
        let levels = (
            finest_level(w, params.quad.below_pixel)
                .max(crate::basis::minimum_level(params.tree.p) + 2),
            finest_level(h, params.quad.below_pixel)
                .max(crate::basis::minimum_level(params.tree.p) + 2),
        );
        let basis = TensorBasis::new(
            params.tree.p,
            FilterFamily::cdv_default(params.tree.p),
            w,
            h,
            levels,
        )?;
        let steps = basis.steps();
        let (cx, cy) = basis.coarse_levels();
        let per_slot = params.tree.rho.ceil() as usize;
        let base_cost = |s: u32| (1usize << (cx + s)) * (1usize << (cy + s)) * per_slot;
        let mut s0 = match params.quad.base_level {
            Some(level) => {
                if level <= cx || level > cx + steps {
                    return Err(AdaptiveError::Parameter {
                        parameter: "base_level",
                        value: level.to_string(),
                        expected: "a level above the coarse level and at most the depth limit",
                    });
                }
                level - cx
            }
            None => (1..steps)
                .rev()
                .find(|&s| {
                    base_cost(s) as f64 <= params.quad.base_fraction * params.stop.budget as f64
                })
                .unwrap_or(1),
        };
        // Coverage up front (module `coverage`): at two samples a pixel or more, where the
        // budget pays for base slots no larger than a pixel, the base tree is raised to them,
        // so that every pixel holds `ceil(rho)` base samples before the tree adapts (on the
        // suite's 4 spp this is ahead of topping the pixels up after the rounds:
        // docs/measurements/plan-quality-history.md); elsewhere (planes whose sides are not
        // powers of two, between 1 and 2 samples a pixel) the reserve and the fill round below
        // cover the pixels. A base level given by the user is kept as given.
        let mut coverage = None;
        let pixels = w * h;
        if params.sampling.cover_pixels
            && params.quad.base_level.is_none()
            && params.stop.budget >= per_slot * pixels
        {
            let covers = |level: u32, size: usize| {
                let cells = 1usize << level;
                cells >= size && (cells % size == 0 || cells >= 2 * size)
            };
            if let Some(sp) = (1..=steps).find(|&s| covers(cx + s, w) && covers(cy + s, h)) {
                if sp > s0 && base_cost(sp) <= params.stop.budget {
                    coverage = Some(format!(
                        "coverage: the base tree raised from level {} to {} (slots no larger \
                         than a pixel, {} of the {} samples) so that every pixel holds {} base \
                         samples",
                        cx + s0,
                        cx + sp,
                        base_cost(sp),
                        params.stop.budget,
                        per_slot
                    ));
                    s0 = sp;
                }
            }
        }
        // The coverage rule (module `coverage`): the samples that top every pixel up to `m`
        // after the base must fit in the budget beside it; the automatic base level comes down
        // until they do (a base level given by the user is kept as given).
        let m = per_slot.min(params.stop.budget / plane.pixels());
        let cover = if params.sampling.cover_pixels { m } else { 0 };
        // The uniform floor in the base (module `coverage`, "Floor"): every pixel topped up
        // to `floor(f N / (W H))` from its own sequence before the first round.
        let share = params.sampling.pixel_floor * params.stop.budget as f64 / pixels as f64;
        let floor = (share.floor() as usize).min(params.stop.budget / pixels);
        let floor = if floor > cover { floor } else { 0 };

        if params.sampling.cover_pixels && params.quad.base_level.is_none() && m > 0 {
            let chosen = s0;
            let need = |s: u32| {
                let base = base_positions_of(plane, &basis, s, per_slot, floor, params);
                let short = super::pixel_counts::pixel_shortfall(plane, &base.xs, &base.ys, m);
                base.len() + short.iter().map(|s| s.1).sum::<usize>()
            };
            while s0 > 1 && need(s0) > params.stop.budget {
                s0 -= 1;
            }
            if s0 < chosen {
                coverage = Some(format!(
                    "coverage: the base level lowered from {} to {} so that the budget of {} \
                     holds the base and the samples that top every pixel up to {m} ({} in all)",
                    cx + chosen,
                    cx + s0,
                    params.stop.budget,
                    need(s0)
                ));
            }
        }
        if params.sampling.cover_pixels && params.stop.budget < plane.pixels() {
            coverage = Some(format!(
                "coverage: the budget of {} is below one sample a pixel ({} pixels): pixels the \
                 tree leaves empty keep the fit's value",
                params.stop.budget,
                plane.pixels()
            ));
        }
        if base_cost(s0) > params.stop.budget {
            return Err(AdaptiveError::BudgetTooSmall {
                budget: params.stop.budget,
                base: base_cost(s0),
                slots: base_cost(s0) / per_slot,
                per_slot,
            });
        }
        // The floor needs base slots of one pixel (the pixel's own sequence continued from
        // its base samples); where the base slots are not pixels (a tiled plan's windows,
        // sides that are not powers of two) it is off, and the notes say so: there the
        // tiled plan measured 0.7-1.4 dB further below the untiled one with it
        // (docs/measurements/plan-quality.md, "The floor in the first round").
        let pixel_slots = (1usize << (cx + s0)) == w && (1usize << (cy + s0)) == h;
        let mut floor = floor;
        if floor > 0 && !pixel_slots {
            let note = format!(
                "floor: pixel_floor asks for {floor} samples a pixel, but the base slots are not \
                 the pixels (a {w}x{h} plane): no floor (the coverage rule's {cover} a pixel \
                 holds)"
            );
            coverage = Some(match coverage {
                Some(c) => format!("{c}; {note}"),
                None => note,
            });
            floor = 0;
        }
        // the base with the floor must fit in the budget: the floor comes down until it does
        let wanted = floor;
        while floor > 0
            && base_positions_of(plane, &basis, s0, per_slot, floor, params).len()
                > params.stop.budget
        {
            floor = if floor - 1 > cover { floor - 1 } else { 0 };
        }
        if floor < wanted {
            coverage = Some(format!(
                "floor: lowered from {wanted} to {floor} samples a pixel so that the base and the \
                 floor fit in the budget of {} (lower pixel_floor, or raise the budget)",
                params.stop.budget
            ));
        }
        Ok(Self {
            params: *params,
            plane,
            tree: QuadTree::uniform(basis, s0),
            base_steps: s0,
            per_slot,
            progress: PlanProgress::default(),
            state: FitState::default(),
            start: None,
            coverage,
            floor,
        })
    }

    /// The plan after the rounds recorded in `progress`: the base tree with the marked cells
    /// activated in order. Fails with [`AdaptiveError::History`] if a recorded cell is not a
    /// slot below the depth limit of the tree so far (a progress record of another run).
    pub fn resume(
        plane: ImagePlane,
        params: &AdaptiveParams,
        progress: PlanProgress,
    ) -> Result<Self, AdaptiveError> {
        let mut plan = Self::new(plane, params)?;
        for (r, cells) in progress.marked.iter().enumerate() {
            for &cell in cells {
                let (w, h) = plan.tree.cell_dims(cell.step.min(plan.tree.steps()));
                let fault = if cell.step >= plan.tree.steps() || cell.kx >= w || cell.ky >= h {
                    Some("outside the tree's cells below the depth limit")
                } else if plan.tree.is_active(cell) {
                    Some("already active")
                } else if cell.parent().is_some_and(|q| !plan.tree.is_active(q)) {
                    Some("its parent is inactive")
                } else {
                    None
                };
                if let Some(reason) = fault {
                    return Err(AdaptiveError::History {
                        round: r + 1,
                        cell: format!("(step {}, kx {}, ky {})", cell.step, cell.kx, cell.ky),
                        reason,
                    });
                }
                plan.tree.deepen(cell);
            }
        }
        plan.progress = progress;
        Ok(plan)
    }

    /// The parameters.
    pub fn params(&self) -> &AdaptiveParams {
        &self.params
    }
    /// The image plane.
    pub fn plane(&self) -> ImagePlane {
        self.plane
    }
    /// The tree as it stands (deepened by every decision so far).
    pub fn tree(&self) -> &QuadTree {
        &self.tree
    }
    /// The base step `s0`: base slots at levels `(cx + s0, cy + s0)`.
    pub fn base_steps(&self) -> u32 {
        self.base_steps
    }
    /// Samples per slot, `ceil(rho)`.
    pub fn per_slot(&self) -> usize {
        self.per_slot
    }
    /// How far the plan has come.
    pub fn progress(&self) -> &PlanProgress {
        &self.progress
    }
    /// The next round's number (0: the base fit).
    pub fn round(&self) -> usize {
        self.progress.marked.len()
    }

    /// The base positions: `ceil(rho)` positions in every base slot by the plan's pattern
    /// (module `positions`), then with a uniform floor every pixel topped up to it from its
    /// own sequence (module `coverage`, "Floor"); the same for every call.
    pub fn base_positions(&self) -> SamplePositions {
        base_positions_of(
            self.plane,
            self.tree.basis(),
            self.base_steps,
            self.per_slot,
            self.floor,
            &self.params,
        )
    }

    /// The uniform floor's samples a pixel that the base positions hold (0: no floor above
    /// the coverage rule's count).
    pub fn floor(&self) -> usize {
        self.floor
    }

    /// The placer of round `round`'s positions (0: the base) by the plan's pattern.
    pub(super) fn placer(&self, round: usize) -> Placer {
        let s = &self.params.sampling;
        Placer::new(s.pattern, s.seed, round)
    }

    /// The round's fit on the tree as it stands, and with the noise test on, the test (the
    /// probe channels fitted beside the image's with the same factorization, seeded by the
    /// seed, the round and the positions). The file protocol reconstructs with this too, so
    /// its pixels are the in-process loop's bit for bit.
    pub fn fit(
        &self,
        xs: &[f64],
        ys: &[f64],
        values: &[&[f64]],
    ) -> Result<(TreeFit, Option<Significance>), AdaptiveError> {
        self.fit_updating(
            xs,
            ys,
            values,
            self.params.fit.solver,
            None,
            &mut FitState::default(),
        )
    }

    /// The solver state the next round's fit continues ([`FitState`]): a caller that keeps it
    /// between processes (the file protocol's carried normal matrix) puts it back here.
    pub fn fit_state_mut(&mut self) -> &mut FitState {
        &mut self.state
    }

    /// PCG's start for the next round's fit (per image channel, then per probe channel): a
    /// caller that keeps it between processes (the file protocol's `pcg.bin`) puts it back.
    pub fn start_mut(&mut self) -> &mut Option<Vec<Vec<f64>>> {
        &mut self.start
    }

    /// [`ImagePlan::fit`] continuing the solver state `state` ([`FitState`]),
    /// PCG starting from `start` (per image channel, then per probe channel; channels
    /// without one start from 0).
    pub fn fit_updating(
        &self,
        xs: &[f64],
        ys: &[f64],
        values: &[&[f64]],
        solver: TreeSolver,
        start: Option<&[Vec<f64>]>,
        state: &mut FitState,
    ) -> Result<(TreeFit, Option<Significance>), AdaptiveError> {
        let params = &self.params;
        let tree = &self.tree;
        let ch = values.len();
        if params.noise.false_alarm <= 0.0 {
            return Ok((
                fit_tree_updating(tree, xs, ys, values, solver, start, state)?,
                None,
            ));
        }
        let probes = probe_values(params.sampling.seed, xs, ys, params.noise.probes);
        let mut all: Vec<&[f64]> = values.to_vec();
        all.extend(probes.iter().map(|p| p.as_slice()));
        // the probes stop at their own tolerance (PCG only)
        let tolerances = params.fit.probe_tolerance.and_then(|t| match solver {
            TreeSolver::Pcg { tolerance, .. } => {
                let mut v = vec![tolerance; ch];
                v.extend(std::iter::repeat_n(t, all.len() - ch));
                Some(v)
            }
            _ => None,
        });
        let mut fit = super::super::fit::fit_tree_channels(
            tree,
            xs,
            ys,
            &all,
            solver,
            tolerances.as_deref(),
            start,
            state,
        )?;
        // the rows of the fit (PCG's, continued) or continued here (the direct solve's)
        let rows = SingleScaleRows::continued(state.rows.take(), tree.basis(), xs, ys);
        let significance = Significance::new(
            tree,
            &fit.coefficients,
            &rows,
            &all,
            ch,
            params.noise.false_alarm,
            tree.leaves().len(),
        );
        state.rows = Some(rows);
        fit.coefficients.truncate(ch);
        Ok((fit, Some(significance)))
    }

    /// The report of a finished run: `base_samples` of `samples` in total, the final `fit`,
    /// the reason to stop and the log of every round ([`AdaptiveReport::pixels`] empty: the
    /// caller that computes the output pixels fills it in, as `refine_image` does).
    pub fn report(
        &self,
        base_samples: usize,
        samples: usize,
        fit: &TreeFit,
        stop: StopReason,
        rounds: Vec<ImageRound>,
        times: AdaptiveTimes,
    ) -> AdaptiveReport {
        let (cx, cy) = self.tree.basis().coarse_levels();
        let mut notes = fit_notes(&fit.report);
        notes.extend(self.coverage.clone());
        notes.extend(rounds.iter().filter_map(|r| r.coverage.clone()));
        notes.extend(noise_notes(&rounds, self.params.noise.false_alarm));
        let spread: Vec<String> = rounds
            .iter()
            .filter(|r| r.spread > 0)
            .map(|r| format!("round {}: {}", r.round, r.spread))
            .collect();
        if !spread.is_empty() {
            notes.push(format!(
                "the marked slots cost less than the least growth ({} x the samples, or the rest \
                 of the budget): spare samples spread over the other slots by {} ({})",
                self.params.growth.min_growth,
                self.params.growth.spread.name(),
                spread.join(", ")
            ));
        }
        let share = self.params.growth.pixel_share;
        if share > 0.0 && !self.base_slots_are_pixels() {
            notes.push(format!(
                "pixel_share: {share} asked for, but the base slots are not the pixels: the tree \
                 alone places the samples (no pixel share)"
            ));
        } else if share > 0.0 && !self.budget_takes_share() {
            notes.push(format!(
                "pixel_share: {share} asked for, but the budget is above {} samples a \
                 pixel, where the share lost to the tree's own spare samples: the tree alone \
                 places the samples (no pixel share)",
                self.share_max_spp()
            ));
        } else if share > 0.0 {
            let by_pixel: Vec<String> = rounds
                .iter()
                .filter(|r| r.pixel_spread > 0)
                .map(|r| format!("round {}: {}", r.round, r.pixel_spread))
                .collect();
            let total: usize = rounds.iter().map(|r| r.pixel_spread).sum();
            notes.push(format!(
                "pixel share {share}: {total} samples over the pixels by the spread of their own \
                 samples (clipped to [0, 1], pooled over 3 x 3 pixels), beside the tree's marking \
                 ({})",
                if by_pixel.is_empty() {
                    "none: no pixel's samples spread".to_string()
                } else {
                    by_pixel.join(", ")
                }
            ));
        }
        AdaptiveReport {
            levels: self.tree.basis().levels(),
            coarse_levels: (cx, cy),
            base_levels: (cx + self.base_steps, cy + self.base_steps),
            base_samples,
            samples,
            budget: self.params.stop.budget,
            functions: fit.report.functions,
            cells_per_step: self.tree.cells_per_step(),
            stop,
            rounds,
            times,
            pixels: ResidualCorrection::default(),
            notes,
        }
    }
}

/// The base positions of a plan on `plane` and `basis` with base step `s0`: `per_slot`
/// positions in every base slot by the plan's pattern, then every pixel holding fewer than
/// `floor` topped up to it (`super::top_up::top_up`: the pixel's own sequence continued
/// where the pixel is a base slot; jittered strata of round 0's stream elsewhere).
fn base_positions_of(
    plane: ImagePlane,
    basis: &TensorBasis,
    s0: u32,
    per_slot: usize,
    floor: usize,
    params: &AdaptiveParams,
) -> SamplePositions {
    let base = QuadTree::uniform(basis.clone(), s0);
    let s = &params.sampling;
    let mut placer = Placer::new(s.pattern, s.seed, 0);
    let mut out = SamplePositions::default();
    for slot in base.leaves() {
        placer.place(&mut out, slot, base.rect(slot), 0, per_slot);
    }
    if floor > 0 {
        let short = super::pixel_counts::pixel_shortfall(plane, &out.xs, &out.ys, floor);
        // a stream of its own (the base placer's is `round_rng(seed, 0)`)
        let mut rng = round_rng(!s.seed, 0);
        let fill = top_up(plane, &base, params, &short, floor, &mut rng);
        out.append(fill);
    }
    out
}

/// The finest level along an axis of `size` pixels, `below` levels under the pixel.
fn finest_level(size: usize, below: u32) -> u32 {
    (size.max(1) as f64).log2().ceil() as u32 + below
}
