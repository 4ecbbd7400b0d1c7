//! End-to-end reconstruction (uniform random samples, automatic levels, rho = 2): the
//! single-scale global solve by banded QR (the default) and by the banded normal equations,
//! p = 3 and 4, fit plus evaluation on a grid as large as the sample set, 1e4 to 1e7 samples
//! (1e7 takes minutes per point on a shared 2-core machine: filter it out with a criterion
//! filter such as `single_scale/.*/(10000|100000|1000000)$`); then the single-scale solve
//! against the sparse global solve on the multilevel K and local inversion.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use rkwave::reconstruct::{fit, FitParams, Method, SingleScaleSolver};
use rkwave::sampling::{Domain, Layout, Signal};
use rkwave::solve::{GlobalLsParams, LocalInversionParams, Solver};

/// Sample counts of the single-scale path.
const SIZES: [usize; 4] = [10_000, 100_000, 1_000_000, 10_000_000];
/// Sample count of the method comparison.
const COMPARE: usize = 20_000;

fn data(m: usize, channels: usize) -> (Vec<f64>, Vec<Vec<f64>>, Vec<f64>) {
    let xs = Layout::Random.generate(m, Domain::UNIT, 7);
    let signals = [Signal::Smooth, Signal::HeaviSine, Signal::Doppler];
    let values = (0..channels)
        .map(|c| signals[c].sample(Domain::UNIT, &xs))
        .collect();
    let grid = (0..m).map(|i| i as f64 / (m - 1) as f64).collect();
    (xs, values, grid)
}

fn end_to_end(c: &mut Criterion) {
    let mut group = c.benchmark_group("single_scale");
    group.sample_size(10);
    for &m in &SIZES {
        let (xs, values, grid) = data(m, 1);
        let refs: Vec<&[f64]> = values.iter().map(|v| v.as_slice()).collect();
        group.throughput(Throughput::Elements(m as u64));
        for p in [3usize, 4] {
            for (name, solver) in [
                ("qr", SingleScaleSolver::Qr),
                ("normal", SingleScaleSolver::NormalEquations),
            ] {
                let params = FitParams {
                    p,
                    family: None,
                    method: Method::SingleScale { ridge: 0.0, solver },
                    ..FitParams::default()
                };
                group.bench_with_input(BenchmarkId::new(format!("p{p}/{name}"), m), &m, |b, _| {
                    b.iter(|| {
                        let f = fit(&xs, &refs, Domain::UNIT, &params).unwrap();
                        f.evaluate(&grid).unwrap()
                    })
                });
            }
        }
    }
    group.finish();
}

fn methods(c: &mut Criterion) {
    let mut group = c.benchmark_group("methods_20k");
    group.sample_size(10);
    let (xs, values, _) = data(COMPARE, 1);
    let refs: Vec<&[f64]> = values.iter().map(|v| v.as_slice()).collect();
    let cases = [
        (
            "single_scale",
            Method::SingleScale {
                ridge: 0.0,
                solver: Default::default(),
            },
        ),
        (
            "global_sparse_cholesky",
            Method::Global(GlobalLsParams::default()),
        ),
        (
            "local_rings0_cholesky",
            Method::Local(LocalInversionParams {
                rings: 0,
                solver: Solver::Cholesky,
                ..Default::default()
            }),
        ),
        (
            "local_rings1_cholesky",
            Method::Local(LocalInversionParams {
                rings: 1,
                solver: Solver::Cholesky,
                ..Default::default()
            }),
        ),
        (
            "local_rings1_svd",
            Method::Local(LocalInversionParams::default()),
        ),
    ];
    for (name, method) in cases {
        let params = FitParams {
            method,
            ..FitParams::default()
        };
        group.bench_function(name, |b| {
            b.iter(|| fit(&xs, &refs, Domain::UNIT, &params).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, end_to_end, methods);
criterion_main!(benches);
