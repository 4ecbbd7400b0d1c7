//! The single-scale global least-squares path: it equals the dense pseudo-inverse solution
//! (the SVD oracle of `tests/common/oracle.rs`, within its normal-equations bound
//! `C eps kappa^2`), and coarsening its normal equations (`A' = H A H^T`) equals accumulating
//! them at the coarser level directly.

mod common;

use common::oracle::{check_ls_solver, Accuracy};
use rkwave::basis::{CdvBasis, FilterFamily};
use rkwave::kernel::{kernel_matrix, ActiveSet};
use rkwave::reconstruct::{single_scale_ls, NormalEquations};
use rkwave::sampling::{Domain, Layout, Signal};

/// `single_scale_ls` (the banded normal equations of `V_{N+1}` and the FWT to `Psi(n, N)`),
/// accumulated at the level itself and coarsened from one level finer, against the dense
/// pseudo-inverse of the multilevel `K`, for `p = 1, 2, 3, 6` on random samples (20 per
/// function of the finer level).
#[test]
fn single_scale_solution_is_the_dense_pseudo_inverse_solution() {
    for p in [1usize, 2, 3, 6] {
        let family = FilterFamily::cdv_default(p);
        let n = rkwave::basis::minimum_level(p);
        let fine = CdvBasis::new(p, family, n, n + 1, Domain::UNIT).unwrap();
        let coarse = CdvBasis::new(p, family, n, n, Domain::UNIT).unwrap();
        let xs = Layout::Random.generate(20 * fine.dimension(), Domain::UNIT, 5);
        let f = Signal::Bumps.sample(Domain::UNIT, &xs);
        let k = kernel_matrix(&ActiveSet::uniform(coarse.clone()), &xs).unwrap();
        let (direct, rep) = single_scale_ls(&coarse, &xs, &[&f], 0.0).unwrap();
        assert_eq!(rep.deficient, 0);
        check_ls_solver(
            &format!("p = {p}: single-scale normal equations"),
            &k,
            &[&f],
            &direct,
            Accuracy::NormalEquations,
        );
        let ne = NormalEquations::accumulate(&fine, &xs, &[&f]).unwrap();
        let (coarsened, rep) = ne.coarsen(fine.bank()).solve(&coarse, 0.0);
        assert_eq!(rep.deficient, 0);
        check_ls_solver(
            &format!("p = {p}: coarsened normal equations"),
            &k,
            &[&f],
            &coarsened,
            Accuracy::NormalEquations,
        );
    }
}

#[test]
fn coarsened_normal_equations_equal_direct_accumulation() {
    for p in [1usize, 2, 3, 6] {
        let family = FilterFamily::cdv_default(p);
        let n = rkwave::basis::minimum_level(p);
        let fine = CdvBasis::new(p, family, n, n + 3, Domain::UNIT).unwrap();
        let coarse = CdvBasis::new(p, family, n, n + 2, Domain::UNIT).unwrap();
        let xs = Layout::Random.generate(20 * fine.dimension(), Domain::UNIT, 4);
        let f = Signal::Bumps.sample(Domain::UNIT, &xs);
        let direct = single_scale_ls(&coarse, &xs, &[&f], 0.0).unwrap().0;
        let ne = NormalEquations::accumulate(&fine, &xs, &[&f]).unwrap();
        let coarsened = ne.coarsen(fine.bank());
        assert_eq!(coarsened.level(), coarse.fine() + 1);
        let (c, rep) = coarsened.solve(&coarse, 0.0);
        assert_eq!(rep.deficient, 0);
        let scale = direct[0].iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let err = c[0]
            .iter()
            .zip(&direct[0])
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-10 * scale, "p = {p}: {err:e} (scale {scale:e})");
    }
}
