//! Pointwise evaluation throughput: all nonzero functions of `Psi(n, N)` at a position, one core.
//! `p = 2, 3, 4` and `N - n = 4, 10` with `n = j_min(p)`; uniform random positions.
//!
//! And the parts of the renderer plan's tree fit per sample, on the plan's own 128² basis
//! (`p = 2`, `J = 8` per axis, the tree uniform to the pixel: 16,384 functions), 65,536
//! uniform random samples (one 4 spp round): the multilevel row of a sample, the
//! single-scale rows `E`, the exact diagonal `G_aa`, and one product `G v` of the tree's
//! normal operator for 1 and 4 vectors. Run with `RAYON_NUM_THREADS=1` for one core's cost
//! (the last three are parallel over samples).

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use rand::{Rng, SeedableRng};
use rkwave::basis::{minimum_level, BasisValue, CdvBasis, FilterFamily};
use rkwave::sampling::Domain;

/// Positions per measured batch.
const POSITIONS: usize = 10_000;

fn evaluation(c: &mut Criterion) {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(42);
    let xs: Vec<f64> = (0..POSITIONS).map(|_| rng.random::<f64>()).collect();
    let mut group = c.benchmark_group("evaluate_all_levels");
    group.throughput(Throughput::Elements(POSITIONS as u64));
    for p in [2usize, 3, 4] {
        for depth in [4u32, 10] {
            let n = minimum_level(p);
            let basis =
                CdvBasis::new(p, FilterFamily::cdv_default(p), n, n + depth, Domain::UNIT).unwrap();
            let mut ev = basis.evaluator();
            let mut out: Vec<BasisValue> = Vec::with_capacity(512);
            group.bench_with_input(
                BenchmarkId::new(format!("p{p}"), format!("N-n={depth}")),
                &xs,
                |b, xs| {
                    b.iter(|| {
                        let mut s = 0.0;
                        for &x in xs {
                            ev.eval_into(x, &mut out).unwrap();
                            s += out.len() as f64;
                        }
                        s
                    })
                },
            );
        }
    }
    group.finish();
}

/// Samples of [`tree_fit_parts`].
const TREE_SAMPLES: usize = 65_536;

fn tree_fit_parts(c: &mut Criterion) {
    use rkwave::adaptive::tree::quad::QuadTree;
    use rkwave::basis::tensor::TensorBasis;
    use rkwave::solve::tree::pcg::{DiagonalSums, SingleScaleRows, TreeNormalOperator};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
    let xs: Vec<f64> = (0..TREE_SAMPLES)
        .map(|_| 128.0 * rng.random::<f64>())
        .collect();
    let ys: Vec<f64> = (0..TREE_SAMPLES)
        .map(|_| 128.0 * rng.random::<f64>())
        .collect();
    let basis = TensorBasis::new(2, FilterFamily::cdv_default(2), 128, 128, (8, 8)).unwrap();
    let steps = basis.steps();
    let tree = QuadTree::uniform(basis, steps - 1);
    let basis = tree.basis();
    let mut group = c.benchmark_group("tree_fit_per_sample");
    group.sample_size(10);
    group.throughput(Throughput::Elements(TREE_SAMPLES as u64));
    group.bench_function("multilevel_row", |b| {
        let mut ev = basis.multilevel_evaluator();
        let mut row = Vec::with_capacity(512);
        b.iter(|| {
            let mut s = 0usize;
            for (&x, &y) in xs.iter().zip(&ys) {
                ev.eval_unordered_into(x, y, &mut row).unwrap();
                s += row.len();
            }
            s
        })
    });
    group.bench_function("single_scale_rows", |b| {
        b.iter(|| SingleScaleRows::new(basis, &xs, &ys).len())
    });
    group.bench_function("exact_diagonal", |b| {
        b.iter(|| DiagonalSums::new(&tree, &xs, &ys, None).samples())
    });
    let rows = SingleScaleRows::new(basis, &xs, &ys);
    let op = TreeNormalOperator::new(&tree, &rows, &xs, &ys);
    let mut v = vec![0.0; basis.len()];
    for f in tree.functions() {
        v[f] = (f as f64).sin();
    }
    for k in [1usize, 4] {
        let vs: Vec<&[f64]> = (0..k).map(|_| v.as_slice()).collect();
        group.bench_function(format!("operator_k{k}"), |b| {
            b.iter(|| op.apply_many(&vs).len())
        });
    }
    // one product's two 2D FWTs alone (synthesis S v, analysis S^T u): the rest of
    // `operator_k1` is the two passes over the rows `E`
    group.bench_function("fwt_pair", |b| {
        b.iter(|| basis.analysis(&basis.synthesis(&v)).len())
    });
    group.finish();
}

criterion_group!(benches, evaluation, tree_fit_parts);
criterion_main!(benches);
