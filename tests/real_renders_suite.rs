//! The issue-38 suite's fixtures under `data/renders/suite/` load, and are what
//! `fixtures.json` says they are.
//!
//! Each set is a uniform Mitsuba 3 render (`benches/mitsuba/suite.py fixtures`): `m x 5` float32
//! rows `(x, y, r, g, b)` in pixel units, exactly the samples of Mitsuba's box film at that spp
//! (the harness seeds every pixel's sampler as `mi.render` does), and the reference, the mean of
//! two independent 1024-spp box films, as float64 rows `(x + 1/2, y + 1/2, r, g, b)` of the pixel
//! centres in row-major order. The box film of a pixel is the mean of its samples,
//!
//! `B(X, Y) = (1 / n_XY) sum_{i in pixel (X, Y)} v_i`,
//!
//! and the tests check, for every set listed in `fixtures.json`: the row count (`rendered_spp`
//! samples in every pixel), finite non-negative radiance, the samples' range as recorded, and the
//! box film's PSNR (clipped to [0, 1]) and relMSE (eps 0.01) against the reference as numpy
//! computed them when the fixtures were written.

use std::path::{Path, PathBuf};

use rkwave::io::read_samples;

mod common;

fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/renders/suite")
}

fn meta() -> serde_json::Value {
    let text = std::fs::read_to_string(data_dir().join("fixtures.json")).expect("fixtures.json");
    serde_json::from_str(&text).expect("fixtures.json parses")
}

/// One set: the samples' positions and colours, the reference per channel, the size.
struct Set {
    width: usize,
    height: usize,
    xs: Vec<f64>,
    ys: Vec<f64>,
    /// `rgb[c][i]`: channel `c` of sample `i`.
    rgb: Vec<Vec<f64>>,
    /// `reference[c][Y * width + X]`.
    reference: Vec<Vec<f64>>,
}

fn load(entry: &serde_json::Value, width: usize, height: usize) -> Set {
    let name = entry["samples"].as_str().expect("samples name");
    // Column 0 is x; the reader's first value channel is y, the next three are r, g, b.
    let set = read_samples(data_dir().join(name)).expect("fixture samples load");
    assert_eq!(set.channels(), 4, "{name}: columns x, y, r, g, b");
    let rname = entry["reference"].as_str().expect("reference name");
    let reference = read_samples(data_dir().join(rname)).expect("fixture reference loads");
    assert_eq!(
        reference.len(),
        width * height,
        "{rname}: one row per pixel"
    );
    for p in 0..width * height {
        let (x, y) = ((p % width) as f64 + 0.5, (p / width) as f64 + 0.5);
        assert_eq!(reference.positions[p], x, "{rname}: row {p}");
        assert_eq!(reference.values[0][p], y, "{rname}: row {p}");
    }
    Set {
        width,
        height,
        xs: set.positions.clone(),
        ys: set.values[0].clone(),
        rgb: set.values[1..].to_vec(),
        reference: reference.values[1..].to_vec(),
    }
}

/// The box film (per-pixel mean) and the per-pixel counts.
fn box_film(s: &Set) -> (Vec<Vec<f64>>, Vec<usize>) {
    let n = s.width * s.height;
    let mut counts = vec![0usize; n];
    let mut sums = vec![vec![0.0; n]; 3];
    for i in 0..s.xs.len() {
        let p = (s.ys[i].floor() as usize) * s.width + s.xs[i].floor() as usize;
        counts[p] += 1;
        for (sum, v) in sums.iter_mut().zip(&s.rgb) {
            sum[p] += v[i];
        }
    }
    for sum in &mut sums {
        for (v, &k) in sum.iter_mut().zip(&counts) {
            *v /= k as f64;
        }
    }
    (sums, counts)
}

fn sets() -> Vec<(serde_json::Value, usize, usize)> {
    let m = meta();
    let res = m["resolution"].as_array().expect("resolution");
    let (w, h) = (
        res[0].as_u64().expect("width") as usize,
        res[1].as_u64().expect("height") as usize,
    );
    let sets = m["sets"].as_array().expect("sets").clone();
    assert!(!sets.is_empty(), "fixtures.json lists no set");
    sets.into_iter().map(|e| (e, w, h)).collect()
}

#[test]
fn suite_fixtures_are_uniform_renders_of_finite_nonnegative_radiance() {
    for (entry, w, h) in sets() {
        let s = load(&entry, w, h);
        let spp = entry["rendered_spp"].as_u64().expect("rendered_spp") as usize;
        assert_eq!(s.xs.len(), w * h * spp, "{entry}: W H spp rows");
        for i in 0..s.xs.len() {
            assert!((0.0..w as f64).contains(&s.xs[i]), "x of row {i}");
            assert!((0.0..h as f64).contains(&s.ys[i]), "y of row {i}");
        }
        let (_, counts) = box_film(&s);
        assert!(counts.iter().all(|&n| n == spp), "{entry}: {spp} a pixel");
        for v in s.rgb.iter().chain(&s.reference).flatten() {
            assert!(v.is_finite() && *v >= 0.0, "{entry}: radiance {v}");
        }
        // The recorded range is that of the float32 samples, widened exactly to f64 and written
        // by Python's shortest round-trip repr; serde_json's default float parser may land one
        // ulp away from it, so the comparison allows 4 ulp (relative 4 eps).
        let (lo, hi) = s
            .rgb
            .iter()
            .flatten()
            .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
        for (got, key) in [(lo, "sample_min"), (hi, "sample_max")] {
            let want = entry[key].as_f64().expect(key);
            assert!(
                (got - want).abs() <= 4.0 * f64::EPSILON * want.abs(),
                "{key}: {got} here, {want} in fixtures.json"
            );
        }
    }
}

#[test]
fn suite_box_film_matches_numpy() {
    for (entry, w, h) in sets() {
        let s = load(&entry, w, h);
        let (image, _) = box_film(&s);
        let (psnr, relmse) = (
            common::metrics::psnr(&image, &s.reference),
            common::metrics::relmse(&image, &s.reference),
        );
        let want_psnr = entry["box_psnr_numpy"].as_f64().expect("box_psnr_numpy");
        let want_rel = entry["box_relmse_numpy"]
            .as_f64()
            .expect("box_relmse_numpy");
        // Same float64 data, same formulas, only the summation order differs: the relative
        // error of either mean is ~ n eps ~ 1e-11 at n ~ 7000 terms; 1e-9 dB and 1e-9 relative
        // leave two orders of margin.
        assert!(
            (psnr - want_psnr).abs() <= 1e-9,
            "{entry}: box PSNR {psnr} dB here, {want_psnr} in numpy"
        );
        assert!(
            (relmse - want_rel).abs() <= 1e-9 * want_rel.abs().max(1e-12),
            "{entry}: box relMSE {relmse} here, {want_rel} in numpy"
        );
    }
}
