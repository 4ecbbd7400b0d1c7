//! `rkwave compare`: every method on the same samples of one or every built-in scene — a
//! side-by-side figure with zoomed crops per run, a CSV and a Markdown table, and an
//! error-against-time figure; with `--adaptive`, the adaptive rows beside them.

use std::io::IsTerminal;
use std::path::PathBuf;

use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use rkwave::image::adaptive::figure::save_adaptive_figure;
use rkwave::image::adaptive::AdaptiveParams;
use rkwave::image::scene::Scene;
use rkwave::image::{ImageMethod, WaveletParams};
use rkwave::lab::adaptive::{
    adaptive_markdown, adaptive_rows_markdown, compare_adaptive, AdaptiveComparison,
};
use rkwave::lab::comparison::{ComparisonJob, ComparisonRequest};
use rkwave::lab::experiment::{Comparison, SamplingParams, TruthParams};
use rkwave::lab::figure::{save_error_vs_time, save_side_by_side};
use rkwave::lab::table::{
    comparison_csv, comparison_markdown, comparison_times_markdown, CSV_HEADER,
};

use super::image_args::{
    check_p, check_rho, check_ridge, parse_resolution, parse_sampler, scene_path, WaveletFitArgs,
};
use super::{check_writable, CliError};
use rkwave::image::adaptive::{ImageSampling, TreeParams};

/// `rkwave compare`.
#[derive(Args, Debug)]
pub struct CompareArgs {
    /// One scene: a JSON file or a built-in scene's name.
    #[arg(long, conflicts_with = "scenes", required_unless_present = "scenes")]
    pub scene: Option<String>,
    /// `all`: every built-in scene (data/scenes/*.json).
    #[arg(long)]
    pub scenes: Option<String>,
    /// Resolution `WxH`.
    #[arg(long, default_value = "256x256")]
    pub resolution: String,
    /// Samples per pixel, plain or in `1e3` notation.
    #[arg(long, default_value_t = 4, value_parser = super::limits::count)]
    pub spp: usize,
    /// Sampler: uniform, stratified or sobol.
    #[arg(long, default_value = "stratified")]
    pub sampler: String,
    /// Noise levels (standard deviations), comma separated; each is a separate run.
    #[arg(long, value_delimiter = ',', default_value = "0,0.05")]
    pub noise: Vec<f64>,
    /// Methods, comma separated (default: all).
    #[arg(long, value_delimiter = ',')]
    pub methods: Vec<String>,
    /// Vanishing moments p of the wavelet methods.
    #[arg(long, default_value_t = 2)]
    pub p: usize,
    /// Samples per basis function, rho = m / (nx ny): sets the wavelet level per axis (4 at
    /// 4 spp is one function per pixel).
    #[arg(long, default_value_t = 4.0)]
    pub rho: f64,
    /// The wavelet fit's ridge and smoothing.
    #[command(flatten)]
    pub fit: WaveletFitArgs,
    /// Seed of positions and noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Ground-truth supersampling rate n (n x n strata per pixel).
    #[arg(long, default_value_t = rkwave::image::truth::DEFAULT_RATE)]
    pub truth_rate: usize,
    /// Output folder.
    #[arg(long, default_value = "out/compare")]
    pub out: PathBuf,
    /// Overwrite existing outputs.
    #[arg(long)]
    pub force: bool,
    /// Print the comparisons as JSON.
    #[arg(long)]
    pub json: bool,
    /// Also the adaptive rows, one run per scene and noise level: the adaptive wavelet at an
    /// average of `--spp` samples per pixel, and the film filters on its (noisy) sample set; a
    /// table `compare_adaptive.md` and one figure per run (image, local depth, samples).
    #[arg(long)]
    pub adaptive: bool,
}

/// Runs `rkwave compare`.
pub fn run(args: &CompareArgs) -> Result<(), CliError> {
    let plane = parse_resolution(&args.resolution)?;
    let sampler = parse_sampler(&args.sampler)?;
    let p = check_p(args.p)?;
    let methods: Vec<ImageMethod> = if args.methods.is_empty() {
        ImageMethod::all()
    } else {
        args.methods
            .iter()
            .map(|m| m.parse().map_err(|e| CliError::parse("--methods", e)))
            .collect::<Result<_, _>>()?
    };
    let files = match (&args.scene, args.scenes.as_deref()) {
        (Some(s), _) => vec![scene_path(s)?],
        (None, Some("all")) => Scene::builtin_files()?,
        (None, other) => {
            return Err(CliError::Invalid(format!(
                "--scenes {}: only `all` is accepted (or give one --scene FILE)",
                other.unwrap_or("")
            )))
        }
    };
    let scenes = files
        .iter()
        .map(Scene::from_file)
        .collect::<Result<Vec<_>, _>>()?;
    let csv_path = args.out.join("compare.csv");
    let md_path = args.out.join("compare.md");
    let time_path = args.out.join("error_vs_time.png");
    for path in [&csv_path, &md_path, &time_path] {
        check_writable(path, args.force)?;
    }
    if args.adaptive {
        check_writable(&args.out.join(ADAPTIVE_TABLE), args.force)?;
        for scene in &scenes {
            for &noise in &args.noise {
                check_writable(&adaptive_figure(args, scene, noise), args.force)?;
            }
        }
    }
    let wavelet = WaveletParams {
        p,
        pixel_filter: None,
        rho: check_rho(args.rho)?,
        ridge: check_ridge(args.fit.ridge)?,
        smoothing: args.fit.smoothing,
    };
    let truth = TruthParams {
        rate: args.truth_rate,
        cache: PathBuf::from("out/truth"),
    };
    let adaptive_params = args.adaptive.then(|| AdaptiveParams {
        tree: TreeParams {
            p,
            ..AdaptiveParams::default().tree
        },
        sampling: ImageSampling {
            seed: args.seed,
            ..AdaptiveParams::default().sampling
        },
        ..AdaptiveParams::default()
    });
    // The job checks the largest run against the memory limit before any work (the methods
    // one after the other, each result image held for the figures; the adaptive rows' tree
    // fit when asked for).
    let job = ComparisonJob::new(ComparisonRequest {
        sampling: SamplingParams {
            plane,
            spp: args.spp,
            sampler,
            noise: 0.0,
            seed: args.seed,
        },
        methods: methods.clone(),
        wavelet,
        truth: truth.clone(),
        filter_at: None,
        adaptive: adaptive_params,
    })?;
    std::fs::create_dir_all(&args.out).map_err(|source| CliError::Write {
        path: args.out.clone(),
        source,
    })?;
    let runs = scenes.len() * args.noise.len();
    let bar = if std::io::stderr().is_terminal() {
        ProgressBar::new(runs as u64)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} {msg} [{elapsed}]").expect("template"),
    );
    let mut comparisons: Vec<Comparison> = Vec::with_capacity(runs);
    for scene in &scenes {
        for &noise in &args.noise {
            bar.set_message(format!("{} noise {noise}", scene.name()));
            let cmp = job.run(scene, noise)?.comparison;
            let fig = args
                .out
                .join(format!("{}_noise{}.png", scene.name(), noise));
            check_writable(&fig, args.force)?;
            save_side_by_side(&cmp, &fig, args.force)?;
            comparisons.push(cmp);
            bar.inc(1);
        }
    }
    bar.finish_and_clear();
    let write = |path: &PathBuf, text: String| -> Result<(), CliError> {
        Ok(rkwave::io::output::write_new(
            path,
            text.as_bytes(),
            args.force,
        )?)
    };
    write(
        &csv_path,
        format!("{CSV_HEADER}\n{}", comparison_csv(&comparisons)),
    )?;
    let md = comparison_markdown(&comparisons);
    let times = comparison_times_markdown(&comparisons);
    write(
        &md_path,
        format!("PSNR (dB):\n\n{md}\nSeconds per method (fit + pixels):\n\n{times}"),
    )?;
    save_error_vs_time(&comparisons, &time_path, args.force)?;
    let adaptive = match &adaptive_params {
        Some(params) => Some(adaptive_rows(args, &scenes, plane, params, &truth)?),
        None => None,
    };
    if args.json {
        let value = match &adaptive {
            None => serde_json::to_value(&comparisons),
            Some(a) => serde_json::to_value(serde_json::json!({
                "comparisons": comparisons,
                "adaptive": a.comparisons,
                "adaptive_notes": a.notes,
            })),
        };
        println!(
            "{}",
            serde_json::to_string_pretty(&value.expect("comparisons serialise"))
                .expect("plain data")
        );
    } else {
        println!(
            "PSNR (dB) against the box-filtered truth ({} x {} strata per pixel), {plane}, {} spp {sampler}:",
            args.truth_rate, args.truth_rate, args.spp
        );
        print!("{md}");
        println!("seconds per method (fit + pixels; sampling and truth excluded):");
        print!("{times}");
        for c in &comparisons {
            for note in c
                .notes
                .iter()
                .chain(c.results.iter().flat_map(|r| &r.notes))
            {
                println!("note ({} noise {}): {note}", c.scene, c.sampling.noise);
            }
        }
        println!(
            "wrote {}, {}, {} and one side-by-side figure per run in {}",
            csv_path.display(),
            md_path.display(),
            time_path.display(),
            args.out.display()
        );
        if let Some(a) = &adaptive {
            println!("adaptive rows (PSNR dB, {} spp on average):", args.spp);
            print!("{}", a.markdown);
            for note in &a.notes {
                println!("note (adaptive): {note}");
            }
            println!(
                "wrote {} and one adaptive figure per scene in {}",
                args.out.join(ADAPTIVE_TABLE).display(),
                args.out.display()
            );
        }
    }
    Ok(())
}

/// The table of the adaptive rows.
const ADAPTIVE_TABLE: &str = "compare_adaptive.md";

/// The adaptive figure of `scene` at `noise` (image, local depth, samples).
fn adaptive_figure(args: &CompareArgs, scene: &Scene, noise: f64) -> PathBuf {
    if noise == 0.0 {
        args.out.join(format!("{}_adaptive.png", scene.name()))
    } else {
        args.out
            .join(format!("{}_noise{noise}_adaptive.png", scene.name()))
    }
}

/// What `--adaptive` adds.
struct AdaptiveRows {
    comparisons: Vec<AdaptiveComparison>,
    markdown: String,
    notes: Vec<String>,
}

/// The adaptive rows of every scene and noise level: the library's comparison, its figure
/// and the table.
fn adaptive_rows(
    args: &CompareArgs,
    scenes: &[Scene],
    plane: rkwave::image::ImagePlane,
    params: &AdaptiveParams,
    truth: &TruthParams,
) -> Result<AdaptiveRows, CliError> {
    let table = args.out.join(ADAPTIVE_TABLE);
    let mut notes = Vec::new();
    let mut comparisons = Vec::with_capacity(scenes.len() * args.noise.len());
    for scene in scenes {
        for &noise in &args.noise {
            let fig = adaptive_figure(args, scene, noise);
            let out = compare_adaptive(scene, plane, args.spp, noise, params, truth)?;
            let c = &out.comparison;
            let title = format!(
                "{} at {plane}, noise {noise}, {} samples ({} spp on average), PSNR {:.2} dB \
             ({:+.2} dB over {} on stratified samples)",
                c.scene,
                c.adaptive.samples,
                args.spp,
                c.rows[0].metrics.psnr,
                c.gain_db,
                c.best_uniform_film.0
            );
            save_adaptive_figure(&out.run, &out.image, &title, &fig, args.force)?;
            notes.extend(
                c.adaptive
                    .notes
                    .iter()
                    .map(|n| format!("{} noise {noise}: {n}", c.scene)),
            );
            comparisons.push(out.comparison);
        }
    }
    let markdown = format!(
        "{}\nEvery method on each sample set:\n\n{}",
        adaptive_markdown(&comparisons),
        adaptive_rows_markdown(&comparisons)
    );
    rkwave::io::output::write_new(&table, markdown.as_bytes(), args.force)?;
    Ok(AdaptiveRows {
        comparisons,
        markdown,
        notes,
    })
}
