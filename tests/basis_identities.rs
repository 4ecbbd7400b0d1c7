//! The five properties of DESIGN §2 for every supported `p`, computed exactly (refinement
//! algebra and the interval FWT), plus the reproducing property of the kernel over random
//! positions.
//!
//! Tolerances: the targets (orthonormality and FWT 1e-12, polynomials and moments
//! 1e-11). Measured values are ~1e-14 or below for every p (see the demo's summary table), so
//! the targets are met with two orders of margin.

use proptest::prelude::*;
use rkwave::basis::facts::{self, BasisFacts};
use rkwave::basis::fwt::analysis;
use rkwave::basis::{minimum_level, CdvBasis, FilterFamily, MAX_VANISHING_MOMENTS};
use rkwave::sampling::Domain;

#[test]
fn identities_hold_for_every_p_and_both_families() {
    for p in 1..=MAX_VANISHING_MOMENTS {
        for family in [FilterFamily::Extremal, FilterFamily::LeastAsymmetric] {
            let n = minimum_level(p);
            for fine in [n, n + 3, 11] {
                let basis = CdvBasis::new(p, family, n, fine.max(n), Domain::UNIT).unwrap();
                let f = BasisFacts::measure(&basis, 10_000, 7);
                let tag = format!("p = {p} {family:?} n = {n} N = {fine}");
                assert!(
                    f.orthonormality_error <= 1e-12,
                    "{tag}: orthonormality {:e}",
                    f.orthonormality_error
                );
                assert!(
                    f.polynomial_error <= 1e-11,
                    "{tag}: polynomials {:e}",
                    f.polynomial_error
                );
                assert!(
                    f.vanishing_moment_error <= 1e-11,
                    "{tag}: moments {:e}",
                    f.vanishing_moment_error
                );
                assert!(f.fwt_error <= 1e-12, "{tag}: FWT {:e}", f.fwt_error);
            }
        }
    }
}

/// On a general domain the basis stays orthonormal and reproduces `((x - a)/(b - a))^d`.
#[test]
fn identities_on_a_general_domain() {
    let domain = Domain::new(-3.5, 1e3).unwrap();
    for p in [1usize, 2, 5, 8] {
        let basis =
            CdvBasis::new(p, FilterFamily::cdv_default(p), minimum_level(p), 9, domain).unwrap();
        let f = BasisFacts::measure(&basis, 10_000, 3);
        assert!(
            f.polynomial_error <= 1e-11,
            "p = {p}: {:e}",
            f.polynomial_error
        );
        assert!(f.orthonormality_error <= 1e-12);
    }
}

/// Levels deeper than the coarse one (`n > j_min`) and deep fine levels.
#[test]
fn identities_at_other_levels() {
    for p in [2usize, 4, 10] {
        let n = minimum_level(p) + 4;
        let basis = CdvBasis::new(p, FilterFamily::cdv_default(p), n, n + 2, Domain::UNIT).unwrap();
        let f = BasisFacts::measure(&basis, 10_000, 5);
        assert!(
            f.polynomial_error <= 1e-11 && f.orthonormality_error <= 1e-12,
            "p = {p}: {f:?}"
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Reproducing property: `sum_a <t^d, Psi_a> Psi_a(x) = t^d` for `d < p`, with the
    /// coefficients obtained from exact `V_{N+1}` moments by the FWT (so every level's wavelets
    /// take part), at random positions; 1e-11.
    #[test]
    fn kernel_reproduces_polynomials(p in 1usize..=10, extra in 0u32..4, x in 0.0f64..=1.0) {
        let family = FilterFamily::cdv_default(p);
        let n = minimum_level(p);
        let fine = n + extra;
        let basis = CdvBasis::new(p, family, n, fine, Domain::UNIT).unwrap();
        let top = CdvBasis::new(p, family, fine + 1, fine + 1, Domain::UNIT).unwrap();
        let values = basis.evaluator().eval(x).unwrap();
        for d in 0..p {
            let v = facts::monomial_coefficients(&top, d);
            let c = analysis(basis.bank(), n, fine, &v);
            let f: f64 = values.iter().map(|b| c[b.index] * b.value).sum();
            prop_assert!((f - x.powi(d as i32)).abs() < 1e-11, "p = {} d = {} x = {}: {}", p, d, x, f);
        }
    }
}

/// Bad parameters are typed errors, never panics.
#[test]
fn bad_parameters_are_errors() {
    use rkwave::basis::BasisError;
    let unit = Domain::UNIT;
    assert!(matches!(
        CdvBasis::new(0, FilterFamily::Extremal, 3, 4, unit),
        Err(BasisError::UnsupportedOrder { p: 0, .. })
    ));
    assert!(matches!(
        CdvBasis::new(11, FilterFamily::Extremal, 6, 7, unit),
        Err(BasisError::UnsupportedOrder { p: 11, .. })
    ));
    assert!(matches!(
        CdvBasis::new(3, FilterFamily::Extremal, 3, 8, unit),
        Err(BasisError::CoarseLevelTooSmall {
            p: 3,
            coarse: 3,
            minimum: 4
        })
    ));
    assert!(matches!(
        CdvBasis::new(3, FilterFamily::Extremal, 6, 5, unit),
        Err(BasisError::CoarseAboveFine { .. })
    ));
    assert!(matches!(
        CdvBasis::new(3, FilterFamily::Extremal, 4, 99, unit),
        Err(BasisError::FineLevelTooDeep { .. })
    ));
    let basis = CdvBasis::new(2, FilterFamily::Extremal, 3, 4, unit).unwrap();
    let mut ev = basis.evaluator();
    for x in [f64::NAN, f64::INFINITY, -1e-300, 1.0 + f64::EPSILON] {
        assert!(
            matches!(ev.eval(x), Err(BasisError::PositionOutside { .. })),
            "x = {x}"
        );
    }
    assert_eq!(minimum_level(1), 0);
    assert_eq!(minimum_level(3), 4);
    assert_eq!(minimum_level(8), 5);
}
