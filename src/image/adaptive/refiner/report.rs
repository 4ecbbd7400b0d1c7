//! What a round and a run of the adaptive image refiner report: per-round logs, seconds by
//! stage, the run's report and its result, and the notes in words.

use serde::Serialize;

use super::super::correction::ResidualCorrection;
use super::super::fit::{TreeFit, TreeFitReport};
use super::super::significance::NoiseLevel;
use super::super::AdaptiveError;
use crate::adaptive::QuadTree;
use crate::adaptive::StopReason;
use crate::image::{ImagePlane, PixelImage};

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
    /// Of the round's new samples, those given to the pixels by their pooled spread
    /// (`GrowthParams::pixel_share`, module `pixel_spread`).
    pub pixel_spread: usize,
    /// Samples held back for the pixels short of the coverage rule's samples so far (module
    /// `coverage`; 0 when it is off).
    pub reserved: usize,
    /// Samples that topped pixels up after this round's fit instead of stopping (the
    /// coverage rule's fill round; 0 otherwise).
    pub filled: usize,
    /// What the coverage rule did in this round, or the pixels it could not fill, in words.
    pub coverage: Option<String>,
    /// The solve.
    pub fit: TreeFitReport,
    /// The last round's fit continued to the solver's tolerance from the round's
    /// coefficients (`AdaptiveParams::round_tolerance` only; `None` otherwise).
    pub final_fit: Option<TreeFitReport>,
    /// The round's fit against a rebuild from scratch (`AdaptiveParams::measure_rebuild`
    /// only; `None` otherwise).
    pub rebuild: Option<RebuildCost>,
    /// Seconds by phase (wall clock of this process).
    pub times: RoundTimes,
}

/// Seconds of one round by phase (wall clock). The fit's own parts are in its report:
/// [`TreeFitReport::kernel_s`] (under PCG the single-scale rows and the exact diagonal; under
/// the direct solve the kernel rows), [`TreeFitReport::normal_s`] and
/// [`TreeFitReport::solve_s`] (the iterations or the factor); `fit_s` less those is the noise
/// test's probe values and its residuals.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct RoundTimes {
    /// The round's fit, the noise test's probe channels and residuals included.
    pub fit_s: f64,
    /// The indicator (the predicted detail of every slot).
    pub indicator_s: f64,
    /// The indicator, the stop test, the tally of the slots and the marking (`indicator_s`
    /// included).
    pub refine_s: f64,
    /// Deepening the tree and drawing the next positions.
    pub position_s: f64,
    /// A stopping round's fit continued to the solver's tolerance (0 otherwise).
    pub final_fit_s: f64,
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
    /// (`AdaptiveParams::measure_rebuild`; 0 otherwise), in none of the stages above.
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
    /// The output pixels: the residual correction's counts (`super::super::correction`).
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
    /// The output pixels (`AdaptiveParams::pixels`; by default the fit's box pixels plus
    /// the significant mean residual, `super::super::correction`).
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

/// The final fit's fallbacks in words: a ridge, an unconverged PCG, unsampled functions.
pub(super) fn fit_notes(r: &TreeFitReport) -> Vec<String> {
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

/// The noise test's cut-offs in words: slots left coarse, densifying rounds.
pub(super) fn noise_notes(rounds: &[ImageRound], false_alarm: f64) -> Vec<String> {
    let mut notes = Vec::new();
    let Some(last) = rounds.last() else {
        return notes;
    };
    if let Some(level) = &last.noise {
        if last.insignificant > 0 {
            notes.push(format!(
                "{} slots not deepened because their detail is not significant (within the \
                 noise at false-alarm rate {false_alarm}; estimated noise sigma {:.3e} from the \
                 residuals, {} probe channel(s))",
                last.insignificant, level.sigma, level.probes
            ));
        }
    }
    let densified: Vec<String> = rounds
        .iter()
        .filter_map(|r| r.densified_to.map(|t| format!("round {} to {t}", r.round)))
        .collect();
    if !densified.is_empty() {
        notes.push(format!(
            "nothing significant left to deepen: the budget raised the samples per slot ({}), \
             so the fit averages the noise",
            densified.join(", ")
        ));
    }
    notes
}
