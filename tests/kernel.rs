//! Kernel matrices: rows equal the pointwise evaluation, the reproducing kernel identity
//! `K K^T`-free check `sum_a <1, Psi_a> K[i, a] = 1`, active subsets, level choice, errors.

use rkwave::basis::{minimum_level, CdvBasis, FilterFamily};
use rkwave::kernel::{kernel_matrix, ActiveSet, KernelError, LevelChoice, LevelParams};
use rkwave::sampling::{Domain, Layout};

#[test]
fn rows_are_the_pointwise_evaluation() {
    let domain = Domain::new(-2.0, 5.0).unwrap();
    let basis = CdvBasis::new(3, FilterFamily::Extremal, 4, 7, domain).unwrap();
    let xs = Layout::Random.generate(3000, domain, 11);
    let k = kernel_matrix(&ActiveSet::uniform(basis.clone()), &xs).unwrap();
    assert_eq!(k.shape(), (3000, 256));
    let mut ev = basis.evaluator();
    for (i, row) in k.outer_iterator().enumerate() {
        let direct = ev.eval(xs[i]).unwrap();
        assert_eq!(row.nnz(), direct.len());
        for ((c, &v), d) in row.iter().zip(&direct) {
            assert_eq!(c, d.index);
            assert_eq!(v, d.value);
        }
    }
}

#[test]
fn active_subset_keeps_only_its_columns() {
    let basis = CdvBasis::new(2, FilterFamily::Extremal, 3, 6, Domain::UNIT).unwrap();
    let keep: Vec<usize> = (0..basis.dimension()).filter(|a| a % 3 != 1).collect();
    let active = ActiveSet::from_indices(basis.clone(), keep.clone());
    let xs = Layout::Uniform.generate(500, Domain::UNIT, 0);
    let k = kernel_matrix(&active, &xs).unwrap();
    let full = kernel_matrix(&ActiveSet::uniform(basis), &xs).unwrap();
    assert_eq!(k.cols(), keep.len());
    for (row, frow) in k.outer_iterator().zip(full.outer_iterator()) {
        let expect: Vec<(usize, f64)> = frow
            .iter()
            .filter(|(c, _)| c % 3 != 1)
            .map(|(c, &v)| (active.column(c).unwrap(), v))
            .collect();
        let got: Vec<(usize, f64)> = row.iter().map(|(c, &v)| (c, v)).collect();
        assert_eq!(got, expect);
    }
}

#[test]
fn bad_positions_name_the_row() {
    let basis = CdvBasis::new(2, FilterFamily::Extremal, 3, 4, Domain::UNIT).unwrap();
    let active = ActiveSet::uniform(basis);
    assert_eq!(kernel_matrix(&active, &[]), Err(KernelError::Empty));
    let err = kernel_matrix(&active, &[0.1, 0.2, f64::NAN]).unwrap_err();
    assert!(matches!(err, KernelError::PositionOutside { row: 3, .. }));
    let err = kernel_matrix(&active, &[0.1, 1.5]).unwrap_err();
    assert!(err.to_string().contains("sample 2"));
}

#[test]
fn automatic_levels_hit_the_oversampling_and_locality_targets() {
    for &m in &[1_000usize, 10_000, 100_000, 1_000_000, 10_000_000] {
        for p in [2usize, 3, 6] {
            let params = LevelParams::default();
            let c = LevelChoice::auto(m, p, params);
            let dim = (1u64 << (c.fine + 1)) as f64;
            assert!(c.coarse >= minimum_level(p) && c.coarse <= c.fine);
            // 2^{N+1} <= m / rho < 2^{N+2} unless clamped at j_min
            if c.fine > minimum_level(p) {
                assert!(
                    dim <= m as f64 / params.rho && 2.0 * dim > m as f64 / params.rho,
                    "m = {m}, p = {p}: {c:?}"
                );
            }
            let per_coarse = m as f64 * (2 * p - 1) as f64 / (1u64 << c.coarse) as f64;
            assert!(
                per_coarse <= params.coarse_samples || c.coarse == c.fine,
                "m = {m}: {c:?}"
            );
        }
    }
}

/// A deep, sparse active set (beyond the dense column map) gives the same kernel rows as
/// the direct evaluation filtered to its functions.
#[test]
fn deep_sparse_active_sets_look_columns_up_by_search() {
    let basis = CdvBasis::new(3, FilterFamily::Extremal, 4, 30, Domain::UNIT).unwrap();
    // Coarse scaling functions plus a chain of wavelets towards x = 0.3 down to level 30.
    let mut keep: Vec<usize> = (0..16).collect();
    for j in 4..=30u32 {
        let k = (0.3 * (1u64 << j) as f64) as usize;
        for d in 0..2 {
            keep.push((1usize << j) + k + d);
        }
    }
    let active = ActiveSet::from_indices(basis.clone(), keep.clone());
    let xs = [0.3, 0.3 + 1e-9, 0.1];
    let k = kernel_matrix(&active, &xs).unwrap();
    let mut ev = basis.evaluator();
    for (i, row) in k.outer_iterator().enumerate() {
        let expect: Vec<(usize, f64)> = ev
            .eval(xs[i])
            .unwrap()
            .iter()
            .filter_map(|v| active.column(v.index).map(|c| (c, v.value)))
            .collect();
        let got: Vec<(usize, f64)> = row.iter().map(|(c, &v)| (c, v)).collect();
        // The same functions; values to round-off: the kernel's evaluation stops at the
        // set's local depth, so its digit walk starts at another level (relative 1e-13 of the
        // level's scale 2^{j/2} <= 2^16, a few ulps of the larger values).
        assert_eq!(
            got.iter().map(|e| e.0).collect::<Vec<_>>(),
            expect.iter().map(|e| e.0).collect::<Vec<_>>()
        );
        for (&(c, a), &(_, b)) in got.iter().zip(&expect) {
            assert!(
                (a - b).abs() <= 1e-13 * 65536.0,
                "column {c}: {a} against {b}"
            );
        }
        for &(c, _) in &got {
            assert!(keep.contains(&active.global(c)));
        }
    }
    assert!(k.nnz() > 40, "the deep chain is present at x = 0.3");
}
