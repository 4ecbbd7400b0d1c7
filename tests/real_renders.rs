//! Real renderer data without the renderer: Mitsuba 3 sample sets stored under `data/renders/`.
//!
//! Each fixture is a uniform render at 64 x 64 pixels, 4 samples per pixel, from Mitsuba's own
//! multi-jittered sampler (`scalar_rgb`, made by `benches/mitsuba/harness.py --fixtures`, see
//! `data/renders/README.md`): `m x 5` rows `(x, y, r, g, b)`, positions in pixel units, and the
//! reference, Mitsuba's box film at 1024 samples per pixel, as rows `(x + 1/2, y + 1/2, r, g, b)`
//! of the pixel centres in row-major order. The box film of a pixel is the mean of the samples
//! in it,
//!
//! `B(X, Y) = (1 / n_XY) sum_{i in pixel (X, Y)} v_i`,
//!
//! an unbiased estimate of the pixel integral the reference approximates. The tests check that
//! definition against rkwave's splat, the PSNR against the value numpy computed when the fixture
//! was written, the absence of bias against the reference (in units of the standard error the
//! samples themselves give), that rkwave's uniform reconstruction of real samples is finite
//! and no further below the box film than the measured table in `docs/measurements/real-renders.md`
//! shows, and that the noise-aware pixel estimates (`--pixels shrunk`, `--pixels fit-clamped`) keep
//! the gains measured on these fixtures.

use std::path::{Path, PathBuf};

mod common;
use common::psnr;

use rkwave::image::filters::BoxFilter;
use rkwave::image::splat::splat;
use rkwave::image::{ImagePlane, ImageSamples};
use rkwave::io::read_samples;

/// Width and height of every fixture.
const SIZE: usize = 64;
/// Samples per pixel of every fixture.
const SPP: usize = 4;
/// Samples per pixel of the references.
const REF_SPP: f64 = 1024.0;

/// The three scenes (see `benches/mitsuba/scenes.py`).
const SCENES: [&str; 3] = ["direct", "cornell", "thinlens"];

fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/renders")
}

fn samples_path(scene: &str) -> PathBuf {
    data_dir().join(format!("{scene}-{SIZE}x{SIZE}-{SPP}spp-samples.npy"))
}

/// One fixture: the samples and the reference, per channel in row-major pixel order.
struct Fixture {
    xs: Vec<f64>,
    ys: Vec<f64>,
    /// `rgb[c][i]`: channel `c` of sample `i`.
    rgb: Vec<Vec<f64>>,
    /// `reference[c][Y * SIZE + X]`.
    reference: Vec<Vec<f64>>,
}

/// Loads a fixture through the library's sample reader (column 0 is `x`; the reader's first
/// value channel is `y`, the next three are r, g, b).
fn load(scene: &str) -> Fixture {
    let set = read_samples(samples_path(scene)).expect("fixture samples load");
    assert_eq!(set.channels(), 4, "{scene}: columns x, y, r, g, b");
    let reference = read_samples(data_dir().join(format!("{scene}-{SIZE}x{SIZE}-reference.npy")))
        .expect("fixture reference loads");
    assert_eq!(
        reference.len(),
        SIZE * SIZE,
        "{scene}: one reference row per pixel"
    );
    // The reference rows are the pixel centres in row-major order.
    for p in 0..SIZE * SIZE {
        let (x, y) = ((p % SIZE) as f64 + 0.5, (p / SIZE) as f64 + 0.5);
        assert_eq!(reference.positions[p], x, "{scene}: reference row {p}");
        assert_eq!(reference.values[0][p], y, "{scene}: reference row {p}");
    }
    Fixture {
        xs: set.positions.clone(),
        ys: set.values[0].clone(),
        rgb: set.values[1..].to_vec(),
        reference: reference.values[1..].to_vec(),
    }
}

fn pixel(x: f64, y: f64) -> usize {
    (y.floor() as usize) * SIZE + x.floor() as usize
}

/// The naive box film: per pixel, the sum of its samples over their count; and the counts.
fn naive_box(f: &Fixture) -> (Vec<Vec<f64>>, Vec<usize>) {
    let mut counts = vec![0usize; SIZE * SIZE];
    let mut sums = vec![vec![0.0; SIZE * SIZE]; 3];
    for i in 0..f.xs.len() {
        let p = pixel(f.xs[i], f.ys[i]);
        counts[p] += 1;
        for (sum, values) in sums.iter_mut().zip(&f.rgb) {
            sum[p] += values[i];
        }
    }
    for s in &mut sums {
        for (v, &n) in s.iter_mut().zip(&counts) {
            *v /= n as f64;
        }
    }
    (sums, counts)
}

/// A fixture's entry in `data/renders/fixtures.json`, written by the harness with numpy.
fn numpy_entry(scene: &str) -> serde_json::Value {
    let text = std::fs::read_to_string(data_dir().join("fixtures.json")).expect("fixtures.json");
    let meta: serde_json::Value = serde_json::from_str(&text).expect("fixtures.json parses");
    meta["sets"]
        .as_array()
        .expect("sets")
        .iter()
        .find(|s| s["scene"] == scene && s["spp"] == SPP as u64)
        .cloned()
        .unwrap_or_else(|| panic!("no {scene} entry in fixtures.json"))
}

#[test]
fn fixtures_are_uniform_renders_of_finite_nonnegative_radiance() {
    for scene in SCENES {
        let f = load(scene);
        assert_eq!(f.xs.len(), SIZE * SIZE * SPP, "{scene}: W H spp rows");
        let (_, counts) = naive_box(&f);
        // Mitsuba's uniform render: exactly `SPP` samples in every pixel.
        assert!(
            counts.iter().all(|&n| n == SPP),
            "{scene}: {SPP} samples per pixel"
        );
        for i in 0..f.xs.len() {
            assert!(
                (0.0..SIZE as f64).contains(&f.xs[i]),
                "{scene}: x of row {i}"
            );
            assert!(
                (0.0..SIZE as f64).contains(&f.ys[i]),
                "{scene}: y of row {i}"
            );
        }
        // Radiance is finite and non-negative in samples and reference alike.
        for v in f.rgb.iter().chain(&f.reference).flatten() {
            assert!(v.is_finite() && *v >= 0.0, "{scene}: radiance {v}");
        }
    }
}

#[test]
fn rkwave_box_splat_is_the_naive_box_film() {
    let plane = ImagePlane::new(SIZE, SIZE).expect("plane");
    for scene in SCENES {
        let f = load(scene);
        let (naive, _) = naive_box(&f);
        let samples = ImageSamples::new(plane, f.xs.clone(), f.ys.clone(), f.rgb.clone())
            .expect("the fixture is a valid image sample set");
        let (image, _) = splat(&samples, &BoxFilter::default());
        // Both are the mean of the same SPP numbers, summed in possibly different orders (and
        // the splat divides a weighted sum by a sum of unit weights): each of the SPP additions
        // and the division round by at most eps relative to the largest partial sum, so the two
        // differ by at most (SPP + 1) eps max|v| per pixel; 2 (SPP + 1) eps covers both sides.
        let vmax = f.rgb.iter().flatten().fold(0.0f64, |m, &v| m.max(v.abs()));
        let tol = 2.0 * (SPP as f64 + 1.0) * f64::EPSILON * vmax;
        for (c, (got, want)) in image.channels.iter().zip(&naive).enumerate() {
            for (p, (&g, &n)) in got.iter().zip(want).enumerate() {
                let d = (g - n).abs();
                assert!(d <= tol, "{scene}: channel {c} pixel {p}: |{d}| > {tol}");
            }
        }
    }
}

#[test]
fn box_psnr_against_the_reference_matches_numpy() {
    for scene in SCENES {
        let f = load(scene);
        let (box_film, _) = naive_box(&f);
        let ours = psnr(&box_film, &f.reference);
        let numpy = numpy_entry(scene)["box_psnr_numpy"]
            .as_f64()
            .expect("box_psnr_numpy");
        // Same float64 data (float32 samples widen exactly), same formula; only the summation
        // order differs: relative error of the MSE ~ 1e-12 at 12 288 terms, i.e. ~ 5e-12 dB.
        assert!(
            (ours - numpy).abs() <= 1e-9,
            "{scene}: box PSNR {ours} dB here, {numpy} dB in numpy"
        );
    }
}

#[test]
fn box_film_is_unbiased_against_the_reference() {
    // Sum over pixels of (box - reference) per channel. Both estimate the same pixel integrals;
    // independent errors with per-pixel variance s_p^2 / n_p (the box film, s_p^2 the samples'
    // unbiased variance in the pixel) and s_p^2 / 1024 (the reference) give the standard error
    // sigma = sqrt(sum_p s_p^2 (1 / n_p + 1 / 1024)). Stratified (multi-jittered) samples have a
    // smaller true variance, so sigma is an overestimate and |sum| <= 5 sigma a safe bound: a
    // bias in the data (a brightness offset or scale, a missing ray weight) breaks it. The sum is
    // blind to a permutation of pixels; the alignment test below covers the pixel convention.
    for scene in SCENES {
        let f = load(scene);
        let (box_film, counts) = naive_box(&f);
        let channels = f.rgb.iter().zip(&box_film).zip(&f.reference);
        for (c, ((values, boxed), reference)) in channels.enumerate() {
            let mut ss = vec![0.0; SIZE * SIZE];
            for ((&x, &y), &v) in f.xs.iter().zip(&f.ys).zip(values) {
                let p = pixel(x, y);
                ss[p] += (v - boxed[p]).powi(2);
            }
            let var: f64 = (0..SIZE * SIZE)
                .map(|p| {
                    let n = counts[p] as f64;
                    ss[p] / (n - 1.0) * (1.0 / n + 1.0 / REF_SPP)
                })
                .sum();
            let bias: f64 = (0..SIZE * SIZE).map(|p| boxed[p] - reference[p]).sum();
            let sigma = var.sqrt();
            assert!(
                bias.abs() <= 5.0 * sigma,
                "{scene}: channel {c}: sum of (box - reference) = {bias}, sigma {sigma}"
            );
        }
    }
}

#[test]
fn box_film_aligns_with_the_reference_only_at_zero_shift() {
    // The pixel convention (x right, y down, pixel (i, j) = [i, i+1) x [j, j+1)) of the samples
    // must be the reference's: among the nine one-pixel shifts (dx, dy) in {-1, 0, 1}^2 of the
    // reference against the box film (MSE of clipped values over the interior pixels) and the
    // vertical flip, (0, 0) is the unique minimiser. Measured ratios of the next best to (0, 0):
    // direct 9.8, cornell 1.76 (Monte Carlo noise), thinlens 5.2; the flip 12 to 235.
    for scene in SCENES {
        let f = load(scene);
        let (box_film, _) = naive_box(&f);
        let clip = |v: f64| v.clamp(0.0, 1.0);
        let mse_at = |dx: isize, dy: isize| -> f64 {
            let mut sum = 0.0;
            for (boxed, reference) in box_film.iter().zip(&f.reference) {
                for y in 1..SIZE - 1 {
                    for x in 1..SIZE - 1 {
                        let (rx, ry) = ((x as isize + dx) as usize, (y as isize + dy) as usize);
                        let d = clip(boxed[y * SIZE + x]) - clip(reference[ry * SIZE + rx]);
                        sum += d * d;
                    }
                }
            }
            sum
        };
        let aligned = mse_at(0, 0);
        for dy in -1..=1 {
            for dx in -1..=1 {
                if (dx, dy) != (0, 0) {
                    let shifted = mse_at(dx, dy);
                    assert!(
                        shifted > aligned,
                        "{scene}: shift ({dx}, {dy}): {shifted} <= {aligned}"
                    );
                }
            }
        }
        let flipped: f64 = (0..3)
            .flat_map(|c| (0..SIZE * SIZE).map(move |p| (c, p)))
            .filter(|&(_, p)| {
                (1..SIZE - 1).contains(&(p % SIZE)) && (1..SIZE - 1).contains(&(p / SIZE))
            })
            .map(|(c, p)| {
                let (x, y) = (p % SIZE, p / SIZE);
                let d = clip(box_film[c][p]) - clip(f.reference[c][(SIZE - 1 - y) * SIZE + x]);
                d * d
            })
            .sum();
        assert!(
            flipped > aligned,
            "{scene}: vertical flip {flipped} <= {aligned}"
        );
    }
}

/// Reads the `.npy` image `rkwave reconstruct --dim 2` writes: version 1.0, `<f8`, C order,
/// shape `(H, W, C)`. Returns the shape and the values per channel in row-major pixel order.
fn read_image_npy(path: &Path) -> ((usize, usize, usize), Vec<Vec<f64>>) {
    let bytes = std::fs::read(path).expect("image written");
    assert_eq!(&bytes[..6], b"\x93NUMPY", "npy magic");
    let header_len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let header = std::str::from_utf8(&bytes[10..10 + header_len]).expect("ascii header");
    assert!(header.contains("'descr': '<f8'"), "{header}");
    assert!(header.contains("'fortran_order': False"), "{header}");
    let shape: Vec<usize> = header
        .split("'shape': (")
        .nth(1)
        .and_then(|s| s.split(')').next())
        .expect("shape")
        .split(',')
        .filter(|s| !s.trim().is_empty())
        .map(|s| s.trim().parse().expect("shape entry"))
        .collect();
    assert_eq!(shape.len(), 3, "{header}");
    let (h, w, ch) = (shape[0], shape[1], shape[2]);
    let data = &bytes[10 + header_len..];
    assert_eq!(data.len(), 8 * h * w * ch, "data length");
    let mut channels = vec![vec![0.0; h * w]; ch];
    for (k, chunk) in data.chunks_exact(8).enumerate() {
        let v = f64::from_le_bytes(chunk.try_into().expect("8 bytes"));
        channels[k % ch][k / ch] = v;
    }
    ((h, w, ch), channels)
}

/// How far below the box film of the same samples rkwave's uniform reconstruction may be,
/// per scene, in dB. Measured with main's rkwave at de5b629 (`reconstruct --dim 2`, p = 3)
/// on these fixtures: direct 28.05 vs 31.79 (-3.74), cornell 24.53 vs 27.55 (-3.02), thinlens
/// 28.43 vs 29.23 (-0.80); the bound is the measured gap plus 1 dB. The uniform fit LOSES to
/// the box film on every fixture (at 128 x 128, `docs/measurements/real-renders.md`, it loses on
/// direct and cornell at 4, 8 and 16 spp and wins only on thinlens); this guards against a further
/// regression, it asserts no win.
const UNIFORM_GAP_DB: [(&str, f64); 3] = [("direct", 4.74), ("cornell", 4.02), ("thinlens", 1.80)];

#[test]
fn uniform_reconstruction_of_real_samples_is_finite_and_within_the_measured_gap() {
    let dir = std::env::temp_dir().join(format!("rkwave-real-renders-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch folder");
    for (scene, gap) in UNIFORM_GAP_DB {
        let f = load(scene);
        let (shape, image) = reconstruct_with(scene, &[], &dir);
        assert_eq!(shape, (SIZE, SIZE, 3), "{scene}: (H, W, C)");
        assert!(
            image.iter().flatten().all(|v| v.is_finite()),
            "{scene}: finite"
        );
        // No range promise is made for the uniform least-squares fit: it rings next to the
        // Cornell box's emitter (values below 0 and above the samples' maximum are measured),
        // so none is asserted here.
        let (box_film, _) = naive_box(&f);
        let (uniform_db, box_db) = (psnr(&image, &f.reference), psnr(&box_film, &f.reference));
        assert!(
            uniform_db >= box_db - gap,
            "{scene}: uniform {uniform_db:.2} dB, box {box_db:.2} dB: more than {gap} dB below"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// What `reconstruct --dim 2 --pixels E` gains on the fixtures, in dB against the box film of
/// the same samples (shrunk) or against the plain fit (fit-clamped). Measured on these fixtures
/// (`docs/measurements/real-renders.md`, "Noise-aware pixel estimates in the engine"): shrunk − box
/// = +0.01 (direct), +4.65 (cornell), +0.02 (thinlens); fit-clamped − fit = +3.19, +4.24, +1.18.
/// The outputs are deterministic, so the bounds guard against regressions, with room for a change
/// of the transform's rounding or of the fit: on cornell (Monte Carlo noise) shrinkage must
/// keep at least 3 dB, i.e. at least halve the box's squared error; on the noise-free scenes it
/// must cost at most 0.1 dB (the pooled noise level there is ~1e-4 of the signal); the clamp
/// must gain at least 1 dB on direct and cornell (it removes the fit's ringing at edges and the
/// emitter). Since the image plane's default p is 2 (issue 28) the fit rings less on the
/// defocused thinlens image: fit-clamped − fit = +0.02 dB there (28.97 against 28.95), so the
/// clamp must only not lose more than 0.1 dB.
const ESTIMATE_GAINS_DB: [(&str, f64, f64); 3] = [
    ("direct", -0.1, 1.0),
    ("cornell", 3.0, 1.0),
    ("thinlens", -0.1, -0.1),
];

/// `rkwave reconstruct --dim 2` of a fixture's samples with `extra` flags: the image's shape
/// `(H, W, C)` and its values per channel.
fn reconstruct_with(
    scene: &str,
    extra: &[&str],
    dir: &Path,
) -> ((usize, usize, usize), Vec<Vec<f64>>) {
    let out = dir.join(format!("{scene}{}.npy", extra.join("")));
    let run = common::command()
        .args(["reconstruct", "--dim", "2", "--resolution"])
        .arg(format!("{SIZE}x{SIZE}"))
        .arg("--input")
        .arg(samples_path(scene))
        .arg("--output")
        .arg(&out)
        .arg("--force")
        .args(extra)
        .output()
        .expect("rkwave runs");
    assert!(
        run.status.success(),
        "{scene} {extra:?}: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    read_image_npy(&out)
}

#[test]
fn shrunk_pixels_gain_on_monte_carlo_noise_and_the_clamp_stays_in_the_samples_range() {
    let dir = std::env::temp_dir().join(format!("rkwave-real-estimates-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch folder");
    for (scene, shrink_gain, clamp_gain) in ESTIMATE_GAINS_DB {
        let f = load(scene);
        let (box_film, _) = naive_box(&f);
        let box_db = psnr(&box_film, &f.reference);
        let shrunk_db = psnr(
            &reconstruct_with(scene, &["--pixels", "shrunk"], &dir).1,
            &f.reference,
        );
        assert!(
            shrunk_db >= box_db + shrink_gain,
            "{scene}: shrunk {shrunk_db:.2} dB, box {box_db:.2} dB: less than {shrink_gain:+} dB"
        );
        let fit_db = psnr(
            &reconstruct_with(scene, &["--pixels", "fit"], &dir).1,
            &f.reference,
        );
        let clamped = reconstruct_with(scene, &["--pixels", "fit-clamped"], &dir).1;
        let clamped_db = psnr(&clamped, &f.reference);
        assert!(
            clamped_db >= fit_db + clamp_gain,
            "{scene}: fit-clamped {clamped_db:.2} dB, fit {fit_db:.2} dB: less than {clamp_gain:+}"
        );
        // Every clamped pixel lies within the range of its own samples.
        for (c, values) in f.rgb.iter().enumerate() {
            let mut lo = vec![f64::INFINITY; SIZE * SIZE];
            let mut hi = vec![f64::NEG_INFINITY; SIZE * SIZE];
            for ((&x, &y), &v) in f.xs.iter().zip(&f.ys).zip(values) {
                let p = pixel(x, y);
                lo[p] = lo[p].min(v);
                hi[p] = hi[p].max(v);
            }
            for (p, &v) in clamped[c].iter().enumerate() {
                assert!(
                    lo[p] <= v && v <= hi[p],
                    "{scene}: channel {c} pixel {p}: {v} outside [{}, {}]",
                    lo[p],
                    hi[p]
                );
            }
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}
