//! The parameters of the adaptive image refiner ([`AdaptiveParams`]) in groups, and their
//! ranges (`validate` per group).
//!
//! The local space ([`TreeParams`]: `p`, `rho`), the Dörfler marking ([`MarkingParams`]) and
//! the stop ([`StopParams`]) are the 1D refiner's types ([`crate::adaptive::params`]); what
//! is the image plane's own sits in its own group: the quadtree's levels
//! ([`QuadTreeParams`]), the sampling at the depth limit ([`ImageSampling`]), the indicator's
//! decay cap ([`IndicatorParams`]), the least growth per round ([`GrowthParams`]), the noise
//! test ([`NoiseParams`]), the solver ([`FitParams`]) and the output pixels
//! ([`OutputParams`]). Serialized flat (module `flat`), one key a parameter as before.

mod flat;

use serde::{Deserialize, Serialize};

use super::super::correction::{PixelEstimate, RESIDUAL_Z};
use super::super::pcg::TreeSolver;
use super::super::AdaptiveError;
use super::positions::PositionPattern;
use crate::adaptive::marking::SpreadRule;
use crate::adaptive::{MarkingParams, StopParams, TreeParams};

/// Parameters of the adaptive image refiner.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(from = "flat::FlatParams", into = "flat::FlatParams")]
pub struct AdaptiveParams {
    /// Vanishing moments `p` (2 is the practical choice in 2D) and samples per slot,
    /// `ceil(rho)` (the local oversampling).
    pub tree: TreeParams,
    /// The quadtree's levels: depth limit below the pixel, base level.
    pub quad: QuadTreeParams,
    /// Samples at the depth limit and the seed.
    pub sampling: ImageSampling,
    /// Dörfler fraction `theta` of the estimated squared error marked per round, in `(0, 1]`.
    pub marking: MarkingParams,
    /// The indicator's decay ratio cap.
    pub indicator: IndicatorParams,
    /// The least growth per round and where its spare samples go.
    pub growth: GrowthParams,
    /// Stop when the estimated RMS error (per unit area) is at most the tolerance (0:
    /// budget-driven); most samples in total (positive); most rounds.
    pub stop: StopParams,
    /// The solver of every round's fit.
    pub fit: FitParams,
    /// The noise test that keeps noise from deepening the tree.
    pub noise: NoiseParams,
    /// The output pixels.
    pub output: OutputParams,
}

/// The levels of the quadtree (what the 1D refiner's interval tree counts as absolute levels).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct QuadTreeParams {
    /// Depth limit below the pixel: the finest level per axis is
    /// `J = ceil(log2 size) + below_pixel` (1: half-pixel functions at edges; quarter-pixel ones
    /// spent the budget on too few edge cells: docs/measurements/image-plane.md, "Variants tried at
    /// 64²").
    pub below_pixel: u32,
    /// Level of the base leaves along x (`None`: the finest whose samples fit in
    /// `base_fraction` of the budget).
    pub base_level: Option<u32>,
    /// Share of the budget the automatic base level may spend.
    pub base_fraction: f64,
}

/// The sampling beyond `ceil(rho)` per leaf.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImageSampling {
    /// Samples per leaf at the depth limit, `ceil(rho_limit)` (at least `ceil(rho)`): where
    /// the tree can go no deeper, more samples per function turn the fit from near
    /// interpolation into an average.
    pub rho_limit: f64,
    /// Seed of the sample positions.
    pub seed: u64,
    /// Where a slot's positions go (module `positions`): the continued per-slot Sobol
    /// sequence or per-batch jittered strata.
    pub pattern: PositionPattern,
    /// At a budget of at least one sample a pixel, give every pixel a sample (module
    /// `coverage`): each round holds back one sample for every pixel still without one, and
    /// the round that would stop first gives each such pixel one sample (false: pixels the
    /// tree leaves empty keep the fit's value).
    pub cover_pixels: bool,
    /// The uniform floor (module `coverage`): a share `f` in `[0, 1]` of the budget's
    /// samples a pixel, `N / (W H)`, that every pixel holds at the end, `floor(f N / (W H))`
    /// (0: none beyond the coverage rule). Where the tree cannot follow the signal (texture
    /// past the depth limit, thin geometry) the final image is close to the box mean of each
    /// pixel's samples, of error `sigma_P^2 / n_P`: pixels the tree leaves at its base
    /// oversampling hold too few; the floor gives them their share, well stratified (the
    /// pixel's own (0, 2)-sequence).
    pub pixel_floor: f64,
}

/// The indicator of the image refiner.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct IndicatorParams {
    /// Cap `r_max` of the indicator's decay ratio (module `indicator`): `1/2` is a straight
    /// edge's ratio; larger values give unresolved oscillations (textures) more priority and
    /// let a few cells go deep before the whole edge is resolved.
    pub max_ratio: f64,
}

/// The least growth per round (the image refiner's addition to Dörfler marking).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GrowthParams {
    /// Least growth per round as a share of the current samples: if the Dörfler set costs
    /// fewer new samples, the next leaves in indicator order are marked too (fewer rounds on a
    /// concentrated indicator; 0: pure Dörfler).
    pub min_growth: f64,
    /// Where the spare samples of a round go when the marked leaves cost less than the least
    /// growth (`super::super::marking::spread`).
    pub spread: SpreadRule,
    /// Share of each round's least growth kept for spreading ([`GrowthParams::spread`])
    /// whatever the marked leaves cost (0: only what they leave).
    pub spread_share: f64,
    /// Share `q` of each round's new samples given to the *pixels* by their own pooled
    /// spread (module `pixel_spread`): `ceil(q G)` of a round's least growth `G` (of a
    /// densifying round's samples), and with `q > 0` whatever the marked slots leave of `G`,
    /// water-filled so that each pixel's count rises towards `lambda s_P` (Neyman's
    /// allocation `n_P ~ s_P`, `s_P` the spread of the pixel's samples, channels clipped to
    /// `[0, 1]` and summed, pooled over its 3 x 3 neighbourhood); each pixel continues its
    /// own sequence. Only at a budget of at most 4 samples a pixel (above it the tree's own
    /// spare samples did better on glossy, caustic and thin-geometry scenes) and where the
    /// base slots are the pixels (0: off, the tree alone).
    pub pixel_share: f64,
}

/// The solver of the rounds' fits.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FitParams {
    /// Solver of every round's fit ([`TreeSolver::Direct`]: the reference; PCG: see
    /// `super::super::pcg`).
    pub solver: TreeSolver,
    /// Relative residual of the iterative solvers ([`TreeSolver::Pcg`],
    /// [`TreeSolver::Schwarz`]) in the rounds' fits, which only feed the indicator (`None`:
    /// the solver's own tolerance). The final fit, the output, is always continued from the
    /// round's coefficients to the solver's tolerance (PCG; the Schwarz CG takes no start and
    /// solves the final fit afresh). Ignored by the direct solve.
    ///
    /// Loose rounds cost a fraction of the iterations for nearly the same fit; the round fits'
    /// larger residuals raise the noise estimate of a noise-free scene, so fewer pixels take a
    /// residual correction (docs/measurements/plan-speed.md, "Loose rounds").
    pub round_tolerance: Option<f64>,
    /// Relative residual of the noise test's probe channels in the rounds' fits under PCG
    /// (`None`: the round's tolerance, as the image's channels). The probes (white noise on
    /// the samples) take most of a round's iterations while the warm-started image
    /// channels take 2-5; their coefficients only enter the per-cell variance `v_C` and the
    /// noise level's residual median, which need one or two digits, not the image's
    /// accuracy (docs/measurements/plan-speed.md, "The rounds' fits: PCG's iterations").
    pub probe_tolerance: Option<f64>,
    /// Measure each round's fit against the same fit rebuilt from scratch (fresh solver
    /// state, zero start: no continued normal matrix or diagonal, no warm start), reported
    /// in `ImageRound::rebuild`. Doubles the fits' cost; the rebuilds' seconds are
    /// kept apart (`AdaptiveTimes::rebuild_s`) and change nothing else.
    pub measure_rebuild: bool,
}

/// The noise test (`super::super::significance`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct NoiseParams {
    /// False-alarm rate `alpha`: a leaf is deepened only where its parent's detail is
    /// significant, so that noise alone marks a leaf in a round with probability at most
    /// about `alpha`; the noise level is estimated from the fit's residuals (0: no test,
    /// every detail counts).
    pub false_alarm: f64,
    /// Probe channels of the noise test (variance of the coefficients and the noise level).
    pub probes: usize,
}

/// The output pixels (`super::super::correction`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct OutputParams {
    /// The fit's box pixels plus the significant mean residual of each pixel's samples,
    /// clamped to the local range of the samples (the default; restores detail the fit cannot
    /// represent and removes its ringing, at the cost of some noise where the residual passes
    /// the test), without the clamp, or the box pixels alone. Does not change the rounds.
    pub pixels: PixelEstimate,
    /// Standard errors `z` of the residual mean beyond which a pixel is corrected: larger
    /// values add less noise and restore less detail (0: every pixel with a nonzero mean
    /// residual).
    pub residual_z: f64,
}

impl Default for AdaptiveParams {
    fn default() -> Self {
        Self {
            tree: TreeParams { p: 2, rho: 2.0 },
            quad: QuadTreeParams {
                below_pixel: 1,
                base_level: None,
                base_fraction: 0.3,
            },
            sampling: ImageSampling {
                rho_limit: 2.0,
                seed: 1,
                pattern: PositionPattern::Sobol,
                cover_pixels: true,
                pixel_floor: 0.0,
            },
            marking: MarkingParams { theta: 0.5 },
            indicator: IndicatorParams { max_ratio: 0.5 },
            growth: GrowthParams {
                min_growth: 0.25,
                spread: SpreadRule::Indicator,
                spread_share: 0.0,
                pixel_share: 0.0,
            },
            stop: StopParams {
                tolerance: 0.0,
                budget: 0,
                max_rounds: 40,
            },
            fit: FitParams {
                solver: TreeSolver::Direct,
                round_tolerance: Some(1e-2),
                probe_tolerance: None,
                measure_rebuild: false,
            },
            noise: NoiseParams {
                false_alarm: 0.01,
                probes: 4,
            },
            output: OutputParams {
                pixels: PixelEstimate::ResidualClamped,
                residual_z: RESIDUAL_Z,
            },
        }
    }
}

/// The uniform floor of a plan a renderer drives ([`AdaptiveParams::renderer_plan`]): half
/// the budget's samples a pixel, given by the base positions before the first round (module
/// `coverage`, "Floor"). Chosen on the issue-38 suite's tuning half: +3.90 dB over the best
/// film against +3.34 without, rounds 120 against 183 (docs/measurements/plan-quality.md,
/// "The floor in the first round"); 0.375 was measured beside it.
pub const RENDERER_PIXEL_FLOOR: f64 = 0.5;

/// The pixel share of a plan a renderer drives ([`AdaptiveParams::renderer_plan`],
/// [`GrowthParams::pixel_share`]): off. The issue-38 suite's tuning half chose 0.5 (0.25, 0.5
/// and 1 on stripes, grid, direct and rough at 4 and 8 spp, then 0.5 on the whole half: +4.31
/// and +4.03 dB over the best film at two seeds against +3.85), but the validation half lost
/// 4-5 dB on glass and 1-4 dB on envmap and wires at 8/16 spp; with the share only at budgets
/// of at most 4 samples a pixel (module `pixel_spread`) it still loses glass 4 by 3.96 dB
/// (docs/measurements/plan-quality.md, "When the share may apply"); and the tiled plan (whose
/// windows' base slots are not the pixels) has no share, so with it the untiled plan moved
/// 3.8 dB ahead of the tiled one on `tests/tiled_plan.rs`'s slanted edge:
/// docs/measurements/plan-quality.md, "The hybrid". `rkwave plan --pixel-share 0.5` asks for it.
pub const RENDERER_PIXEL_SHARE: f64 = 0.0;

/// The noise test's probe channels in a plan a renderer drives ([`AdaptiveParams::renderer_plan`]):
/// one. Under PCG the probes were about 85 % of the rounds' channel-iterations (the image
/// channels, warm-started, converge in 2-3 iterations; a probe of white noise takes 8-15), and
/// the noise level `sigma` (a median over every sample's probe residual) keeps its accuracy
/// with one probe; the variance `v_C` (pooled over a cell's neighbours: `27 k` degrees of
/// freedom) is unbiased with a wider spread. Chosen on the issue-38 suite's tuning half
/// against four probes (docs/measurements/plan-speed.md, "The noise test's probes"); the
/// in-process default keeps four (its direct solve takes the probes as right-hand sides of one
/// factorization, at little cost).
pub const RENDERER_PROBES: usize = 1;

/// The renderer plan's probe tolerance ([`FitParams::probe_tolerance`]): chosen on the
/// suite's tuning half against `3e-2` and the rounds' `1e-2`
/// (docs/measurements/plan-speed.md, "The rounds' fits: PCG's iterations").
pub const RENDERER_PROBE_TOLERANCE: f64 = 5e-2;

/// A parameter out of its range.
fn bad(parameter: &'static str, value: String, expected: &'static str) -> AdaptiveError {
    AdaptiveError::Parameter {
        parameter,
        value,
        expected,
    }
}

/// Fails with `bad(..)` unless `ok`.
fn check(
    ok: bool,
    parameter: &'static str,
    value: impl ToString,
    expected: &'static str,
) -> Result<(), AdaptiveError> {
    if ok {
        Ok(())
    } else {
        Err(bad(parameter, value.to_string(), expected))
    }
}

impl AdaptiveParams {
    /// The parameters of a new plan a renderer drives (`rkwave plan`, Python's `Plan`): the
    /// defaults, with the final image denoised ([`PixelEstimate::Blend`]: per pixel the
    /// inverse-risk combination of the corrected pixels shrunk at the samples' noise level and
    /// the films chosen by SURE; a renderer's samples carry Monte Carlo noise, and where they
    /// carry none the shrinkage keeps the image: docs/measurements/real-renders.md, "Placement that
    /// follows the pixel integral" and "The plan's final image as the inverse-risk blend of shrunk
    /// and auto"); and fitted by matrix-free PCG ([`TreeSolver::plan_pcg`]:
    /// the loop's calls several times faster, a tenth of the memory, the same final image to
    /// a tenth of a dB: docs/measurements/plan-speed.md, "The renderer loop on PCG"); the
    /// uniform floor ([`ImageSampling::pixel_floor`]) at `RENDERER_PIXEL_FLOOR` (half the
    /// budget's samples a pixel, in the base: docs/measurements/plan-quality.md, "The floor in
    /// the first round"); the pixel share ([`GrowthParams::pixel_share`]) at `RENDERER_PIXEL_SHARE`;
    /// and the noise test with `RENDERER_PROBES` probe channels (one: the
    /// probes were most of PCG's work).
    pub fn renderer_plan() -> Self {
        let d = Self::default();
        Self {
            output: OutputParams {
                pixels: PixelEstimate::Blend,
                ..d.output
            },
            fit: FitParams {
                solver: TreeSolver::plan_pcg(),
                probe_tolerance: Some(RENDERER_PROBE_TOLERANCE),
                ..d.fit
            },
            sampling: ImageSampling {
                pixel_floor: RENDERER_PIXEL_FLOOR,
                ..d.sampling
            },
            growth: GrowthParams {
                pixel_share: RENDERER_PIXEL_SHARE,
                ..d.growth
            },
            noise: NoiseParams {
                probes: RENDERER_PROBES,
                ..d.noise
            },
            ..d
        }
    }

    /// Checks every parameter's range, group by group (the budget last but the solver's:
    /// the default budget, 0, is the one value a caller always sets).
    pub fn validate(&self) -> Result<(), AdaptiveError> {
        let (tree, marking) = (&self.tree, &self.marking);
        check(
            (1..=8).contains(&tree.p),
            "p",
            tree.p,
            "vanishing moments in 1..=8",
        )?;
        self.quad.validate()?;
        check(
            tree.rho.is_finite() && (1.0..=256.0).contains(&tree.rho),
            "rho",
            tree.rho,
            "samples per slot in [1, 256]",
        )?;
        self.sampling.validate()?;
        self.growth.validate()?;
        check(
            marking.theta > 0.0 && marking.theta <= 1.0,
            "theta",
            marking.theta,
            "a Dörfler fraction in (0, 1]",
        )?;
        self.quad.validate_base_fraction()?;
        self.indicator.validate()?;
        self.growth.validate_min_growth()?;
        let tolerance = self.stop.tolerance;
        check(
            tolerance.is_finite() && tolerance >= 0.0,
            "tolerance",
            tolerance,
            "a finite RMS error >= 0 (0: run until the budget is spent)",
        )?;
        self.noise.validate()?;
        self.output.validate()?;
        check(
            self.stop.budget != 0,
            "budget",
            "0",
            "a positive number of samples",
        )?;
        self.fit.validate()
    }
}

impl QuadTreeParams {
    /// Checks the depth limit below the pixel (the base fraction: `validate_base_fraction`).
    pub fn validate(&self) -> Result<(), AdaptiveError> {
        check(
            self.below_pixel <= 6,
            "below_pixel",
            self.below_pixel,
            "levels below the pixel in 0..=6",
        )
    }

    fn validate_base_fraction(&self) -> Result<(), AdaptiveError> {
        check(
            self.base_fraction > 0.0 && self.base_fraction <= 1.0,
            "base_fraction",
            self.base_fraction,
            "a share of the budget in (0, 1]",
        )
    }
}

impl ImageSampling {
    /// Checks the samples per leaf at the depth limit and the uniform floor.
    pub fn validate(&self) -> Result<(), AdaptiveError> {
        check(
            self.rho_limit.is_finite() && (1.0..=256.0).contains(&self.rho_limit),
            "rho_limit",
            self.rho_limit,
            "samples per slot at the depth limit in [1, 256]",
        )?;
        check(
            self.pixel_floor.is_finite() && (0.0..=1.0).contains(&self.pixel_floor),
            "pixel_floor",
            self.pixel_floor,
            "a share of the samples a pixel in [0, 1] (0: no floor)",
        )
    }
}

impl IndicatorParams {
    /// Checks the decay ratio cap.
    pub fn validate(&self) -> Result<(), AdaptiveError> {
        check(
            self.max_ratio > 0.0 && self.max_ratio < 1.0,
            "max_ratio",
            self.max_ratio,
            "a decay ratio cap in (0, 1)",
        )
    }
}

impl GrowthParams {
    /// Checks the share kept for spreading (the least growth: `validate_min_growth`).
    pub fn validate(&self) -> Result<(), AdaptiveError> {
        check(
            self.spread_share.is_finite() && (0.0..=1.0).contains(&self.spread_share),
            "spread_share",
            self.spread_share,
            "a share from 0 to 1",
        )?;
        check(
            self.pixel_share.is_finite() && (0.0..=1.0).contains(&self.pixel_share),
            "pixel_share",
            self.pixel_share,
            "a share from 0 to 1",
        )
    }

    fn validate_min_growth(&self) -> Result<(), AdaptiveError> {
        check(
            self.min_growth.is_finite() && (0.0..=10.0).contains(&self.min_growth),
            "min_growth",
            self.min_growth,
            "a share of the samples in [0, 10]",
        )
    }
}

impl NoiseParams {
    /// Checks the false-alarm rate and, with a noise test, the probe channels.
    pub fn validate(&self) -> Result<(), AdaptiveError> {
        check(
            self.false_alarm.is_finite() && (0.0..1.0).contains(&self.false_alarm),
            "false_alarm",
            self.false_alarm,
            "a false-alarm rate in [0, 1) (0: no noise test)",
        )?;
        check(
            self.false_alarm == 0.0 || (1..=64).contains(&self.probes),
            "probes",
            self.probes,
            "probe channels in 1..=64 for the noise test",
        )
    }
}

impl OutputParams {
    /// Checks the residual test's threshold.
    pub fn validate(&self) -> Result<(), AdaptiveError> {
        check(
            self.residual_z.is_finite() && self.residual_z >= 0.0,
            "residual_z",
            self.residual_z,
            "a finite number of standard errors >= 0",
        )
    }
}

impl FitParams {
    /// Checks the iterative solvers' settings and the rounds' tolerance.
    pub fn validate(&self) -> Result<(), AdaptiveError> {
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
                return Err(bad(
                    "solver",
                    format!("{:?}", self.solver),
                    "a Schwarz tolerance in (0, 1), at least one iteration, tiles of at least \
                     one pixel and a finite halo >= 0",
                ));
            }
        }
        if let Some(t) = self.round_tolerance {
            check(
                t > 0.0 && t < 1.0,
                "round_tolerance",
                t,
                "a relative residual in (0, 1) (or null: the solver's tolerance)",
            )?;
        }
        if let Some(t) = self.probe_tolerance {
            check(
                t > 0.0 && t < 1.0,
                "probe_tolerance",
                t,
                "a relative residual in (0, 1) (or null: the round's tolerance)",
            )?;
        }
        if let TreeSolver::Pcg {
            tolerance,
            max_iterations,
        } = self.solver
        {
            if !(tolerance > 0.0 && tolerance < 1.0) || max_iterations == 0 {
                return Err(bad(
                    "solver",
                    format!("{:?}", self.solver),
                    "a PCG tolerance in (0, 1) and at least one iteration",
                ));
            }
        }
        Ok(())
    }
}
