//! The image-plane engine end to end (sampling excluded, pixels computed): stratified samples
//! at 4 per pixel, 3 channels, automatic levels (about one function per pixel), the normal
//! equations solved by sparse Cholesky or Jacobi-preconditioned CG, `p = 2` and `p = 3`, then
//! the exact box pixel integrals `I = B_y C B_x^T` of the reconstruction. Beside it, pbrt-v4's
//! default Gaussian film filter (weighted splatting) on the same samples, for the ratio
//! wavelet / film. A last group compares the CG preconditioners (none / Jacobi / local
//! inversion) at 256².
//!
//! Benchmark names (`group/function/size`), usable as criterion filters:
//!
//! * `image_end_to_end_4spp_3ch/p{2,3}_{cholesky,cg_jacobi}/{256,512}` and
//!   `image_end_to_end_4spp_3ch/gaussian_film/{256,512}`;
//! * `image_cg_preconditioners/{none,jacobi,local}/256`;
//! * `image_fwt_2d/{line_by_line,rows}/{256,1024}`: one 2D non-standard analysis of a
//!   `w x w` single-scale grid (p = 2, levels 4..log2 w), by the 1D steps applied line by line
//!   with strided column copies (the transform before 2026-12-02, kept here as the reference)
//!   and by [`TensorBasis::analysis`] (parallel rows, whole-row column pass; the same bits);
//! * `image_1024/p2_cg_jacobi/1024` and `image_1024/gaussian_film/1024`: only when the
//!   environment variable `RKWAVE_BENCH_1024=1` is set (tens of seconds per iteration; the
//!   Cholesky factor at 1024² needs about 2.7 GB, so only CG runs there).
//!
//! Every group takes 10 samples. Examples:
//!
//! ```text
//! cargo bench --bench image -- 256 --warm-up-time 1 --measurement-time 3   # 256² only
//! cargo bench --bench image -- image_end_to_end                          # 256² and 512²
//! RKWAVE_BENCH_1024=1 cargo bench --bench image -- image_1024            # 1024², p = 2
//! ```

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use rkwave::basis::fwt::analysis_step;
use rkwave::basis::tensor::TensorBasis;
use rkwave::basis::FilterFamily;
use rkwave::image::filters::GaussianFilter;
use rkwave::image::fit::{NormalSolver, StencilPreconditioner};
use rkwave::image::pixels::{fit_pixels, PixelFilter};
use rkwave::image::sampler::Sampler;
use rkwave::image::splat::splat;
use rkwave::image::{fit_image, ImageFitParams, ImagePlane, ImageSamples};

/// Square resolutions of the end-to-end comparison.
const SIZES: [usize; 2] = [256, 512];
/// Samples per pixel.
const SPP: usize = 4;
/// Resolution of the preconditioner comparison.
const PRECONDITIONER_SIZE: usize = 256;
/// Channels (RGB).
const CHANNELS: usize = 3;

/// Stratified samples (`SPP` per pixel) of a smooth field with a hard-edged disc, per channel.
fn data(w: usize) -> ImageSamples {
    let plane = ImagePlane::new(w, w).unwrap();
    let (xs, ys) = Sampler::Stratified.positions(plane, SPP, 7);
    let (cx, cy, r2) = (0.4 * w as f64, 0.55 * w as f64, (0.2 * w as f64).powi(2));
    let values = (0..CHANNELS)
        .map(|c| {
            xs.iter()
                .zip(&ys)
                .map(|(&x, &y)| {
                    let disc = if (x - cx).powi(2) + (y - cy).powi(2) < r2 {
                        0.5
                    } else {
                        0.0
                    };
                    (x * 0.05 + c as f64).sin() * (y * 0.031).cos() + disc
                })
                .collect()
        })
        .collect();
    ImageSamples::new(plane, xs, ys, values).unwrap()
}

fn params(p: usize, solver: NormalSolver) -> ImageFitParams {
    ImageFitParams {
        p,
        solver,
        ..ImageFitParams::default()
    }
}

fn cg(preconditioner: StencilPreconditioner) -> NormalSolver {
    NormalSolver::Cg {
        preconditioner,
        tolerance: 1e-10,
        forward_error: None,
        max_iterations: 10_000,
    }
}

/// Fit, then the exact box pixels of every channel.
fn run(d: &ImageSamples, prm: &ImageFitParams) -> Vec<Vec<f64>> {
    let refs: Vec<&[f64]> = d.values().iter().map(|v| v.as_slice()).collect();
    let plane = d.plane();
    let fit = fit_image(plane.width(), plane.height(), d.xs(), d.ys(), &refs, prm).unwrap();
    fit_pixels(&fit, PixelFilter::Box).unwrap()
}

fn end_to_end(c: &mut Criterion) {
    let mut group = c.benchmark_group("image_end_to_end_4spp_3ch");
    group.sample_size(10);
    for &w in &SIZES {
        let d = data(w);
        group.throughput(Throughput::Elements(d.len() as u64));
        for p in [2usize, 3] {
            for (name, solver) in [
                ("cholesky", NormalSolver::Cholesky),
                ("cg_jacobi", cg(StencilPreconditioner::Jacobi)),
            ] {
                let prm = params(p, solver);
                group.bench_with_input(BenchmarkId::new(format!("p{p}_{name}"), w), &w, |b, _| {
                    b.iter(|| run(&d, &prm))
                });
            }
        }
        let gaussian = GaussianFilter::default();
        group.bench_with_input(BenchmarkId::new("gaussian_film", w), &w, |b, _| {
            b.iter(|| splat(&d, &gaussian))
        });
    }
    group.finish();
}

fn large(c: &mut Criterion) {
    if std::env::var("RKWAVE_BENCH_1024").as_deref() != Ok("1") {
        return;
    }
    let mut group = c.benchmark_group("image_1024");
    group.sample_size(10);
    let w = 1024;
    let d = data(w);
    group.throughput(Throughput::Elements(d.len() as u64));
    let prm = params(2, cg(StencilPreconditioner::Jacobi));
    group.bench_with_input(BenchmarkId::new("p2_cg_jacobi", w), &w, |b, _| {
        b.iter(|| run(&d, &prm))
    });
    let gaussian = GaussianFilter::default();
    group.bench_with_input(BenchmarkId::new("gaussian_film", w), &w, |b, _| {
        b.iter(|| splat(&d, &gaussian))
    });
    group.finish();
}

fn preconditioners(c: &mut Criterion) {
    let mut group = c.benchmark_group("image_cg_preconditioners");
    group.sample_size(10);
    let w = PRECONDITIONER_SIZE;
    let d = data(w);
    for (name, pre) in [
        ("none", StencilPreconditioner::None),
        ("jacobi", StencilPreconditioner::Jacobi),
        ("local", StencilPreconditioner::Local),
    ] {
        let prm = params(2, cg(pre));
        group.bench_with_input(BenchmarkId::new(name, w), &w, |b, _| {
            b.iter(|| run(&d, &prm))
        });
    }
    group.finish();
}

/// The 2D analysis as the 1D steps line by line (rows, then each column copied out and back).
fn analysis_line_by_line(b: &TensorBasis, data: &[f64]) -> Vec<f64> {
    let (nx, _) = b.dims();
    let (cx, cy) = b.coarse_levels();
    let bank = b.bank();
    let mut x = data.to_vec();
    let mut line = vec![0.0; nx];
    let mut out = vec![0.0; nx];
    for s in (0..b.steps()).rev() {
        let (jx, jy) = (cx + s, cy + s);
        let (lx, ly) = (2usize << jx, 2usize << jy);
        for ky in 0..ly {
            analysis_step(bank, jx, &x[ky * nx..ky * nx + lx], &mut out[..lx]);
            x[ky * nx..ky * nx + lx].copy_from_slice(&out[..lx]);
        }
        for kx in 0..lx {
            for ky in 0..ly {
                line[ky] = x[ky * nx + kx];
            }
            analysis_step(bank, jy, &line[..ly], &mut out[..ly]);
            for ky in 0..ly {
                x[ky * nx + kx] = out[ky];
            }
        }
    }
    x
}

fn fwt_2d(c: &mut Criterion) {
    let mut group = c.benchmark_group("image_fwt_2d");
    group.sample_size(10);
    for w in [256usize, 1024] {
        let level = w.trailing_zeros();
        let basis =
            TensorBasis::new(2, FilterFamily::cdv_default(2), w, w, (level, level)).unwrap();
        let data: Vec<f64> = (0..basis.len())
            .map(|i| ((i * 7919) % 1000) as f64 * 1e-3)
            .collect();
        assert_eq!(basis.analysis(&data), analysis_line_by_line(&basis, &data));
        group.throughput(Throughput::Elements(basis.len() as u64));
        group.bench_with_input(BenchmarkId::new("line_by_line", w), &w, |b, _| {
            b.iter(|| analysis_line_by_line(&basis, &data))
        });
        group.bench_with_input(BenchmarkId::new("rows", w), &w, |b, _| {
            b.iter(|| basis.analysis(&data))
        });
    }
    group.finish();
}

criterion_group!(benches, end_to_end, large, preconditioners, fwt_2d);
criterion_main!(benches);
