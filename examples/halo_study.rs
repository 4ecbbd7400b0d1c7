//! The halo study of the tiled image fit (`rkwave::lab::halo_study`): prints the Markdown
//! table and writes the JSON report.
//!
//! `cargo run --release --example halo_study -- [SCENE] [SIZE] [TILE] [OUT.json]`
//! (defaults: `shapes`, 512, 128, `out/halo_study.json`).

use std::path::PathBuf;

use rkwave::image::sampler::Sampler;
use rkwave::image::scene::Scene;
use rkwave::image::ImagePlane;
use rkwave::lab::experiment::SamplingParams;
use rkwave::lab::halo_study::{halo_study, HaloStudyParams};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let scene_name = args.first().map_or("shapes", String::as_str);
    let size: usize = args.get(1).map_or(Ok(512), |s| s.parse())?;
    let tile: usize = args.get(2).map_or(Ok(128), |s| s.parse())?;
    let out = PathBuf::from(args.get(3).map_or("out/halo_study.json", String::as_str));
    let scene = Scene::from_file(Scene::builtin_dir().join(format!("{scene_name}.json")))?;
    let params = HaloStudyParams {
        sampling: SamplingParams {
            plane: ImagePlane::new(size, size)?,
            spp: 4,
            sampler: Sampler::Stratified,
            noise: 0.0,
            seed: 1,
        },
        tile,
        halos: vec![0, 1, 2, 4, 8, 12, 16],
        ps: vec![2, 3],
        noises: vec![0.0, 0.05],
        truth_rate: 8,
    };
    let study = halo_study(&scene, &params)?;
    print!("{}", study.markdown());
    if let Some(dir) = out.parent() {
        std::fs::create_dir_all(dir)?;
    }
    std::fs::write(&out, serde_json::to_string_pretty(&study)?)?;
    eprintln!("wrote {}", out.display());
    Ok(())
}
