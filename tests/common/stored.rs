//! The stored Mitsuba renders under `data/renders/` (64², 4 spp; `data/renders/README.md`),
//! loaded once for every test that reads them.

use std::path::Path;

use rkwave::image::{ImagePlane, ImageSamples};
use rkwave::io::read_samples;

/// The three scenes stored (see `benches/mitsuba/scenes.py`).
pub const STORED_SCENES: [&str; 3] = ["direct", "cornell", "thinlens"];

/// `scene`'s 4 spp samples on the 64² plane and its reference, `reference[c][Y * 64 + X]` for
/// the three colour channels. The files hold `(x, y, r, g, b)` rows: the sample reader's
/// first value channel is `y`, the next three the radiance.
pub fn stored_render(scene: &str) -> (ImageSamples, Vec<Vec<f64>>) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/renders");
    let set = read_samples(dir.join(format!("{scene}-64x64-4spp-samples.npy")))
        .expect("stored samples load");
    let reference = read_samples(dir.join(format!("{scene}-64x64-reference.npy")))
        .expect("stored reference loads");
    let plane = ImagePlane::new(64, 64).expect("64² plane");
    let samples = ImageSamples::new(
        plane,
        set.positions.clone(),
        set.values[0].clone(),
        set.values[1..].to_vec(),
    )
    .expect("stored samples lie on the plane");
    (samples, reference.values[1..].to_vec())
}
