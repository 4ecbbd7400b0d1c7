//! One refinement round on a tree with 1e6 samples (the three-jump signal, p = 3, base depth
//! from the sample count) against a full rebuild of the same problem (every basis evaluation,
//! K and the solve from scratch). Slow by nature: about 20 minutes on the 2-core machine
//! (a 1e6-sample tree takes ~50 s to build, a round ~35 s).

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use rkwave::refine::{BaseSampling, StopParams};
use rkwave::refine::{RefineParams, Refiner, SignalOracle};
use rkwave::sampling::{Domain, Signal};

/// Base samples of the tree.
const SAMPLES: usize = 1_000_000;

fn round_vs_rebuild(c: &mut Criterion) {
    let oracle = SignalOracle::new(Signal::Jumps, Domain::UNIT);
    let params = RefineParams {
        sampling: BaseSampling {
            base_samples: SAMPLES,
            ..RefineParams::default().sampling
        },
        stop: StopParams {
            tolerance: 1e-12,
            budget: 2 * SAMPLES,
            ..RefineParams::default().stop
        },
        ..RefineParams::default()
    };
    let mut group = c.benchmark_group("refine_1e6");
    group.sample_size(10);
    group.bench_function("one_round", |b| {
        b.iter_batched(
            || Refiner::new(&oracle, &params).unwrap(),
            |mut r| r.refine_once().unwrap(),
            BatchSize::PerIteration,
        )
    });
    let done = Refiner::new(&oracle, &params).unwrap().into_result();
    group.bench_function("full_rebuild", |b| b.iter(|| done.rebuild().unwrap()));
    group.finish();
}

criterion_group!(benches, round_vs_rebuild);
criterion_main!(benches);
