//! The parameters of the adaptive image refiner ([`AdaptiveParams`]) and their ranges.

use serde::{Deserialize, Serialize};

use super::super::correction::{PixelEstimate, RESIDUAL_Z};
use super::super::pcg::TreeSolver;
use super::super::AdaptiveError;
use crate::adaptive::marking::SpreadRule;

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
    /// Cap `r_max` of the indicator's decay ratio (module `indicator`): `1/2` is a straight
    /// edge's ratio; larger values give unresolved oscillations (textures) more priority and
    /// let a few cells go deep before the whole edge is resolved.
    pub max_ratio: f64,
    /// Least growth per round as a share of the current samples: if the Dörfler set costs
    /// fewer new samples, the next slots in indicator order are marked too (fewer rounds on a
    /// concentrated indicator; 0: pure Dörfler).
    pub min_growth: f64,
    /// Where the spare samples of a round go when the marked slots cost less than the least
    /// growth ([`super::super::marking::spread`]).
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
    /// [`super::super::pcg`]).
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
    /// False-alarm rate `alpha` of the noise test ([`super::super::significance`]): a slot is
    /// deepened only where its parent's detail is significant, so that noise alone marks a
    /// slot in a round with probability at most about `alpha`; the noise level is estimated
    /// from the fit's residuals (0: no test, every detail counts).
    #[serde(default = "default_false_alarm")]
    pub false_alarm: f64,
    /// Probe channels of the noise test (variance of the coefficients and the noise level).
    #[serde(default = "default_probes")]
    pub probes: usize,
    /// The output pixels ([`super::super::correction`]): the fit's box pixels plus the significant
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
    /// in [`super::ImageRound::rebuild`]. Doubles the fits' cost; the rebuilds' seconds are kept
    /// apart ([`super::AdaptiveTimes::rebuild_s`]) and change nothing else.
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
