//! The adaptive image engine on the command line (issue 13, item 5): `compare --adaptive`
//! adds the adaptive rows (text, JSON, table, one figure per scene).

mod common;

/// `compare --adaptive` on a small scene: the JSON carries the adaptive comparison (the
/// adaptive wavelet within the budget, the film filters on the adaptive samples beside the
/// stratified ones), the table and the figure are written, the noisy run is said to have no
/// adaptive rows, and nothing is replaced without --force.
#[test]
fn compare_adaptive_adds_the_adaptive_rows() {
    let dir = common::scratch("cmpad", "rows");
    let out = dir.join("cmp");
    let args = [
        "compare",
        "--scene",
        "slanted_edge",
        "--resolution",
        "32x32",
        "--spp",
        "4",
        "--noise",
        "0,0.05",
        "--methods",
        "box",
        "--adaptive",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ];
    let run = common::rkwave(&args);
    assert!(run.status.success(), "{}", common::text(&run));
    let json: serde_json::Value =
        serde_json::from_slice(&run.stdout).expect("one JSON object on stdout");
    assert_eq!(json["comparisons"].as_array().map(Vec::len), Some(2));
    let adaptive = &json["adaptive"][0];
    assert_eq!(adaptive["scene"], "slanted_edge");
    let samples = adaptive["adaptive"]["samples"].as_u64().unwrap();
    assert!(samples > 0 && samples <= 4 * 32 * 32, "{samples}");
    let rows = adaptive["rows"].as_array().unwrap();
    assert_eq!(rows[0]["method"], "adaptive wavelet");
    for from in ["stratified", "adaptive"] {
        for film in ["box", "triangle", "gaussian", "mitchell", "lanczos"] {
            assert!(
                rows.iter()
                    .any(|r| r["samples_from"] == from && r["method"] == film),
                "{film} on {from} samples missing"
            );
        }
    }
    let gain = adaptive["gain_db"].as_f64().unwrap();
    let best = adaptive["best_uniform_film"][1].as_f64().unwrap();
    let psnr = rows[0]["metrics"]["psnr"].as_f64().unwrap();
    assert!((psnr - best - gain).abs() < 1e-9);
    assert!(json["adaptive_notes"][0]
        .as_str()
        .is_some_and(|n| n.contains("noise-free")));
    for f in ["compare_adaptive.md", "slanted_edge_adaptive.png"] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    let table = std::fs::read_to_string(out.join("compare_adaptive.md")).unwrap();
    assert!(table.contains("| slanted_edge | 4 | adaptive |"), "{table}");
    let again = common::user_error(&args);
    assert!(again.contains("--force"), "{again}");
    let _ = std::fs::remove_dir_all(&dir);
}
