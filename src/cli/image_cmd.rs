//! `rkwave image`: sample a scene, reconstruct its pixels by one method, write the image and
//! report the error against the ground truth.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use clap::Args;
use indicatif::ProgressBar;
use rkwave::image::experiment::{
    compare_methods, equivalent_filter, sample_scene, ImageReport, Method, SamplingParams,
    TruthParams, WaveletParams,
};
use rkwave::image::filters::FilmFilterKind;
use rkwave::image::sampler::Sampler;
use rkwave::image::scene::Scene;
use rkwave::image::ImagePlane;
use rkwave::io::image_file::{write_image, ImageFormat};

use super::{check_writable, CliError};

/// `rkwave image`.
#[derive(Args, Debug)]
pub struct ImageArgs {
    /// Scene: a JSON file, or the name of a built-in scene (data/scenes/NAME.json).
    #[arg(long)]
    pub scene: String,
    /// Resolution `WxH` in pixels.
    #[arg(long, default_value = "256x256")]
    pub resolution: String,
    /// Samples per pixel.
    #[arg(long, default_value_t = 4)]
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
    /// Relative ridge on the wavelet normal equations (G + ridge diag(G)).
    #[arg(long, default_value_t = 1e-9)]
    pub ridge: f64,
    /// Relative weight of a first-difference penalty on neighbouring wavelet coefficients
    /// (0: the least-squares fit).
    #[arg(long, default_value_t = 0.0)]
    pub smoothing: f64,
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
    pub adaptive: super::image_adaptive_cmd::AdaptiveArgs,
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

/// Parses `--resolution`.
pub fn parse_resolution(s: &str) -> Result<ImagePlane, CliError> {
    s.parse::<ImagePlane>()
        .map_err(|e| CliError::Invalid(format!("--resolution: {e}")))
}

/// Parses `--sampler`.
pub fn parse_sampler(s: &str) -> Result<Sampler, CliError> {
    s.parse::<Sampler>()
        .map_err(|e| CliError::Invalid(format!("--sampler: {e}")))
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

fn parse_pixel(s: &str) -> Result<(usize, usize), CliError> {
    let bad = || {
        CliError::Invalid(format!(
            "--show-filter {s}: expected a pixel X,Y such as 10,20"
        ))
    };
    let (x, y) = s.split_once(',').ok_or_else(bad)?;
    Ok((
        x.trim().parse().map_err(|_| bad())?,
        y.trim().parse().map_err(|_| bad())?,
    ))
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

fn filter_csv_path(out: &Path, x: usize, y: usize) -> PathBuf {
    let stem = out
        .file_stem()
        .map_or("image".into(), |s| s.to_string_lossy().into_owned());
    out.with_file_name(format!("{stem}_filter_{x}_{y}.csv"))
}

/// Runs `rkwave image`.
pub fn run(args: &ImageArgs) -> Result<(), CliError> {
    // Before any work, in both modes: a format we cannot write is refused up front.
    ImageFormat::from_path(&args.out).map_err(|e| CliError::Invalid(format!("--out: {e}")))?;
    if args.adaptive.adaptive {
        return super::image_adaptive_cmd::run(args);
    }
    check_writable(&args.out, args.force)?;
    let plane = parse_resolution(&args.resolution)?;
    let sampler = parse_sampler(&args.sampler)?;
    let method: Method = args
        .method
        .parse()
        .map_err(|e| CliError::Invalid(format!("--method: {e}")))?;
    let pixel_filter = match &args.pixel_filter {
        None => None,
        Some(name) => {
            if matches!(method, Method::Film(_)) {
                return Err(CliError::Invalid(format!(
                    "--pixel-filter {name} applies to the wavelet methods only; \
                     --method {method} is itself a pixel filter"
                )));
            }
            let kind: FilmFilterKind = name
                .parse()
                .map_err(|e| CliError::Invalid(format!("--pixel-filter: {e}")))?;
            (kind != FilmFilterKind::Box).then_some(kind)
        }
    };
    let show = args.show_filter.as_deref().map(parse_pixel).transpose()?;
    if let Some((x, y)) = show {
        check_writable(&filter_csv_path(&args.out, x, y), args.force)?;
    }
    let scene =
        Scene::from_file(scene_path(&args.scene)?).map_err(|e| CliError::Invalid(e.to_string()))?;
    let sampling = SamplingParams {
        plane,
        spp: args.spp,
        sampler,
        noise: args.noise,
        seed: args.seed,
    };
    let wavelet = WaveletParams {
        p: check_p(args.p)?,
        pixel_filter,
        rho: check_rho(args.rho.unwrap_or(4.0))?,
        ridge: check_ridge(args.ridge)?,
        smoothing: args.smoothing,
    };
    let truth = TruthParams {
        rate: args.truth_rate,
        cache: args.truth_cache.clone(),
    };
    let bar = spinner(&format!("{} on {} at {plane}", method, scene.name()));
    let cmp = compare_methods(&scene, &sampling, &[method], &wavelet, &truth)
        .map_err(|e| CliError::Invalid(e.to_string()))?;
    bar.finish_and_clear();
    let report = ImageReport::from_comparison(&cmp, 0);
    write_image(&args.out, &cmp.results[0].image, args.force).map_err(|e| CliError::Write {
        path: args.out.clone(),
        source: std::io::Error::other(e.to_string()),
    })?;
    let mut filter_file = None;
    if let Some((x, y)) = show {
        let samples =
            sample_scene(&scene, &sampling).map_err(|e| CliError::Invalid(e.to_string()))?;
        let weights = equivalent_filter(method, &samples, &wavelet, x, y)
            .map_err(|e| CliError::Invalid(e.to_string()))?;
        let path = filter_csv_path(&args.out, x, y);
        let mut text = String::from("index,x,y,weight\n");
        for w in &weights {
            text.push_str(&format!("{},{},{},{}\n", w.index, w.x, w.y, w.weight));
        }
        rkwave::io::output::write_new(&path, text.as_bytes(), args.force)?;
        filter_file = Some((path, weights.len()));
    }
    if args.json {
        let mut value = serde_json::to_value(&report).expect("report serialises");
        value["out"] = serde_json::json!(args.out);
        if let Some((path, n)) = &filter_file {
            value["filter_file"] = serde_json::json!({"path": path, "samples": n});
        }
        println!("{}", serde_json::to_string_pretty(&value).expect("json"));
    } else {
        println!(
            "{} {} {} spp {} noise {}: {} samples -> {}",
            report.scene,
            report.resolution,
            sampling.spp,
            sampling.sampler,
            sampling.noise,
            report.samples,
            args.out.display()
        );
        println!(
            "method {}: PSNR {:.2} dB, RMSE {:.5}, relMSE {:.5}, SSIM {:.4}",
            report.method, report.psnr, report.rmse, report.rel_mse, report.ssim
        );
        if let Some(f) = report.functions {
            println!("basis functions: {f}");
        }
        let t = report.time_s;
        println!(
            "time: sampling {:.3} s, truth {:.3} s ({} x {} per pixel, {:?}), fit {:.3} s, pixels {:.3} s, method {:.3} s",
            t.sampling, t.truth, report.truth_rate, report.truth_rate, report.truth_source, t.fit, t.pixels, t.method
        );
        if let Some(mb) = report.peak_mb {
            println!("peak memory: {mb:.0} MB");
        }
        for note in &report.notes {
            println!("note: {note}");
        }
        if let Some((path, n)) = filter_file {
            println!(
                "equivalent filter: {n} sample weights -> {}",
                path.display()
            );
        }
    }
    Ok(())
}
