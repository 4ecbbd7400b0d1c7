//! The plan's jobs: a renderer's adaptive loop, one library call per step a front end takes.
//!
//! * [`PlanStart`]: a new plan on a `W x H` image from [`PlanOptions`] (the budget required,
//!   the rest defaulting to [`AdaptiveParams::renderer_plan`]): validated, its memory checked
//!   from the sizes ([`PlanStart::check_memory`]) before the basis at the depth limit is
//!   built, then the state and the base positions ([`PlanStart::run`]).
//! * [`PlanRound`]: one round on every sample so far: the options given on a later call must
//!   be the plan's own (a plan keeps its parameters), then the round's fit and the next
//!   positions or the stop ([`PlanState::advance_dropped`]; its fit's memory is checked before
//!   the fit, and a direct solve that would not fit falls back to PCG with a note).
//! * [`PlanFinal`]: the final image of a plan from its state and its samples: the fit on the
//!   tree the samples were planned for and the plan's output pixels (or the fit's box pixels
//!   alone, [`PixelEstimate::FitOnly`]). The command line's `plan --final-image`, its
//!   `reconstruct --dim 2 --state` and Python's `Plan.image()` all make their image by
//!   [`PlanFinal::run`], so the three give the same pixels bit for bit (module docs of
//!   [`PlanFinal`] for the one shortcut, taken only where it is exact).

use std::fmt;
use std::str::FromStr;

use crate::adaptive::marking::SpreadRule;
use crate::error::{Fix, Param};
use crate::image::adaptive::{
    AdaptiveParams, FitParams, GrowthParams, ImageSampling, NoiseParams, OutputParams,
    PixelEstimate, PositionPattern, QuadTreeParams, SamplePositions, StopParams, TreeParams,
    TreeSolver,
};
use crate::image::plan::new_round::ReadSamples;
use crate::image::plan::{PlanReconstruction, PlanState, PlanStep, ProtocolError};
use crate::image::{DroppedSamples, ImagePlane, ImageSamples, NonFinitePolicy};
use crate::resources::{memory_limit, ImageRequest, ImageSolve};

use super::{check_p, ImageParams, JobError};

/// A plan's sample budget: the total, or an average per pixel (`spp x W x H`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlanBudget {
    /// Samples in all.
    Samples(usize),
    /// Samples per pixel on average.
    PerPixel(usize),
}

impl PlanBudget {
    /// The total on `plane` (saturating: a budget beyond `usize` is refused by the memory
    /// check, not wrapped).
    pub fn samples(self, plane: ImagePlane) -> usize {
        match self {
            PlanBudget::Samples(n) => n,
            PlanBudget::PerPixel(spp) => spp.saturating_mul(plane.pixels()),
        }
    }
}

/// The solver of a plan's fits, by name (`pcg`, `direct`, `schwarz`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlanSolver {
    /// Matrix-free conjugate gradients, rounds warm-started ([`TreeSolver::plan_pcg`]: to a
    /// relative residual of `3e-4`), the default of a new plan.
    Pcg,
    /// The sparse Cholesky of the normal matrix carried between rounds.
    Direct,
    /// Conjugate gradients on the assembled matrix with an additive Schwarz preconditioner
    /// (experimental; tiles of 8 pixels, halo 1, to `1e-10`).
    Schwarz,
}

impl PlanSolver {
    /// The tree fit's solver of this choice.
    pub fn tree_solver(self) -> TreeSolver {
        match self {
            PlanSolver::Pcg => TreeSolver::plan_pcg(),
            PlanSolver::Direct => TreeSolver::Direct,
            PlanSolver::Schwarz => TreeSolver::Schwarz {
                tolerance: 1e-10,
                max_iterations: 400,
                tile: 8.0,
                halo: 1.0,
            },
        }
    }
}

impl FromStr for PlanSolver {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim().to_ascii_lowercase().as_str() {
            "pcg" => Ok(PlanSolver::Pcg),
            "direct" => Ok(PlanSolver::Direct),
            "schwarz" => Ok(PlanSolver::Schwarz),
            _ => Err(
                "expected pcg (conjugate gradients, the default), direct (sparse \
                      Cholesky) or schwarz (experimental)"
                    .into(),
            ),
        }
    }
}

impl fmt::Display for PlanSolver {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            PlanSolver::Pcg => "pcg",
            PlanSolver::Direct => "direct",
            PlanSolver::Schwarz => "schwarz",
        })
    }
}

/// The options of a plan a front end asked for; every `None` takes the plan's value (its
/// state's on a later call) or, for a new plan, the default of a renderer's plan
/// ([`AdaptiveParams::renderer_plan`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlanOptions {
    /// The sample budget (required to start a plan).
    pub budget: Option<PlanBudget>,
    /// Vanishing moments `p` of the tree's basis, 1 to 4 (default 2).
    pub p: Option<usize>,
    /// Samples per slot of the tree (default 2).
    pub rho: Option<f64>,
    /// Depth limit in levels below the pixel (default 1).
    pub below_pixel: Option<u32>,
    /// Seed of the positions (default 1).
    pub seed: Option<u64>,
    /// False-alarm rate of the noise test per round (default 0.01; 0: no test).
    pub false_alarm: Option<f64>,
    /// Least growth per round as a share of the samples so far (default 0.25).
    pub min_growth: Option<f64>,
    /// Where a slot's positions go (default Sobol).
    pub pattern: Option<PositionPattern>,
    /// Where a round's spare samples go (default by the indicator).
    pub spread: Option<SpreadRule>,
    /// Share of each round's new samples given to the pixels by their pooled spread
    /// ([`crate::image::adaptive::GrowthParams::pixel_share`]).
    pub pixel_share: Option<f64>,
    /// The final image's pixels (default `blend` for a new plan).
    pub output_pixels: Option<PixelEstimate>,
    /// The solver of the rounds' fits (default PCG for a new plan).
    pub solver: Option<PlanSolver>,
}

impl PlanOptions {
    /// The options of a plan on tiles ([`super::tiled_plan`]), checked at its entries (a new
    /// tiled plan, a later call): a pixel share `q != 0` is refused. The tiles' windows would
    /// place a share of their own, unreported by the tiled plan's rounds, and the tiled plan
    /// would no longer follow the untiled one; `q = 0` (the default) is the plan without it.
    pub fn check_tiled(&self) -> Result<(), JobError> {
        match self.pixel_share {
            Some(q) if q != 0.0 => Err(JobError::Conflict {
                first: Param::PixelShare,
                second: Param::Tile,
                reason: "is not available with the tiled plan (its tiles would give the \
                         pixels a share the rounds do not report, and the tiled plan would no \
                         longer follow the untiled one)",
            }),
            _ => Ok(()),
        }
    }

    /// The refiner's parameters: the options given, the rest from `base` (the state's on a
    /// later call, [`AdaptiveParams::renderer_plan`] for a new plan); `p` checked (1 to 4).
    pub fn params(
        &self,
        plane: ImagePlane,
        base: &AdaptiveParams,
    ) -> Result<AdaptiveParams, JobError> {
        Ok(AdaptiveParams {
            tree: TreeParams {
                p: self.p.map_or(Ok(base.tree.p), check_p)?,
                rho: self.rho.unwrap_or(base.tree.rho),
            },
            quad: QuadTreeParams {
                below_pixel: self.below_pixel.unwrap_or(base.quad.below_pixel),
                ..base.quad
            },
            sampling: ImageSampling {
                seed: self.seed.unwrap_or(base.sampling.seed),
                pattern: self.pattern.unwrap_or(base.sampling.pattern),
                ..base.sampling
            },
            noise: NoiseParams {
                false_alarm: self.false_alarm.unwrap_or(base.noise.false_alarm),
                ..base.noise
            },
            stop: StopParams {
                budget: self.budget.map_or(base.stop.budget, |b| b.samples(plane)),
                ..base.stop
            },
            growth: GrowthParams {
                min_growth: self.min_growth.unwrap_or(base.growth.min_growth),
                spread: self.spread.unwrap_or(base.growth.spread),
                pixel_share: self.pixel_share.unwrap_or(base.growth.pixel_share),
                ..base.growth
            },
            output: OutputParams {
                pixels: self.output_pixels.unwrap_or(base.output.pixels),
                ..base.output
            },
            fit: FitParams {
                solver: self.solver.map_or(base.fit.solver, PlanSolver::tree_solver),
                ..base.fit
            },
            ..*base
        })
    }
}

/// Bytes a plan holds per function of its basis at the depth limit, whatever its tree: the
/// tree's active flag, the exact diagonal's mask and sum, and PCG's carried start of one
/// channel and its noise probe (full layout, 8 bytes each). A lower bound: more channels
/// hold more starts (the rounds' own check counts them, [`PlanState::advance_dropped`]).
const PLAN_BYTES_PER_FUNCTION: f64 = 1.0 + 1.0 + 8.0 + 2.0 * 8.0;

/// A new plan, validated, nothing allocated yet (module docs).
#[derive(Debug, Clone)]
pub struct PlanStart {
    plane: ImagePlane,
    params: AdaptiveParams,
}

impl PlanStart {
    /// Refuses a `halo` without tiles: the halo is the tiles' ([`super::tiled_plan`]), so a call
    /// that gives one needs a `tile` size, or a plan on tiles to continue (`tiled`).
    pub fn check_halo(
        tile: Option<usize>,
        halo: Option<usize>,
        tiled: bool,
    ) -> Result<(), JobError> {
        if halo.is_some() && tile.is_none() && !tiled {
            return Err(JobError::HaloWithoutTiles);
        }
        Ok(())
    }

    /// Validates `options` for a new plan on `plane`: a budget is required; every range of
    /// the refiner's parameters ([`AdaptiveParams::validate`]). Allocates nothing.
    pub fn new(plane: ImagePlane, options: &PlanOptions) -> Result<PlanStart, JobError> {
        if options.budget.is_none() {
            return Err(JobError::Missing {
                param: Param::Budget,
                what: "a new plan needs a sample budget",
                how: "(the total), or the samples per pixel",
            });
        }
        let params = options.params(plane, &AdaptiveParams::renderer_plan())?;
        params
            .validate()
            .map_err(|e| JobError::Plan(ProtocolError::Adaptive(e)))?;
        Ok(PlanStart { plane, params })
    }

    /// The plan's parameters, defaults filled in.
    pub fn params(&self) -> &AdaptiveParams {
        &self.params
    }

    /// The plan's memory from its sizes alone: the larger of its structures at the depth
    /// limit (the basis's `2^(Jx + Jy)` functions, `J = ceil(log2 size) + below_pixel`
    /// per axis, times `PLAN_BYTES_PER_FUNCTION`) beside the base positions, and the last
    /// round's fit of the whole budget by PCG (one channel: a lower bound), as
    /// [`ImageRequest::tree`] estimates it. Refused above the memory limit naming the
    /// budget and the depth limit, before anything is allocated.
    pub fn check_memory(&self) -> Result<(), JobError> {
        let (p, below) = (self.params.tree.p, self.params.quad.below_pixel);
        let budget = self.params.stop.budget as f64;
        let level = |size: usize| {
            ((size.max(1) as f64).log2().ceil() as u32 + below)
                .max(crate::basis::minimum_level(p) + 2)
        };
        let functions =
            2f64.powi(level(self.plane.width()) as i32 + level(self.plane.height()) as i32);
        let structures = ImageRequest {
            pixels: self.plane.pixels() as f64,
            channels: 1,
            samples: 0.0,
            from_file: false,
            // the structures counted as positions of 16 bytes (ImageRequest's unit)
            positions: functions * PLAN_BYTES_PER_FUNCTION / 16.0,
            solve: ImageSolve::None,
            images: 0,
        };
        let fit = ImageRequest::tree(
            (self.plane.width(), self.plane.height()),
            1,
            budget,
            p,
            below,
            self.params.tree.rho,
            false,
            2,
        );
        let request = structures.larger(fit);
        let estimate = request.estimate();
        let limit = memory_limit();
        if estimate.total() > limit as f64 {
            return Err(JobError::PlanTooLarge {
                plane: self.plane,
                budget: self.params.stop.budget,
                functions,
                parts: estimate.parts(),
                needed: estimate.total(),
                limit,
            });
        }
        Ok(())
    }

    /// Starts the plan: the memory checked first ([`PlanStart::check_memory`]), then the
    /// state and the base positions for the seed.
    pub fn run(&self) -> Result<(PlanState, SamplePositions), JobError> {
        self.check_memory()?;
        Ok(PlanState::start(self.plane, &self.params)?)
    }
}

/// One round of a plan on every sample so far (module docs).
#[derive(Debug)]
pub struct PlanRound<'a> {
    state: &'a mut PlanState,
}

/// The samples a round fits ([`PlanRound::gather`]).
#[derive(Clone, Debug)]
pub struct RoundSamples {
    /// Every finite sample so far.
    pub samples: ImageSamples,
    /// The samples dropped for a non-finite value.
    pub dropped: DroppedSamples,
    /// The plan's kept rows these samples continue (finite, dropped, bytes of the file), or
    /// `None`: the kept file is written afresh.
    pub continued: Option<(usize, usize, u64)>,
}

impl<'a> PlanRound<'a> {
    /// Refuses a round of a plan on tiles ([`super::tiled_plan`]) under `policy` unless it
    /// refuses non-finite samples ([`NonFinitePolicy::Refuse`]): the tiled plan's rounds do not
    /// count dropped samples, so it takes no [`NonFinitePolicy::Drop`]. Every front end asks this
    /// before it reads a tiled plan's samples.
    pub fn check_tiled_samples(policy: NonFinitePolicy) -> Result<(), JobError> {
        match policy {
            NonFinitePolicy::Refuse => Ok(()),
            NonFinitePolicy::Drop => Err(JobError::TiledPlanKeepsNonFinite),
        }
    }

    /// Validates a later call's `options` (and the image `plane`, if given) against the plan
    /// in `state`: each option given must be the plan's own ([`PlanState::check_params`]
    /// names the first that differs). Reads no samples.
    pub fn new(
        state: &'a mut PlanState,
        plane: Option<ImagePlane>,
        options: &PlanOptions,
    ) -> Result<PlanRound<'a>, JobError> {
        let plane = plane.unwrap_or(state.plane);
        let params = options.params(plane, &state.params)?;
        state.check_params(plane, &params)?;
        Ok(PlanRound { state })
    }

    /// The image plane of the plan (the samples are read on it).
    pub fn plane(&self) -> ImagePlane {
        self.state.plane
    }

    /// The round on the finite `samples` (the positions handed out so far) whose non-finite
    /// samples were `dropped`: the fit, then the next positions or the stop. On an error the
    /// state is unchanged.
    pub fn run(
        self,
        samples: &ImageSamples,
        dropped: DroppedSamples,
    ) -> Result<PlanStep, JobError> {
        Ok(self.state.advance_dropped(samples, dropped)?)
    }

    /// The samples of every round so far, for a round given only its `new` samples (with
    /// `new_dropped`, the positions of their non-finite samples): refused unless they are the
    /// positions of the last round handed out ([`PlanState::check_new_round`]); then `earlier`
    /// (the samples of the earlier rounds, in the order read) followed by them, the round
    /// [`PlanRound::run`] fits as it would every sample so far given in that order.
    pub fn join_new(
        &self,
        earlier: ReadSamples,
        new: ImageSamples,
        new_dropped: DroppedSamples,
    ) -> Result<(ImageSamples, DroppedSamples), JobError> {
        self.state
            .check_new_round(earlier.rows(), &new, &new_dropped)?;
        Ok(earlier.joined(new, new_dropped)?)
    }

    /// The samples this round fits, from the samples a call was `given` (`given_dropped`:
    /// the positions of their non-finite ones) and the plan's `kept` samples with the bytes of
    /// their file (`PlanState::read_samples`; `None` where not kept or not readable):
    /// with `new_only` the round's new samples joined to the kept ones ([`Self::join_new`],
    /// which refuses them unless the kept rows and they are every position handed out);
    /// otherwise every sample so far as given. [`RoundSamples::continued`] says which kept
    /// rows the samples continue, so the file is appended to instead of written afresh
    /// (`PlanState::keep_samples`).
    pub fn gather(
        &self,
        kept: Option<(ReadSamples, u64)>,
        new_only: bool,
        given: ImageSamples,
        given_dropped: DroppedSamples,
    ) -> Result<RoundSamples, JobError> {
        let counts = |read: &ReadSamples, used: u64| {
            let finite = read.samples.as_ref().map_or(0, |s| s.len());
            (finite, read.dropped.xs.len(), used)
        };
        match (new_only, kept) {
            (true, kept) => {
                let (read, used) = kept.unwrap_or_default();
                let continued = (read.rows() > 0).then(|| counts(&read, used));
                let (samples, dropped) = self.join_new(read, given, given_dropped)?;
                Ok(RoundSamples {
                    samples,
                    dropped,
                    continued,
                })
            }
            (false, kept) => {
                let continued = kept
                    .filter(|(read, _)| read.rows() > 0 && read.starts(&given, &given_dropped))
                    .map(|(read, used)| counts(&read, used));
                Ok(RoundSamples {
                    samples: given,
                    dropped: given_dropped,
                    continued,
                })
            }
        }
    }

    /// What a round's `step` decided for the caller of a plan with parameters `params`, in
    /// words, for every front end to print (the command line) or warn (Python): the coverage
    /// rule's fill, the samples dropped, a solver other than the plan's, a carried solver
    /// state not continued, a ridge added to a singular normal matrix, and with a pixel share
    /// `q > 0` how many of the next positions it gave to the pixels (none above a budget of
    /// [`crate::image::adaptive::SHARE_MAX_SPP`] samples a pixel, where the base slots are not
    /// the pixels or where no pixel's samples spread: [`GrowthParams::pixel_share`]).
    pub fn notes(params: &AdaptiveParams, step: &PlanStep) -> Vec<String> {
        let mut notes: Vec<String> = step.log.coverage.iter().cloned().collect();
        notes.extend(step.dropped.note());
        notes.extend(
            [
                &step.solver_note,
                &step.gram_note,
                &step.pcg_note,
                &step.samples_note,
            ]
            .into_iter()
            .flatten()
            .cloned(),
        );
        if step.log.fit.ridge > 0.0 {
            notes.push(format!(
                "the normal matrix was numerically singular: a relative ridge {:.0e} was added",
                step.log.fit.ridge
            ));
        }
        let share = params.growth.pixel_share;
        if share > 0.0 && step.next_positions > 0 {
            notes.push(match step.log.pixel_spread {
                0 => format!(
                    "pixel share {share}: none of the {} next positions went to the pixels by \
                     their spread (the share applies at budgets of at most {} samples a pixel, \
                     where the base slots are the pixels and some pixel's samples spread): the \
                     tree alone placed them",
                    step.next_positions,
                    crate::image::adaptive::SHARE_MAX_SPP
                ),
                n => format!(
                    "pixel share {share}: {n} of the {} next positions went to the pixels by \
                     the spread of their own samples, the rest by the tree's marking",
                    step.next_positions
                ),
            });
        }
        notes
    }
}

/// The final image of a plan (module docs): validated against what the caller asked for,
/// then [`PlanFinal::run`].
///
/// Every front end's final image is [`PlanFinal::run`]. For the samples of the round that
/// stopped the plan it is the output pixels of that round's fit (under an iterative solver
/// continued to the solver's tolerance) with that round's noise estimate, carried in the
/// state ([`crate::image::plan::FinalFit`]): no second solve, and the in-process loop's
/// image. When the caller hands the stopping round over ([`PlanFinal::run`]'s `stopping`),
/// the image that round made from the same fit is used as it is. So `plan --final-image`,
/// `reconstruct --dim 2 --state` and `Plan.image()` are the same pixels. For the samples of
/// an earlier round, or when the carried fit is missing or is not of these samples (a note
/// says so, [`PlanReconstruction::fit_note`]), the samples are fitted on their tree from the
/// solver state the plan carries.
#[derive(Debug)]
pub struct PlanFinal<'a> {
    state: &'a PlanState,
    estimate: PixelEstimate,
    unused: Vec<Param>,
    p: Option<usize>,
}

impl<'a> PlanFinal<'a> {
    /// Validates a final image of the plan in `state`: the image `plane` if given must be the
    /// plan's; the uniform path's parameters (`pixels`, `rho`, the ridge, the smoothing, and
    /// in `asked.also_asked` the tiles) are refused (the plan's tree and its own parameters
    /// make the image); a `p`, family or method that the plan's tree overrides are kept for
    /// the notes ([`PlanFinal::notes`]). `fit_only`: the fit's box pixels alone instead of
    /// the plan's output pixels.
    pub fn new(
        state: &'a PlanState,
        plane: Option<ImagePlane>,
        asked: &ImageParams,
        fit_only: bool,
    ) -> Result<PlanFinal<'a>, JobError> {
        PlanFinal::check_request(asked)?;
        if let Some(given) = plane.filter(|&g| g != state.plane) {
            return Err(JobError::OtherPlane {
                given,
                plan: state.plane,
            });
        }
        let unused = [Param::Family, Param::Method]
            .into_iter()
            .filter(|p| asked.also_asked.contains(p))
            .collect();
        Ok(PlanFinal {
            state,
            estimate: if fit_only {
                PixelEstimate::FitOnly
            } else {
                state.params.output.pixels
            },
            unused,
            p: asked.fit.p.filter(|&p| p != state.params.tree.p),
        })
    }

    /// The refusals of [`PlanFinal::new`] that need no state (call it before reading one):
    /// the uniform path's parameters.
    pub fn check_request(asked: &ImageParams) -> Result<(), JobError> {
        if asked.pixels.is_some() {
            return Err(JobError::Conflict {
                first: Param::Pixels,
                second: Param::State,
                reason: "is for the uniform path: a plan's final image is its own output \
                         pixels (or the fit alone, with the fit-only choice)",
            });
        }
        let uniform = [
            (Param::Rho, asked.fit.rho.is_some()),
            (Param::Ridge, asked.fit.ridge.is_some()),
            (Param::Smoothing, asked.fit.smoothing.is_some()),
            (Param::Tile, asked.also_asked.contains(&Param::Tile)),
            (Param::Halo, asked.also_asked.contains(&Param::Halo)),
            (Param::Workers, asked.also_asked.contains(&Param::Workers)),
        ];
        if let Some((param, _)) = uniform.iter().find(|(_, given)| *given) {
            return Err(JobError::Conflict {
                first: *param,
                second: Param::State,
                reason: "is for the uniform fit: with a plan's state the plan's tree and its \
                         own parameters are used",
            });
        }
        Ok(())
    }

    /// The final image of a plan with nothing asked beyond the plan's own (Python's
    /// `Plan.image()`, `rkwave plan --final-image`).
    pub fn of(state: &'a PlanState, fit_only: bool) -> PlanFinal<'a> {
        PlanFinal::new(state, None, &ImageParams::default(), fit_only)
            .expect("nothing asked: nothing to refuse")
    }

    /// The output pixels made.
    pub fn estimate(&self) -> PixelEstimate {
        self.estimate
    }

    /// What was asked for and not used, each said in a note (the plan fixes the basis and the
    /// solve); format them where the parameters are spelled for the reader.
    pub fn notes(&self) -> Vec<String> {
        let mut notes = Vec::new();
        if let Some(p) = self.p {
            notes.push(format!(
                "p = {} from the plan's tree ({} {p} is not used with {})",
                self.state.params.tree.p,
                Fix::Set(Param::P),
                Fix::Set(Param::State)
            ));
        }
        for param in &self.unused {
            notes.push(format!(
                "{} is not used: the plan's tree fixes the basis and fits by its own least \
                 squares",
                Fix::Set(*param)
            ));
        }
        notes
    }

    /// The final image of the finite `samples` of the plan's rounds `0..=k` (for some `k`)
    /// whose non-finite samples were `dropped`, and `stopping`: the step of the round that
    /// stopped the plan on these samples, when the caller has it (its image is this image bit
    /// for bit: type docs).
    pub fn run(
        &self,
        samples: &ImageSamples,
        dropped: DroppedSamples,
        stopping: Option<&PlanStep>,
    ) -> Result<PlanReconstruction, JobError> {
        let reusable = stopping
            .and_then(|s| s.reconstruction.as_deref())
            .filter(|done| {
                self.estimate == self.state.params.output.pixels
                    && samples.len() == done.fit.report.samples
            });
        if let Some(done) = reusable {
            return Ok(done.clone());
        }
        Ok(self
            .state
            .reconstruct_dropped(samples, dropped, self.estimate)?)
    }
}
