//! The flags of `rkwave image` (its adaptive mode's included) and the checks of the
//! image-plane flags that several commands share.

use std::io::IsTerminal;
use std::path::PathBuf;

use clap::{Args, ValueEnum};
use indicatif::ProgressBar;
use rkwave::image::adaptive::TreeSolver;
use rkwave::image::sampler::Sampler;
use rkwave::image::scene::Scene;
use rkwave::image::ImagePlane;

use super::CliError;

/// `rkwave image`.
#[derive(Args, Debug)]
pub struct ImageArgs {
    /// Scene: a JSON file, or the name of a built-in scene (data/scenes/NAME.json).
    #[arg(long)]
    pub scene: String,
    /// Resolution `WxH` in pixels.
    #[arg(long, default_value = "256x256")]
    pub resolution: String,
    /// Samples per pixel, plain or in `1e3` notation.
    #[arg(long, default_value_t = 4, value_parser = super::limits::count)]
    pub spp: usize,
    /// Sampler: uniform, stratified or sobol.
    #[arg(long, default_value = "stratified")]
    pub sampler: String,
    /// Method: wavelet, local, box, triangle, gaussian, mitchell or lanczos.
    #[arg(long, default_value = "wavelet")]
    pub method: String,
    /// Vanishing moments p of the wavelet methods.
    #[arg(long, default_value_t = 2)]
    pub p: usize,
    /// Pixel filter applied to the wavelet reconstruction (box by default; a film filter name).
    #[arg(long)]
    pub pixel_filter: Option<String>,
    /// Standard deviation of Gaussian noise added to every sample value.
    #[arg(long, default_value_t = 0.0)]
    pub noise: f64,
    /// Samples per basis function, rho = m / (nx ny): sets the wavelet level per axis
    /// (default 4: at 4 spp one function per pixel); with `--adaptive`, samples per slot of
    /// the tree (default 2).
    #[arg(long)]
    pub rho: Option<f64>,
    /// The wavelet fit's ridge and smoothing.
    #[command(flatten)]
    pub fit: WaveletFitArgs,
    /// Seed of positions and noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Also write the equivalent reconstruction filter of pixel `X,Y` (the weight of each
    /// sample) as CSV beside the image.
    #[arg(long)]
    pub show_filter: Option<String>,
    /// Ground-truth supersampling rate n (n x n strata per pixel).
    #[arg(long, default_value_t = rkwave::image::truth::DEFAULT_RATE)]
    pub truth_rate: usize,
    /// Ground-truth cache folder.
    #[arg(long, default_value = "out/truth")]
    pub truth_cache: PathBuf,
    /// Output image: .png (8-bit sRGB), .exr (linear float) or .npy.
    #[arg(long)]
    pub out: PathBuf,
    /// Overwrite existing outputs.
    #[arg(long)]
    pub force: bool,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// The adaptive mode's flags.
    #[command(flatten)]
    pub adaptive: AdaptiveArgs,
}

/// Flags of the adaptive mode of `rkwave image`.
#[derive(Args, Debug)]
pub struct AdaptiveArgs {
    /// Adaptive sampling: a quadtree of the wavelet basis refined where the scene needs it,
    /// with `--spp` as the average samples per pixel (or `--budget`).
    #[arg(long)]
    pub adaptive: bool,
    /// Total sample budget of the adaptive mode (default: spp x pixels), plain or in `1e6` notation.
    #[arg(long, value_parser = super::limits::count)]
    pub budget: Option<usize>,
    /// Adaptive mode: depth limit in levels below the pixel.
    #[arg(long, default_value_t = 1)]
    pub below_pixel: u32,
    /// Adaptive mode: the solver of each round's fit. `direct`: the sparse Cholesky of the
    /// assembled normal matrix (the reference); `pcg`: matrix-free Jacobi-preconditioned CG
    /// (about 7x less memory; to 1e-6, at most 400 iterations); `schwarz`: CG on the
    /// assembled matrix preconditioned by additive Schwarz on 8-pixel tiles (to 1e-10, at most
    /// 400). For both, the rounds' fits, which only steer the refinement, stop at relative
    /// residual 1e-2 (tens of iterations) and the final fit is continued to the solver's
    /// tolerance.
    /// Iterations per round are printed for the last two; `--adaptive-params` sets the
    /// tolerances (`{"round_tolerance": null}`: every round to the solver's tolerance).
    #[arg(long, value_enum, default_value_t = SolverChoice::Direct)]
    pub solver: SolverChoice,
    /// Adaptive mode: false-alarm rate of the noise test, the chance per round that noise
    /// alone deepens a slot (the noise level is estimated from the fits' residuals; 0: no
    /// noise test, every detail is deepened).
    #[arg(long, default_value_t = 0.01)]
    pub false_alarm: f64,
    /// Adaptive mode: a JSON object overriding fields of the refiner's parameters
    /// (`AdaptiveParams`, e.g. `{"theta": 0.3, "spread": "uniform", "rho_limit": 4}`), applied
    /// after the other flags; for experiments on the refiner's policy.
    #[arg(long, value_name = "JSON")]
    pub adaptive_params: Option<String>,
    /// Adaptive mode: write the fit's box pixels alone. The default output adds the
    /// significant mean residual of each pixel's samples and clamps the result to the range
    /// of the samples in the pixel's 3x3 neighbourhood; the rows show both either way
    /// (`--adaptive-params '{"pixels": "residual_corrected"}'`: the residual without the
    /// clamp).
    #[arg(long)]
    pub no_residual: bool,
}

/// The tree fit's solver on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SolverChoice {
    /// Sparse Cholesky of the assembled normal matrix.
    Direct,
    /// Matrix-free Jacobi-preconditioned CG.
    Pcg,
    /// CG preconditioned by additive Schwarz on overlapping tiles.
    Schwarz,
}

impl SolverChoice {
    /// The tree fit's solver of this choice.
    pub fn solver(self) -> TreeSolver {
        match self {
            Self::Direct => TreeSolver::Direct,
            Self::Pcg => TreeSolver::default(),
            Self::Schwarz => TreeSolver::Schwarz {
                tolerance: 1e-10,
                max_iterations: 400,
                tile: 8.0,
                halo: 1.0,
            },
        }
    }
}

/// The wavelet fit's regularization flags, shared by `image` and `compare`.
#[derive(Args, Debug, Clone, Copy)]
pub struct WaveletFitArgs {
    /// Relative ridge on the wavelet normal equations (G + ridge diag(G)).
    #[arg(long, default_value_t = 1e-9)]
    pub ridge: f64,
    /// Relative weight of a first-difference penalty on neighbouring wavelet coefficients
    /// (0: the least-squares fit).
    #[arg(long, default_value_t = 0.0)]
    pub smoothing: f64,
}

/// A scene argument: an existing file, or a built-in scene's name.
pub fn scene_path(arg: &str) -> Result<PathBuf, CliError> {
    let direct = PathBuf::from(arg);
    if direct.exists() {
        return Ok(direct);
    }
    let builtin = Scene::builtin_dir().join(format!("{arg}.json"));
    if builtin.exists() {
        return Ok(builtin);
    }
    let names = Scene::builtin_files()
        .map(|fs| {
            fs.iter()
                .filter_map(|f| f.file_stem().map(|s| s.to_string_lossy().into_owned()))
                .collect::<Vec<_>>()
                .join(", ")
        })
        .unwrap_or_default();
    Err(CliError::Invalid(format!(
        "--scene {arg}: no such file and no built-in scene of that name (built-in: {names})"
    )))
}

/// Before any work: each of `outputs` is new (or `force`), its folder exists and takes a
/// file (the command does not create it), and it is none of `inputs` after symbolic links,
/// hard links and path spellings ([`rkwave::io::output::check_output`]).
pub fn check_outputs(
    outputs: &[&std::path::Path],
    force: bool,
    inputs: &[&std::path::Path],
) -> Result<(), CliError> {
    for out in outputs {
        rkwave::io::output::check_output(out, force, inputs)?;
    }
    Ok(())
}

/// Parses `--resolution`.
pub fn parse_resolution(s: &str) -> Result<ImagePlane, CliError> {
    s.parse::<ImagePlane>()
        .map_err(|e| CliError::flag("--resolution", e))
}

/// Parses `--sampler`.
pub fn parse_sampler(s: &str) -> Result<Sampler, CliError> {
    s.parse::<Sampler>()
        .map_err(|e| CliError::parse("--sampler", e))
}

/// Parses `--p` for the wavelet methods.
pub fn check_p(p: usize) -> Result<usize, CliError> {
    if !(1..=4).contains(&p) {
        return Err(CliError::Invalid(format!(
            "--p {p}: the image plane supports p = 1 to 4 (2 or 3 are practical)"
        )));
    }
    Ok(p)
}

/// Checks `--rho` (samples per basis function).
pub fn check_rho(rho: f64) -> Result<f64, CliError> {
    if !(rho.is_finite() && (0.01..=1e6).contains(&rho)) {
        return Err(CliError::Invalid(format!(
            "--rho {rho}: give samples per basis function in [0.01, 1e6] (4 is one function \
             per pixel at 4 spp)"
        )));
    }
    Ok(rho)
}

/// Checks `--ridge` (relative ridge of the wavelet normal equations).
pub fn check_ridge(ridge: f64) -> Result<f64, CliError> {
    if !(ridge.is_finite() && (0.0..=1e-2).contains(&ridge)) {
        return Err(CliError::Invalid(format!(
            "--ridge {ridge}: give a relative ridge in [0, 1e-2] (1e-9 by default)"
        )));
    }
    Ok(ridge)
}

/// A spinner on stderr when it is a terminal, hidden otherwise.
pub fn spinner(message: &str) -> ProgressBar {
    let bar = if std::io::stderr().is_terminal() {
        ProgressBar::new_spinner()
    } else {
        ProgressBar::hidden()
    };
    bar.set_message(message.to_string());
    bar.enable_steady_tick(std::time::Duration::from_millis(120));
    bar
}

/// The plan in the folder `dir` ([`rkwave::io::plan_files`]), its errors as the command
/// line's: a refusal of the plan's state machine or of an output as those, the rest (no plan
/// there, an unreadable state) by their kind.
pub fn load_plan(dir: &std::path::Path) -> Result<rkwave::image::plan::PlanState, CliError> {
    rkwave::image::plan::PlanState::load(dir).map_err(plan_file)
}

/// A plan's file error as the command line's (see [`load_plan`]).
pub fn plan_file(e: rkwave::io::plan_files::PlanFileError) -> CliError {
    use rkwave::io::plan_files::PlanFileError;
    match e {
        PlanFileError::Write(e) => CliError::from(e),
        PlanFileError::Plan(e) => CliError::from(e),
        e => CliError::from(e),
    }
}
