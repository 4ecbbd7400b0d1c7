//! The flags of `rkwave reconstruct`, shared by its 1D path, its image-plane path and the
//! reconstruction on a plan's tree.

use std::path::PathBuf;

use clap::Args;
use rkwave::sampling::Domain;

use super::solve_args::{MethodArg, SolveArgs};
use super::{FamilyArg, FilterSpec};

/// `rkwave reconstruct`.
#[derive(Args, Debug)]
pub struct ReconstructArgs {
    /// Samples: CSV with header `x,value[,value...]` or NumPy `.npy` (m x (1 + channels)).
    #[arg(long)]
    pub input: PathBuf,
    /// Domain `a,b` (default: the smallest and largest sample position).
    #[arg(long, allow_hyphen_values = true)]
    pub domain: Option<Domain>,
    /// Vanishing moments p (1 = Haar, up to 10); default 3 in 1D and 2 on the image plane
    /// (`--dim 2`, as `rkwave image` and the plan: chosen by measurement on real renders,
    /// docs/measurements/real-renders.md).
    #[arg(long)]
    pub p: Option<usize>,
    /// Interior filter family; default CDV's choice (db for p <= 3, sym for p >= 4).
    #[arg(long, value_enum)]
    pub family: Option<FamilyArg>,
    /// Solve method.
    #[arg(long, value_enum, default_value_t = MethodArg::Single)]
    pub method: MethodArg,
    /// Solve knobs.
    #[command(flatten)]
    pub solve: SolveArgs,
    /// Grid points of the output (uniform, both ends included).
    #[arg(long, default_value_t = 1000, value_parser = super::limits::grid)]
    pub grid: usize,
    /// Output: `.npy` (NumPy float64, `G x (1 + channels)`) or CSV (`x,<channels>`) otherwise.
    #[arg(long)]
    pub output: PathBuf,
    /// Overwrite an existing output.
    #[arg(long)]
    pub force: bool,
    /// Print a JSON report.
    #[arg(long)]
    pub json: bool,
    /// Dimension of the sample positions: 1 (`x,value...`) or 2 (image plane, `x,y,c1...`,
    /// see `reconstruct2d_cmd`).
    #[arg(long, default_value_t = 1)]
    pub dim: usize,
    /// Image resolution `WxH` (with `--dim 2`).
    #[arg(long)]
    pub resolution: Option<String>,
    /// With `--dim 2`: the folder of an `rkwave plan` run; the samples are fitted on the tree
    /// that plan built (its p, levels and depth map; `--method` and `--p` are not used).
    #[arg(long)]
    pub state: Option<PathBuf>,
    /// With `--dim 2 --state`: write the fit's box pixels alone. The default output adds the
    /// significant mean residual of each pixel's samples and clamps the result to the range
    /// of the samples in the pixel's 3x3 neighbourhood (the plan's `pixels` parameter).
    #[arg(long)]
    pub no_residual: bool,
    /// With `--dim 2` (no `--state`): the pixel estimate. `auto` (default) per pixel the
    /// candidate of least estimated risk against the mean of the pixel's samples (the mean,
    /// the films by SURE, shrinkage of the pixel means at their own noise, mixtures, their
    /// projections onto the samples' range), every pixel within the range of the samples
    /// around it (falls back to `fit`, with a note,
    /// when a pixel has no sample or most have one; the default is `fit` when a flag only the
    /// fit reads is given: --p, --family, --method, --levels, --rho, --ridge, --smoothing);
    /// `fit` the least-squares fit's box pixels; `fit-clamped` the fit clamped to the range of each pixel's samples;
    /// `box` the mean of each pixel's samples; `shrunk` the box pixels, wavelet-shrunk at the
    /// noise level of the samples' own spread (printed; for Monte Carlo noise). `box` and
    /// `shrunk` do not fit, so `--method` and `--p` are not used.
    #[arg(long, value_name = "auto|fit|fit-clamped|box|shrunk")]
    pub pixels: Option<rkwave::image::UniformEstimate>,
    /// 1D: read the samples in chunks, never whole (a `.npy` file sorted by x, `--method
    /// single --factorization qr`; the same coefficients). `auto` streams when reading them
    /// whole would exceed `--memory-limit`.
    #[arg(long, value_enum, default_value_t = StreamArg::Auto)]
    pub stream: StreamArg,
    /// With `--dim 2`: drop the samples whose value is NaN or infinite (counted in the
    /// report) instead of refusing the file.
    #[arg(long)]
    pub drop_nonfinite: bool,
    // --- The image plane's fit knobs and tiles (`reconstruct2d_cmd`) ---
    /// With `--dim 2`: relative weight of a first-difference penalty on neighbouring
    /// coefficients (default 0, the least-squares fit; not with --tile).
    #[arg(long)]
    pub smoothing: Option<f64>,
    /// With `--dim 2`: fit the image tile by tile, tiles of T x T pixels, each on its tile and
    /// a halo of --halo pixels, in memory bounded by the tile size and --workers, not by the
    /// image (the input is read in chunks twice and spilled into one scratch file per row of
    /// tiles, see --scratch).
    #[arg(long, value_name = "T")]
    pub tile: Option<usize>,
    /// With `--tile`: the halo in pixels around each tile [default: 12, from the halo study
    /// in docs/measurements/image-plane.md].
    #[arg(long, value_name = "H")]
    pub halo: Option<usize>,
    /// With `--tile`: tiles fitted at once [default: the number of cores].
    #[arg(long, value_name = "N")]
    pub workers: Option<usize>,
    /// With `--tile`: the folder for the band files (about the input's size at 8 bytes a
    /// value, removed after the fit) [default: the output's folder].
    #[arg(long, value_name = "DIR")]
    pub scratch: Option<std::path::PathBuf>,
}

/// `p` of the image plane when `--p` is not given (`rkwave image`'s and the plan's).
pub const IMAGE_P: usize = 2;
/// `p` of the 1D path when `--p` is not given.
pub const LINE_P: usize = 3;

impl ReconstructArgs {
    /// The filter bank: `--p` and `--family`, `p` by default [`LINE_P`] in 1D and
    /// [`IMAGE_P`] on the image plane.
    pub fn filter(&self) -> FilterSpec {
        let default = if self.dim == 2 { IMAGE_P } else { LINE_P };
        FilterSpec {
            p: self.p.unwrap_or(default),
            family: self.family,
        }
    }

    /// Refuses the image plane's flags with `--dim 1`.
    pub fn check_image_flags(&self) -> Result<(), super::CliError> {
        let given = [
            ("--smoothing", self.smoothing.is_some()),
            ("--tile", self.tile.is_some()),
            ("--halo", self.halo.is_some()),
            ("--workers", self.workers.is_some()),
            ("--scratch", self.scratch.is_some()),
            ("--drop-nonfinite", self.drop_nonfinite),
        ];
        match given.iter().find(|(_, g)| *g) {
            Some((flag, _)) if self.dim != 2 => Err(super::CliError::Invalid(format!(
                "{flag} is for the image plane: use it with --dim 2 --resolution WxH, or drop it"
            ))),
            _ => Ok(()),
        }
    }

    /// The dimension of the samples (1 or 2), once the flags are checked against it: the
    /// image plane's flags, `--no-residual` and `--state` only with `--dim 2`, `--stream`
    /// only with `--dim 1`. The command line dispatches on it (`--dim 1`: `reconstruct_cmd`,
    /// `--dim 2`: `reconstruct2d_cmd`).
    pub fn checked_dim(&self) -> Result<usize, super::CliError> {
        use super::CliError;
        self.check_image_flags()?;
        if self.no_residual && (self.dim != 2 || self.state.is_none()) {
            return Err(CliError::Invalid(
                "--no-residual turns off the residual correction of an adaptive plan's image: use \
                 it with --dim 2 --state DIR"
                    .into(),
            ));
        }
        if self.dim != 1 && self.stream != StreamArg::Auto {
            return Err(CliError::Invalid(
                "--stream reads 1D samples in chunks: use it with --dim 1".into(),
            ));
        }
        match self.dim {
            1 if self.state.is_some() => Err(CliError::Invalid(
                "--state is the plan of an image (`rkwave plan`): use it with --dim 2".into(),
            )),
            d @ (1 | 2) => Ok(d),
            d => Err(CliError::Invalid(format!("--dim {d}: expected 1 or 2"))),
        }
    }
}

/// `--stream`: whether `rkwave reconstruct --dim 1` reads its samples in chunks.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum StreamArg {
    /// When a `.npy` input read whole would exceed the memory limit (a CSV input is read whole).
    Auto,
    /// Always (a `.npy` or CSV input sorted by position).
    Always,
    /// Never: the samples are read whole (and sorted if need be).
    Never,
}
