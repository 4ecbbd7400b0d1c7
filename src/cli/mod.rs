//! The command line: arguments are parsed and validated into plain values here, then those
//! values build the library objects. No algorithm lives in the binary.

pub mod adapt_cmd;
pub mod adapt_text;
pub mod basis_cmd;
pub mod compare_cmd;
pub mod demo;
pub mod demo_image;
pub mod eval_cmd;
pub mod figures;
pub mod hints;
pub mod image_adaptive_cmd;
pub mod image_args;
pub mod image_cmd;
pub mod limits;
pub mod plan_cmd;
pub mod reconstruct2d_cmd;
pub mod reconstruct_args;
pub mod reconstruct_cmd;
pub mod reconstruct_stream;
pub mod report_args;
pub mod report_cmd;
pub mod scaling_cmd;
pub mod solve_args;
pub mod sweep_cmd;

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};
use rkwave::basis::FilterFamily;
use rkwave::error::{Classified, ErrorKind};
use rkwave::sampling::Domain;
use thiserror::Error;

/// rkwave: least-squares reconstruction from scattered samples in CDV interval wavelet bases.
#[derive(Parser, Debug)]
#[command(name = "rkwave", version, about, long_about = None)]
pub struct Cli {
    /// What to do; without a subcommand, the built-in demo writes its figures and report to
    /// `out/`.
    #[command(subcommand)]
    pub command: Option<Command>,
    /// Memory a request may use, e.g. `4G` (default: 3/4 of the machine's memory); larger
    /// requests are refused before allocating, with what they would need.
    #[arg(long, global = true, value_parser = memory_limit)]
    pub memory_limit: Option<u64>,
}

/// The subcommands.
#[derive(Subcommand, Debug)]
pub enum Command {
    /// Basis facts (orthonormality, polynomial reproduction, vanishing moments, FWT) and a figure.
    Basis(BasisArgs),
    /// Every nonzero basis function at the given positions.
    Eval(EvalArgs),
    /// The built-in demo (what `cargo run --release` runs).
    Demo(DemoArgs),
    /// Reconstruct a user's samples (CSV or .npy) onto a grid.
    Reconstruct(reconstruct_args::ReconstructArgs),
    /// Local inversion against the global pseudo-inverse (docs/design.md §5).
    Report(report_args::ReportArgs),
    /// The report over a grid of knobs: CSV and a figure of error against time.
    Sweep(sweep_cmd::SweepArgs),
    /// End-to-end time and memory against the number of samples.
    Scaling(scaling_cmd::ScalingArgs),
    /// Adaptive sampling and reconstruction (docs/design.md §6): refine where the signal needs it.
    Adapt(adapt_cmd::AdaptArgs),
    /// Render a scene's pixels from image-plane samples by one method, measured against the truth.
    Image(image_args::ImageArgs),
    /// Every image-plane method on the same samples: figures and a table.
    Compare(compare_cmd::CompareArgs),
    /// Adaptive image sampling driven by a renderer: the next round's positions from every
    /// sample so far (state kept in a folder).
    Plan(plan_cmd::PlanArgs),
}

/// Interior filter family on the command line.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum FamilyArg {
    /// Extremal phase (dbP).
    Db,
    /// Least asymmetric (symP).
    Sym,
}

/// The filter bank: vanishing moments `p` and the interior family.
#[derive(Args, Debug, Clone, Copy)]
pub struct FilterSpec {
    /// Vanishing moments p (1 = Haar, up to 10).
    #[arg(long, default_value_t = 3)]
    pub p: usize,
    /// Interior filter family; default CDV's choice (db for p <= 3, sym for p >= 4).
    #[arg(long, value_enum)]
    pub family: Option<FamilyArg>,
}

impl FilterSpec {
    /// The family given, if any (`None`: CDV's choice for `p`).
    pub fn family_given(&self) -> Option<FilterFamily> {
        self.family.map(|f| match f {
            FamilyArg::Db => FilterFamily::Extremal,
            FamilyArg::Sym => FilterFamily::LeastAsymmetric,
        })
    }
    /// The family (CDV's default when not given).
    pub fn family(&self) -> FilterFamily {
        self.family_given()
            .unwrap_or_else(|| FilterFamily::cdv_default(self.p))
    }
}

/// The levels: coarse scaling level `n` and finest wavelet level `N`.
#[derive(Args, Debug, Clone, Copy)]
pub struct LevelSpec {
    /// Coarse scaling level n (default j_min(p)).
    #[arg(long)]
    pub coarse: Option<u32>,
    /// Finest wavelet level N.
    #[arg(long, default_value_t = 8)]
    pub fine: u32,
}

impl LevelSpec {
    /// The coarse level (`j_min(p)` when not given).
    pub fn coarse(&self, p: usize) -> u32 {
        self.coarse
            .unwrap_or_else(|| rkwave::basis::minimum_level(p.max(1)))
    }
}

/// The basis: `p`, family, levels and domain.
#[derive(Args, Debug, Clone, Copy)]
pub struct BasisSpec {
    /// Filter bank.
    #[command(flatten)]
    pub filter: FilterSpec,
    /// Levels.
    #[command(flatten)]
    pub levels: LevelSpec,
    /// Domain `a,b`.
    #[arg(long, default_value = "0,1", allow_hyphen_values = true)]
    pub domain: Domain,
}

impl BasisSpec {
    /// Builds the basis, validating every parameter.
    pub fn build(&self) -> Result<rkwave::basis::CdvBasis, CliError> {
        build_basis(&self.filter, &self.levels, self.domain)
    }
}

/// Builds the basis of `filter` and `levels` on `domain`, validating every parameter.
pub fn build_basis(
    filter: &FilterSpec,
    levels: &LevelSpec,
    domain: Domain,
) -> Result<rkwave::basis::CdvBasis, CliError> {
    Ok(rkwave::basis::CdvBasis::new(
        filter.p,
        filter.family(),
        levels.coarse(filter.p),
        levels.fine,
        domain,
    )?)
}

/// `rkwave basis`.
#[derive(Args, Debug)]
pub struct BasisArgs {
    /// The basis.
    #[command(flatten)]
    pub spec: BasisSpec,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Draw the scaling functions and wavelets of the coarse level to this PNG (or .svg).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Positions at which polynomial reproduction is checked.
    #[arg(long, default_value_t = 20_000, value_parser = limits::samples)]
    pub points: usize,
    /// Seed of the random test data.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Overwrite an existing plot file.
    #[arg(long)]
    pub force: bool,
}

/// `rkwave eval`.
#[derive(Args, Debug)]
pub struct EvalArgs {
    /// The basis.
    #[command(flatten)]
    pub spec: BasisSpec,
    /// Positions, comma separated.
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        required = true
    )]
    pub x: Vec<f64>,
    /// Print JSON (one object with a list per position).
    #[arg(long)]
    pub json: bool,
}

/// `rkwave demo`.
#[derive(Args, Debug, Default)]
pub struct DemoArgs {
    /// Output folder.
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
}

/// Everything that can go wrong on the command line: any library error, kept as it is and
/// classified by its own kind ([`rkwave::error::Classified`]: no list of the library's error
/// types here, so a new library error needs no edit of the command line), and the command
/// line's own checks of its flags. [`CliError::kind`] classifies each;
/// [`CliError::exit_code`] maps the kind to the exit code. The library's messages name
/// parameters through typed fixes ([`rkwave::error::Fix`]), spelled as flags where the error
/// is printed ([`hints::in_flags`]).
#[derive(Debug, Error)]
pub enum CliError {
    /// A library error: its message and its kind are the library's.
    #[error("{0}")]
    Library(Box<dyn Classified + Send + Sync>),
    /// A library error said in the command line's words: the message names the flag or the
    /// file; the kind is the library error's, so the exit code stays the library's.
    #[error("{message}")]
    Reworded {
        /// The library error's kind.
        kind: ErrorKind,
        /// What the command line says.
        message: String,
    },
    /// A file operation failed.
    #[error("cannot write {path}: {source}")]
    Write {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// An output file exists and would be overwritten.
    #[error("{path} exists: pass --force to overwrite it or choose another path")]
    WouldOverwrite {
        /// The file.
        path: PathBuf,
    },
    /// A flag's value the library refused: the flag, then the library's error.
    #[error("{flag}: {source}")]
    Flag {
        /// The flag, e.g. `--resolution`.
        flag: &'static str,
        /// The library's error.
        source: Box<CliError>,
    },
    /// A flag's value that does not parse (a name or a number): the flag, then why.
    #[error("{flag}: {message}")]
    Parse {
        /// The flag, e.g. `--method`.
        flag: &'static str,
        /// The parser's message.
        message: String,
    },
    /// A flag's value the command line itself refuses (its message names the flag).
    #[error("{0}")]
    Invalid(String),
    /// A broken contract of the command line itself (a bug to report).
    #[error("internal error, please report: {0}")]
    Internal(String),
}

/// Any error the library classifies becomes [`CliError::Library`] (`?` on every library
/// call). `CliError` itself is not [`Classified`], so this does not overlap `From<T> for T`.
impl<E: Classified + Send + Sync + 'static> From<E> for CliError {
    fn from(e: E) -> Self {
        CliError::Library(Box::new(e))
    }
}

impl CliError {
    /// `source`, refused as the value of `flag`.
    pub fn flag(flag: &'static str, source: impl Into<CliError>) -> Self {
        CliError::Flag {
            flag,
            source: Box::new(source.into()),
        }
    }

    /// A value of `flag` that does not parse, for the parser's `error`.
    pub fn parse(flag: &'static str, error: impl std::fmt::Display) -> Self {
        CliError::Parse {
            flag,
            message: error.to_string(),
        }
    }

    /// A library error `e` said as `message` (the command line's words), keeping `e`'s kind.
    pub fn reworded(e: &impl Classified, message: String) -> Self {
        CliError::Reworded {
            kind: e.kind(),
            message,
        }
    }

    /// The kind of failure: the wrapped library error's, or the command line's own.
    pub fn kind(&self) -> ErrorKind {
        match self {
            CliError::Library(e) => e.kind(),
            CliError::Reworded { kind, .. } => *kind,
            CliError::Write { .. } => ErrorKind::WriteFailed,
            CliError::WouldOverwrite { .. } => ErrorKind::OutputRefused,
            CliError::Flag { source, .. } => source.kind(),
            CliError::Parse { .. } | CliError::Invalid(_) => ErrorKind::InvalidInput,
            CliError::Internal(_) => ErrorKind::Internal,
        }
    }

    /// Exit code: 2 when the request can be fixed by the caller (bad input, a refusal, an
    /// undetermined or unconverged fit, an unreadable input: [`ErrorKind::is_caller_fixable`]),
    /// 1 when the machine failed (writing or drawing an output, a broken internal contract).
    pub fn exit_code(&self) -> i32 {
        if self.kind().is_caller_fixable() {
            2
        } else {
            1
        }
    }
}

/// Before computing: refuses to overwrite `path` unless `force`, and checks that its
/// directory (or, when the command will create it, the nearest existing ancestor) takes a
/// new file, so an unwritable output fails at once with exit code 2.
pub fn check_writable(path: &std::path::Path, force: bool) -> Result<(), CliError> {
    if std::fs::symlink_metadata(path).is_ok() && !force {
        return Err(CliError::WouldOverwrite {
            path: path.to_path_buf(),
        });
    }
    let mut dir = path.parent().map(std::path::Path::to_path_buf);
    while let Some(d) = &dir {
        if d.as_os_str().is_empty() || d.is_dir() {
            break;
        }
        dir = d.parent().map(std::path::Path::to_path_buf);
    }
    let probe_dir = match dir {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => PathBuf::from("."),
    };
    if probe_dir.join(path.file_name().unwrap_or_default()) == path {
        rkwave::io::output::check_output(path, true, &[])?;
    } else {
        rkwave::io::output::check_output(&probe_dir.join(".rkwave-probe"), true, &[]).map_err(
            |e| {
                CliError::reworded(
                    &e,
                    format!(
                        "cannot write {}: its directory would be created in {}, which \
                         refuses new files ({e})",
                        path.display(),
                        probe_dir.display()
                    ),
                )
            },
        )?;
    }
    Ok(())
}

/// Before a sample file is read ([`rkwave::resources::check_reading`]).
pub fn check_reading(path: &std::path::Path) -> Result<(), CliError> {
    rkwave::resources::check_reading(path, || "split the samples or raise --memory-limit".into())
        .map_err(CliError::from)
}

/// Prints `note` after `note: `, wrapped at [`rkwave::image::job::text::NOTE_WIDTH`]
/// characters (its continuation lines indented under the text).
pub fn print_note(note: &str) {
    println!(
        "{}",
        rkwave::image::job::text::wrap(
            &format!("note: {note}"),
            rkwave::image::job::text::NOTE_WIDTH,
            "      "
        )
    );
}

/// Prints `report` as one pretty JSON object (`--json`); the reports are plain data, whose
/// serialization cannot fail.
pub fn print_json(report: &impl serde::Serialize) {
    println!(
        "{}",
        serde_json::to_string_pretty(report).expect("plain data")
    );
}

/// `--memory-limit`: bytes or a size such as `4G`.
fn memory_limit(text: &str) -> Result<u64, String> {
    rkwave::resources::parse_size(text).map_err(|e| e.to_string())
}

/// Runs the parsed command.
pub fn run(cli: Cli) -> Result<(), CliError> {
    rkwave::resources::set_memory_limit(cli.memory_limit);
    match cli.command {
        None => demo::run(&DemoArgs {
            out: PathBuf::from("out"),
        }),
        Some(Command::Demo(args)) => demo::run(&args),
        Some(Command::Basis(args)) => basis_cmd::run(&args),
        Some(Command::Eval(args)) => eval_cmd::run(&args),
        Some(Command::Reconstruct(args)) => match args.checked_dim()? {
            2 => reconstruct2d_cmd::run(&args),
            _ => reconstruct_cmd::run(&args),
        },
        Some(Command::Report(args)) => report_cmd::run(&args),
        Some(Command::Sweep(args)) => sweep_cmd::run(&args),
        Some(Command::Adapt(args)) => adapt_cmd::run(&args),
        Some(Command::Scaling(args)) => scaling_cmd::run(&args),
        Some(Command::Image(args)) if args.adaptive.adaptive => image_adaptive_cmd::run(&args),
        Some(Command::Image(args)) => image_cmd::run(&args),
        Some(Command::Compare(args)) => compare_cmd::run(&args),
        Some(Command::Plan(args)) => plan_cmd::run(&args),
    }
}

#[cfg(test)]
mod tests {
    /// clap's own consistency checks over every subcommand: no two arguments of a command
    /// share a name (a flattened group adding `--rho` beside a command's `--rho` fails here,
    /// where at run time it would break every invocation of that command).
    #[test]
    fn command_line_definition_is_consistent() {
        use clap::CommandFactory;
        super::Cli::command().debug_assert();
    }
}
