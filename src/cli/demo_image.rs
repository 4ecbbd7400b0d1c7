//! The image part of the demo: one built-in scene reconstructed by the wavelet engine and by
//! every film filter from the same samples, the figure and the table written to `out/`; then
//! the same scene by adaptive sampling (the wavelet tree grown with the samples), its figure
//! of image, depth and samples, and its table.

use std::fmt::Write as _;
use std::path::Path;

use rkwave::image::adaptive::figure::save_adaptive_figure;
use rkwave::image::adaptive::AdaptiveParams;
use rkwave::image::sampler::Sampler;
use rkwave::image::scene::Scene;
use rkwave::image::{ImageMethod, ImagePlane, WaveletParams};
use rkwave::lab::adaptive::{adaptive_markdown, compare_adaptive};
use rkwave::lab::experiment::{compare_methods, SamplingParams, TruthParams};
use rkwave::lab::figure::save_side_by_side;
use rkwave::lab::table::comparison_markdown;

use super::CliError;
use rkwave::image::adaptive::StopParams;

/// The demo's scene (a built-in one) and resolution.
const DEMO_SCENE: &str = "shapes";
const DEMO_SIDE: usize = 128;
/// The adaptive demo's resolution (the same scene, 4 spp on average).
const ADAPTIVE_SIDE: usize = 64;

/// Renders the demo scene, writes `out/image_compare.png` and appends the table to `summary`.
pub fn run(out: &Path, summary: &mut String) -> Result<(), CliError> {
    let scene = Scene::from_file(Scene::builtin_dir().join(format!("{DEMO_SCENE}.json")))?;
    let sampling = SamplingParams {
        plane: ImagePlane::new(DEMO_SIDE, DEMO_SIDE).expect("valid demo resolution"),
        spp: 4,
        sampler: Sampler::Stratified,
        noise: 0.0,
        seed: 1,
    };
    let truth = TruthParams {
        cache: out.join("truth"),
        ..TruthParams::default()
    };
    let cmp = compare_methods(
        &scene,
        &sampling,
        &ImageMethod::all(),
        &WaveletParams::default(),
        &truth,
    )?;
    let fig = out.join("image_compare.png");
    save_side_by_side(&cmp, &fig, true)?;
    let _ = writeln!(
        summary,
        "\n## Image plane: `{DEMO_SCENE}` at {DEMO_SIDE}x{DEMO_SIDE}, 4 spp stratified, PSNR (dB) \
         against the box-filtered truth ({} x {} strata per pixel)\n\n{}\nFigure: `image_compare.png`.",
        truth.rate,
        truth.rate,
        comparison_markdown(std::slice::from_ref(&cmp))
    );
    eprintln!("image plane: {DEMO_SCENE} done");
    let plane = ImagePlane::new(ADAPTIVE_SIDE, ADAPTIVE_SIDE).expect("valid demo resolution");
    let params = AdaptiveParams {
        stop: StopParams {
            budget: 4 * plane.pixels(),
            ..AdaptiveParams::default().stop
        },
        ..AdaptiveParams::default()
    };
    let adaptive = compare_adaptive(&scene, plane, 4, 0.0, &params, &truth)?;
    let c = &adaptive.comparison;
    let fig = out.join("image_adaptive.png");
    let title = format!(
        "{DEMO_SCENE} at {plane}, {} adaptive samples, PSNR {:.2} dB ({:+.2} dB over {} on \
         stratified samples)",
        c.adaptive.samples, c.rows[0].metrics.psnr, c.gain_db, c.best_uniform_film.0
    );
    save_adaptive_figure(&adaptive.run, &adaptive.image, &title, &fig, true)?;
    let _ = writeln!(
        summary,
        "\n## Adaptive sampling on the image plane: `{DEMO_SCENE}` at {plane}, 4 spp on \
         average, against the film filters on stratified samples (and on the adaptive \
         samples)\n\n{}\nFigure (image, local depth of the wavelet tree, samples by round): \
         `image_adaptive.png`.",
        adaptive_markdown(std::slice::from_ref(c))
    );
    eprintln!("adaptive image plane: {DEMO_SCENE} done");
    Ok(())
}
