//! Ground truth: the box-filtered pixel integral of a scene,
//!
//! `I(X, Y) = int_X^{X+1} int_Y^{Y+1} L(x / W, y / H) dy dx`,
//!
//! estimated by stratified supersampling: an `n x n` grid of strata per pixel, one jittered
//! point per stratum (fixed seed), averaged. For a piecewise-smooth scene the error of one
//! pixel is `O(n^{-3/2})` where an edge crosses it (only the `O(n)` strata the edge cuts are
//! random, each contributing at most `1/n^2`) and `O(n^{-2})` elsewhere; the default `n = 16`
//! (256 points per pixel) puts it near `1e-3` at edges and far below elsewhere.
//!
//! Results are cached on disk ([`truth_cached`]) keyed by scene name, its JSON fingerprint,
//! resolution and rate, as a small binary file: `RKTRUTH1`, then `W`, `H`, channels, `n` as
//! little-endian `u64`, then the channel-major `f64` values.

use std::path::{Path, PathBuf};

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rayon::prelude::*;

use super::scene::Scene;
use super::{ImagePlane, PixelImage};

/// Default supersampling rate: `16 x 16` strata per pixel.
pub const DEFAULT_RATE: usize = 16;

/// Seed of the jitter (fixed so the truth is reproducible and cacheable).
const TRUTH_SEED: u64 = 0x7275_7468;

/// The box-filtered pixel integrals of `scene` on `plane` by `rate x rate` jittered strata per
/// pixel (rows in parallel).
pub fn box_truth(scene: &Scene, plane: ImagePlane, rate: usize) -> PixelImage {
    let rate = rate.max(1);
    let (w, h) = (plane.width(), plane.height());
    let rows: Vec<Vec<[f64; 3]>> = (0..h)
        .into_par_iter()
        .map(|py| {
            let mut rng = Pcg64::seed_from_u64(TRUTH_SEED ^ (py as u64).wrapping_mul(0x9e37_79b9));
            let inv = 1.0 / rate as f64;
            (0..w)
                .map(|px| {
                    let mut acc = [0.0; 3];
                    for j in 0..rate {
                        for i in 0..rate {
                            let x = px as f64 + (i as f64 + rng.random::<f64>()) * inv;
                            let y = py as f64 + (j as f64 + rng.random::<f64>()) * inv;
                            let v = scene.radiance_on(plane, x, y);
                            (0..3).for_each(|c| acc[c] += v[c]);
                        }
                    }
                    acc.map(|a| a * inv * inv)
                })
                .collect()
        })
        .collect();
    let mut image = PixelImage::zeros(plane, 3);
    for (py, row) in rows.iter().enumerate() {
        for (px, v) in row.iter().enumerate() {
            for (channel, value) in image.channels.iter_mut().zip(v) {
                channel[py * w + px] = *value;
            }
        }
    }
    image
}

/// The cache file of a truth image in `dir`.
pub fn cache_path(dir: &Path, scene: &Scene, plane: ImagePlane, rate: usize) -> PathBuf {
    dir.join(format!(
        "{}_{}_s{}_{:016x}.bin",
        scene.name(),
        plane,
        rate,
        scene.fingerprint()
    ))
}

/// Whether the truth came from the cache.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum TruthSource {
    /// Read from the cache file.
    Cached,
    /// Computed now (and written to the cache when possible).
    Computed,
}

/// [`box_truth`] through the cache in `dir` (created if missing). A cache that cannot be
/// written is not an error: the truth is returned all the same (the failure is in the
/// returned message).
pub fn truth_cached(
    dir: &Path,
    scene: &Scene,
    plane: ImagePlane,
    rate: usize,
) -> (PixelImage, TruthSource, Option<String>) {
    let path = cache_path(dir, scene, plane, rate);
    if let Some(image) = read_cache(&path, plane, rate) {
        return (image, TruthSource::Cached, None);
    }
    let image = box_truth(scene, plane, rate);
    let note = write_cache(&path, &image, rate)
        .err()
        .map(|e| format!("ground-truth cache {} not written: {e}", path.display()));
    (image, TruthSource::Computed, note)
}

fn read_cache(path: &Path, plane: ImagePlane, rate: usize) -> Option<PixelImage> {
    let bytes = std::fs::read(path).ok()?;
    if bytes.len() < 40 || &bytes[..8] != b"RKTRUTH1" {
        return None;
    }
    let word = |k: usize| u64::from_le_bytes(bytes[8 + 8 * k..16 + 8 * k].try_into().unwrap());
    let (w, h, c, n) = (word(0), word(1), word(2), word(3));
    if (w as usize, h as usize, n as usize) != (plane.width(), plane.height(), rate) {
        return None;
    }
    let count = plane.pixels() * c as usize;
    if bytes.len() != 40 + 8 * count || c != 3 {
        return None;
    }
    let values: Vec<f64> = bytes[40..]
        .chunks_exact(8)
        .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
        .collect();
    let channels = values.chunks(plane.pixels()).map(<[f64]>::to_vec).collect();
    Some(PixelImage { plane, channels })
}

fn write_cache(path: &Path, image: &PixelImage, rate: usize) -> std::io::Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    let mut bytes = b"RKTRUTH1".to_vec();
    for v in [
        image.plane.width(),
        image.plane.height(),
        image.channel_count(),
        rate,
    ] {
        bytes.extend_from_slice(&(v as u64).to_le_bytes());
    }
    for ch in &image.channels {
        for v in ch {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    // Write then rename, so a concurrent reader never sees half a file.
    let tmp = path.with_extension(format!("tmp{}", std::process::id()));
    std::fs::write(&tmp, bytes)?;
    std::fs::rename(tmp, path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn truth_of_a_half_plane_is_the_covered_area_and_the_cache_round_trips() {
        // The edge x = 2.5 pixels (u = 0.625 on a 4-pixel-wide plane): pixel column 2 is half
        // covered, so its truth is exactly 0.5 up to the strata the edge cuts: with n = 16 the
        // edge lies on a stratum boundary (2.5 = 2 + 8/16), so no stratum is cut and the
        // estimate is exact.
        let scene = Scene::from_json(
            r#"{"name":"edge","layers":[{"shape":"half_plane","point":[0.625,0],"normal_deg":0,"color":[1,1,1]}]}"#,
            Path::new("edge.json"),
        )
        .unwrap();
        let plane = ImagePlane::new(4, 3).unwrap();
        let t = box_truth(&scene, plane, 16);
        for y in 0..3 {
            assert_eq!(t.get(0, 1, y), 0.0);
            assert_eq!(t.get(1, 2, y), 0.5);
            assert_eq!(t.get(2, 3, y), 1.0);
        }
        let dir = std::env::temp_dir().join(format!("rkwave-truth-{}", std::process::id()));
        let (a, s1, _) = truth_cached(&dir, &scene, plane, 16);
        let (b, s2, _) = truth_cached(&dir, &scene, plane, 16);
        assert_eq!((s1, s2), (TruthSource::Computed, TruthSource::Cached));
        assert_eq!(a, b);
        std::fs::remove_dir_all(dir).unwrap();
    }
}
