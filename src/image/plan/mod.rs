//! The plan's state machine: the adaptive refiner's rounds with the renderer outside the
//! process, between calls.
//!
//! A renderer is not in the process, so the rounds of `ImagePlan` are split at the oracle
//! calls. The plan's state between calls is a [`PlanState`]: the plane, the parameters, the
//! refinement history ([`PlanProgress`]: the cells marked per round) and a record of every
//! position it handed out. A call
//!
//! 1. *starts* a plan ([`PlanState::start`]): the base positions for the seed;
//! 2. *advances* it ([`PlanState::advance`]) with every sample so far (positions as handed out,
//!    values rendered): the round's fit on the tree, then the next positions or the stop; a
//!    caller that keeps no samples gives only the last round's, joined to the samples the
//!    plan has read ([`new_round::ReadSamples`], [`PlanState::check_new_round`]: the same round bit for
//!    bit);
//! 3. *reconstructs* ([`PlanState::reconstruct`]) on the tree the samples were planned for:
//!    the fit, and the output pixels ([`crate::image::adaptive::correction`]: by default the fit's box pixels
//!    plus the significant mean residual, with the noise estimate of the same fit and the
//!    plan's `z`).
//!
//! Driven with the positions as handed out (in order, as `f64`), this is the in-process loop
//! [`crate::image::adaptive::refine_image`] step for step: the same tree, the same fits, the same pixels
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
//! *Work carried between calls.* Beside the state, `gram.bin` holds the
//! normal matrix `G = K_T^T K_T` of the last round's fit ([`TreeGram::to_bytes`]), so the next
//! call continues it with the new samples' rows instead of summing every sample again
//! ([`crate::image::adaptive::gram`]: the continued matrix is the rebuilt one bit for bit, so the rounds are
//! the same with or without it). It is a cache: tagged with the plan ([`PlanState::tag`]:
//! plane and parameters) and checksummed; a missing file is assembled afresh silently (the
//! first fit), a damaged one, one of another plan, or one whose samples are not the first of
//! the call's is assembled afresh with a note ([`PlanStep::gram_note`]). Under PCG (the
//! renderer plan's default), `pcg.bin` ([`CarriedPcg`], tagged and checksummed
//! the same way) holds the last round's coefficients, image and probe channels, as the next
//! round's start and its exact diagonal `G_aa` with a hash of the samples summed, continued
//! when they are the first of the call's in order: the calls are then the in-process loop's
//! rounds bit for bit; without it (missing, damaged: a note, [`PlanStep::pcg_note`]) a round
//! starts from zero and reaches the same tolerance. The round that stops the plan leaves its
//! fit in `final.bin` ([`FinalFit`]: coefficients continued to the solver's tolerance, the
//! noise estimate, a fingerprint of the samples), from which every final image of those
//! samples is made without a second solve ([`PlanState::reconstruct`]; missing, damaged or
//! other samples: fitted again, [`PlanReconstruction::fit_note`]). While the plan runs,
//! `rows.bin` ([`CarriedRows`]) holds the single-scale rows `E` of the samples fitted, a
//! piece appended per call, so a call evaluates only its new samples' rows (the rows read
//! back are the evaluated ones bit for bit; missing after fitted rounds, damaged or of other
//! positions: evaluated afresh with a note in [`PlanStep::pcg_note`]). A process that keeps
//! the state in memory (Python's `Plan`) carries all of them without the files.
//!
//! *Memory.* A fit whose assembled solve (the direct one) would exceed the memory limit is
//! fitted by matrix-free PCG instead, with a note ([`PlanStep::solver_note`]); only a fit that
//! does not fit under PCG either is refused.

//!
//! *Files.* This module knows no paths: the state is JSON text ([`PlanState::to_json`],
//! [`PlanState::from_json`]) and the carried solver state is bytes ([`TreeGram::to_bytes`],
//! [`CarriedPcg::to_bytes`]); `io::plan_files` reads and writes them in the plan's
//! folder (`state.json`, `gram.bin`, `pcg.bin`, `final.bin`, `rows.bin`, and `samples.bin`, the samples
//! read, [`new_round::ReadSamples::piece_bytes`]) and commits a round (the state and the positions, both
//! or neither).
//!
//! *Why `image::plan`.* The state machine drives the refiner's rounds
//! ([`crate::image::adaptive`]: the tree, its fits, the output pixels) from outside, so it
//! sits beside it, not inside it; the plan's jobs (`image::job`) and the files
//! (`io::plan_files`) sit on top of it, and nothing below calls back into it.

mod carried_rows;
mod final_fit;
pub mod new_round;
mod state;

use std::path::PathBuf;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::adaptive::QuadTree;
use crate::adaptive::StopReason;
use crate::image::adaptive::{
    mix64, AdaptiveError, AdaptiveParams, ImagePlan, ImageRound, PlanProgress, ResidualCorrection,
    SamplePositions, TreeFit,
};
use crate::image::{DroppedSamples, ImagePlane, PixelImage};

/// The `format` field of a plan state.
pub const STATE_FORMAT: &str = "rkwave-image-plan";
/// The version of the state layout this build reads and writes.
pub const STATE_VERSION: u32 = 1;

pub use crate::image::adaptive::gram::{CarriedGram, TreeGram};
pub use crate::image::adaptive::pcg::CarriedPcg;
pub use carried_rows::{CarriedRows, ROWS_FILE};
pub use final_fit::{samples_fingerprint, CarriedFinal, FinalFit};

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
    /// A round given only its new samples, but the samples read before it are not those of
    /// every earlier round.
    #[error(
        "the plan handed out round {round} and holds {held} samples of the earlier rounds, \
         which have {expected}: a round given only its new samples needs every earlier \
         round's; pass every sample so far"
    )]
    EarlierUnknown {
        /// Rows held.
        held: usize,
        /// Rows of the rounds before the last handed out.
        expected: usize,
        /// The last round handed out.
        round: usize,
    },
    /// A round given only its new samples, but the plan has stopped: no round is pending.
    #[error(
        "the plan stopped at round {round}: no positions are pending, so there is no new \
         round to give; its final image is made from every sample so far"
    )]
    NoRoundPending {
        /// The round at which the plan stopped.
        round: usize,
    },
    /// A round given only its new samples: they are the positions of an earlier round.
    #[error(
        "the {given} samples given as the new round are the positions of round {matched}, \
         which this plan has read already (a round repeated, or the last one lost): it \
         expects the {expected} positions it handed out for round {round}"
    )]
    NewRoundRepeated {
        /// Samples given.
        given: usize,
        /// The round whose positions they are.
        matched: usize,
        /// The last round handed out.
        round: usize,
        /// Its positions.
        expected: usize,
    },
    /// A round given only its new samples: they are every sample of rounds `0..=matched`.
    #[error(
        "the {given} samples given as the new round are every sample of rounds 0..={matched}: \
         give only the {expected} samples of the positions handed out for round {round}, or \
         pass these as every sample so far"
    )]
    NewRoundCumulative {
        /// Samples given.
        given: usize,
        /// The last round they complete.
        matched: usize,
        /// The last round handed out.
        round: usize,
        /// Its positions.
        expected: usize,
    },
    /// A round given only its new samples: another count than the round's.
    #[error(
        "{given} samples given as the new round, but this plan handed out {expected} positions \
         for round {round}: give exactly the samples of those positions (none lost, none added)"
    )]
    NewRoundCount {
        /// Samples given.
        given: usize,
        /// The last round handed out.
        round: usize,
        /// Its positions.
        expected: usize,
    },
    /// A round given only its new samples: the round's count, other positions.
    #[error(
        "the {given} samples given as the new round are not the positions this plan handed \
         out for round {round} (the same count, other positions: another run, moved, or \
         rounded on the way, e.g. to float32): give the positions of round {round} as written, \
         in float64"
    )]
    NewRoundMoved {
        /// Samples given.
        given: usize,
        /// The last round handed out.
        round: usize,
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
    /// A new plan asked for in a folder that holds a plan (its state file, untiled or tiled)
    /// already ([`PlanState::check_new`]).
    #[error(
        "{} holds a plan already: continue it ({}), start a new one ({}) or plan in another \
         folder ({})",
        .dir.display(),
        crate::error::Fix::Set(crate::error::Param::Samples),
        crate::error::Fix::Set(crate::error::Param::Overwrite),
        crate::error::Fix::Set(crate::error::Param::State)
    )]
    HoldsPlan {
        /// The folder.
        dir: PathBuf,
    },
    /// The state file is not a plan state this build reads.
    #[error("{}: not a plan state ({problem}): start a new state", .file.display())]
    State {
        /// The file.
        file: PathBuf,
        /// What is wrong.
        problem: String,
    },
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

/// A plan between calls: everything `ImagePlan::resume` needs and the record of the
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
    /// `gram.bin`, not in the JSON).
    #[serde(skip)]
    pub carried: CarriedGram,
    /// The last round's PCG start and diagonal (module docs; kept in `pcg.bin`).
    #[serde(skip)]
    pub pcg: CarriedPcg,
    /// The stopping round's fit, the final image's without a second solve ([`FinalFit`];
    /// kept in `final.bin`).
    #[serde(skip)]
    pub final_fit: CarriedFinal,
    /// The single-scale rows of the samples fitted so far ([`CarriedRows`]; kept in
    /// `rows.bin`).
    #[serde(skip)]
    pub rows: CarriedRows,
    /// The plan as of this state's progress, resumed once when the state was read or started
    /// ([`ResumedPlan`]; not kept in any file).
    #[serde(skip)]
    pub resumed: ResumedPlan,
}

/// The plan of a state ([`ImagePlan::resume`] of its plane, parameters and progress), built
/// once when the state is read ([`PlanState::from_json`], which resumes it to check the
/// history) or started, and reused by the state's calls instead of resuming it again (the
/// base tree and its coverage rule cost a resumption several milliseconds at 128², their
/// base positions drawn again). Used only while it is the plan of the state's own plane,
/// parameters and progress (compared whole), so a state changed meanwhile resumes afresh.
/// Solver state only: two plan states that differ in it are equal.
#[derive(Clone, Debug, Default)]
pub struct ResumedPlan(Option<ImagePlan>);

impl PartialEq for ResumedPlan {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl ResumedPlan {
    /// The plan kept, if it is the plan of `plane`, `params` and `progress`.
    fn of(
        &self,
        plane: ImagePlane,
        params: &AdaptiveParams,
        progress: &PlanProgress,
    ) -> Option<&ImagePlan> {
        self.0.as_ref().filter(|plan| {
            plan.plane() == plane && plan.params() == params && plan.progress() == progress
        })
    }
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
    /// Why the samples read could not be kept in the plan's folder for a later round given
    /// only its new samples (`io::plan_files`; `None`: kept, or a plan in memory).
    pub samples_note: Option<String>,
    /// Seconds (wall clock) of the whole call on the state: matching the samples to the
    /// rounds, the round ([`ImageRound::times`]) and, at the stop, the final image.
    pub round_s: f64,
    /// Seconds of the final image's output pixels from the stopping round's fit (0 when the
    /// plan goes on, or when the caller did not ask for them).
    pub image_s: f64,
    /// When this round stopped the plan: the final reconstruction from its fit, with the
    /// plan's output pixels, without fitting the samples again (under the direct solve, the
    /// default, bit for bit [`PlanState::reconstruct`] of the same samples; under an
    /// iterative solve, the stopping round's fit continued to the solver's tolerance);
    /// `None` otherwise, and when the caller did not ask for it
    /// ([`PlanState::advance_imaging`]).
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
    /// Why the stopping round's carried fit ([`FinalFit`]) was not used and the samples were
    /// fitted again (`None`: it was used, or these are not the stopping round's samples).
    pub fit_note: Option<String>,
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

impl ProtocolError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            ProtocolError::Adaptive(e) => e.kind(),
            ProtocolError::Plane { .. }
            | ProtocolError::Mismatch { .. }
            | ProtocolError::Channels { .. }
            | ProtocolError::OtherParameters { .. }
            | ProtocolError::HoldsPlan { .. }
            | ProtocolError::State { .. }
            | ProtocolError::EarlierUnknown { .. }
            | ProtocolError::NoRoundPending { .. }
            | ProtocolError::NewRoundCumulative { .. }
            | ProtocolError::NewRoundCount { .. }
            | ProtocolError::NewRoundMoved { .. } => crate::error::ErrorKind::InvalidInput,
            ProtocolError::AlreadyPlanned { .. } | ProtocolError::NewRoundRepeated { .. } => {
                crate::error::ErrorKind::OutputRefused
            }
        }
    }
}

crate::error::classified!(ProtocolError);
