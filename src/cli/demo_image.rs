//! The image part of the demo: one built-in scene reconstructed by the wavelet engine and by
//! every film filter from the same samples, the figure and the table written to `out/`.

use std::fmt::Write as _;
use std::path::Path;

use rkwave::image::experiment::{
    compare_methods, comparison_markdown, Method, SamplingParams, TruthParams, WaveletParams,
};
use rkwave::image::figure::save_side_by_side;
use rkwave::image::sampler::Sampler;
use rkwave::image::scene::Scene;
use rkwave::image::ImagePlane;

use super::CliError;

/// The demo's scene (a built-in one) and resolution.
const DEMO_SCENE: &str = "shapes";
const DEMO_SIDE: usize = 128;

/// Renders the demo scene, writes `out/image_compare.png` and appends the table to `summary`.
pub fn run(out: &Path, summary: &mut String) -> Result<(), CliError> {
    let scene = Scene::from_file(Scene::builtin_dir().join(format!("{DEMO_SCENE}.json")))
        .map_err(|e| CliError::Invalid(e.to_string()))?;
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
        &Method::all(),
        &WaveletParams::default(),
        &truth,
    )
    .map_err(|e| CliError::Invalid(e.to_string()))?;
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
    Ok(())
}
