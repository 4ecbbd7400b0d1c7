//! Typed reports of the image-plane commands that take a renderer's samples: what a
//! reconstruction from files or one call of the plan protocol did, for the text output and
//! `--json` alike (the command line only prints them).

use std::path::{Path, PathBuf};

use serde::Serialize;

use super::adaptive::{ResidualCorrection, SamplePositions, TreeFitReport};
use super::method::{ImageMethod, ImageReconstruction};
use super::plan::{PlanReconstruction, PlanState, PlanStep};
use super::wavelet::WaveletReport;
use super::{ImagePlane, ImageSamples};
use crate::refine::StopReason;

/// Peak resident memory of this process so far (`VmHWM` of `/proc/self/status`), in MB;
/// `None` where that file does not exist.
pub fn peak_memory_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// Seconds per stage of a reconstruction from a sample file.
#[derive(Clone, Debug, Serialize)]
pub struct FileStageSeconds {
    /// Reading and checking the samples.
    pub read: f64,
    /// The fit (normal equations and solve; 0 for film filters).
    pub fit: f64,
    /// Pixel values from the fit or the splat.
    pub pixels: f64,
    /// Writing the image.
    pub write: f64,
    /// End to end.
    pub total: f64,
}

/// A reconstruction of a renderer's samples onto pixels (`reconstruct --dim 2`).
#[derive(Clone, Debug, Serialize)]
pub struct FileReconstructionReport {
    /// The sample file.
    pub input: PathBuf,
    /// The image written.
    pub output: PathBuf,
    /// `WxH`.
    pub resolution: String,
    /// Samples `m`.
    pub samples: usize,
    /// Value channels per sample.
    pub channels: usize,
    /// The reconstruction method's name (`wavelet`, `local`, a film's), or `auto` for the
    /// pixel estimate of that name (films chosen per pixel; `pixels` says which).
    pub method: String,
    /// Vanishing moments of the wavelet methods.
    pub p: usize,
    /// Basis functions (wavelet methods).
    pub functions: Option<usize>,
    /// The solve's report (wavelet methods).
    pub solve: Option<WaveletReport>,
    /// Seconds per stage.
    pub time_s: FileStageSeconds,
    /// Peak resident memory in MB, where the platform reports it.
    pub peak_mb: Option<f64>,
    /// Every fallback or cut-off, in words.
    pub notes: Vec<String>,
    /// The pixel estimate, its noise level and thresholds (set by the caller; `None` when
    /// none was chosen).
    pub pixels: Option<super::estimate::EstimateReport>,
    /// The samples dropped for a non-finite value (set by the caller; none by default).
    pub nonfinite: super::DroppedSamples,
}

impl FileReconstructionReport {
    /// The report of `samples` from `input` reconstructed by `method` (basis `p`) into
    /// `output` as `done` (its image aside); `read` and `write` seconds measured by the
    /// caller, `total` since it started.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        input: &Path,
        output: &Path,
        plane: ImagePlane,
        samples: &ImageSamples,
        method: ImageMethod,
        p: usize,
        done: &ImageReconstruction,
        read: f64,
        write: f64,
        total: f64,
    ) -> Self {
        Self {
            input: input.to_path_buf(),
            output: output.to_path_buf(),
            resolution: plane.to_string(),
            samples: samples.len(),
            channels: samples.channels(),
            method: method.into(),
            p,
            functions: done.functions,
            solve: done.solve.clone(),
            time_s: FileStageSeconds {
                read,
                fit: done.time_s.fit,
                pixels: done.time_s.pixels,
                write,
                total,
            },
            peak_mb: peak_memory_mb(),
            notes: done.notes.clone(),
            pixels: None,
            nonfinite: super::DroppedSamples::default(),
        }
    }

    /// The report with the pixel estimate made: its report in `pixels`, and as the method
    /// `auto` where that estimate was made, the box film's name for `box` and `shrunk` (the
    /// pixel statistics), the fit's method otherwise.
    pub fn with_pixels(mut self, estimated: super::estimate::EstimateReport) -> Self {
        use super::estimate::UniformEstimate;
        match estimated.estimate {
            UniformEstimate::Auto => self.method = UniformEstimate::Auto.name().into(),
            UniformEstimate::Box | UniformEstimate::Shrunk => {
                self.method = ImageMethod::Film(super::filters::FilmFilterKind::Box).into()
            }
            UniformEstimate::Fit | UniformEstimate::FitClamped => {}
        }
        self.pixels = Some(estimated);
        self
    }
}

/// One call of the plan protocol (`plan`): the positions written and where the plan stands.
#[derive(Clone, Debug, Serialize)]
pub struct PlanCallReport {
    /// The state file.
    pub state: PathBuf,
    /// The positions file written.
    pub out: PathBuf,
    /// `WxH`.
    pub resolution: String,
    /// Rounds whose positions have been handed out, the ones just written included.
    pub round: usize,
    /// Positions written by this call.
    pub positions: usize,
    /// Positions handed out in all.
    pub total_positions: usize,
    /// The sample budget.
    pub budget: usize,
    /// Why the plan stopped (`None` while it runs).
    pub stop: Option<StopReason>,
    /// The round fitted on the samples given (`None` for a new plan).
    pub step: Option<PlanStep>,
}

impl PlanCallReport {
    /// The report of a call that left the plan in `state` (saved under `dir`) and wrote
    /// `next` to `out`, after `step` (`None`: the call started the plan).
    pub fn new(
        state: &PlanState,
        dir: &Path,
        out: &Path,
        next: &SamplePositions,
        step: Option<PlanStep>,
    ) -> Self {
        Self {
            state: PlanState::path(dir),
            out: out.to_path_buf(),
            resolution: state.plane.to_string(),
            round: state.round(),
            positions: next.len(),
            total_positions: state.positions(),
            budget: state.params.stop.budget,
            stop: state.stop,
            step,
        }
    }
}

/// A reconstruction on the tree of a plan (`reconstruct --dim 2 --state`).
#[derive(Clone, Debug, Serialize)]
pub struct PlanReconstructionReport {
    /// The sample file.
    pub input: PathBuf,
    /// The image written.
    pub output: PathBuf,
    /// The state file.
    pub state: PathBuf,
    /// `WxH`.
    pub resolution: String,
    /// Samples `m`.
    pub samples: usize,
    /// Value channels per sample.
    pub channels: usize,
    /// The last round of the samples.
    pub round: usize,
    /// Whether the samples are the plan's final set.
    pub complete: bool,
    /// Vanishing moments of the plan's basis.
    pub p: usize,
    /// Levels of the plan's basis per axis.
    pub levels: (u32, u32),
    /// Active cells of the tree per step.
    pub cells_per_step: Vec<usize>,
    /// The solve on the tree.
    pub fit: TreeFitReport,
    /// The output pixels: what the residual correction did (pixels corrected, noise, `z`).
    pub pixels: ResidualCorrection,
    /// Seconds end to end.
    pub time_s: f64,
    /// Every fallback, the parameters the plan overrides and the output's correction, in
    /// words.
    pub notes: Vec<String>,
    /// The samples dropped for a non-finite value.
    pub nonfinite: super::DroppedSamples,
}

impl PlanReconstructionReport {
    /// The report of `done` (from `samples` in `input`, the plan in `dir`) written to
    /// `output`; `overridden` names the caller's parameters the plan does not use, `time_s`
    /// is the time end to end. The notes are `overridden`, then [`plan_fit_notes`], then the
    /// residual correction's.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        state: &PlanState,
        dir: &Path,
        input: &Path,
        output: &Path,
        samples: &ImageSamples,
        done: &PlanReconstruction,
        overridden: Vec<String>,
        time_s: f64,
    ) -> Self {
        let mut notes = overridden;
        notes.extend(plan_fit_notes(done));
        notes.push(done.correction.note());
        notes.extend(done.dropped.note());
        Self {
            input: input.to_path_buf(),
            output: output.to_path_buf(),
            state: PlanState::path(dir),
            resolution: state.plane.to_string(),
            samples: samples.len(),
            channels: samples.channels(),
            round: done.round,
            complete: done.complete,
            p: state.params.tree.p,
            levels: done.tree.basis().levels(),
            cells_per_step: done.tree.cells_per_step(),
            fit: done.fit.report.clone(),
            pixels: done.correction.clone(),
            time_s,
            notes,
            nonfinite: done.dropped.clone(),
        }
    }
}

/// What a reconstruction on a plan's tree must say: an unfinished plan, a ridge, functions
/// without samples.
pub fn plan_fit_notes(done: &PlanReconstruction) -> Vec<String> {
    let mut notes = Vec::new();
    if !done.complete {
        notes.push(format!(
            "the plan has not stopped: this is the fit of the samples of rounds 0..={} on \
             their tree, not the final image",
            done.round
        ));
    }
    notes.extend(done.fit_note.clone());
    let fit = &done.fit.report;
    if fit.ridge > 0.0 {
        notes.push(format!(
            "the normal matrix was numerically singular: a relative ridge {:.0e} was added",
            fit.ridge
        ));
    }
    if fit.unsampled > 0 {
        notes.push(format!(
            "{} functions have no sample in their support (held at 0 by the ridge)",
            fit.unsampled
        ));
    }
    notes
}
