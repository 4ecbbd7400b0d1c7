//! `rkwave image`: sample a scene, reconstruct its pixels by one method, write the image and
//! report the error against the ground truth.

use std::path::{Path, PathBuf};

use rkwave::image::filters::FilmFilterKind;
use rkwave::image::scene::Scene;
use rkwave::image::{ImageMethod, WaveletParams};
use rkwave::io::image_file::{write_image, ImageFormat};
use rkwave::lab::comparison::{ComparisonJob, ComparisonRequest};
use rkwave::lab::experiment::{ImageReport, SamplingParams, TruthParams};

use super::image_args::{
    check_outputs, check_p, check_rho, check_ridge, parse_resolution, parse_sampler, scene_path,
    spinner, ImageArgs,
};
use super::CliError;

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

fn filter_csv_path(out: &Path, x: usize, y: usize) -> PathBuf {
    let stem = out
        .file_stem()
        .map_or("image".into(), |s| s.to_string_lossy().into_owned());
    out.with_file_name(format!("{stem}_filter_{x}_{y}.csv"))
}

/// Runs `rkwave image` without `--adaptive` (`image_adaptive_cmd` runs it with).
pub fn run(args: &ImageArgs) -> Result<(), CliError> {
    // Before any work: a format we cannot write is refused up front.
    ImageFormat::from_path(&args.out).map_err(|e| CliError::flag("--out", e))?;
    let scene_file = scene_path(&args.scene)?;
    check_outputs(&[&args.out], args.force, &[&scene_file])?;
    let plane = parse_resolution(&args.resolution)?;
    let sampler = parse_sampler(&args.sampler)?;
    let method: ImageMethod = args
        .method
        .parse()
        .map_err(|e| CliError::parse("--method", e))?;
    let pixel_filter = match &args.pixel_filter {
        None => None,
        Some(name) => {
            if matches!(method, ImageMethod::Film(_)) {
                return Err(CliError::Invalid(format!(
                    "--pixel-filter {name} applies to the wavelet methods only; \
                     --method {method} is itself a pixel filter"
                )));
            }
            let kind: FilmFilterKind = name
                .parse()
                .map_err(|e| CliError::parse("--pixel-filter", e))?;
            (kind != FilmFilterKind::Box).then_some(kind)
        }
    };
    let show = args.show_filter.as_deref().map(parse_pixel).transpose()?;
    if let Some((x, y)) = show {
        check_outputs(
            &[&filter_csv_path(&args.out, x, y)],
            args.force,
            &[&scene_file],
        )?;
    }
    let scene = Scene::from_file(&scene_file)?;
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
        ridge: check_ridge(args.fit.ridge)?,
        smoothing: args.fit.smoothing,
    };
    let truth = TruthParams {
        rate: args.truth_rate,
        cache: args.truth_cache.clone(),
    };
    // The job checks the request against the memory limit before sampling (the samples, the
    // fit, the truth and the output image; twice the samples when the equivalent filter
    // resamples the scene).
    let job = ComparisonJob::new(ComparisonRequest {
        sampling,
        methods: vec![method],
        wavelet,
        truth,
        filter_at: show,
        adaptive: None,
    })?;
    let bar = spinner(&format!("{} on {} at {plane}", method, scene.name()));
    let run = job.run(&scene, sampling.noise)?;
    bar.finish_and_clear();
    let cmp = run.comparison;
    let report = ImageReport::from_comparison(&cmp, 0);
    write_image(&args.out, &cmp.results[0].image, args.force)?;
    let mut filter_file = None;
    if let (Some((x, y)), Some(weights)) = (show, &run.weights) {
        let path = filter_csv_path(&args.out, x, y);
        let mut text = String::from("index,x,y,weight\n");
        for w in weights {
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
        super::print_json(&value);
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
            super::print_note(note);
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
