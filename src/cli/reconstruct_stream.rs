//! `rkwave reconstruct --dim 1` out of core: a `.npy` or CSV input read in chunks
//! ([`rkwave::io::chunks::CountedChunks`]) into the streamed single-scale QR
//! ([`rkwave::reconstruct::stream::fit_streamed`]), the same coefficients as the in-memory
//! path; the passes over the file are listed in the text report and in `--json`
//! (`stream.passes`).

use std::path::Path;
use std::time::Instant;

use rkwave::io::chunks::{CountedChunks, SampleChunkReader};
use rkwave::io::{GridWriter, IoError, SampleSet};
use rkwave::reconstruct::stream::{fit_streamed, StreamError, StreamReport};
use rkwave::reconstruct::{FitParams, Method, SingleScaleSolver, SolveReport};
use rkwave::report::reconstruction::{onto_grid, ReconstructReport, ReconstructTimes};
use rkwave::sampling::Domain;
use serde::Serialize;

use super::reconstruct_args::{ReconstructArgs, StreamArg};
use super::CliError;

/// The fix named when samples too large to read whole meet a method that needs them whole.
const STREAMING_FIX: &str = "--method single --factorization qr reads a file sorted by x in \
                             chunks (--stream always), or raise --memory-limit";

/// Bytes of reading `m` samples of `channels` values whole from a file of `file_bytes`: the
/// file's bytes, the sample set, and the QR's unit positions and sort order.
fn in_memory_bytes(file_bytes: u64, m: usize, channels: usize) -> f64 {
    file_bytes as f64 + 8.0 * m as f64 * (1.0 + channels as f64) + 16.0 * m as f64
}

fn streams(params: &FitParams) -> bool {
    matches!(
        params.method,
        Method::SingleScale {
            solver: SingleScaleSolver::Qr,
            ..
        }
    )
}

fn is_npy(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("npy"))
}

/// Whether `--stream` (and, for `auto`, the size of a `.npy` input against the memory
/// limit) asks for the streamed path; refuses what cannot work, before any work.
pub fn chooses_streaming(args: &ReconstructArgs, params: &FitParams) -> Result<bool, CliError> {
    let npy = is_npy(&args.input);
    match args.stream {
        StreamArg::Never => Ok(false),
        StreamArg::Always if !streams(params) => Err(CliError::Invalid(
            "--stream streams the single-scale QR only: use --method single --factorization qr"
                .into(),
        )),
        StreamArg::Always => Ok(true),
        StreamArg::Auto if !npy => Ok(false),
        StreamArg::Auto => {
            let source = SampleChunkReader::open(&args.input)?.counted()?;
            let file_bytes = std::fs::metadata(&args.input).map_or(0, |m| m.len());
            let needed = in_memory_bytes(file_bytes, source.rows(), source.value_channels());
            if needed <= rkwave::resources::memory_limit() as f64 {
                return Ok(false);
            }
            if streams(params) {
                return Ok(true);
            }
            rkwave::resources::check(
                || format!("reading {} samples whole", source.rows()),
                needed,
                || STREAMING_FIX.to_string(),
            )
            .map_err(CliError::from)?;
            Ok(false)
        }
    }
}

/// The report of a streamed reconstruction: the usual one and the passes over the file.
#[derive(Serialize)]
struct StreamedReport<'a> {
    #[serde(flatten)]
    report: &'a ReconstructReport,
    stream: &'a StreamReport,
}

fn from_stream(e: StreamError) -> CliError {
    match e {
        StreamError::Reconstruct(e) => CliError::from(e),
        StreamError::Source(e) => match e.downcast::<IoError>() {
            Ok(io) => CliError::from(*io),
            Err(other) => CliError::Invalid(other.to_string()),
        },
        other => CliError::Invalid(other.to_string()),
    }
}

/// Runs the streamed `rkwave reconstruct --dim 1`.
pub fn run(args: &ReconstructArgs, params: &FitParams, started: Instant) -> Result<(), CliError> {
    let source: CountedChunks = SampleChunkReader::open(&args.input)?.counted()?;
    let m = source.rows();
    let names = source.names().to_vec();
    let mut passes = Vec::new();
    if !source.reader().is_npy() {
        passes.push("rows, channels and bounds of the CSV file (every row parsed)".to_string());
    }
    let domain = match args.domain {
        Some(d) => d,
        None => {
            if !source.knows_bounds() {
                passes.push("bounds of the positions (no --domain given)".to_string());
            }
            let (a, b) = source.bounds()?;
            domain_of_bounds(a, b)?
        }
    };
    let read_s = started.elapsed().as_secs_f64();
    let (fitted, report) = fit_streamed(&source, domain, params).map_err(from_stream)?;
    passes.extend(report.passes);
    let mut writer = GridWriter::create(&args.output, &names, args.grid)?;
    // No sample is held: the residual comes from the QR (below) or from a pass of its own.
    let held = SampleSet {
        positions: Vec::new(),
        values: vec![Vec::new(); names.len()],
        names: names.clone(),
    };
    let qr_residual =
        matches!(&fitted.solve, SolveReport::SingleScale(r) if r.residual_rms.is_some());
    let mut rec = onto_grid(fitted, &held, domain, args.grid, |xs, values| {
        writer.write_block(xs, values).map_err(CliError::from)
    })?;
    if !qr_residual {
        let evaluator = rec.fit.evaluator()?;
        let mut squares = vec![0.0; names.len()];
        source.read_rows(0..m, |xs, vs| {
            let fitted = evaluator.evaluate(xs)?;
            for ((s, r), f) in squares.iter_mut().zip(&fitted).zip(vs) {
                *s += r.iter().zip(f).map(|(a, b)| (a - b) * (a - b)).sum::<f64>();
            }
            Ok::<(), CliError>(())
        })?;
        rec.residual_rms = squares.iter().map(|s| (s / m as f64).sqrt()).collect();
        passes.push("residual at the samples (the ridge's rows hide the QR's)".to_string());
    }
    let t_finish = Instant::now();
    writer.finish(args.force)?;
    let finish_s = t_finish.elapsed().as_secs_f64();
    let mut report = ReconstructReport::new(
        args.input.clone(),
        args.output.clone(),
        &held,
        &params.method,
        &rec,
        ReconstructTimes::of_command(read_s, finish_s, started),
    );
    report.samples = m;
    let stream = StreamReport { passes };
    if args.json {
        let out = StreamedReport {
            report: &report,
            stream: &stream,
        };
        super::print_json(&out);
        return Ok(());
    }
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    println!(
        "{} samples x {} channels streamed from {} in {} passes ({}) -> {}; wrote {}",
        report.samples,
        report.channels,
        if source.reader().is_npy() {
            ".npy"
        } else {
            "CSV"
        },
        stream.passes.len(),
        stream.passes.join("; "),
        fit_summary(&report, &rec.residual_rms),
        args.output.display()
    );
    Ok(())
}

/// The fit's line of the text report: functions, levels, oversampling, residual, time.
pub(super) fn fit_summary(report: &ReconstructReport, residual_rms: &[f64]) -> String {
    format!(
        "P = {} functions (levels {}..{}, oversampling {:.2}), residual RMS [{}], {:.3} s",
        report.functions,
        report.coarse,
        report.fine,
        report.oversampling,
        residual_rms
            .iter()
            .map(|r| format!("{r:.3e}"))
            .collect::<Vec<_>>()
            .join(", "),
        report.time_s.total,
    )
}

/// The domain `[a, b]` of samples spanning `a..b` (no `--domain` given).
pub(super) fn domain_of_bounds(a: f64, b: f64) -> Result<Domain, CliError> {
    Domain::new(a, b).map_err(|e| match e {
        rkwave::sampling::DomainError::NotIncreasing { .. } => CliError::Invalid(format!(
            "all samples sit at x = {}: give --domain a,b explicitly",
            rkwave::norms::show(a)
        )),
        other => CliError::Invalid(format!(
            "the samples span [{}, {}], which is no usable domain: {other}",
            rkwave::norms::show(a),
            rkwave::norms::show(b)
        )),
    })
}
