//! The adaptive rounds on the image plane (the 2D analogue of [`crate::refine`]).
//!
//! (About 890 lines: parameters, reports, the round and the loop stay together so the
//! refiner's decisions read in one place; the report structs are the seam to split along. The
//! noise test and its notes live in [`super::significance`], the spreading of spare samples in
//! [`super::marking`].)
//!
//! 1. Base: the tree full up to the base step `s0` (slots of `V_{cx+s0} (x) V_{cy+s0}`),
//!    `ceil(rho)` jittered-stratified samples in every slot.
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
//!    ([`super::marking::spread`], by [`AdaptiveParams::spread`]), so a budget-driven run
//!    ends at the budget after about `log(budget / base) / log(1 + min_growth)` rounds
//!    (measured: at 128², 4 spp, camera stopped at the round limit, 40, with 42,428 of
//!    65,536 samples spent, rounds after the third adding 24 to 3,000 samples each).
//!    Noise ([`super::significance`]): slots whose parent's detail is within the noise are
//!    not markable; when nothing significant is left, a *densifying* round (no cell marked)
//!    raises the samples of every slot instead (up to double, at least the least growth),
//!    and later children are topped up to the raised count.
//!
//! One round is [`ImagePlan::step`]: given the tree and every sample so far, it fits and either
//! stops or deepens the tree and returns the next positions. [`refine_image`] is a loop over
//! it with a scene as the oracle; the file protocol ([`super::protocol`]) runs the same step
//! once per call, so a renderer outside the process gets the same rounds.
//!
//! Invariant after every round: every slot holds at least `ceil(rho)` samples, and the samples
//! never exceed the budget. Deterministic for a seed: the marked slots are processed in
//! indicator order (ties by cell) with one PCG-64 stream per round.
//!
//! Every round refits: by default the direct solve (kernel rows, `G` continued from the last
//! round's, Cholesky), bit-identical to a rebuild, so the file protocol's rounds are the
//! in-process ones bit for bit. [`AdaptiveParams::solver`] may choose matrix-free PCG
//! ([`super::pcg`]), which in the in-process loop starts from the last round's coefficients;
//! the file protocol starts each PCG round from 0, so under PCG its fits agree with the
//! loop's to the PCG tolerance, not bit for bit.

use std::collections::HashMap;
use std::time::Instant;

use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use serde::{Deserialize, Serialize};

use super::correction::{output_pixels, PixelEstimate, ResidualCorrection, RESIDUAL_Z};
use super::fit::{fit_tree_updating, FitState, TreeFit, TreeFitReport};
use super::indicator::indicate;
use super::marking::{dorfler, spread, within_budget, SpreadRule};
use super::pcg::{SingleScaleRows, TreeSolver};
use super::significance::{noise_notes, probe_values, NoiseLevel, Significance};
use super::tree::{Cell, QuadTree};
use super::{AdaptiveError, ImageOracle};
use crate::basis::tensor::TensorBasis;
use crate::basis::FilterFamily;
use crate::image::{ImagePlane, PixelImage};
use crate::refine::StopReason;

/// Parameters of the adaptive image refiner.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AdaptiveParams {
    /// Vanishing moments `p` (2 is the practical choice in 2D).
    pub p: usize,
    /// Depth limit below the pixel: the finest level per axis is
    /// `J = ceil(log2 size) + below_pixel` (1: half-pixel functions at edges; measured at 64²,
    /// 4 spp on `shapes`, quarter-pixel ones spent the budget on too few edge cells).
    pub below_pixel: u32,
    /// Level of the base slots along x (`None`: the finest whose samples fit in
    /// `base_fraction` of the budget).
    pub base_level: Option<u32>,
    /// Share of the budget the automatic base level may spend.
    pub base_fraction: f64,
    /// Samples per slot, `ceil(rho)` (the local oversampling).
    pub rho: f64,
    /// Dörfler fraction of the estimated squared error marked per round, in `(0, 1]`.
    pub theta: f64,
    /// Cap `r_max` of the indicator's decay ratio ([`super::indicator`]): `1/2` is a straight
    /// edge's ratio; larger values give unresolved oscillations (textures) more priority and
    /// let a few cells go deep before the whole edge is resolved.
    pub max_ratio: f64,
    /// Least growth per round as a share of the current samples: if the Dörfler set costs
    /// fewer new samples, the next slots in indicator order are marked too (fewer rounds on a
    /// concentrated indicator; 0: pure Dörfler).
    pub min_growth: f64,
    /// Where the spare samples of a round go when the marked slots cost less than the least
    /// growth ([`super::marking::spread`]).
    #[serde(default)]
    pub spread: SpreadRule,
    /// Share of each round's least growth kept for spreading ([`AdaptiveParams::spread`])
    /// whatever the marked slots cost (0: only what they leave).
    #[serde(default)]
    pub spread_share: f64,
    /// Samples per slot at the depth limit, `ceil(rho_limit)` (at least `ceil(rho)`): where
    /// the tree can go no deeper, more samples per function turn the fit from near
    /// interpolation into an average.
    #[serde(default = "default_rho_limit")]
    pub rho_limit: f64,
    /// Stop when the estimated RMS error (per unit area) is at most this (0: budget-driven).
    pub tolerance: f64,
    /// Most samples in total.
    pub budget: usize,
    /// Most refinement rounds.
    pub max_rounds: usize,
    /// Seed of the sample positions.
    pub seed: u64,
    /// Solver of every round's fit ([`TreeSolver::Direct`]: the reference; PCG: see
    /// [`super::pcg`]).
    #[serde(default = "direct_solver")]
    pub solver: TreeSolver,
    /// Relative residual of the iterative solvers ([`TreeSolver::Pcg`],
    /// [`TreeSolver::Schwarz`]) in the rounds' fits, which only feed the indicator (`None`:
    /// the solver's own tolerance). The final fit, the output, is always continued from the
    /// round's coefficients to the solver's tolerance (PCG; the Schwarz CG takes no start and
    /// solves the final fit afresh). Ignored by the direct solve.
    ///
    /// Measured (PCG to `1e-6`, `shapes`, 8 spp): at 128² loose rounds at `1e-2` take 18-31
    /// iterations against 218-254 and the run 14 s against 52 s, and at 256² 62 s against
    /// 158 s, with the fit's PSNR within 0.5 dB and the output's higher (the round fits'
    /// residuals raise the noise estimate of a noise-free scene from `1e-5` to `3e-3`, so
    /// fewer pixels take a residual correction).
    #[serde(default = "default_round_tolerance")]
    pub round_tolerance: Option<f64>,
    /// False-alarm rate `alpha` of the noise test ([`super::significance`]): a slot is
    /// deepened only where its parent's detail is significant, so that noise alone marks a
    /// slot in a round with probability at most about `alpha`; the noise level is estimated
    /// from the fit's residuals (0: no test, every detail counts).
    #[serde(default = "default_false_alarm")]
    pub false_alarm: f64,
    /// Probe channels of the noise test (variance of the coefficients and the noise level).
    #[serde(default = "default_probes")]
    pub probes: usize,
    /// The output pixels ([`super::correction`]): the fit's box pixels plus the significant
    /// mean residual of each pixel's samples, clamped to the local range of the samples (the
    /// default; restores detail the fit cannot represent and removes its ringing, at the cost
    /// of some noise where the residual passes the test), without the clamp, or the box
    /// pixels alone. Does not change the rounds.
    #[serde(default)]
    pub pixels: PixelEstimate,
    /// Standard errors `z` of the residual mean beyond which a pixel is corrected: larger
    /// values add less noise and restore less detail (0: every pixel with a nonzero mean
    /// residual).
    #[serde(default = "default_residual_z")]
    pub residual_z: f64,
    /// Measure each round's fit against the same fit rebuilt from scratch (fresh solver
    /// state, zero start: no continued normal matrix or diagonal, no warm start), reported
    /// in [`ImageRound::rebuild`]. Doubles the fits' cost; the rebuilds' seconds are kept
    /// apart ([`AdaptiveTimes::rebuild_s`]) and change nothing else.
    #[serde(default)]
    pub measure_rebuild: bool,
}

fn default_residual_z() -> f64 {
    RESIDUAL_Z
}

fn default_false_alarm() -> f64 {
    AdaptiveParams::default().false_alarm
}
fn default_probes() -> usize {
    AdaptiveParams::default().probes
}

fn default_round_tolerance() -> Option<f64> {
    AdaptiveParams::default().round_tolerance
}

fn default_rho_limit() -> f64 {
    AdaptiveParams::default().rho_limit
}

fn direct_solver() -> TreeSolver {
    TreeSolver::Direct
}

impl Default for AdaptiveParams {
    fn default() -> Self {
        Self {
            p: 2,
            below_pixel: 1,
            base_level: None,
            base_fraction: 0.3,
            rho: 2.0,
            rho_limit: 2.0,
            theta: 0.5,
            min_growth: 0.25,
            spread: SpreadRule::Indicator,
            spread_share: 0.0,
            max_ratio: 0.5,
            tolerance: 0.0,
            budget: 0,
            max_rounds: 40,
            seed: 1,
            solver: TreeSolver::Direct,
            round_tolerance: Some(1e-2),
            false_alarm: 0.01,
            probes: 4,
            pixels: PixelEstimate::ResidualClamped,
            residual_z: RESIDUAL_Z,
            measure_rebuild: false,
        }
    }
}

impl AdaptiveParams {
    /// Checks every parameter's range.
    pub fn validate(&self) -> Result<(), AdaptiveError> {
        let bad = |parameter, value: String, expected| {
            Err(AdaptiveError::Parameter {
                parameter,
                value,
                expected,
            })
        };
        if !(1..=8).contains(&self.p) {
            return bad("p", self.p.to_string(), "vanishing moments in 1..=8");
        }
        if self.below_pixel > 6 {
            return bad(
                "below_pixel",
                self.below_pixel.to_string(),
                "levels below the pixel in 0..=6",
            );
        }
        if !(self.rho.is_finite() && (1.0..=256.0).contains(&self.rho)) {
            return bad("rho", self.rho.to_string(), "samples per slot in [1, 256]");
        }
        if !(self.rho_limit.is_finite() && (1.0..=256.0).contains(&self.rho_limit)) {
            return bad(
                "rho_limit",
                self.rho_limit.to_string(),
                "samples per slot at the depth limit in [1, 256]",
            );
        }
        if !(self.spread_share.is_finite() && (0.0..=1.0).contains(&self.spread_share)) {
            return bad(
                "spread_share",
                self.spread_share.to_string(),
                "a share of the least growth in [0, 1]",
            );
        }
        if !(self.theta > 0.0 && self.theta <= 1.0) {
            return bad(
                "theta",
                self.theta.to_string(),
                "a Dörfler fraction in (0, 1]",
            );
        }
        if !(self.base_fraction > 0.0 && self.base_fraction <= 1.0) {
            return bad(
                "base_fraction",
                self.base_fraction.to_string(),
                "a share of the budget in (0, 1]",
            );
        }
        if !(self.max_ratio > 0.0 && self.max_ratio < 1.0) {
            return bad(
                "max_ratio",
                self.max_ratio.to_string(),
                "a decay ratio cap in (0, 1)",
            );
        }
        if !(self.min_growth.is_finite() && (0.0..=10.0).contains(&self.min_growth)) {
            return bad(
                "min_growth",
                self.min_growth.to_string(),
                "a share of the samples in [0, 10]",
            );
        }
        if !(self.tolerance.is_finite() && self.tolerance >= 0.0) {
            return bad(
                "tolerance",
                self.tolerance.to_string(),
                "a finite RMS error >= 0 (0: run until the budget is spent)",
            );
        }
        if !(self.false_alarm.is_finite() && (0.0..1.0).contains(&self.false_alarm)) {
            return bad(
                "false_alarm",
                self.false_alarm.to_string(),
                "a false-alarm rate in [0, 1) (0: no noise test)",
            );
        }
        if self.false_alarm > 0.0 && !(1..=64).contains(&self.probes) {
            return bad(
                "probes",
                self.probes.to_string(),
                "probe channels in 1..=64 for the noise test",
            );
        }
        if !(self.residual_z.is_finite() && self.residual_z >= 0.0) {
            return bad(
                "residual_z",
                self.residual_z.to_string(),
                "a finite number of standard errors >= 0",
            );
        }
        if self.budget == 0 {
            return bad("budget", "0".into(), "a positive number of samples");
        }
        if let TreeSolver::Schwarz {
            tolerance,
            max_iterations,
            tile,
            halo,
        } = self.solver
        {
            if !(tolerance > 0.0 && tolerance < 1.0)
                || max_iterations == 0
                || !(tile.is_finite() && tile >= 1.0)
                || !(halo.is_finite() && halo >= 0.0)
            {
                return bad(
                    "solver",
                    format!("{:?}", self.solver),
                    "a Schwarz tolerance in (0, 1), at least one iteration, tiles of at least \
                     one pixel and a finite halo >= 0",
                );
            }
        }
        if let Some(t) = self.round_tolerance {
            if !(t > 0.0 && t < 1.0) {
                return bad(
                    "round_tolerance",
                    t.to_string(),
                    "a relative residual in (0, 1) (or null: the solver's tolerance)",
                );
            }
        }
        if let TreeSolver::Pcg {
            tolerance,
            max_iterations,
        } = self.solver
        {
            if !(tolerance > 0.0 && tolerance < 1.0) || max_iterations == 0 {
                return bad(
                    "solver",
                    format!("{:?}", self.solver),
                    "a PCG tolerance in (0, 1) and at least one iteration",
                );
            }
        }
        Ok(())
    }
}

/// What one round saw and did.
#[derive(Clone, Debug, Serialize)]
pub struct ImageRound {
    /// Round number (0 = the base fit).
    pub round: usize,
    /// Samples in this round's fit.
    pub samples: usize,
    /// Samples added for this round's fit.
    pub new_samples: usize,
    /// Active functions.
    pub functions: usize,
    /// Deepest slot step.
    pub max_depth: u32,
    /// Estimated RMS error (per unit area) of this round's fit.
    pub estimate_rms: f64,
    /// Slots marked after this fit (0 in the last round).
    pub marked: usize,
    /// Estimated noise of this round's samples (`None`: no noise test).
    pub noise: Option<NoiseLevel>,
    /// Slots below the depth limit not deepened because their detail is within the noise.
    pub insignificant: usize,
    /// Samples per slot after a densifying round (nothing significant left to deepen: the
    /// budget raises the oversampling so that the fit averages the noise), `None` otherwise.
    pub densified_to: Option<usize>,
    /// Samples spread over the slots that stay slots (beyond the marked slots' children), so
    /// that the round adds at least `min_growth` times the samples or spends the budget.
    pub spread: usize,
    /// The solve.
    pub fit: TreeFitReport,
    /// The last round's fit continued to the solver's tolerance from the round's
    /// coefficients ([`AdaptiveParams::round_tolerance`] only; `None` otherwise).
    pub final_fit: Option<TreeFitReport>,
    /// The round's fit against a rebuild from scratch ([`AdaptiveParams::measure_rebuild`]
    /// only; `None` otherwise).
    pub rebuild: Option<RebuildCost>,
}

/// One round's fit, continued from the last round's solver state, against the same fit
/// rebuilt from scratch: `round_s / rebuild_s` is what the continuation saves (both with the
/// noise test's probe fits and residuals when the test is on).
#[derive(Clone, Debug, Serialize)]
pub struct RebuildCost {
    /// Seconds of the round's fit (continued state, warm start).
    pub round_s: f64,
    /// Seconds of the same fit from scratch.
    pub rebuild_s: f64,
    /// `round_s / rebuild_s`.
    pub ratio: f64,
    /// The rebuild's solve.
    pub fit: TreeFitReport,
}

/// Seconds by stage.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct AdaptiveTimes {
    /// Oracle calls.
    pub sample_s: f64,
    /// Fits (all rounds).
    pub fit_s: f64,
    /// Indicators, marking, deepening.
    pub refine_s: f64,
    /// Fits rebuilt from scratch to measure the rounds against
    /// ([`AdaptiveParams::measure_rebuild`]; 0 otherwise), in none of the stages above.
    pub rebuild_s: f64,
}

/// What the adaptive run did.
#[derive(Clone, Debug, Serialize)]
pub struct AdaptiveReport {
    /// Finest levels `(Jx, Jy)` (the depth limit).
    pub levels: (u32, u32),
    /// Coarse levels `(cx, cy)`.
    pub coarse_levels: (u32, u32),
    /// Levels of the base slots `(cx + s0, cy + s0)`.
    pub base_levels: (u32, u32),
    /// Base samples.
    pub base_samples: usize,
    /// Samples in total.
    pub samples: usize,
    /// The budget.
    pub budget: usize,
    /// Active functions of the final tree.
    pub functions: usize,
    /// Active cells per step.
    pub cells_per_step: Vec<usize>,
    /// Why the refiner stopped.
    pub stop: StopReason,
    /// Per round.
    pub rounds: Vec<ImageRound>,
    /// Seconds by stage.
    pub times: AdaptiveTimes,
    /// The output pixels: the residual correction's counts ([`super::correction`]).
    pub pixels: ResidualCorrection,
    /// Fallbacks and the output's correction, in words.
    pub notes: Vec<String>,
}

/// The result: tree, samples, fit.
#[derive(Clone, Debug)]
pub struct AdaptiveImage {
    /// The final tree.
    pub tree: QuadTree,
    /// Sample x positions (pixel units).
    pub xs: Vec<f64>,
    /// Sample y positions.
    pub ys: Vec<f64>,
    /// Values per channel.
    pub values: Vec<Vec<f64>>,
    /// The round that added each sample (0 = base).
    pub round_of: Vec<u32>,
    /// The fit on the final tree.
    pub fit: TreeFit,
    /// The output pixels ([`AdaptiveParams::pixels`]; by default the fit's box pixels plus
    /// the significant mean residual, [`super::correction`]).
    pub image: PixelImage,
    /// What happened.
    pub report: AdaptiveReport,
}

impl AdaptiveImage {
    /// Exact box pixels of the final fit alone (no residual correction).
    pub fn fit_pixels(&self) -> Result<PixelImage, AdaptiveError> {
        let b = self.tree.basis();
        let plane = ImagePlane::new(b.width(), b.height()).expect("the basis has a valid size");
        Ok(PixelImage {
            plane,
            channels: self.fit.box_pixels(&self.tree)?,
        })
    }
}

/// Sample positions (pixel units) the refiner asks a renderer for.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SamplePositions {
    /// x positions.
    pub xs: Vec<f64>,
    /// y positions.
    pub ys: Vec<f64>,
}

impl SamplePositions {
    /// Number of positions.
    pub fn len(&self) -> usize {
        self.xs.len()
    }
    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.xs.is_empty()
    }

    /// Appends `need` jittered-stratified positions in `rect`: a `k x k` grid (`k^2 >= need`),
    /// `need` of its strata chosen at random, one uniform point in each.
    pub(crate) fn stratified(&mut self, rect: [f64; 4], need: usize, rng: &mut Pcg64) {
        if need == 0 {
            return;
        }
        let k = (need as f64).sqrt().ceil() as usize;
        let mut strata: Vec<usize> = (0..k * k).collect();
        if k * k > need {
            strata.shuffle(rng);
        }
        let (dx, dy) = (
            (rect[1] - rect[0]) / k as f64,
            (rect[3] - rect[2]) / k as f64,
        );
        for &s in &strata[..need] {
            let (i, j) = (s % k, s / k);
            self.xs
                .push((rect[0] + (i as f64 + rng.random::<f64>()) * dx).min(rect[1]));
            self.ys
                .push((rect[2] + (j as f64 + rng.random::<f64>()) * dy).min(rect[3]));
        }
    }
}

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
/// next. [`refine_image`] is a loop over it with a scene as the oracle; a renderer outside the
/// process drives the same rounds through files ([`super::protocol`]).
#[derive(Clone, Debug)]
pub struct ImagePlan {
    params: AdaptiveParams,
    plane: ImagePlane,
    tree: QuadTree,
    base_steps: u32,
    per_slot: usize,
    progress: PlanProgress,
    /// The last fit's solver state, continued by the next round's fit ([`FitState`]: the
    /// direct solve's normal matrix, the same bits without it, see [`super::gram`]; PCG's
    /// diagonal; a resumed plan starts without).
    state: FitState,
    /// The last fit's coefficients per image channel, then per probe channel of the noise
    /// test (a sample keeps its probe values), PCG's start in the next round (solver
    /// state only, kept for [`TreeSolver::Pcg`]: the tree only grows, so they are a point of
    /// the next tree's space with its new functions at 0; a resumed plan starts from 0).
    start: Option<Vec<Vec<f64>>>,
}

impl ImagePlan {
    /// The plan before any sample: validated parameters, the basis at the depth limit and the
    /// base tree (full up to the base step, chosen from the budget unless given).
    pub fn new(plane: ImagePlane, params: &AdaptiveParams) -> Result<Self, AdaptiveError> {
        params.validate()?;
        // A lower bound of what the budget's samples hold at the last fit: the position (16
        // bytes), one value (8) and the finest level's (2p - 1)^2 kernel entries (16 each).
        let per_sample = 24.0 + 16.0 * ((2 * params.p - 1) as f64).powi(2);
        crate::resources::check(
            || format!("a budget of {} samples", params.budget),
            params.budget as f64 * per_sample,
            || {
                format!(
                    "lower the budget to at most {} samples",
                    (crate::resources::memory_limit() as f64 / per_sample) as u64
                )
            },
        )?;
        let (w, h) = (plane.width(), plane.height());
        let levels = (
            finest_level(w, params.below_pixel).max(crate::basis::minimum_level(params.p) + 2),
            finest_level(h, params.below_pixel).max(crate::basis::minimum_level(params.p) + 2),
        );
        let basis = TensorBasis::new(params.p, FilterFamily::cdv_default(params.p), w, h, levels)?;
        let steps = basis.steps();
        let (cx, cy) = basis.coarse_levels();
        let per_slot = params.rho.ceil() as usize;
        let base_cost = |s: u32| (1usize << (cx + s)) * (1usize << (cy + s)) * per_slot;
        let s0 = match params.base_level {
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
                .find(|&s| base_cost(s) as f64 <= params.base_fraction * params.budget as f64)
                .unwrap_or(1),
        };
        if base_cost(s0) > params.budget {
            return Err(AdaptiveError::BudgetTooSmall {
                budget: params.budget,
                base: base_cost(s0),
                slots: base_cost(s0) / per_slot,
                per_slot,
            });
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
                plan.tree.activate(cell);
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

    /// The base positions: `ceil(rho)` jittered-stratified positions in every base slot, from
    /// the seed's round-0 stream (the same for every call).
    pub fn base_positions(&self) -> SamplePositions {
        let base = QuadTree::uniform(self.tree.basis().clone(), self.base_steps);
        let mut rng = round_rng(self.params.seed, 0);
        let mut out = SamplePositions::default();
        for slot in base.slots() {
            out.stratified(base.rect(slot), self.per_slot, &mut rng);
        }
        out
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
            self.params.solver,
            None,
            &mut FitState::default(),
        )
    }

    /// [`ImagePlan::fit`] continuing the solver state `state` ([`FitState`]),
    /// PCG starting from `start` (per image channel, then per probe channel; channels
    /// without one start from 0).
    fn fit_updating(
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
        if params.false_alarm <= 0.0 {
            return Ok((
                fit_tree_updating(tree, xs, ys, values, solver, start, state)?,
                None,
            ));
        }
        let probes = probe_values(params.seed, xs, ys, params.probes);
        let mut all: Vec<&[f64]> = values.to_vec();
        all.extend(probes.iter().map(|p| p.as_slice()));
        let mut fit = fit_tree_updating(tree, xs, ys, &all, solver, start, state)?;
        // the rows of the fit (PCG's, continued) or continued here (the direct solve's)
        let rows = SingleScaleRows::continued(state.rows.take(), tree.basis(), xs, ys);
        let significance = Significance::new(
            tree,
            &fit.coefficients,
            &rows,
            &all,
            ch,
            params.false_alarm,
            tree.slots().len(),
        );
        state.rows = Some(rows);
        fit.coefficients.truncate(ch);
        Ok((fit, Some(significance)))
    }

    /// One round on every sample so far (`values[c][i]` channel `c` at `(xs[i], ys[i])`):
    /// fit on the tree, indicate, then stop or mark, deepen and return the positions that
    /// top the marked slots' children up to `ceil(rho)` samples.
    ///
    /// With [`AdaptiveParams::round_tolerance`] and an iterative solver the round's fit stops
    /// at the round tolerance; when the round stops the refinement, its fit is continued from
    /// those coefficients to the solver's own tolerance (reported in
    /// [`ImageRound::final_fit`]), so the output is the accurate fit.
    pub fn step(
        &mut self,
        xs: &[f64],
        ys: &[f64],
        values: &[&[f64]],
    ) -> Result<Round, AdaptiveError> {
        let solver = self.params.solver;
        let loose = self
            .params
            .round_tolerance
            .and_then(|t| solver.with_tolerance(t))
            .filter(|&s| s != solver);
        let mut round = self.step_with(xs, ys, values, loose.unwrap_or(solver))?;
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
            round.fit_s += t.elapsed().as_secs_f64();
            round.log.final_fit = Some(last.report.clone());
            round.fit = last;
        }
        Ok(round)
    }

    /// [`ImagePlan::step`] with the round's fit by `solver`.
    fn step_with(
        &mut self,
        xs: &[f64],
        ys: &[f64],
        values: &[&[f64]],
        solver: TreeSolver,
    ) -> Result<Round, AdaptiveError> {
        let round = self.round();
        let t = Instant::now();
        let mut state = std::mem::take(&mut self.state);
        let start = self.start.take();
        let fitted = self.fit_updating(xs, ys, values, solver, start.as_deref(), &mut state);
        self.state = state;
        let (fit, significance) = fitted?;
        let fit_s = t.elapsed().as_secs_f64();
        let rebuild = if self.params.measure_rebuild {
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
        if matches!(self.params.solver, TreeSolver::Pcg { .. }) {
            // the next round starts from this one's image and probe coefficients
            let mut start = fit.coefficients.clone();
            if let Some(s) = &significance {
                start.extend(s.probe_coefficients().iter().cloned());
            }
            self.start = Some(start);
        }
        let params = &self.params;
        let tree = &self.tree;
        let t = Instant::now();
        let threshold = significance
            .as_ref()
            .map(|s| move |cell: Cell| s.threshold(tree, cell));
        let ind = indicate(
            tree,
            &fit.coefficients,
            params.max_ratio,
            threshold.as_ref().map(|f| f as &dyn Fn(Cell) -> f64),
        );
        let estimate_rms = (ind.total_sq / self.plane.pixels() as f64).sqrt();
        let mut log = ImageRound {
            round,
            samples: xs.len(),
            new_samples: xs.len().saturating_sub(self.progress.samples_fitted),
            functions: fit.report.functions,
            max_depth: tree.slots().iter().map(|c| c.step).max().unwrap_or(0),
            estimate_rms,
            marked: 0,
            noise: significance.as_ref().map(|s| s.level.clone()),
            insignificant: ind.insignificant.len(),
            densified_to: None,
            spread: 0,
            fit: fit.report.clone(),
            final_fit: None,
            rebuild,
        };
        let nothing_significant = ind.markable_sq <= 0.0 || ind.units.is_empty();
        let stop = if estimate_rms <= params.tolerance {
            Some(StopReason::Tolerance)
        } else if nothing_significant && ind.insignificant.is_empty() {
            Some(StopReason::DepthLimit)
        } else if round >= params.max_rounds {
            Some(StopReason::MaxRounds)
        } else {
            None
        };
        if let Some(stop) = stop {
            return Ok(Round {
                log,
                fit,
                decision: Decision::Stop(stop),
                fit_s,
                refine_s: t.elapsed().as_secs_f64(),
                position_s: 0.0,
            });
        }
        let left = params.budget.saturating_sub(xs.len());
        // the oversampling so far: ceil(rho), or more after densifying rounds
        let counts = tree.slot_counts(xs, ys);
        let slots = tree.slots();
        let target = slots
            .iter()
            .map(|s| counts.get(s).copied().unwrap_or(0))
            .min()
            .unwrap_or(0)
            .max(self.per_slot);
        // the round's least growth: min_growth x the samples, or the rest of the budget
        let goal = ((params.min_growth * xs.len() as f64).ceil() as usize).min(left);
        // indicator of every slot (weights of the spare samples)
        let eta: HashMap<Cell, f64> = ind
            .units
            .iter()
            .chain(&ind.insignificant)
            .chain(&ind.at_limit)
            .copied()
            .collect();
        if nothing_significant {
            // densifying: up to double the samples per slot, at least the least growth
            let doubling: usize = slots
                .iter()
                .map(|s| (2 * target).saturating_sub(counts.get(s).copied().unwrap_or(0)))
                .sum();
            let extra = doubling.max(goal).min(left);
            let refine_s = t.elapsed().as_secs_f64();
            if extra == 0 {
                return Ok(Round {
                    log,
                    fit,
                    decision: Decision::Stop(StopReason::Budget),
                    fit_s,
                    refine_s,
                    position_s: 0.0,
                });
            }
            let t = Instant::now();
            let mut rng = round_rng(params.seed, round + 1);
            let mut next = SamplePositions::default();
            let (_, to) = self.spread_samples(
                &slots,
                &counts,
                &eta,
                SpreadRule::Uniform,
                extra,
                &mut next,
                &mut rng,
            );
            log.densified_to = Some(to);
            self.progress.marked.push(Vec::new());
            self.progress.samples_fitted = xs.len();
            return Ok(Round {
                log,
                fit,
                decision: Decision::Sample(next),
                fit_s,
                refine_s,
                position_s: t.elapsed().as_secs_f64(),
            });
        }
        let etas: Vec<f64> = ind.units.iter().map(|u| u.1).collect();
        let n = dorfler(&etas, params.theta).max(1);
        // every unit is a candidate: the Dörfler set, extended to the least growth
        let marked: Vec<Cell> = ind.units.iter().map(|u| u.0).collect();
        // samples already in each child of each marked slot
        let index: HashMap<Cell, usize> = marked.iter().enumerate().map(|(i, &c)| (c, i)).collect();
        let mut child_counts = vec![[0usize; 4]; marked.len()];
        for (&x, &y) in xs.iter().zip(ys) {
            let slot = tree.slot_at(x, y);
            if let Some(&i) = index.get(&slot) {
                let c = tree.cell_at(slot.step + 1, x, y);
                child_counts[i][(c.ky & 1) * 2 + (c.kx & 1)] += 1;
            }
        }
        // children at the depth limit get at least ceil(rho_limit) samples
        let limit_slot = target.max(params.rho_limit.ceil() as usize);
        let steps = tree.steps();
        let per_child = move |cell: &Cell| {
            if cell.step + 1 >= steps {
                limit_slot
            } else {
                target
            }
        };
        let costs: Vec<usize> = marked
            .iter()
            .zip(&child_counts)
            .map(|(m, cc)| cc.iter().map(|&c| per_child(m).saturating_sub(c)).sum())
            .collect();
        // a share of the least growth kept for spreading
        let reserved = (params.spread_share * goal as f64).ceil() as usize;
        let mark_goal = goal - reserved.min(goal);
        let mut k = n;
        let mut spent: usize = costs[..n].iter().sum();
        while k < costs.len() && spent < mark_goal && etas[k] > 0.0 {
            spent += costs[k];
            k += 1;
        }
        let k = within_budget(&costs[..k], left - reserved.min(left));
        let spent: usize = costs[..k].iter().sum();
        // the spare samples: the least growth the marked slots do not take
        let extra = goal.saturating_sub(spent).max(reserved).min(left - spent);
        if k == 0 && extra == 0 {
            return Ok(Round {
                log,
                fit,
                decision: Decision::Stop(StopReason::Budget),
                fit_s,
                refine_s: t.elapsed().as_secs_f64(),
                position_s: 0.0,
            });
        }
        log.marked = k;
        let refine_s = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let mut rng = round_rng(params.seed, round + 1);
        let mut next = SamplePositions::default();
        for (cell, counts) in marked[..k].iter().zip(&child_counts) {
            let per_slot = per_child(cell);
            self.tree.activate(*cell);
            for (q, child) in cell.children().into_iter().enumerate() {
                let need = per_slot.saturating_sub(counts[q]);
                next.stratified(self.tree.rect(child), need, &mut rng);
            }
        }
        if extra > 0 {
            // the slots that stay slots (the marked ones' children are topped up above)
            let deepened: std::collections::HashSet<Cell> = marked[..k].iter().copied().collect();
            let stay: Vec<Cell> = slots
                .iter()
                .copied()
                .filter(|s| !deepened.contains(s))
                .collect();
            let (added, _) = self.spread_samples(
                &stay,
                &counts,
                &eta,
                params.spread,
                extra,
                &mut next,
                &mut rng,
            );
            log.spread = added;
        }
        self.progress.marked.push(marked[..k].to_vec());
        self.progress.samples_fitted = xs.len();
        Ok(Round {
            log,
            fit,
            decision: Decision::Sample(next),
            fit_s,
            refine_s,
            position_s: t.elapsed().as_secs_f64(),
        })
    }

    /// Spreads `extra` samples over `slots` (holding `counts`) by `rule`
    /// ([`super::marking::spread`], weights `eta`), jittered-stratified in each slot's
    /// rectangle, in slot order. Returns the samples added and the least count after.
    #[allow(clippy::too_many_arguments)]
    fn spread_samples(
        &self,
        slots: &[Cell],
        counts: &HashMap<Cell, usize>,
        eta: &HashMap<Cell, f64>,
        rule: SpreadRule,
        extra: usize,
        next: &mut SamplePositions,
        rng: &mut Pcg64,
    ) -> (usize, usize) {
        let have: Vec<usize> = slots
            .iter()
            .map(|s| counts.get(s).copied().unwrap_or(0))
            .collect();
        let weights: Vec<f64> = match rule {
            SpreadRule::Uniform => vec![1.0; slots.len()],
            SpreadRule::Indicator => slots
                .iter()
                .map(|s| eta.get(s).copied().unwrap_or(0.0))
                .collect(),
        };
        let add = spread(&weights, &have, extra);
        for (s, &a) in slots.iter().zip(&add) {
            next.stratified(self.tree.rect(*s), a, rng);
        }
        let least = have.iter().zip(&add).map(|(h, a)| h + a).min().unwrap_or(0);
        (add.iter().sum(), least)
    }

    /// The report of a finished run: `base_samples` of `samples` in total, the final `fit`,
    /// the reason to stop and the log of every round ([`AdaptiveReport::pixels`] empty: the
    /// caller that computes the output pixels fills it in, as [`refine_image`] does).
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
        notes.extend(noise_notes(&rounds, self.params.false_alarm));
        let spread: Vec<String> = rounds
            .iter()
            .filter(|r| r.spread > 0)
            .map(|r| format!("round {}: {}", r.round, r.spread))
            .collect();
        if !spread.is_empty() {
            notes.push(format!(
                "the marked slots cost less than the least growth ({} x the samples, or the rest \
                 of the budget): spare samples spread over the other slots by {:?} ({})",
                self.params.min_growth,
                self.params.spread,
                spread.join(", ")
            ));
        }
        AdaptiveReport {
            levels: self.tree.basis().levels(),
            coarse_levels: (cx, cy),
            base_levels: (cx + self.base_steps, cy + self.base_steps),
            base_samples,
            samples,
            budget: self.params.budget,
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

/// Growing sample store of the in-process loop: the oracle's values at the plan's positions.
struct Store<'a> {
    oracle: &'a dyn ImageOracle,
    xs: Vec<f64>,
    ys: Vec<f64>,
    values: Vec<Vec<f64>>,
    round_of: Vec<u32>,
}

impl Store<'_> {
    fn sample(&mut self, positions: &SamplePositions, round: u32) {
        let mut buf = vec![0.0; self.values.len()];
        for (&x, &y) in positions.xs.iter().zip(&positions.ys) {
            self.oracle.sample(x, y, &mut buf);
            self.xs.push(x);
            self.ys.push(y);
            for (c, v) in self.values.iter_mut().zip(&buf) {
                c.push(*v);
            }
            self.round_of.push(round);
        }
    }
}

fn round_rng(seed: u64, round: usize) -> Pcg64 {
    Pcg64::seed_from_u64(seed ^ (round as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15))
}

fn finest_level(size: usize, below: u32) -> u32 {
    (size.max(1) as f64).log2().ceil() as u32 + below
}

/// Refines the image of `oracle` on `plane`: adaptive tree and samples, until the tolerance,
/// the depth limit, the budget or the round limit. A loop over [`ImagePlan::step`], the oracle
/// sampling each round's positions.
pub fn refine_image(
    oracle: &dyn ImageOracle,
    plane: ImagePlane,
    params: &AdaptiveParams,
) -> Result<AdaptiveImage, AdaptiveError> {
    let mut plan = ImagePlan::new(plane, params)?;
    let mut times = AdaptiveTimes::default();
    let mut store = Store {
        oracle,
        xs: Vec::new(),
        ys: Vec::new(),
        values: vec![Vec::new(); oracle.channels()],
        round_of: Vec::new(),
    };
    let t = Instant::now();
    store.sample(&plan.base_positions(), 0);
    times.sample_s += t.elapsed().as_secs_f64();
    let base_samples = store.xs.len();
    let mut rounds = Vec::new();
    let (fit, stop) = loop {
        let values: Vec<&[f64]> = store.values.iter().map(|v| v.as_slice()).collect();
        let round = plan.step(&store.xs, &store.ys, &values)?;
        times.fit_s += round.fit_s;
        times.refine_s += round.refine_s;
        times.sample_s += round.position_s;
        times.rebuild_s += round.log.rebuild.as_ref().map_or(0.0, |r| r.rebuild_s);
        rounds.push(round.log);
        match round.decision {
            Decision::Stop(stop) => break (round.fit, stop),
            Decision::Sample(next) => {
                let t = Instant::now();
                store.sample(&next, rounds.len() as u32);
                times.sample_s += t.elapsed().as_secs_f64();
            }
        }
    };
    // the output pixels, with the final round's noise estimate (as the protocol's)
    let sigma = rounds
        .last()
        .and_then(|r| r.noise.as_ref())
        .map_or(0.0, |n| n.sigma);
    let (_, image, correction) = output_pixels(
        &plan.tree,
        &fit,
        &store.xs,
        &store.ys,
        &store.values,
        params.pixels,
        sigma,
        params.residual_z,
    )?;
    let mut report = plan.report(base_samples, store.xs.len(), &fit, stop, rounds, times);
    report.notes.push(correction.note());
    report.pixels = correction;
    Ok(AdaptiveImage {
        tree: plan.tree,
        xs: store.xs,
        ys: store.ys,
        values: store.values,
        round_of: store.round_of,
        fit,
        image,
        report,
    })
}

fn fit_notes(r: &TreeFitReport) -> Vec<String> {
    let mut notes = Vec::new();
    if r.ridge > 0.0 {
        notes.push(format!(
            "the final normal matrix was numerically singular (smallest pivot {:.1e}): a \
             relative ridge {:.0e} was added",
            r.min_pivot, r.ridge
        ));
    }
    if !r.converged {
        notes.push(format!(
            "PCG stopped at relative residual {:.1e} after {} iterations (condition estimate \
             {:.1e}){}",
            r.relative_residual,
            r.iterations,
            r.condition,
            if r.solver == "pcg->direct" {
                ": the direct solve took over"
            } else {
                ": its coefficients are used as they are"
            }
        ));
    }
    if r.unsampled > 0 {
        notes.push(format!(
            "{} active functions have no sample in their support (held at 0 by the ridge)",
            r.unsampled
        ));
    }
    notes
}
