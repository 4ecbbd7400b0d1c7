//! The command line as a user meets it: the acceptance command for every p, JSON
//! fields, and bad input as a clear error with exit code 2.

mod common;

use common::{rkwave, scratch};

#[test]
fn basis_json_meets_the_targets_for_every_p() {
    for p in 1..=8usize {
        let jmin = rkwave::basis::minimum_level(p).to_string();
        let ps = p.to_string();
        let out = rkwave(&[
            "basis", "--p", &ps, "--coarse", &jmin, "--fine", "12", "--json",
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
        assert_eq!(v["p"], p);
        assert_eq!(v["fine"], 12);
        assert_eq!(v["dimension"], 8192);
        let num = |k: &str| v[k].as_f64().unwrap_or_else(|| panic!("field {k}"));
        assert!(num("orthonormality_error") <= 1e-12, "p = {p}: {v}");
        assert!(num("polynomial_error") <= 1e-11, "p = {p}: {v}");
        assert!(num("vanishing_moment_error") <= 1e-11, "p = {p}: {v}");
        assert!(num("fwt_error") <= 1e-12, "p = {p}: {v}");
        assert!(v["polynomial_points"].as_u64().unwrap() >= 10_000);
    }
}

#[test]
fn eval_json_lists_kind_side_level_index_value() {
    let out = rkwave(&[
        "eval", "--p", "3", "--coarse", "4", "--fine", "6", "--x", "0,0.3,1", "--json",
    ]);
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let points = v["points"].as_array().unwrap();
    assert_eq!(points.len(), 3);
    for pt in points {
        for f in pt["functions"].as_array().unwrap() {
            assert!(["scaling", "wavelet"].contains(&f["kind"].as_str().unwrap()));
            assert!(["left", "interior", "right"].contains(&f["side"].as_str().unwrap()));
            // Psi(4, 6): scaling functions of level n = 4, wavelets of levels 4..=6, and
            // level j has 2^j functions of each kind on the interval.
            let level = f["level"].as_u64().unwrap();
            let index = f["index"].as_u64().unwrap();
            match f["kind"].as_str().unwrap() {
                "scaling" => assert_eq!(level, 4, "{f}"),
                _ => assert!((4..=6).contains(&level), "{f}"),
            }
            assert!(index < 1 << level, "{f}");
            assert!(f["value"].as_f64().unwrap().is_finite());
        }
    }
    // At x = 0 only left edge functions and the interior functions reaching 0 are nonzero.
    let at0 = points[0]["functions"].as_array().unwrap();
    assert!(at0.iter().all(|f| f["side"] != "right"));
}

#[test]
fn bad_input_exits_with_code_2_and_names_the_fix() {
    let cases: &[(&[&str], &str)] = &[
        (&["basis", "--p", "0"], "choose p in 1..=10"),
        (&["basis", "--p", "11"], "choose p in 1..=10"),
        (&["basis", "--p", "3", "--coarse", "3"], "choose n >= 4"),
        (
            &["basis", "--p", "3", "--coarse", "7", "--fine", "6"],
            "choose n <= N",
        ),
        (&["basis", "--domain", "1,0"], "domain"),
        (&["basis", "--domain", "0,nan"], "domain"),
        (&["basis", "--domain", "1,1"], "domain"),
        (&["eval", "--x", "1.5"], "outside the domain"),
        (&["eval", "--x", "NaN"], "outside the domain"),
        (
            &["eval", "--x", "-0.1", "--domain", "0,1"],
            "outside the domain",
        ),
        (&["eval", "--x", "abc"], "invalid"),
        (&["basis", "--fine", "-3"], ""),
    ];
    for (args, needle) in cases {
        let out = rkwave(args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}

#[test]
fn plot_is_written_and_not_overwritten_without_force() {
    let dir = scratch("cli", "plot");
    let path = dir.join("basis.png");
    let p = path.to_str().unwrap();
    let out = rkwave(&["basis", "--p", "2", "--fine", "4", "--plot", p]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let img = image::open(&path).expect("a PNG");
    assert!(img.width() > 500);
    let again = rkwave(&["basis", "--p", "2", "--fine", "4", "--plot", p]);
    assert_eq!(again.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&again.stderr).contains("--force"));
    let forced = rkwave(&["basis", "--p", "2", "--fine", "4", "--plot", p, "--force"]);
    assert!(forced.status.success());
}

#[test]
fn report_json_at_the_paper_setting_meets_the_error_target() {
    let out = rkwave(&[
        "report",
        "--p",
        "3",
        "--coarse",
        "4",
        "--fine",
        "8",
        "--samples",
        "1024",
        "--layout",
        "uniform",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    // Submatrices: 1 <= min <= median <= max, at most all m = 1024 rows and P = 2^9 columns.
    for (what, limit) in [("rows", 1024.0), ("cols", 512.0)] {
        let s = |k: &str| v["submatrix"][what][k].as_f64().unwrap();
        assert!(
            1.0 <= s("min") && s("min") <= s("median") && s("median") <= s("max"),
            "{what}: {v}"
        );
        assert!(s("max") <= limit, "{what}: {v}");
    }
    let max_abs = v["error"]["max_abs"].as_f64().unwrap();
    assert!(max_abs <= 2e-10, "{v}");
    // The RMS of the entries of K~ - K+ cannot exceed their largest magnitude.
    let rms = v["error"]["rms"].as_f64().unwrap();
    assert!((0.0..=max_abs).contains(&rms), "{v}");
    // ||K~ - K+||_F / ||K+||_F: the entries are below 2e-10 and K+ of an orthonormal basis
    // sampled at rho = 2 has entries of order 1 / sqrt(m), so far below 1e-6.
    assert!(v["error"]["rel_frobenius"].as_f64().unwrap() < 1e-6, "{v}");
    for key in ["local_vs_global", "local_vs_truth", "global_vs_truth"] {
        assert!(v["reconstruction"][key].as_f64().unwrap().is_finite());
    }
    // Condition numbers are >= 1 by definition; uniform samples at rho = 2 keep every block
    // well conditioned (an unsampled direction would show as >= 1e12).
    let cond = |k: &str| v["condition"][k].as_f64().unwrap();
    assert!(
        1.0 <= cond("median") && cond("median") <= cond("max") && cond("max") < 1e6,
        "{v}"
    );
    // Every stage reports its time (a value, not a speed claim: speed is in the benches).
    for key in ["kernel", "local", "global"] {
        let t = v["time_s"][key].as_f64().unwrap();
        assert!(t.is_finite() && t >= 0.0, "{key}: {v}");
    }
    assert!(v["groups"].as_u64().unwrap() > 0);
    // The paper's own n = 3 is below j_min(3): a clear error.
    let bad = rkwave(&["report", "--coarse", "3", "--fine", "8"]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("choose n >= 4"));
}

#[test]
fn reconstruct_reads_csv_writes_the_grid_and_reports() {
    let dir = scratch("cli", "reconstruct");
    let input = dir.join("samples.csv");
    let mut text = String::from("x,a,b\n");
    for i in 0..3000 {
        let x = (i as f64 + 0.5) / 3000.0;
        text.push_str(&format!("{x},{},{}\n", 1.0 + 2.0 * x, x * x));
    }
    std::fs::write(&input, text).unwrap();
    let output = dir.join("grid.csv");
    let out = rkwave(&[
        "reconstruct",
        "--input",
        input.to_str().unwrap(),
        "--domain",
        "0,1",
        "--grid",
        "11",
        "--output",
        output.to_str().unwrap(),
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["samples"], 3000);
    assert_eq!(v["channels"], 2);
    assert!(v["oversampling"].as_f64().unwrap() >= 2.0);
    // Polynomials of degree < p = 3 are reproduced: residuals at rounding level.
    for r in v["residual_rms"].as_array().unwrap() {
        assert!(r.as_f64().unwrap() < 1e-10, "{v}");
    }
    let grid = std::fs::read_to_string(&output).unwrap();
    let lines: Vec<&str> = grid.lines().collect();
    assert_eq!(lines[0], "x,a,b");
    assert_eq!(lines.len(), 12);
    let mid: Vec<f64> = lines[6].split(',').map(|t| t.parse().unwrap()).collect();
    assert!(
        (mid[0] - 0.5).abs() < 1e-15
            && (mid[1] - 2.0).abs() < 1e-10
            && (mid[2] - 0.25).abs() < 1e-10
    );
    // Malformed input names the row; existing output is not overwritten.
    let bad = rkwave(&[
        "reconstruct",
        "--input",
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/data/bad_files/wrong_columns.csv"
        ),
        "--output",
        dir.join("o2.csv").to_str().unwrap(),
    ]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("row 3"));
    let again = rkwave(&[
        "reconstruct",
        "--input",
        input.to_str().unwrap(),
        "--output",
        output.to_str().unwrap(),
    ]);
    assert_eq!(again.status.code(), Some(2));
}

/// `--output FILE.npy` writes the grid as NumPy float64 `G x (1 + channels)`: read back with
/// the library's reader, it holds the grid positions and values within the approximation
/// error of `sin(6x)` at p = 3 from 20,000 random samples (measured 3e-8; bound 1e-6).
#[test]
fn reconstruct_writes_npy_output_that_reads_back() {
    let dir = scratch("cli", "npy");
    let input = dir.join("s.csv");
    let mut text = String::from("x,y\n");
    let mut state = 12345u64;
    for _ in 0..20_000 {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let x = (state >> 11) as f64 / (1u64 << 53) as f64;
        text.push_str(&format!("{x},{}\n", (6.0 * x).sin()));
    }
    std::fs::write(&input, text).unwrap();
    let output = dir.join("g.npy");
    let _ = std::fs::remove_file(&output);
    let out = rkwave(&[
        "reconstruct",
        "--input",
        input.to_str().unwrap(),
        "--output",
        output.to_str().unwrap(),
        "--grid",
        "1001",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let set = rkwave::io::read_samples(&output).unwrap();
    assert_eq!(set.len(), 1001);
    let err = set
        .positions
        .iter()
        .zip(&set.values[0])
        .map(|(x, v)| (v - (6.0 * x).sin()).abs())
        .fold(0.0, f64::max);
    assert!(err < 1e-6, "max error {err:e}");
}
