//! The image-plane engine end to end (sampling excluded): stratified samples at 4 per pixel,
//! 3 channels, automatic levels (about one function per pixel), the normal equations solved
//! by sparse Cholesky against Jacobi-preconditioned CG, `p = 2` against `p = 3`, then the
//! reconstruction evaluated at every pixel centre. A second group compares the CG
//! preconditioners (none / Jacobi / local inversion) at the smallest size.
//!
//! `cargo bench --bench image -- --warm-up-time 1 --measurement-time 3` runs in a few minutes
//! on 2 cores; `SIZES` holds the resolutions (1024² takes tens of seconds per iteration).

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use rand::{Rng, SeedableRng};
use rkwave::basis::FilterFamily;
use rkwave::image::fit::{NormalSolver, Preconditioner};
use rkwave::image::{fit_image, ImageFitParams};

/// Square resolutions of the end-to-end comparison.
const SIZES: [usize; 3] = [256, 512, 1024];
/// Samples per pixel.
const SPP: usize = 4;
/// Resolution of the preconditioner comparison.
const PRECONDITIONER_SIZE: usize = 256;
/// Channels (RGB).
const CHANNELS: usize = 3;

struct Data {
    xs: Vec<f64>,
    ys: Vec<f64>,
    values: Vec<Vec<f64>>,
    centres: (Vec<f64>, Vec<f64>),
}

/// Stratified samples (one jittered sample per sub-cell would also do; SPP per pixel here)
/// of a smooth field with a hard-edged disc, per channel.
fn data(w: usize, h: usize) -> Data {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
    let (mut xs, mut ys) = (Vec::new(), Vec::new());
    for py in 0..h {
        for px in 0..w {
            for _ in 0..SPP {
                xs.push(px as f64 + rng.random::<f64>());
                ys.push(py as f64 + rng.random::<f64>());
            }
        }
    }
    let (cx, cy, r2) = (0.4 * w as f64, 0.55 * h as f64, (0.2 * w as f64).powi(2));
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
    let centres = (0..w * h)
        .map(|i| ((i % w) as f64 + 0.5, (i / w) as f64 + 0.5))
        .unzip();
    Data {
        xs,
        ys,
        values,
        centres,
    }
}

fn params(p: usize, solver: NormalSolver) -> ImageFitParams {
    ImageFitParams {
        p,
        family: FilterFamily::cdv_default(p),
        solver,
        ..ImageFitParams::default()
    }
}

fn cg(preconditioner: Preconditioner) -> NormalSolver {
    NormalSolver::Cg {
        preconditioner,
        tolerance: 1e-10,
        max_iterations: 10_000,
    }
}

fn run(d: &Data, w: usize, prm: &ImageFitParams) -> Vec<Vec<f64>> {
    let refs: Vec<&[f64]> = d.values.iter().map(|v| v.as_slice()).collect();
    let fit = fit_image(w, w, &d.xs, &d.ys, &refs, prm).unwrap();
    fit.evaluate_many(&d.centres.0, &d.centres.1).unwrap()
}

fn end_to_end(c: &mut Criterion) {
    let mut group = c.benchmark_group("image_end_to_end_4spp_3ch");
    group.sample_size(10);
    for &w in &SIZES {
        let d = data(w, w);
        group.throughput(Throughput::Elements(d.xs.len() as u64));
        for p in [2usize, 3] {
            for (name, solver) in [
                ("cholesky", NormalSolver::Cholesky),
                ("cg_jacobi", cg(Preconditioner::Jacobi)),
            ] {
                let prm = params(p, solver);
                group.bench_with_input(BenchmarkId::new(format!("p{p}_{name}"), w), &w, |b, _| {
                    b.iter(|| run(&d, w, &prm))
                });
            }
        }
    }
    group.finish();
}

fn preconditioners(c: &mut Criterion) {
    let mut group = c.benchmark_group("image_cg_preconditioners");
    group.sample_size(10);
    let w = PRECONDITIONER_SIZE;
    let d = data(w, w);
    for (name, pre) in [
        ("none", Preconditioner::None),
        ("jacobi", Preconditioner::Jacobi),
        ("local", Preconditioner::Local),
    ] {
        let prm = params(2, cg(pre));
        group.bench_with_input(BenchmarkId::new(name, w), &w, |b, _| {
            b.iter(|| run(&d, w, &prm))
        });
    }
    group.finish();
}

criterion_group!(benches, end_to_end, preconditioners);
criterion_main!(benches);
