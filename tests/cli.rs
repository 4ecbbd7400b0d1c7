//! The command line as a user meets it: the acceptance command for every p, JSON
//! fields, and bad input as a clear error with exit code 2.

use std::process::Command;

fn rkwave(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_rkwave"))
        .args(args)
        .output()
        .expect("binary runs")
}

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
            assert!(f["level"].as_u64().is_some() && f["index"].as_u64().is_some());
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
    let dir = std::env::temp_dir().join(format!("rkwave_cli_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
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
    std::fs::remove_dir_all(&dir).ok();
}
