//! Issue 12 through the library: every panic, runaway allocation and silent answer the
//! hostile-user session found, as a typed error, a bounded request or a reported warning.

use rkwave::io::parse_csv;
use rkwave::kernel::LevelParams;
use rkwave::reconstruct::{fit, FitParams, Levels, Method, ReconstructError};
use rkwave::refine::{ExpressionOracle, SampleOracle};
use rkwave::sampling::Domain;
use rkwave::solve::{GlobalLsParams, LocalInversionParams, Solver, CHOLESKY_MAX_CONDITION};

fn params(p: usize, levels: Levels, method: Method) -> FitParams {
    FitParams {
        p,
        family: None,
        levels,
        method,
    }
}

fn auto() -> Levels {
    Levels::Auto(LevelParams::default())
}

/// Deterministic uniform numbers in [0, 1) (a 64-bit LCG; no test depends on their quality
/// beyond covering the interval).
fn uniform(n: usize, seed: u64) -> Vec<f64> {
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    (0..n)
        .map(|_| {
            s = s
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        })
        .collect()
}

#[test]
fn levels_at_the_documented_limit_are_refused_not_allocated() {
    let xs = [0.1, 0.2];
    let f = [1.0, 2.0];
    let fixed = Levels::Fixed {
        coarse: 60,
        fine: 60,
    };
    let err = fit(
        &xs,
        &[&f],
        Domain::UNIT,
        &params(
            3,
            fixed,
            Method::SingleScale {
                ridge: 0.0,
                solver: rkwave::reconstruct::SingleScaleSolver::default(),
            },
        ),
    )
    .unwrap_err();
    assert!(
        matches!(err, ReconstructError::Undersampled { .. }),
        "{err}"
    );
    // rho = 1e-308 asks for far more functions than samples: refused before allocating.
    let tiny_rho = Levels::Auto(LevelParams {
        rho: 1e-308,
        ..LevelParams::default()
    });
    let err = fit(
        &xs,
        &[&f],
        Domain::UNIT,
        &params(
            3,
            tiny_rho,
            Method::SingleScale {
                ridge: 0.0,
                solver: rkwave::reconstruct::SingleScaleSolver::default(),
            },
        ),
    )
    .unwrap_err();
    assert!(err.to_string().contains("rho"), "{err}");
}

#[test]
fn two_samples_haar_global_is_an_error_not_a_panic() {
    for xs in [[0.1, 0.2], [0.1, 0.1]] {
        let f = [1.0, 2.0];
        let r = fit(
            &xs,
            &[&f],
            Domain::UNIT,
            &params(1, auto(), Method::Global(GlobalLsParams::default())),
        );
        // Either a typed error or a finite answer; the panic was an index past the end.
        if let Ok(fitted) = r {
            assert!(fitted.coefficients[0].iter().all(|c| c.is_finite()));
        }
    }
}

#[test]
fn samples_packed_into_one_nanometre_fit_without_a_huge_block() {
    // 1e5 samples in [0.5, 0.5 + 1e-9]: the single-scale path falls back to local inversion,
    // whose one block holds every sample; it used to allocate r x r identity columns (80 GB).
    let m = 100_000;
    let xs: Vec<f64> = uniform(m, 3).iter().map(|u| 0.5 + 1e-9 * u).collect();
    let f: Vec<f64> = xs.iter().map(|x| x.sin()).collect();
    let fitted = fit(&xs, &[&f], Domain::UNIT, &FitParams::default()).unwrap();
    assert!(!fitted.fallbacks.is_empty());
    assert!(!fitted.warnings().is_empty());
    let at = fitted.evaluate(&xs[..1000]).unwrap();
    // The data are fitted where they are (sin is affine at that scale).
    let worst = at[0]
        .iter()
        .zip(&f)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-6, "{worst}");
}

#[test]
fn local_inversion_on_clusters_warns_that_the_answer_is_unsupported() {
    // Three tight clusters: most basis functions see no sample.
    let mut xs = Vec::new();
    for (c, u) in [(0.1, 1), (0.5, 2), (0.9, 3)] {
        xs.extend(uniform(300, u).iter().map(|t| c + 0.02 * (t - 0.5)));
    }
    let f: Vec<f64> = xs.iter().map(|x| (8.0 * x).sin()).collect();
    for solver in [Solver::Svd, Solver::Qr, Solver::Cholesky] {
        let lp = LocalInversionParams {
            solver,
            ..LocalInversionParams::default()
        };
        let fitted = fit(
            &xs,
            &[&f],
            Domain::UNIT,
            &params(3, auto(), Method::Local(lp)),
        )
        .unwrap();
        let w = fitted.warnings();
        assert!(
            w.iter()
                .any(|s| s.contains("cut-off") || s.contains("not supported")),
            "{solver:?}: {w:?}"
        );
    }
}

#[test]
fn cholesky_blocks_stay_within_their_tolerance_of_svd() {
    // Random samples make some local blocks ill-conditioned; the Cholesky solver must hand
    // those to the SVD. Stated per-block tolerance: cond^2 eps <= 1e8 * 2.2e-16 relative to
    // the block answer; summed over the ~3(2p-1) blocks that reach a point and with
    // coefficients of size ~ |f| <= 4, 1e-6 absolute bounds it with margin.
    assert_eq!(CHOLESKY_MAX_CONDITION, 1e4);
    let m = 30_000;
    let xs = uniform(m, 11);
    let f: Vec<f64> = xs.iter().map(|x| (20.0 * x).sin() + x.exp()).collect();
    let grid: Vec<f64> = (0..2001).map(|i| i as f64 / 2000.0).collect();
    let run = |solver| {
        let lp = LocalInversionParams {
            solver,
            ..LocalInversionParams::default()
        };
        let fitted = fit(
            &xs,
            &[&f],
            Domain::UNIT,
            &params(3, auto(), Method::Local(lp)),
        )
        .unwrap();
        fitted.evaluate(&grid).unwrap().remove(0)
    };
    let svd = run(Solver::Svd);
    let chol = run(Solver::Cholesky);
    let worst = svd
        .iter()
        .zip(&chol)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(worst <= 1e-6, "max |cholesky - svd| = {worst:e}");
}

#[test]
fn expressions_read_as_in_mathematics() {
    let v = |e: &str, x: f64| ExpressionOracle::parse(e).unwrap().sample(x);
    assert_eq!(v("-x^2", 3.0), -9.0);
    assert_eq!(v("2^-1", 0.0), 0.5);
    assert_eq!(v("2^3^2", 0.0), 512.0);
    assert_eq!(v("1e3*x", 0.5), 500.0);
    assert_eq!(v("2.5E-1 + .5", 0.0), 0.75);
    assert_eq!(v("-(x - 1)", 3.0), -2.0);
    assert_eq!(v("max(x, 2) + min(1, x)", 3.0), 4.0);
    // The Gaussian as everyone writes it.
    assert_eq!(v("exp(-((x-0.5)/0.01)^2)", 0.5), 1.0);
    let g = v("exp(-((x-0.5)/0.01)^2)", 0.51);
    assert!((g - (-1.0f64).exp()).abs() < 1e-12, "{g}");
    for bad in [
        "x +* 2", "sin(", "1e", "foo(x)", "sin x", "min(x)", "(((x", "x)",
    ] {
        let e = ExpressionOracle::parse(bad).unwrap_err().to_string();
        assert!(!e.contains("ops") && !e.contains("node"), "{bad}: {e}");
    }
    let deep = format!("{}x{}", "(".repeat(4000), ")".repeat(4000));
    let e = ExpressionOracle::parse(&deep).unwrap_err();
    assert!(e.reason.contains("nests deeper than"), "{e}");
}

#[test]
fn csv_accepts_every_line_end() {
    for text in [
        "x,y\r0.1,1\r0.2,2\r",
        "x,y\r\n0.1,1\r\n0.2,2\r\n",
        "x,y\n0.1,1\n0.2,2",
        "x,y\r0.1,1\n0.2,2\r\n",
    ] {
        let set = parse_csv(text.as_bytes(), "t.csv").unwrap();
        assert_eq!(set.positions, vec![0.1, 0.2], "{text:?}");
        assert_eq!(set.values[0], vec![1.0, 2.0]);
    }
    // A bad field is still reported on its physical line with CR line ends.
    let e = parse_csv(b"x,y\r0.1,1\r0.2,zz\r", "t.csv")
        .unwrap_err()
        .to_string();
    assert!(e.contains("line 3"), "{e}");
}

#[test]
fn norms_do_not_overflow() {
    let r = rkwave::norms::rms([f64::MAX / 2.0, f64::MAX / 2.0]);
    assert!(r.is_finite() && (r / (f64::MAX / 2.0) - 1.0).abs() < 1e-15);
}
