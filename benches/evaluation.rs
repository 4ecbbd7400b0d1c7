//! Pointwise evaluation throughput: all nonzero functions of `Psi(n, N)` at a position, one core.
//! `p = 2, 3, 4` and `N - n = 4, 10` with `n = j_min(p)`; uniform random positions.

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

criterion_group!(benches, evaluation);
criterion_main!(benches);
