//! `rkwave adapt`, the 1D adaptive refiner through the binary: its `--json` report (every key
//! present, the adaptive error below the uniform one at the same budget) and its refusals
//! (exit 2, one `error:` line), including a base tree too large for the budget refused before
//! anything of its size is allocated.

mod common;

use common::rkwave;

#[test]
fn adapt_reports_json_and_rejects_bad_input_with_exit_code_2() {
    let out = rkwave(&[
        "adapt", "--signal", "jumps", "--budget", "1024", "--grid", "4096", "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    for key in [
        "samples",
        "basis_size",
        "max_depth",
        "error_l2",
        "error_max",
        "error_l2_quadrature",
        "rounds",
    ] {
        assert!(!v[key].is_null(), "missing {key}");
    }
    assert!(v["samples"].as_u64().unwrap() <= 1024);
    assert!(v["uniform"]["error_l2"].as_f64().unwrap() > v["error_l2"].as_f64().unwrap());
    assert!(!v["rounds"].as_array().unwrap().is_empty());
    let out = rkwave(&[
        "adapt",
        "--signal",
        "sin(8*x) + (x > 0.6)",
        "--budget",
        "600",
        "--grid",
        "1024",
        "--json",
    ]);
    assert!(out.status.success());
    for bad in [
        vec!["--signal", "jumps", "--budget", "0"],
        vec!["--signal", "jumps", "--tolerance", "0"],
        vec!["--signal", "jumps", "--tolerance", "-1e-3"],
        vec!["--signal", "jumps", "--max-depth", "4"],
        vec!["--signal", "sin(8*x"],
        vec!["--signal", "wobble"],
        vec![
            "--signal",
            "1/(x - 0.5)",
            "--base-samples",
            "255",
            "--layout",
            "endpoints",
        ],
    ] {
        let args: Vec<&str> = std::iter::once("adapt")
            .chain(bad.iter().copied())
            .collect();
        let out = rkwave(&args);
        assert_eq!(out.status.code(), Some(2), "{bad:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.starts_with("error: "), "{bad:?}: {err}");
    }
}

/// `rkwave adapt --coarse 40 --max-depth 40` is refused before anything of size `2^40` is
/// allocated: exit 2 with a message naming the coarse level and a value that works.
#[test]
fn adapt_refuses_a_base_tree_above_the_budget_up_front() {
    let out = rkwave(&[
        "adapt",
        "--signal",
        "jumps",
        "--coarse",
        "40",
        "--max-depth",
        "40",
    ]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.starts_with("error: "), "{err}");
    assert!(err.contains("coarse level n to at most 14"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}
