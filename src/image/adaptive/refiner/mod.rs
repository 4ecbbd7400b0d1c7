//! The adaptive rounds on the image plane (the 2D analogue of [`crate::refine`]).
//!
//! 1. Base: the tree full up to the base step `s0` (slots of `V_{cx+s0} (x) V_{cy+s0}`),
//!    `ceil(rho)` samples in every slot, placed by the plan's pattern ([`positions`]: by
//!    default each slot's own Owen-scrambled Sobol (0, 2)-sequence, continued by every later
//!    batch in the slot).
//! 2. Round: fit on the tree ([`super::fit_tree`]); indicate ([`super::indicator`]); stop if the
//!    estimated RMS error `sqrt(sum eta^2 / (W H))` is at most the tolerance, if nothing below
//!    the depth limit can be marked, or at the round limit; otherwise mark by Dörfler
//!    ([`super::marking::dorfler`], at least one slot; extended in indicator order until the
//!    round adds `min_growth` times the current samples), keep the longest prefix the remaining
//!    budget pays for ([`super::marking::within_budget`]), activate the marked slots and top
//!    up each of their four children to `ceil(rho)` samples (`ceil(rho_limit)` at the depth
//!    limit). *Least growth*: every sampling round adds at least `min_growth` times the
//!    samples of its fit, or the rest of the budget if less; when the marked slots cost less,
//!    the spare samples are spread over the slots that stay slots
//!    ([`super::marking::spread`], by [`GrowthParams::spread`]), so a budget-driven run
//!    ends at the budget after about `log(budget / base) / log(1 + min_growth)` rounds
//!    (without it, a concentrated indicator stopped runs at the round limit with a third of
//!    the budget unspent: docs/measurements/image-plane.md, "Variants tried at 64²").
//!    Noise ([`super::significance`]): slots whose parent's detail is within the noise are
//!    not markable; when nothing significant is left, a *densifying* round (no cell marked)
//!    raises the samples of every slot instead (up to double, at least the least growth),
//!    and later children are topped up to the raised count. Under
//!    [`crate::adaptive::marking::SpreadRule::Uncertainty`] the spare and densifying samples
//!    go where detail does not decay (slots at the depth limit or within the noise) by the
//!    uncertainty of the slot's mean, `sqrt(A) s` (`s` the spread of the fit's residuals in
//!    the slot), and a tree deep wherever its detail is significant densifies instead of
//!    stopping while budget remains.
//!
//! 3. Coverage ([`coverage`]): at a budget of at least one sample a pixel, each round holds
//!    back the samples that top every pixel up to `min(ceil(rho), floor(budget / (W H)))`,
//!    and the round that would stop tops the pixels left short up instead (one more round
//!    fits on them and stops), so no pixel is left without a sample
//!    ([`ImageSampling::cover_pixels`]).
//!
//! One round is [`ImagePlan::step`]: given the tree and every sample so far, it fits and either
//! stops or deepens the tree and returns the next positions; its decision (the stop test, the
//! budget cut, densify or mark and deepen) is the rounds driver's, the 1D refiner's too
//! ([`crate::adaptive::rounds`]). [`refine_image`] is a loop over
//! it with a scene as the oracle; the file protocol (module `protocol`) runs the same step
//! once per call, so a renderer outside the process gets the same rounds.
//!
//! Invariant after every round: every slot holds at least `ceil(rho)` samples, and the samples
//! never exceed the budget (nor, under the coverage rule, the budget less the samples held
//! back for the pixels). Deterministic for a seed: the marked slots are processed in
//! indicator order (ties by cell) with one PCG-64 stream per round.
//!
//! Every round refits: by default the direct solve (kernel rows, `G` continued from the last
//! round's, Cholesky), bit-identical to a rebuild, so the file protocol's rounds are the
//! in-process ones bit for bit. [`FitParams::solver`] may choose matrix-free PCG
//! ([`super::pcg`]), which in the in-process loop starts from the last round's coefficients;
//! the file protocol starts each PCG round from 0, so under PCG its fits agree with the
//! loop's to the PCG tolerance, not bit for bit.

//!
//! The files, by job: [`params`] (the parameters and their ranges), [`report`] (what a round
//! and a run report), [`positions`] (drawing new sample positions), [`plan`] (the plan between
//! rounds: construction, resumption, the fit), [`step`] (one round as named steps: fit,
//! indicate, stop), [`deepen`] (densify, or mark, deepen and sample), [`coverage`] (every
//! pixel a sample at low budgets), [`run`] (the in-process loop).

mod coverage;
mod deepen;
mod params;
mod pixel_counts;
mod pixel_spread;
mod plan;
mod positions;
mod report;
mod run;
mod step;
mod top_up;

pub use params::{
    AdaptiveParams, FitParams, GrowthParams, ImageSampling, IndicatorParams, NoiseParams,
    OutputParams, QuadTreeParams,
};
pub use pixel_counts::{empty_pixels, pixel_shortfall};
pub use pixel_spread::SHARE_MAX_SPP;
pub use plan::{Decision, ImagePlan, PlanProgress, Round};
pub use positions::{slot_sobol, ParsePatternError, PositionPattern, SamplePositions};
pub use report::{
    AdaptiveImage, AdaptiveReport, AdaptiveTimes, ImageRound, RebuildCost, RoundTimes,
};
pub use run::refine_image;
