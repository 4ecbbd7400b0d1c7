//! The uniform image fit by conjugate gradients against the sparse Cholesky, and `--pixels
//! auto` on the command line.
//!
//! The default solver ([`NormalSolver::Auto`]) runs Jacobi PCG on `A = G + lambda diag(G)`
//! above `64²` functions, stopped at a relative residual `||b - A z|| / ||b|| <= 1e-6`, and
//! falls back to the Cholesky where it does not get there. The tests hold it to:
//!
//! - the stopping rule, on the true residual (recomputed from the fit's own `A`, not the one
//!   the iteration recurred): at most `2 tol`, the recurrence's rounding drift being orders of
//!   magnitude below `tol` after a few dozen iterations;
//! - the Cholesky's pixels within `1e-4` of the image's range: `||z - z*|| / ||z*|| <= cond(A)
//!   tol`, and at four samples per function `cond(A)` of the equilibrated matrix is a few tens
//!   (dense samples: a Riesz basis), so `1e-4` leaves a factor of about 3 above it;
//! - pinned functions (no sample in their support) exactly 0, as the Cholesky pins them;
//! - a fallback that is reported and gives the Cholesky's coefficients bit for bit.

mod common;

use common::image_cli::reconstruct2d;
use common::runner::{rkwave, scratch, succeeds};
use rkwave::image::fit::{
    NormalSolver, StencilPreconditioner, CG_TOLERANCE, CHOLESKY_MAX_FUNCTIONS,
};
use rkwave::image::pixels::{fit_pixels, PixelFilter};
use rkwave::image::sampler::Sampler;
use rkwave::image::{fit_image, ImageFit, ImageFitParams, ImagePlane};
use rkwave::io::{write_npy, SampleSet};

/// Three channels of a scene with a smooth part, a hard-edged disc and seeded noise.
fn values(xs: &[f64], ys: &[f64], w: f64, seed: u64) -> Vec<Vec<f64>> {
    (0..3)
        .map(|c| {
            xs.iter()
                .zip(ys)
                .enumerate()
                .map(|(i, (&x, &y))| {
                    let disc = if (x - 0.4 * w).powi(2) + (y - 0.5 * w).powi(2) < (0.2 * w).powi(2)
                    {
                        0.7
                    } else {
                        0.0
                    };
                    // a hash of (i, c, seed) as noise in [-0.05, 0.05]
                    let h = ((i as u64 ^ (seed << 20)).wrapping_mul(0x9E37_79B9_7F4A_7C15)
                        >> (11 + c)) as f64
                        / (1u64 << (53 - c)) as f64;
                    (0.05 * x + c as f64).sin() * (0.03 * y).cos() + disc + 0.1 * (h.fract() - 0.5)
                })
                .collect()
        })
        .collect()
}

fn fit(
    w: usize,
    h: usize,
    xs: &[f64],
    ys: &[f64],
    v: &[Vec<f64>],
    solver: NormalSolver,
) -> ImageFit {
    let refs: Vec<&[f64]> = v.iter().map(|c| c.as_slice()).collect();
    let params = ImageFitParams {
        solver,
        ..ImageFitParams::default()
    };
    fit_image(w, h, xs, ys, &refs, &params).unwrap()
}

/// `||b - A z|| / ||b||` per channel, `A z` by the fit's own operator, `b = A z*` from the
/// Cholesky's coefficients `z*` (the same `A`: same samples, same ridge).
fn true_residuals(cg: &ImageFit, chol: &ImageFit) -> Vec<f64> {
    let n = cg.coefficients[0].len();
    let apply = |z: &[Vec<f64>]| {
        let refs: Vec<&[f64]> = z.iter().map(|c| c.as_slice()).collect();
        let mut out = vec![vec![0.0; n]; z.len()];
        cg.system().apply(&refs, &mut out);
        out
    };
    let (az, b) = (apply(&cg.coefficients), apply(&chol.coefficients));
    az.iter()
        .zip(&b)
        .map(|(a, b)| {
            let r: f64 = a.iter().zip(b).map(|(a, b)| (a - b).powi(2)).sum();
            let bn: f64 = b.iter().map(|b| b * b).sum();
            (r / bn).sqrt()
        })
        .collect()
}

/// Largest pixel difference over the pixels' range.
fn pixel_gap(a: &ImageFit, b: &ImageFit) -> f64 {
    let (pa, pb) = (
        fit_pixels(a, PixelFilter::Box).unwrap(),
        fit_pixels(b, PixelFilter::Box).unwrap(),
    );
    let range = pb
        .iter()
        .flatten()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    let gap = pa
        .iter()
        .flatten()
        .zip(pb.iter().flatten())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    gap / (range.1 - range.0)
}

#[test]
fn cg_matches_the_cholesky_on_seeded_sample_sets() {
    for (seed, (w, h), sampler, spp) in [
        (1, (128, 96), Sampler::Stratified, 4),
        (2, (128, 128), Sampler::Sobol, 4),
        (3, (100, 140), Sampler::Stratified, 8),
        (4, (128, 80), Sampler::Uniform, 4),
    ] {
        let plane = ImagePlane::new(w, h).unwrap();
        let (xs, ys) = sampler.positions(plane, spp, seed);
        let v = values(&xs, &ys, w as f64, seed);
        let cg = fit(w, h, &xs, &ys, &v, NormalSolver::Auto);
        let chol = fit(w, h, &xs, &ys, &v, NormalSolver::Cholesky);
        let what = format!("seed {seed}, {w}x{h}, {sampler:?}, {spp} spp");
        let report = cg.report.cg.as_ref().expect("CG above 64² functions");
        assert!(cg.report.functions > CHOLESKY_MAX_FUNCTIONS, "{what}");
        if report.fallback.is_none() {
            for r in true_residuals(&cg, &chol) {
                assert!(r <= 2.0 * CG_TOLERANCE, "{what}: true residual {r:e}");
            }
        }
        let gap = pixel_gap(&cg, &chol);
        assert!(
            gap < 1e-4,
            "{what}: pixels differ by {gap:e} of their range"
        );
    }
}

#[test]
fn pinned_functions_stay_zero_and_the_ridge_is_the_same() {
    // Samples on the left 60% only: the functions on the right have none and are pinned.
    let (w, h) = (140, 80);
    let plane = ImagePlane::new(w, h).unwrap();
    let (xs, ys) = Sampler::Stratified.positions(plane, 4, 9);
    let (xs, ys): (Vec<f64>, Vec<f64>) = xs
        .into_iter()
        .zip(ys)
        .filter(|(x, _)| *x < 0.6 * w as f64)
        .unzip();
    let v = values(&xs, &ys, w as f64, 9);
    let cg = fit(w, h, &xs, &ys, &v, NormalSolver::Auto);
    let chol = fit(w, h, &xs, &ys, &v, NormalSolver::Cholesky);
    assert!(cg.report.unsampled > 0 && cg.report.cg.is_some());
    assert_eq!(cg.report.unsampled, chol.report.unsampled);
    assert_eq!(cg.report.ridge, chol.report.ridge);
    for (zc, zs) in cg.coefficients.iter().zip(&chol.coefficients) {
        for (a, b) in zc.iter().zip(zs) {
            assert!(*b != 0.0 || *a == 0.0, "a pinned coefficient moved: {a}");
        }
    }
    assert!(pixel_gap(&cg, &chol) < 1e-4);
}

#[test]
fn a_capped_cg_falls_back_to_the_cholesky_and_says_so() {
    let (w, h) = (128, 70);
    let plane = ImagePlane::new(w, h).unwrap();
    let (xs, ys) = Sampler::Stratified.positions(plane, 4, 5);
    let v = values(&xs, &ys, w as f64, 5);
    let capped = NormalSolver::Cg {
        preconditioner: StencilPreconditioner::Jacobi,
        tolerance: 1e-14,
        forward_error: None,
        max_iterations: 2,
    };
    let fell = fit(w, h, &xs, &ys, &v, capped);
    let chol = fit(w, h, &xs, &ys, &v, NormalSolver::Cholesky);
    let report = fell.report.cg.as_ref().unwrap();
    assert!(!report.converged);
    let why = report
        .fallback
        .as_deref()
        .expect("the fallback is reported");
    assert!(
        why.contains("sparse Cholesky") && why.contains("at most 2"),
        "{why}"
    );
    assert!(fell.report.factor.is_some());
    // the same system, factored the same way: the same bits
    assert_eq!(fell.coefficients, chol.coefficients);
}

#[test]
fn small_systems_take_the_cholesky() {
    // levels are dyadic: 64 x 64 functions at 64 x 64 pixels, 128 x 64 at 128 x 64
    for (w, solver) in [(64, "Cholesky"), (128, "Cg")] {
        let plane = ImagePlane::new(w, 64).unwrap();
        let (xs, ys) = Sampler::Stratified.positions(plane, 4, 3);
        let v = values(&xs, &ys, w as f64, 3);
        let f = fit(w, 64, &xs, &ys, &v, NormalSolver::Auto);
        let used = serde_json::to_value(f.report.solver).unwrap();
        let name = used
            .as_str()
            .map(String::from)
            .or_else(|| used.as_object().and_then(|o| o.keys().next().cloned()))
            .unwrap();
        assert_eq!(name, solver, "{w}x64, {} functions", f.report.functions);
    }
}

/// `n` stratified samples per pixel of the scene on `w x h` (`hole`: none in the first
/// column of pixels), written as `.npy` `m x 5`.
fn sample_file(dir: &std::path::Path, w: usize, h: usize, hole: bool) -> std::path::PathBuf {
    let plane = ImagePlane::new(w, h).unwrap();
    let (xs, ys) = Sampler::Stratified.positions(plane, 4, 2);
    let (xs, ys): (Vec<f64>, Vec<f64>) = xs
        .into_iter()
        .zip(ys)
        .filter(|(x, _)| !hole || *x >= 1.0)
        .unzip();
    let mut columns = vec![ys.clone()];
    columns.extend(values(&xs, &ys, w as f64, 2));
    let path = dir.join(if hole { "hole.npy" } else { "s.npy" });
    write_npy(&path, &SampleSet::new(xs, columns).unwrap()).unwrap();
    path
}

fn json(args: &[&str]) -> serde_json::Value {
    serde_json::from_str(&succeeds(args)).unwrap()
}

#[test]
fn the_report_of_auto_says_auto_and_the_estimate_used() {
    let dir = scratch("uniform-cg", "auto-json");
    let out = dir.join("o.npy");
    let out = out.to_str().unwrap();
    let base = |input: &std::path::Path| {
        let mut args = reconstruct2d(input, std::path::Path::new(out), "48x40");
        args.extend(["--force".into(), "--json".into()]);
        args
    };
    let full = sample_file(&dir, 48, 40, false);
    let args = base(&full);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let r = json(&args);
    assert_eq!(r["method"], "auto", "{r}");
    assert_eq!(r["pixels"]["requested"], "auto");
    assert_eq!(r["pixels"]["estimate"], "auto");
    // A column of pixels without samples: auto falls back to the fit, and says so.
    let hole = sample_file(&dir, 48, 40, true);
    let args = base(&hole);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let r = json(&args);
    assert_eq!(r["method"], "wavelet", "{r}");
    assert_eq!(r["pixels"]["requested"], "auto");
    assert_eq!(r["pixels"]["estimate"], "fit");
    assert!(r["pixels"]["fallback"]
        .as_str()
        .unwrap()
        .contains("no sample"));
    // --pixels fit above 64² functions: the report names CG and its iterations.
    let big = sample_file(&dir, 128, 80, false);
    let mut args = reconstruct2d(&big, std::path::Path::new(out), "128x80");
    args.extend(["--force".into(), "--json".into()]);
    args.extend(["--pixels".into(), "fit".into()]);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let r = json(&args);
    let cg = &r["solve"]["solve"]["cg"];
    assert!(cg["converged"].as_bool().unwrap(), "{r}");
    assert!(cg["fallback"].is_null());
    assert!(cg["iterations"][0].as_u64().unwrap() > 0);
}

#[test]
fn auto_is_checked_against_its_own_memory_not_the_fit_s() {
    // 256 x 256 at 4 spp, 3 channels: auto's estimate is 33 MB (the samples 10 MB, their
    // bins, 14 images), the fit's (PCG) 50 MB (the samples, the normal matrix 25 MB, vectors,
    // the image); a limit between admits auto and refuses the fit, naming it.
    let dir = scratch("uniform-cg", "auto-memory");
    let input = sample_file(&dir, 256, 256, false);
    let out = dir.join("o.npy");
    let args = |pixels: &str| {
        let mut args = vec!["--memory-limit".to_string(), "42M".into()];
        args.extend(reconstruct2d(&input, &out, "256x256"));
        args.extend(["--force".into(), "--pixels".into(), pixels.into()]);
        args
    };
    succeeds(&args("auto"));
    let refused = rkwave(&args("fit"));
    assert_eq!(refused.status.code(), Some(2));
    let text = String::from_utf8_lossy(&refused.stderr);
    assert!(
        text.contains("wavelet") && text.contains("normal matrix"),
        "{text}"
    );
}
