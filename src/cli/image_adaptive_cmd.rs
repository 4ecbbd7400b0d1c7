//! `rkwave image --adaptive`: the adaptive wavelet image of a scene at a sample budget, beside
//! the film filters at the same total samples (stratified) and on the adaptive samples; the
//! local depth and the sample positions as figures (each alone, and side by side as the 2D
//! analogue of the supplement's figure 4).

use std::path::{Path, PathBuf};

use rkwave::image::adaptive::figure::{depth_image, samples_image, save_adaptive_figure};
use rkwave::image::adaptive::{AdaptiveParams, PixelEstimate};
use rkwave::image::scene::Scene;
use rkwave::image::PixelImage;
use rkwave::io::image_file::{write_image, ImageFormat};
use rkwave::lab::adaptive::compare_adaptive;
use rkwave::lab::experiment::TruthParams;

use super::image_args::{
    check_outputs, check_p, check_rho, parse_resolution, scene_path, spinner, ImageArgs,
    SolverChoice,
};
use super::CliError;
use rkwave::image::adaptive::{
    FitParams, ImageSampling, NoiseParams, OutputParams, QuadTreeParams, StopParams, TreeParams,
};

/// `params` with the fields of the JSON object `json` replaced (validated by the library).
fn override_params(params: AdaptiveParams, json: &str) -> Result<AdaptiveParams, CliError> {
    let bad = |why: String| {
        CliError::Invalid(format!(
            "--adaptive-params {json}: {why}; give a JSON object of AdaptiveParams fields, \
             e.g. '{{\"theta\": 0.3}}'"
        ))
    };
    let given: serde_json::Value = serde_json::from_str(json).map_err(|e| bad(e.to_string()))?;
    let fields = given
        .as_object()
        .ok_or_else(|| bad("not a JSON object".into()))?;
    let mut value = serde_json::to_value(params).expect("parameters serialise");
    for (name, field) in fields {
        if value.get(name).is_none() {
            return Err(bad(format!("no parameter named {name:?}")));
        }
        value[name] = field.clone();
    }
    serde_json::from_value(value).map_err(|e| bad(e.to_string()))
}

fn figure_path(out: &Path, what: &str) -> PathBuf {
    let stem = out
        .file_stem()
        .map_or("image".into(), |s| s.to_string_lossy().into_owned());
    out.with_file_name(format!("{stem}_{what}.png"))
}

fn write(path: &Path, image: &PixelImage, force: bool) -> Result<(), CliError> {
    Ok(write_image(path, image, force)?)
}

/// Runs `rkwave image --adaptive`.
pub fn run(args: &ImageArgs) -> Result<(), CliError> {
    // Before any work: a format we cannot write is refused up front.
    ImageFormat::from_path(&args.out).map_err(|e| CliError::flag("--out", e))?;
    let a = &args.adaptive;
    let depth_path = figure_path(&args.out, "depth");
    let samples_path = figure_path(&args.out, "samples");
    let figure = figure_path(&args.out, "adaptive");
    let scene_file = scene_path(&args.scene)?;
    check_outputs(
        &[&args.out, &depth_path, &samples_path, &figure],
        args.force,
        &[&scene_file],
    )?;
    let plane = parse_resolution(&args.resolution)?;
    if !(args.noise.is_finite() && args.noise >= 0.0) {
        return Err(CliError::Invalid(format!(
            "--noise {}: give a standard deviation >= 0",
            args.noise
        )));
    }
    let budget = a.budget.unwrap_or(args.spp.saturating_mul(plane.pixels()));
    let spp = budget / plane.pixels();
    let given = match a.budget {
        Some(b) => format!("--budget {b}"),
        None => format!("--spp {}", args.spp),
    };
    if spp == 0 {
        return Err(CliError::Invalid(format!(
            "{given}: the comparison needs at least one sample per pixel on average ({} for \
             {plane})",
            plane.pixels()
        )));
    }
    if budget % plane.pixels() != 0 {
        return Err(CliError::Invalid(format!(
            "{given} is not a whole number of samples per pixel at {plane} ({} pixels): the \
             film filters it is compared with take the same count on stratified samples; give \
             --budget {} or {}, or --spp",
            plane.pixels(),
            spp * plane.pixels(),
            (spp + 1).saturating_mul(plane.pixels())
        )));
    }
    let scene = Scene::from_file(&scene_file)?;
    let params = AdaptiveParams {
        tree: TreeParams {
            p: check_p(args.p)?,
            rho: args.rho.map_or(Ok(2.0), check_rho)?,
        },
        quad: QuadTreeParams {
            below_pixel: a.below_pixel,
            ..AdaptiveParams::default().quad
        },
        noise: NoiseParams {
            false_alarm: a.false_alarm,
            ..AdaptiveParams::default().noise
        },
        sampling: ImageSampling {
            seed: args.seed,
            ..AdaptiveParams::default().sampling
        },
        stop: StopParams {
            budget,
            ..AdaptiveParams::default().stop
        },
        fit: FitParams {
            solver: a.solver.solver(),
            ..AdaptiveParams::default().fit
        },
        output: OutputParams {
            pixels: if a.no_residual {
                PixelEstimate::FitOnly
            } else {
                PixelEstimate::ResidualClamped
            },
            ..AdaptiveParams::default().output
        },
        ..AdaptiveParams::default()
    };
    let params = match &a.adaptive_params {
        Some(json) => override_params(params, json)?,
        None => params,
    };
    let truth = TruthParams {
        rate: args.truth_rate,
        cache: args.truth_cache.clone(),
    };
    // The job checks the request against the memory limit before sampling (the budget's
    // samples, the tree fit at the depth limit, the truth and the images).
    let bar = spinner(&format!("adaptive on {} at {plane}", scene.name()));
    let out = compare_adaptive(&scene, plane, spp, args.noise, &params, &truth)?;
    bar.finish_and_clear();
    write(&args.out, &out.image, args.force)?;
    write(&depth_path, &depth_image(&out.run), args.force)?;
    write(&samples_path, &samples_image(&out.run, 4), args.force)?;
    let c = &out.comparison;
    let title = format!(
        "{} at {plane}, {} samples ({:.2} spp), PSNR {:.2} dB ({:+.2} dB over {} on stratified \
         samples)",
        c.scene,
        c.adaptive.samples,
        c.adaptive.samples as f64 / plane.pixels() as f64,
        c.rows[0].metrics.psnr,
        c.gain_db,
        c.best_uniform_film.0
    );
    save_adaptive_figure(&out.run, &out.image, &title, &figure, args.force)?;
    if args.json {
        let mut value = serde_json::to_value(c).expect("report serialises");
        value["out"] = serde_json::json!(args.out);
        value["depth_map"] = serde_json::json!(depth_path);
        value["sample_positions"] = serde_json::json!(samples_path);
        value["figure"] = serde_json::json!(figure);
        super::print_json(&value);
        return Ok(());
    }
    let r = &c.adaptive;
    println!(
        "{} {plane} adaptive (noise {}): {} samples of {} (base {}), {} functions, {} rounds, \
         stop {:?}, levels base {:?} limit {:?} -> {}",
        c.scene,
        c.noise,
        r.samples,
        r.budget,
        r.base_samples,
        r.functions,
        r.rounds.len(),
        r.stop,
        r.base_levels,
        r.levels,
        args.out.display()
    );
    for row in &c.rows {
        println!(
            "{:27} {:10} {:>8} samples: PSNR {:.2} dB, SSIM {:.4}",
            row.method, row.samples_from, row.samples, row.metrics.psnr, row.metrics.ssim
        );
    }
    println!(
        "adaptive wavelet - best film filter on stratified samples ({}): {:+.2} dB",
        c.best_uniform_film.0, c.gain_db
    );
    println!(
        "time: adaptive {:.2} s (sampling {:.2}, fits {:.2}, refining {:.2})",
        c.adaptive_s, r.times.sample_s, r.times.fit_s, r.times.refine_s
    );
    println!(
        "figures: image, depth and samples side by side {}; depth {}, samples {}",
        figure.display(),
        depth_path.display(),
        samples_path.display()
    );
    if a.solver != SolverChoice::Direct {
        let per_round: Vec<String> = r
            .rounds
            .iter()
            .map(|x| {
                let cond = if x.fit.condition > 0.0 {
                    format!(", cond {:.0e}", x.fit.condition)
                } else {
                    String::new()
                };
                format!(
                    "{} it (res {:.0e}{cond}, {})",
                    x.fit.iterations, x.fit.relative_residual, x.fit.solver
                )
            })
            .collect();
        let last = r
            .rounds
            .last()
            .and_then(|x| x.final_fit.as_ref())
            .map_or_else(String::new, |f| {
                format!(
                    "; final fit continued to {} it (res {:.0e})",
                    f.iterations, f.relative_residual
                )
            });
        println!("CG per round: {}{last}", per_round.join("; "));
    }
    let rebuilds: Vec<String> = r
        .rounds
        .iter()
        .filter_map(|x| x.rebuild.as_ref())
        .map(|b| format!("{:.2}/{:.2} s ({:.2})", b.round_s, b.rebuild_s, b.ratio))
        .collect();
    if !rebuilds.is_empty() {
        println!(
            "round fit against a rebuild from scratch (continued/rebuilt s, ratio): {} \
             (rebuilds, {:.2} s, not in the times above)",
            rebuilds.join("; "),
            r.times.rebuild_s
        );
    }
    if let Some(level) = r.rounds.last().and_then(|l| l.noise.as_ref()) {
        let densified = r.rounds.iter().filter(|l| l.densified_to.is_some()).count();
        println!(
            "noise test: estimated sigma {:.4} (false-alarm rate {}), {} slots not deepened \
             (not significant), {densified} densifying rounds",
            level.sigma,
            a.false_alarm,
            r.rounds.last().map_or(0, |l| l.insignificant)
        );
    }
    for note in &r.notes {
        super::print_note(note);
    }
    Ok(())
}
