//! Messages that must not mislead (issue 12): extreme numbers in `{:e}` form, the real cause
//! named (a domain width that overflows or is subnormal), and hints that name a parameter
//! that exists with a value that works — checked by following each hint and seeing the call
//! succeed.

mod common;

use common::{scratch, user_error, write};
use rkwave::basis::{CdvBasis, FilterFamily};
use rkwave::io::{validate_positions, SampleSet};
use rkwave::kernel::{check_positions, kernel_matrix, ActiveSet, LevelParams};
use rkwave::reconstruct::{fit, FitParams, Levels, Method, ReconstructError};
use rkwave::sampling::{Domain, DomainError};
use rkwave::solve::{global_ls, GlobalLsParams, GlobalMethod, RankPolicy, SolveError};

/// No number printed in full positional form: no run of more than 20 digits.
#[track_caller]
fn compact(message: &str) {
    let mut run = 0;
    for c in message.chars() {
        run = if c.is_ascii_digit() { run + 1 } else { 0 };
        assert!(run <= 20, "a long number in: {message}");
    }
    assert!(
        message.len() < 600,
        "{} characters: {message}",
        message.len()
    );
}

#[test]
fn domain_errors_name_the_cause_in_short_numbers() {
    let e = Domain::new(-1e308, 1e308).unwrap_err();
    assert!(matches!(e, DomainError::TooWide { .. }));
    let m = e.to_string();
    compact(&m);
    assert!(
        m.contains("[-1e308, 1e308]") && m.contains("width b - a overflows"),
        "{m}"
    );

    for (a, b) in [(0.0, 1e-310), (1e-320, 3e-320), (-5e-324, 5e-324)] {
        let e = Domain::new(a, b).unwrap_err();
        assert!(matches!(e, DomainError::TooNarrow { .. }), "{a} {b}: {e}");
        let m = e.to_string();
        compact(&m);
        assert!(m.contains("subnormal"), "{m}");
    }
    // The smallest normal width is accepted, and maps its ends exactly.
    let d = Domain::new(0.0, f64::MIN_POSITIVE).unwrap();
    assert_eq!((d.to_unit(0.0), d.to_unit(f64::MIN_POSITIVE)), (0.0, 1.0));

    let e = Domain::new(f64::NAN, 1e300).unwrap_err().to_string();
    compact(&e);
    assert!(e.contains("NaN") && e.contains("1e300"), "{e}");
    let e = Domain::new(1e300, -1e300).unwrap_err().to_string();
    compact(&e);
    assert!(e.contains("[1e300, -1e300]"), "{e}");

    let wide = Domain::new(-1e300, 1e300).unwrap();
    assert_eq!(wide.to_string(), "[-1e300, 1e300]");
    assert_eq!(Domain::UNIT.to_string(), "[0, 1]");
}

#[test]
fn position_errors_print_extremes_in_exponent_form() {
    let set = SampleSet::new(vec![0.5, 1e300], vec![vec![1.0, 2.0]]).unwrap();
    let m = validate_positions(&set, Domain::UNIT)
        .unwrap_err()
        .to_string();
    compact(&m);
    assert!(m.contains("x = 1e300") && m.contains("[0, 1]"), "{m}");

    let tiny = Domain::new(0.0, 1e-300).unwrap();
    let m = check_positions(tiny, &[1e-301, -1e-200])
        .unwrap_err()
        .to_string();
    compact(&m);
    assert!(
        m.contains("sample 2") && m.contains("-1e-200") && m.contains("1e-300"),
        "{m}"
    );

    let basis = CdvBasis::new(2, FilterFamily::Extremal, 3, 4, tiny).unwrap();
    let m = basis.to_unit(-1e-200).unwrap_err().to_string();
    compact(&m);
}

/// A uniform kernel matrix on `[0, 1]`: `m` samples, levels `n..N`, order `p`.
fn kernel(m: usize, p: usize, n: u32, fine: u32) -> (sprs::CsMat<f64>, Vec<f64>) {
    let basis = CdvBasis::new(p, FilterFamily::cdv_default(p), n, fine, Domain::UNIT).unwrap();
    let xs: Vec<f64> = (0..m).map(|i| (i as f64 + 0.5) / m as f64).collect();
    let k = kernel_matrix(&ActiveSet::uniform(basis), &xs).unwrap();
    let f: Vec<f64> = xs.iter().map(|x| (3.0 * x).sin()).collect();
    (k, f)
}

#[test]
fn solve_hints_name_parameters_that_work() {
    // Fewer samples than functions: the hint names two parameter values; each succeeds.
    let (k, f) = kernel(20, 3, 4, 4); // P = 32
    let e = global_ls(&k, &[&f], &GlobalLsParams::default()).unwrap_err();
    assert!(matches!(
        e,
        SolveError::Undersampled {
            samples: 20,
            functions: 32
        }
    ));
    let m = e.to_string();
    for gone in ["iterative solver", "RankPolicy::Regularize /"] {
        assert!(!m.contains(gone), "{m}");
    }
    assert!(
        m.contains("GlobalLsParams::rank_policy = RankPolicy::Regularize")
            && m.contains("GlobalLsParams::method = GlobalMethod::Cgls")
            && m.contains("at least 32 samples"),
        "{m}"
    );
    let regularized = GlobalLsParams {
        rank_policy: RankPolicy::Regularize,
        ..GlobalLsParams::default()
    };
    let cgls = GlobalLsParams {
        method: GlobalMethod::Cgls,
        ..GlobalLsParams::default()
    };
    for params in [regularized, cgls] {
        let fit = global_ls(&k, &[&f], &params).unwrap();
        // An underdetermined least-squares answer interpolates the samples.
        let kc = apply(&k, &fit.coefficients[0]);
        let worst = kc
            .iter()
            .zip(&f)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-6, "{params:?}: residual {worst:e}");
    }

    // Not converged: the hint says how far to raise max_iter, and raising it works.
    let (k, f) = kernel(400, 3, 4, 6);
    let few = GlobalLsParams {
        method: GlobalMethod::Cgls,
        max_iter: 2,
        ..GlobalLsParams::default()
    };
    let m = global_ls(&k, &[&f], &few).unwrap_err().to_string();
    assert!(m.contains("GlobalLsParams::max_iter above 2"), "{m}");
    global_ls(
        &k,
        &[&f],
        &GlobalLsParams {
            max_iter: 20_000,
            ..few
        },
    )
    .unwrap();
}

/// `K c` for a dense vector `c`.
fn apply(k: &sprs::CsMat<f64>, c: &[f64]) -> Vec<f64> {
    let mut y = vec![0.0; k.rows()];
    for (v, (i, j)) in k.iter() {
        y[i] += v * c[j];
    }
    y
}

#[test]
fn undersampled_fits_suggest_only_what_can_work() {
    let xs = [0.1, 0.5, 0.9];
    let ys = [1.0, 2.0, 0.5];
    // Automatic levels at the smallest basis for p = 3: neither rho nor a smaller level helps.
    let e = fit(&xs, &[&ys], Domain::UNIT, &FitParams::default()).unwrap_err();
    let m = e.to_string();
    assert!(matches!(
        e,
        ReconstructError::Undersampled {
            samples: 3,
            functions: 32,
            ..
        }
    ));
    assert!(
        !m.contains("rho") && !m.contains("fine level") && !m.contains("automatic"),
        "{m}"
    );
    assert!(
        m.contains("smallest basis for p = 3") && m.contains("p = 1 needs 2 samples"),
        "{m}"
    );
    // ... and the hint works: p = 1.
    fit(
        &xs,
        &[&ys],
        Domain::UNIT,
        &FitParams {
            p: 1,
            ..FitParams::default()
        },
    )
    .unwrap();
    // Global least squares, which lowers nothing, says the same.
    let global = FitParams {
        method: Method::Global(GlobalLsParams::default()),
        ..FitParams::default()
    };
    let m = fit(&xs, &[&ys], Domain::UNIT, &global)
        .unwrap_err()
        .to_string();
    assert!(!m.contains("rho") && m.contains("smallest basis"), "{m}");

    // Fixed levels above the smallest: a smaller fine level is named, and works.
    let xs: Vec<f64> = (0..40).map(|i| (i as f64 + 0.5) / 40.0).collect();
    let ys: Vec<f64> = xs.iter().map(|x| x * x).collect();
    let fixed = |fine| FitParams {
        levels: Levels::Fixed { coarse: 4, fine },
        ..FitParams::default()
    };
    let m = fit(&xs, &[&ys], Domain::UNIT, &fixed(6))
        .unwrap_err()
        .to_string();
    assert!(
        m.contains("Levels::Fixed") && m.contains("at least 4 for p = 3"),
        "{m}"
    );
    fit(&xs, &[&ys], Domain::UNIT, &fixed(4)).unwrap();

    // Automatic levels with a tiny oversampling rate: a larger rho is named, and works.
    let auto = |rho| FitParams {
        levels: Levels::Auto(LevelParams {
            rho,
            ..LevelParams::default()
        }),
        ..FitParams::default()
    };
    let m = fit(&xs, &[&ys], Domain::UNIT, &auto(1e-3))
        .unwrap_err()
        .to_string();
    assert!(m.contains("LevelParams::rho = 0.001"), "{m}");
    fit(&xs, &[&ys], Domain::UNIT, &auto(2.0)).unwrap();
}

#[test]
fn cli_domain_messages_say_what_is_wrong() {
    let d = scratch("messages", "domain");
    let out = d.join("o.csv");
    let out = out.to_str().unwrap();
    let three = write(&d.join("three.csv"), "x,value\n0,1\n0.5,2\n1,3\n");
    let e = user_error(&[
        "reconstruct",
        "--input",
        &three,
        "--output",
        out,
        "--domain=-1e308,1e308",
    ]);
    compact(&e);
    assert!(e.contains("overflows") && e.contains("1e308"), "{e}");
    let e = user_error(&[
        "reconstruct",
        "--input",
        &three,
        "--output",
        out,
        "--domain=0,1e-310",
    ]);
    compact(&e);
    assert!(e.contains("subnormal"), "{e}");

    // The samples' own span: overflowing, subnormal.
    let wide = write(&d.join("wide.csv"), "x,value\n-1e308,1\n0,2\n1e308,3\n");
    let e = user_error(&["reconstruct", "--input", &wide, "--output", out]);
    compact(&e);
    assert!(
        e.contains("overflows") && !e.contains("all samples sit"),
        "{e}"
    );
    let tiny = write(
        &d.join("tiny.csv"),
        "x,value\n1e-320,1\n2e-320,2\n3e-320,3\n",
    );
    let e = user_error(&["reconstruct", "--input", &tiny, "--output", out]);
    compact(&e);
    assert!(e.contains("subnormal"), "{e}");

    // Three samples at p = 3 with automatic levels: no hint at automatic levels or rho.
    let e = user_error(&["reconstruct", "--input", &three, "--output", out]);
    assert!(!e.contains("automatic") && !e.contains("rho"), "{e}");
    assert!(e.contains("smallest basis for p = 3"), "{e}");
    assert!(!std::path::Path::new(out).exists());
}

/// On the command line a hint names flags, never the library's Rust names: an undersampled
/// global solve, fixed levels too fine for the samples, and automatic levels asking for more
/// oversampling than the samples allow each print advice a user can type.
#[test]
fn cli_hints_name_flags_not_library_names() {
    let d = scratch("messages", "flags");
    let out = d.join("o.csv");
    let out = out.to_str().unwrap();
    let rows: String = (0..12)
        .map(|i| format!("{},{}\n", i as f64 / 11.0, (i as f64).sin()))
        .collect();
    let few = write(&d.join("few.csv"), &format!("x,value\n{rows}"));
    // 300 samples in [0, 0.1] and one at 1: enough in number, but most functions unsampled.
    let mut rows: String = (0..300)
        .map(|i| format!("{},{}\n", i as f64 / 3000.0, (i as f64).sin()))
        .collect();
    rows.push_str("1,0\n");
    let clustered = write(&d.join("clustered.csv"), &format!("x,value\n{rows}"));
    for (extra, flag) in [
        (&["--method", "global", "--levels", "4..6"][..], "--method"),
        (&["--levels", "4..9"][..], "--levels"),
        (&["--rho", "1000"][..], ""),
    ] {
        let input = if flag == "--method" { &clustered } else { &few };
        let mut args = vec!["reconstruct", "--input", input, "--output", out];
        args.extend_from_slice(extra);
        let e = user_error(&args);
        assert!(!e.contains("::"), "{extra:?}: a Rust path in {e}");
        assert!(e.contains(flag), "{extra:?}: {flag} not named in {e}");
    }
}
