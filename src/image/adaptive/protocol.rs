//! The renderer in the loop: the refiner's rounds driven through files.
//!
//! A renderer is not in the process, so the rounds of [`ImagePlan`] are split at the oracle
//! calls. The plan's state between calls is a [`PlanState`]: the plane, the parameters, the
//! refinement history ([`PlanProgress`]: the cells marked per round) and a record of every
//! position it handed out. A call
//!
//! 1. *starts* a plan ([`PlanState::start`]): the base positions for the seed;
//! 2. *advances* it ([`PlanState::advance`]) with every sample so far (positions as handed out,
//!    values rendered): the round's fit on the tree, then the next positions or the stop;
//! 3. *reconstructs* ([`PlanState::reconstruct`]) on the tree the samples were planned for:
//!    the fit, and the output pixels ([`super::correction`]: by default the fit's box pixels
//!    plus the significant mean residual, with the noise estimate of the same fit and the
//!    plan's `z`).
//!
//! Driven with the positions as handed out (in order, as `f64`), this is the in-process loop
//! [`super::refine_image`] step for step: the same tree, the same fits, the same pixels
//! (`tests/image_adaptive_protocol.rs`).
//!
//! *Which samples.* The plan recognises its positions by a fingerprint of the multiset
//! `F = sum_i h(x_i, y_i) mod 2^64` (`h` a 64-bit mix of the coordinates' bits; order-free, so
//! a renderer may return samples in any order) and the count, recorded per round
//! cumulatively. Samples from another run, another seed, a lost or repeated round, or
//! positions rounded on the way (`float32`) do not match and are refused, naming the round
//! the plan expects; the samples of an earlier round are recognised as such.
//!
//! *Non-finite radiance.* Samples whose value is NaN or infinite are split off before a call
//! ([`crate::image::nonfinite`]); under the drop policy their positions still count in the
//! fingerprint (the sum over kept and dropped positions is the sum over all), so the round is
//! recognised and fitted on the finite samples, and the drop is reported
//! ([`PlanStep::dropped`]). A refused round changes nothing: the state is only written when a
//! call succeeds, so the same round can be answered again.
//!
//! The state is JSON with a format name and version ([`STATE_FORMAT`], [`STATE_VERSION`]);
//! a state of another format or version, or one whose history does not fit its own
//! parameters, is refused.
//!
//! *Work carried between calls.* Beside the state, `gram.bin` ([`GRAM_FILE`]) holds the
//! normal matrix `G = K_T^T K_T` of the last round's fit ([`TreeGram::to_bytes`]), so the next
//! call continues it with the new samples' rows instead of summing every sample again
//! ([`super::gram`]: the continued matrix is the rebuilt one bit for bit, so the rounds are
//! the same with or without it). It is a cache: tagged with the plan ([`PlanState::tag`]:
//! plane and parameters) and checksummed; a missing file is assembled afresh silently (the
//! first fit), a damaged one, one of another plan, or one whose samples are not the first of
//! the call's is assembled afresh with a note ([`PlanStep::gram_note`]). Under PCG (the
//! renderer plan's default), `pcg.bin` ([`PCG_FILE`], [`CarriedPcg`], tagged and checksummed
//! the same way) holds the last round's coefficients, image and probe channels, as the next
//! round's start and its exact diagonal `G_aa` with a hash of the samples summed, continued
//! when they are the first of the call's in order: the calls are then the in-process loop's
//! rounds bit for bit; without it (missing, damaged: a note, [`PlanStep::pcg_note`]) a round
//! starts from zero and reaches the same tolerance. A process that keeps the state in memory
//! (Python's `Plan`) carries both without the files.
//!
//! *Memory.* A fit whose assembled solve (the direct one) would exceed the memory limit is
//! fitted by matrix-free PCG instead, with a note ([`PlanStep::solver_note`]); only a fit that
//! does not fit under PCG either is refused.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::correction::{output_pixels, PixelEstimate, ResidualCorrection};
use super::fit::{FitState, TreeFit};
use super::gram::TreeGram;
use super::mix64;
use super::pcg::TreeSolver;
use super::refiner::{
    AdaptiveParams, Decision, ImagePlan, ImageRound, PlanProgress, SamplePositions,
};
use super::solver::{fallback_note, fitting_solver};
use super::AdaptiveError;
use crate::adaptive::QuadTree;
use crate::adaptive::StopReason;
use crate::image::{DroppedSamples, ImagePlane, ImageSamples, PixelImage};
use crate::io::output::OutputError;

/// The `format` field of a plan state.
pub const STATE_FORMAT: &str = "rkwave-image-plan";
/// The version of the state layout this build reads and writes.
pub const STATE_VERSION: u32 = 1;
/// The state's file name inside its directory.
pub const STATE_FILE: &str = "state.json";
/// The carried normal matrix's file name inside the state's directory (module docs).
pub const GRAM_FILE: &str = "gram.bin";
/// The carried PCG start's file name inside the state's directory (module docs).
pub const PCG_FILE: &str = "pcg.bin";

mod files;

pub use super::gram::CarriedGram;
pub use super::pcg::CarriedPcg;

/// Why a protocol call was refused.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum ProtocolError {
    /// The refiner (parameters, solve).
    #[error(transparent)]
    Adaptive(#[from] AdaptiveError),
    /// The samples do not lie on the state's image plane.
    #[error(
        "the samples lie on a {given} image but the plan is for {state}: use the samples of \
         this plan or another state"
    )]
    Plane {
        /// The plan's plane.
        state: ImagePlane,
        /// The samples' plane.
        given: ImagePlane,
    },
    /// The samples are not the positions the plan handed out.
    #[error(
        "the {given} samples are not the positions this plan handed out (it expects the \
         {expected} positions of rounds 0..={round}, as written, in float64): they come from \
         another run, miss a round or were moved; pass every sample of this plan, or start a \
         new state"
    )]
    Mismatch {
        /// Samples given.
        given: usize,
        /// Positions handed out so far.
        expected: usize,
        /// The last round handed out.
        round: usize,
    },
    /// The samples are those of an earlier round: that round was planned already.
    #[error(
        "the {given} samples are the positions of rounds 0..={matched}, which this plan has \
         advanced past: it handed out round {round} ({expected} positions in all); render \
         those too and pass every sample"
    )]
    AlreadyPlanned {
        /// Samples given.
        given: usize,
        /// The round they complete.
        matched: usize,
        /// The last round handed out.
        round: usize,
        /// Positions handed out so far.
        expected: usize,
    },
    /// The samples' channels differ from earlier calls.
    #[error(
        "the samples have {given} channels but earlier rounds had {state}: render the same \
         channels every round"
    )]
    Channels {
        /// Channels of earlier rounds.
        state: usize,
        /// Channels given.
        given: usize,
    },
    /// A parameter differs from the one the state was planned with.
    #[error(
        "the plan in this state was made with {parameter} = {state}, this call gives \
         {given}: pass the same parameters on every call, or start a new state"
    )]
    OtherParameters {
        /// The parameter.
        parameter: String,
        /// The state's value.
        state: String,
        /// The value given.
        given: String,
    },
    /// The state file is not a plan state this build reads.
    #[error("{}: not a plan state ({problem}): start a new state", .file.display())]
    State {
        /// The file.
        file: PathBuf,
        /// What is wrong.
        problem: String,
    },
    /// The state file could not be read.
    #[error("cannot read the plan state {}: {source}", .file.display())]
    Read {
        /// The file.
        file: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The state could not be written.
    #[error(transparent)]
    Write(#[from] OutputError),
}

/// Positions handed out, cumulative up to one round.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct IssuedRound {
    /// The round whose positions these are (0: the base).
    pub round: usize,
    /// Positions of this round.
    pub positions: usize,
    /// Positions of rounds `0..=round`.
    pub total: usize,
    /// Fingerprint of the positions of rounds `0..=round` (hex).
    pub fingerprint: String,
}

/// A plan between calls: everything [`ImagePlan::resume`] needs and the record of the
/// positions handed out.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlanState {
    /// Always [`STATE_FORMAT`].
    pub format: String,
    /// Always [`STATE_VERSION`] when written by this build.
    pub version: u32,
    /// The image plane.
    pub plane: ImagePlane,
    /// The refiner's parameters (seed and budget included).
    pub params: AdaptiveParams,
    /// Channels of the samples (`None` before the first samples).
    pub channels: Option<usize>,
    /// The refinement history.
    pub progress: PlanProgress,
    /// Positions handed out, per round.
    pub issued: Vec<IssuedRound>,
    /// Why the plan stopped (`None` while it runs).
    pub stop: Option<StopReason>,
    /// The last fit's normal matrix, continued by the next round (module docs; kept in
    /// [`GRAM_FILE`], not in the JSON).
    #[serde(skip)]
    pub carried: CarriedGram,
    /// The last round's PCG start and diagonal (module docs; kept in [`PCG_FILE`]).
    #[serde(skip)]
    pub pcg: CarriedPcg,
}

/// What one call of [`PlanState::advance`] did.
#[derive(Clone, Debug, Serialize)]
pub struct PlanStep {
    /// The round's log (its fit on the samples given).
    pub log: ImageRound,
    /// Positions to render next (empty when the plan stopped).
    #[serde(skip)]
    pub next: SamplePositions,
    /// Number of positions to render next.
    pub next_positions: usize,
    /// The round those positions belong to (`None` when the plan stopped).
    pub next_round: Option<usize>,
    /// Why the plan stopped (`None`: render the next positions and call again).
    pub stop: Option<StopReason>,
    /// Positions handed out in all, including the next ones.
    pub total_positions: usize,
    /// The budget.
    pub budget: usize,
    /// The samples dropped for a non-finite value (none unless the caller's policy drops).
    pub dropped: DroppedSamples,
    /// Why the normal matrix carried from the last call was not continued and the round's was
    /// assembled afresh (`None`: continued, or the first fit).
    pub gram_note: Option<String>,
    /// Why PCG's start carried from the last call was not used, or its diagonal not continued
    /// (`None`: used, or there was none).
    pub pcg_note: Option<String>,
    /// Why this round was fitted by another solver than the plan's (the direct solve would
    /// not fit in memory; `None`: the plan's solver).
    pub solver_note: Option<String>,
    /// When this round stopped the plan: the final reconstruction from its fit, with the
    /// plan's output pixels, without fitting the samples again (under the direct solve, the
    /// default, bit for bit [`PlanState::reconstruct`] of the same samples; under an
    /// iterative solve, the stopping round's fit continued to the solver's tolerance);
    /// `None` otherwise.
    #[serde(skip)]
    pub reconstruction: Option<Box<PlanReconstruction>>,
}

/// A reconstruction on the tree a plan built.
#[derive(Clone, Debug)]
pub struct PlanReconstruction {
    /// The tree the samples were planned for.
    pub tree: QuadTree,
    /// The fit on it.
    pub fit: TreeFit,
    /// The fit's box pixels alone.
    pub fit_image: PixelImage,
    /// The output pixels (by the estimate asked for; by default the fit's box pixels plus
    /// the significant mean residual).
    pub image: PixelImage,
    /// What the residual correction did.
    pub correction: ResidualCorrection,
    /// The last round of the samples.
    pub round: usize,
    /// Whether the plan has stopped at that round (the samples are the final set).
    pub complete: bool,
    /// The samples dropped for a non-finite value (none unless the caller's policy drops).
    pub dropped: DroppedSamples,
    /// Why the fit used another solver than the plan's (the direct solve would not fit in
    /// memory; `None`: the plan's solver).
    pub solver_note: Option<String>,
}

/// The order-free fingerprint `sum_i h(x_i, y_i) mod 2^64` of positions, added to `start`.
fn fingerprint(start: u64, xs: &[f64], ys: &[f64]) -> u64 {
    xs.iter().zip(ys).fold(start, |acc, (x, y)| {
        acc.wrapping_add(mix64(x.to_bits() ^ mix64(y.to_bits()).rotate_left(17)))
    })
}

fn parse_hex(s: &str) -> Option<u64> {
    u64::from_str_radix(s, 16).ok()
}

impl PlanState {
    /// Starts a plan: the state and the base positions for the seed.
    pub fn start(
        plane: ImagePlane,
        params: &AdaptiveParams,
    ) -> Result<(Self, SamplePositions), ProtocolError> {
        let plan = ImagePlan::new(plane, params)?;
        let base = plan.base_positions();
        let state = Self {
            format: STATE_FORMAT.into(),
            version: STATE_VERSION,
            plane,
            params: *params,
            channels: None,
            progress: plan.progress().clone(),
            issued: vec![IssuedRound {
                round: 0,
                positions: base.len(),
                total: base.len(),
                fingerprint: format!("{:016x}", fingerprint(0, &base.xs, &base.ys)),
            }],
            stop: None,
            carried: CarriedGram::default(),
            pcg: CarriedPcg::default(),
        };
        Ok((state, base))
    }

    /// Refuses `plane` and `params` unless they are the state's (each parameter compared by
    /// its serialised value; the first that differs is named).
    pub fn check_params(
        &self,
        plane: ImagePlane,
        params: &AdaptiveParams,
    ) -> Result<(), ProtocolError> {
        if plane != self.plane {
            return Err(ProtocolError::OtherParameters {
                parameter: "resolution".into(),
                state: self.plane.to_string(),
                given: plane.to_string(),
            });
        }
        let ours = serde_json::to_value(self.params).expect("parameters serialise");
        let theirs = serde_json::to_value(params).expect("parameters serialise");
        if let (Some(a), Some(b)) = (ours.as_object(), theirs.as_object()) {
            for (key, value) in a {
                let other = b.get(key).cloned().unwrap_or_default();
                if *value != other {
                    return Err(ProtocolError::OtherParameters {
                        parameter: key.clone(),
                        state: value.to_string(),
                        given: other.to_string(),
                    });
                }
            }
        }
        Ok(())
    }

    /// The last round handed out.
    pub fn round(&self) -> usize {
        self.issued.last().map_or(0, |r| r.round)
    }

    /// Positions handed out so far.
    pub fn positions(&self) -> usize {
        self.issued.last().map_or(0, |r| r.total)
    }

    /// The index into [`PlanState::issued`] whose positions are exactly those of `samples`
    /// and `dropped` together.
    fn matching_round(
        &self,
        samples: &ImageSamples,
        dropped: &DroppedSamples,
    ) -> Result<usize, ProtocolError> {
        if samples.plane() != self.plane {
            return Err(ProtocolError::Plane {
                state: self.plane,
                given: samples.plane(),
            });
        }
        if let Some(c) = self.channels {
            if c != samples.channels() {
                return Err(ProtocolError::Channels {
                    state: c,
                    given: samples.channels(),
                });
            }
        }
        let f = fingerprint(
            fingerprint(0, samples.xs(), samples.ys()),
            &dropped.xs,
            &dropped.ys,
        );
        let given = samples.len() + dropped.xs.len();
        let found = self
            .issued
            .iter()
            .position(|r| r.total == given && parse_hex(&r.fingerprint) == Some(f));
        let last = self.issued.len() - 1;
        match found {
            Some(k) => Ok(k),
            None => Err(ProtocolError::Mismatch {
                given,
                expected: self.positions(),
                round: last,
            }),
        }
    }

    /// The plan as of round `k` (the tree after the markings of rounds `1..=k`), fitting by
    /// `solver`.
    fn plan_at(&self, k: usize, solver: TreeSolver) -> Result<ImagePlan, ProtocolError> {
        let mut params = self.params;
        params.fit.solver = solver;
        let progress = if k == self.progress.marked.len() {
            self.progress.clone()
        } else {
            PlanProgress {
                marked: self.progress.marked[..k].to_vec(),
                samples_fitted: 0,
            }
        };
        ImagePlan::resume(self.plane, &params, progress).map_err(|e| match e {
            AdaptiveError::History { .. } => ProtocolError::State {
                file: PathBuf::from(STATE_FILE),
                problem: e.to_string(),
            },
            e => e.into(),
        })
    }

    /// The plan as of round `k` fitting by the plan's solver, or by PCG when the direct fit
    /// of `samples` would not fit in memory (with the note saying so); refused, before the
    /// fit, when the fit, the output image and the `next` positions it may hand out exceed
    /// the memory limit under PCG too ([`fitting_solver`]): the tree has at most the base
    /// levels plus one per round, up to the depth limit.
    fn fitting_plan(
        &self,
        k: usize,
        samples: &ImageSamples,
        next: usize,
    ) -> Result<(ImagePlan, Option<String>), ProtocolError> {
        use crate::resources::tree_levels;
        let plan = self.plan_at(k, self.params.fit.solver)?;
        let p = self.params.tree.p;
        let limit = tree_levels(p, self.plane.width(), self.plane.height(), {
            self.params.quad.below_pixel
        });
        let levels = (plan.base_steps() + plan.progress().marked.len() as u32 + 1).min(limit);
        let sizes = (samples.len(), samples.channels(), next);
        let (solver, note) = fitting_solver(
            self.params.fit.solver,
            self.plane,
            (p, levels, self.params.tree.rho),
            sizes,
        )
        .map_err(|e| ProtocolError::Adaptive(e.into()))?;
        if solver == self.params.fit.solver {
            return Ok((plan, None));
        }
        Ok((self.plan_at(k, solver)?, note))
    }

    /// PCG's carried start and diagonal put into `plan` ([`CarriedPcg::offer`]); the note
    /// of what was set aside.
    fn offer_pcg(&self, plan: &mut ImagePlan, samples: &ImageSamples) -> Option<String> {
        let (start, diagonal, note) = self.pcg.offer(samples.xs(), samples.ys());
        plan.fit_state_mut().diagonal = diagonal;
        *plan.start_mut() = start;
        note
    }

    /// Checks the state's own consistency: format, version, one issued record per round.
    fn check_layout(&self, file: &Path) -> Result<(), ProtocolError> {
        let bad = |problem: String| ProtocolError::State {
            file: file.to_path_buf(),
            problem,
        };
        if self.format != STATE_FORMAT {
            return Err(bad(format!(
                "format `{}`, expected `{STATE_FORMAT}`",
                self.format
            )));
        }
        if self.version != STATE_VERSION {
            return Err(bad(format!(
                "version {}, this build reads version {STATE_VERSION}",
                self.version
            )));
        }
        if self.issued.len() != self.progress.marked.len() + 1
            || self.issued.iter().enumerate().any(|(i, r)| r.round != i)
            || self
                .issued
                .iter()
                .any(|r| parse_hex(&r.fingerprint).is_none())
        {
            return Err(bad(format!(
                "{} records of handed-out positions for {} rounds",
                self.issued.len(),
                self.progress.marked.len() + 1
            )));
        }
        Ok(())
    }

    /// One round on every sample so far: the fit on the tree, then the next positions (recorded
    /// as handed out) or the stop. The samples must be the positions handed out so far.
    pub fn advance(&mut self, samples: &ImageSamples) -> Result<PlanStep, ProtocolError> {
        self.advance_dropped(samples, DroppedSamples::default())
    }

    /// [`PlanState::advance`] on the finite `samples` of a round whose non-finite samples
    /// were `dropped` (their positions complete the round; module docs). On an error the
    /// state is unchanged.
    pub fn advance_dropped(
        &mut self,
        samples: &ImageSamples,
        dropped: DroppedSamples,
    ) -> Result<PlanStep, ProtocolError> {
        let k = self.matching_round(samples, &dropped)?;
        let last = self.issued.len() - 1;
        if k < last {
            return Err(ProtocolError::AlreadyPlanned {
                given: samples.len() + dropped.xs.len(),
                matched: k,
                round: last,
                expected: self.positions(),
            });
        }
        let next = self.params.stop.budget.saturating_sub(self.positions());
        let (mut plan, mut solver_note) = self.fitting_plan(k, samples, next)?;
        let values: Vec<&[f64]> = samples.values().iter().map(|v| v.as_slice()).collect();
        let carried = self.carried.gram.take();
        let mut gram_note = self.carried.note.take();
        let offered = carried.as_ref().map(TreeGram::samples);
        plan.fit_state_mut().gram = carried;
        let mut pcg_note = self.offer_pcg(&mut plan, samples);
        let mut stepped = plan.step(samples.xs(), samples.ys(), &values);
        if let Err(AdaptiveError::Resource(e)) = &stepped {
            // the fit's own, finer estimate refused the direct solve: PCG instead
            if !matches!(plan.params().fit.solver, TreeSolver::Pcg { .. }) {
                solver_note = Some(fallback_note(e));
                plan = self.plan_at(k, TreeSolver::plan_pcg())?;
                pcg_note = self.offer_pcg(&mut plan, samples);
                stepped = plan.step(samples.xs(), samples.ys(), &values);
            }
        }
        self.carried.gram = plan.fit_state_mut().gram.take();
        self.pcg = CarriedPcg {
            start: plan.start_mut().take(),
            diagonal: plan.fit_state_mut().diagonal.take(),
            note: None,
        };
        let round = stepped?;
        let direct = round.log.fit.solver == "direct";
        if let Some(m) = offered.filter(|_| direct && round.log.fit.normal_kept_samples == 0) {
            gram_note.get_or_insert(format!(
                "the carried normal matrix ({m} samples) was not continued: the samples do not \
                 start with its samples in the same order, or the tree lost functions; \
                 assembled afresh"
            ));
        }
        // A stopping round's fit is the final fit (the tree is unchanged by the stop): its
        // output pixels are those `reconstruct` would compute again from the same samples.
        let reconstruction = match round.decision {
            Decision::Stop(_) => {
                let sigma = round.log.noise.as_ref().map_or(0.0, |n| n.sigma);
                let (fit_image, image, correction) = output_pixels(
                    plan.tree(),
                    &round.fit,
                    samples.xs(),
                    samples.ys(),
                    samples.values(),
                    self.params.output.pixels,
                    sigma,
                    self.params.output.residual_z,
                )?;
                Some(Box::new(PlanReconstruction {
                    tree: plan.tree().clone(),
                    fit: round.fit,
                    fit_image,
                    image,
                    correction,
                    round: k,
                    complete: true,
                    dropped: dropped.clone(),
                    solver_note: solver_note.clone(),
                }))
            }
            Decision::Sample(_) => None,
        };
        self.channels = Some(samples.channels());
        let (next, next_round, stop) = match round.decision {
            Decision::Sample(next) => {
                let prev = self.issued[last].clone();
                let start = parse_hex(&prev.fingerprint).expect("checked when loaded");
                self.issued.push(IssuedRound {
                    round: last + 1,
                    positions: next.len(),
                    total: prev.total + next.len(),
                    fingerprint: format!("{:016x}", fingerprint(start, &next.xs, &next.ys)),
                });
                self.progress = plan.progress().clone();
                (next, Some(last + 1), None)
            }
            Decision::Stop(stop) => {
                self.stop = Some(stop);
                (SamplePositions::default(), None, Some(stop))
            }
        };
        Ok(PlanStep {
            log: round.log,
            next_positions: next.len(),
            next,
            next_round,
            stop,
            total_positions: self.positions(),
            budget: self.params.stop.budget,
            dropped,
            gram_note,
            pcg_note,
            solver_note,
            reconstruction,
        })
    }

    /// The fit of `samples` (the positions of rounds `0..=k` handed out by this plan, for some
    /// `k`) on the tree they were planned for: after the markings of rounds `1..=k`, and the
    /// output pixels the plan's parameters ask for ([`AdaptiveParams::pixels`]). With the
    /// samples of the round at which the plan stopped, this is the in-process loop's result.
    pub fn reconstruct(&self, samples: &ImageSamples) -> Result<PlanReconstruction, ProtocolError> {
        self.reconstruct_as(samples, self.params.output.pixels)
    }

    /// [`PlanState::reconstruct`] with the output pixels `estimate` instead of the plan's
    /// (the fit, its noise estimate and `z` are the plan's: the rounds do not depend on it).
    pub fn reconstruct_as(
        &self,
        samples: &ImageSamples,
        estimate: PixelEstimate,
    ) -> Result<PlanReconstruction, ProtocolError> {
        self.reconstruct_dropped(samples, DroppedSamples::default(), estimate)
    }

    /// [`PlanState::reconstruct_as`] on the finite `samples` of rounds whose non-finite
    /// samples were `dropped` (module docs).
    pub fn reconstruct_dropped(
        &self,
        samples: &ImageSamples,
        dropped: DroppedSamples,
        estimate: PixelEstimate,
    ) -> Result<PlanReconstruction, ProtocolError> {
        let k = self.matching_round(samples, &dropped)?;
        let (mut plan, solver_note) = self.fitting_plan(k, samples, 0)?;
        let values: Vec<&[f64]> = samples.values().iter().map(|v| v.as_slice()).collect();
        // the carried normal matrix, continued (the same bits as assembled afresh), and
        // PCG's carried start and diagonal
        self.offer_pcg(&mut plan, samples);
        let start = plan.start_mut().take();
        let mut carried = FitState {
            gram: self.carried.gram.clone(),
            diagonal: plan.fit_state_mut().diagonal.take(),
            ..FitState::default()
        };
        let (fit, significance) = plan.fit_updating(
            samples.xs(),
            samples.ys(),
            &values,
            plan.params().fit.solver,
            start.as_deref(),
            &mut carried,
        )?;
        // the noise estimate of this fit, as the in-process loop's last round
        let sigma = significance.map_or(0.0, |s| s.level.sigma);
        let (fit_image, image, correction) = output_pixels(
            plan.tree(),
            &fit,
            samples.xs(),
            samples.ys(),
            samples.values(),
            estimate,
            sigma,
            self.params.output.residual_z,
        )?;
        Ok(PlanReconstruction {
            tree: plan.tree().clone(),
            fit,
            fit_image,
            image,
            correction,
            round: k,
            complete: self.stop.is_some() && k + 1 == self.issued.len(),
            dropped,
            solver_note,
        })
    }
}

impl ProtocolError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            ProtocolError::Adaptive(e) => e.kind(),
            ProtocolError::Plane { .. }
            | ProtocolError::Mismatch { .. }
            | ProtocolError::Channels { .. }
            | ProtocolError::OtherParameters { .. }
            | ProtocolError::State { .. } => crate::error::ErrorKind::InvalidInput,
            ProtocolError::AlreadyPlanned { .. } => crate::error::ErrorKind::OutputRefused,
            ProtocolError::Read { .. } => crate::error::ErrorKind::Unreadable,
            ProtocolError::Write(e) => e.kind(),
        }
    }
}

crate::error::classified!(ProtocolError);
