//! `rkwave image`, `rkwave compare` and `rkwave reconstruct --dim 2` from the outside: bad
//! input is a clear message and exit code 2, good input writes what it says.

mod common;

use std::process::Output;

use common::{rkwave, Scratch};

fn scratch(name: &str) -> Scratch {
    common::scratch("image-cli", name)
}

/// Exit code 2 and a stderr message containing every `needle`.
fn fails_with(out: &Output, needles: &[&str]) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "stderr: {err}");
    for n in needles {
        assert!(err.contains(n), "`{n}` not in: {err}");
    }
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn image_rejects_bad_resolutions_and_scenes_naming_the_value() {
    let dir = scratch("bad");
    let out = dir.join("a.png");
    let o = out.to_str().unwrap();
    fails_with(
        &rkwave(&[
            "image",
            "--scene",
            "shapes",
            "--resolution",
            "0x10",
            "--out",
            o,
        ]),
        &["0 x 10"],
    );
    fails_with(
        &rkwave(&[
            "image",
            "--scene",
            "shapes",
            "--resolution",
            "100000x10",
            "--out",
            o,
        ]),
        &["100000", "65536"],
    );
    fails_with(
        &rkwave(&[
            "image",
            "--scene",
            "shapes",
            "--resolution",
            "12",
            "--out",
            o,
        ]),
        &["`12`"],
    );
    let star = dir.join("star.json");
    std::fs::write(
        &star,
        r#"{"name":"s","layers":[{"shape":"star","center":[0.5,0.5]}]}"#,
    )
    .unwrap();
    fails_with(
        &rkwave(&[
            "image",
            "--scene",
            star.to_str().unwrap(),
            "--method",
            "box",
            "--out",
            o,
        ]),
        &["unknown shape `star`"],
    );
    let bad = dir.join("bad.json");
    std::fs::write(
        &bad,
        r#"{"name":"s","layers":[{"shape":"disk","center":[0.5,0.5],"radius":"big","color":[1,1,1]}]}"#,
    )
    .unwrap();
    fails_with(
        &rkwave(&[
            "image",
            "--scene",
            bad.to_str().unwrap(),
            "--method",
            "box",
            "--out",
            o,
        ]),
        &["field `radius`"],
    );
    fails_with(
        &rkwave(&[
            "image", "--scene", "shapes", "--method", "bilinear", "--out", o,
        ]),
        &["bilinear"],
    );
    fails_with(
        &rkwave(&[
            "image",
            "--scene",
            "shapes",
            "--out",
            dir.join("a.jpg").to_str().unwrap(),
        ]),
        &[".png"],
    );
    fails_with(
        &rkwave(&["image", "--scene", "nosuchscene", "--out", o]),
        &["nosuchscene"],
    );
}

#[test]
fn image_with_a_film_filter_writes_the_image_and_a_json_report() {
    let dir = scratch("film");
    let out = dir.join("g.npy");
    let o = rkwave(&[
        "image",
        "--scene",
        "slanted_edge",
        "--resolution",
        "24x16",
        "--spp",
        "4",
        "--method",
        "gaussian",
        "--truth-rate",
        "4",
        "--truth-cache",
        dir.join("truth").to_str().unwrap(),
        "--show-filter",
        "3,4",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for key in [
        "psnr", "rmse", "rel_mse", "ssim", "samples", "time_s", "peak_mb",
    ] {
        assert!(v.get(key).is_some(), "{key} missing in {v}");
    }
    assert_eq!(v["samples"], 24 * 16 * 4);
    // A 24 x 16 x 3 array of f64 after a 128-byte header.
    assert_eq!(
        std::fs::metadata(&out).unwrap().len(),
        128 + 24 * 16 * 3 * 8
    );
    // The equivalent filter's weights sum to one.
    let csv = std::fs::read_to_string(dir.join("g_filter_3_4.csv")).unwrap();
    let total: f64 = csv
        .lines()
        .skip(1)
        .map(|l| l.rsplit(',').next().unwrap().parse::<f64>().unwrap())
        .sum();
    assert!((total - 1.0).abs() < 1e-12, "{total}");
    // Never overwritten without --force.
    let again = rkwave(&[
        "image",
        "--scene",
        "slanted_edge",
        "--method",
        "box",
        "--out",
        out.to_str().unwrap(),
    ]);
    fails_with(&again, &["--force"]);
}

#[test]
fn reconstruct_dim_2_rejects_wrong_columns_and_samples_outside() {
    let dir = scratch("rec");
    let o = dir.join("r.png");
    let two = dir.join("two.csv");
    std::fs::write(&two, "x,y\n1,2\n3,4\n").unwrap();
    fails_with(
        &rkwave(&[
            "reconstruct",
            "--dim",
            "2",
            "--input",
            two.to_str().unwrap(),
            "--resolution",
            "8x8",
            "--output",
            o.to_str().unwrap(),
        ]),
        &["3 to 6 columns", "found 2"],
    );
    let outside = dir.join("out.csv");
    std::fs::write(&outside, "x,y,v\n1,2,0.5\n9.5,2,0.1\n").unwrap();
    fails_with(
        &rkwave(&[
            "reconstruct",
            "--dim",
            "2",
            "--input",
            outside.to_str().unwrap(),
            "--resolution",
            "8x8",
            "--output",
            o.to_str().unwrap(),
        ]),
        &["sample 1", "9.5", "outside"],
    );
    fails_with(
        &rkwave(&[
            "reconstruct",
            "--dim",
            "2",
            "--input",
            outside.to_str().unwrap(),
            "--output",
            o.to_str().unwrap(),
        ]),
        &["--resolution"],
    );
}

/// `image --adaptive` runs end to end on a small scene: the image and its two figures are
/// written, the JSON names the samples used, and the budget is kept.
#[test]
fn image_adaptive_writes_the_image_and_its_figures() {
    let dir = scratch("adaptive");
    let out = dir.join("g.png");
    let run = rkwave(&[
        "image",
        "--scene",
        "shapes",
        "--resolution",
        "32x32",
        "--spp",
        "4",
        "--adaptive",
        "--truth-cache",
        dir.join("truth").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    let text = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&run.stderr)
    );
    for f in ["g.png", "g_depth.png", "g_samples.png", "g_adaptive.png"] {
        assert!(dir.join(f).exists(), "{f} missing");
    }
    let json: serde_json::Value = serde_json::from_str(&text).expect("one JSON object");
    let samples = json["samples"]
        .as_u64()
        .or_else(|| json["adaptive"]["samples"].as_u64());
    assert!(
        samples.is_some_and(|s| s > 0 && s <= 4 * 32 * 32),
        "samples within the budget: {json}"
    );
}
