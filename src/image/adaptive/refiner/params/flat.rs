//! The flat serialized form of [`AdaptiveParams`] ([`FlatParams`]): plan state files and JSON
//! reports hold one key a parameter, as written before the parameters were grouped, so that
//! state files written by earlier versions still load and the output is byte for byte the same.

use serde::{Deserialize, Serialize};

use super::super::super::correction::{PixelEstimate, RESIDUAL_Z};
use super::super::super::pcg::TreeSolver;
use super::super::positions::PositionPattern;
use super::{
    AdaptiveParams, FitParams, GrowthParams, ImageSampling, IndicatorParams, NoiseParams,
    OutputParams, QuadTreeParams,
};
use crate::adaptive::marking::SpreadRule;
use crate::adaptive::{MarkingParams, StopParams, TreeParams};

/// The flat serialized form of [`AdaptiveParams`]: one key a field, the keys and their order
/// as before the grouping, the defaults of keys older files lack.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub(super) struct FlatParams {
    p: usize,
    below_pixel: u32,
    base_level: Option<u32>,
    base_fraction: f64,
    rho: f64,
    theta: f64,
    max_ratio: f64,
    min_growth: f64,
    /// Older files lack it: they spread by the indicator, as they were written.
    #[serde(default = "spread_of_old_files")]
    spread: SpreadRule,
    #[serde(default)]
    spread_share: f64,
    /// Older files lack it: the tree alone, as they were written.
    #[serde(default)]
    pixel_share: f64,
    #[serde(default = "default_rho_limit")]
    rho_limit: f64,
    tolerance: f64,
    budget: usize,
    max_rounds: usize,
    seed: u64,
    #[serde(default = "direct_solver")]
    solver: TreeSolver,
    #[serde(default = "default_round_tolerance")]
    round_tolerance: Option<f64>,
    /// Older files lack it: their probes stop at the round's tolerance, as they were written.
    #[serde(default)]
    probe_tolerance: Option<f64>,
    #[serde(default = "default_false_alarm")]
    false_alarm: f64,
    #[serde(default = "default_probes")]
    probes: usize,
    #[serde(default)]
    pixels: PixelEstimate,
    #[serde(default = "default_residual_z")]
    residual_z: f64,
    #[serde(default)]
    measure_rebuild: bool,
    /// Older files lack it: they continue with jittered strata, as they were written.
    #[serde(default = "pattern_of_old_files")]
    pattern: PositionPattern,
    /// Older files lack it: the plan covers every pixel at one sample a pixel or more.
    #[serde(default = "cover_pixels_default")]
    cover_pixels: bool,
    /// Older files lack it: no floor, as they were written (and a plan without one writes
    /// no key, so its file is as before).
    #[serde(default, skip_serializing_if = "no_floor")]
    pixel_floor: f64,
}

fn no_floor(f: &f64) -> bool {
    *f == 0.0
}

fn cover_pixels_default() -> bool {
    true
}

fn spread_of_old_files() -> SpreadRule {
    SpreadRule::Indicator
}

fn pattern_of_old_files() -> PositionPattern {
    PositionPattern::Stratified
}

fn default_residual_z() -> f64 {
    RESIDUAL_Z
}

fn default_false_alarm() -> f64 {
    AdaptiveParams::default().noise.false_alarm
}

fn default_probes() -> usize {
    AdaptiveParams::default().noise.probes
}

fn default_round_tolerance() -> Option<f64> {
    AdaptiveParams::default().fit.round_tolerance
}

fn default_rho_limit() -> f64 {
    AdaptiveParams::default().sampling.rho_limit
}

fn direct_solver() -> TreeSolver {
    TreeSolver::Direct
}

impl From<AdaptiveParams> for FlatParams {
    fn from(a: AdaptiveParams) -> Self {
        Self {
            p: a.tree.p,
            below_pixel: a.quad.below_pixel,
            base_level: a.quad.base_level,
            base_fraction: a.quad.base_fraction,
            rho: a.tree.rho,
            theta: a.marking.theta,
            max_ratio: a.indicator.max_ratio,
            min_growth: a.growth.min_growth,
            spread: a.growth.spread,
            spread_share: a.growth.spread_share,
            pixel_share: a.growth.pixel_share,
            rho_limit: a.sampling.rho_limit,
            tolerance: a.stop.tolerance,
            budget: a.stop.budget,
            max_rounds: a.stop.max_rounds,
            seed: a.sampling.seed,
            solver: a.fit.solver,
            round_tolerance: a.fit.round_tolerance,
            probe_tolerance: a.fit.probe_tolerance,
            false_alarm: a.noise.false_alarm,
            probes: a.noise.probes,
            pixels: a.output.pixels,
            residual_z: a.output.residual_z,
            measure_rebuild: a.fit.measure_rebuild,
            pattern: a.sampling.pattern,
            cover_pixels: a.sampling.cover_pixels,
            pixel_floor: a.sampling.pixel_floor,
        }
    }
}

impl From<FlatParams> for AdaptiveParams {
    fn from(f: FlatParams) -> Self {
        Self {
            tree: TreeParams { p: f.p, rho: f.rho },
            quad: QuadTreeParams {
                below_pixel: f.below_pixel,
                base_level: f.base_level,
                base_fraction: f.base_fraction,
            },
            sampling: ImageSampling {
                rho_limit: f.rho_limit,
                seed: f.seed,
                pattern: f.pattern,
                cover_pixels: f.cover_pixels,
                pixel_floor: f.pixel_floor,
            },
            marking: MarkingParams { theta: f.theta },
            indicator: IndicatorParams {
                max_ratio: f.max_ratio,
            },
            growth: GrowthParams {
                min_growth: f.min_growth,
                spread: f.spread,
                spread_share: f.spread_share,
                pixel_share: f.pixel_share,
            },
            stop: StopParams {
                tolerance: f.tolerance,
                budget: f.budget,
                max_rounds: f.max_rounds,
            },
            fit: FitParams {
                solver: f.solver,
                round_tolerance: f.round_tolerance,
                probe_tolerance: f.probe_tolerance,
                measure_rebuild: f.measure_rebuild,
            },
            noise: NoiseParams {
                false_alarm: f.false_alarm,
                probes: f.probes,
            },
            output: OutputParams {
                pixels: f.pixels,
                residual_z: f.residual_z,
            },
        }
    }
}
