//! `reconstruct --dim 2 --tile`: the tiled image through the binary against the untiled one,
//! independence of the worker count, the 2D fit flags, and bad input refused before any
//! work (exit 2, the flag and the fix named, no output left behind).

mod common;

use common::image_cli::{arg, npy_pixels, reconstruct2d, samples_npy};
use common::{rkwave, scratch, succeeds, text, user_error};

fn with(mut args: Vec<String>, extra: &[&str]) -> Vec<String> {
    args.extend(extra.iter().map(|s| s.to_string()));
    args
}

/// At the default halo the tiled image is the untiled one within 1e-6 of the value range
/// (the measured bound of the halo study, docs/measurements/image-plane.md), and the worker count
/// does not change a bit of it.
#[test]
fn tiled_matches_untiled_and_ignores_the_worker_count() {
    let dir = scratch("tiles", "match");
    let input = samples_npy(&dir.join("s.npy"), 64, 48, 4 * 64 * 48, 2);
    let untiled = dir.join("untiled.npy");
    // The untiled least-squares fit (not the default `--pixels auto`), which the tiles reproduce.
    succeeds(&with(
        reconstruct2d(&input, &untiled, "64x48"),
        &["--pixels", "fit"],
    ));
    let one = dir.join("one.npy");
    let three = dir.join("three.npy");
    succeeds(&with(
        reconstruct2d(&input, &one, "64x48"),
        &["--tile", "16", "--workers", "1"],
    ));
    let out = succeeds(&with(
        reconstruct2d(&input, &three, "64x48"),
        &["--tile", "16", "--workers", "3", "--json"],
    ));
    let json: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(json["tiled"]["tiles"].as_array().unwrap().len(), 12);
    assert_eq!(json["tiled"]["halo"], 12);
    // Every tile is solved exactly, whatever the untiled fit would choose (tests/tiles_nyquist.rs).
    assert_eq!(json["tiled"]["solver"], "Cholesky");
    // No `--pixels` given: the tiles' box pixels are not the untiled default (`auto`); said.
    assert!(
        json["notes"].as_array().unwrap().iter().any(|n| n
            .as_str()
            .unwrap()
            .starts_with("pixels: the fit's box pixels")),
        "{}",
        json["notes"]
    );
    let n = 64 * 48 * 2;
    let (u, a, b) = (
        npy_pixels(&untiled, n),
        npy_pixels(&one, n),
        npy_pixels(&three, n),
    );
    assert_eq!(a, b, "the worker count changed the image");
    assert_eq!(json["tiled"]["passes"], 2, "a file is read twice");
    let left: Vec<_> = std::fs::read_dir(&*dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with(".rkwave-tiles"))
        .collect();
    assert!(left.is_empty(), "band files left behind: {left:?}");
    let (lo, hi) = u
        .iter()
        .fold((f64::MAX, f64::MIN), |(l, h), &v| (l.min(v), h.max(v)));
    let worst = u
        .iter()
        .zip(&a)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    assert!(
        worst <= 1e-6 * (hi - lo),
        "max |tiled - untiled| = {worst:e}"
    );
}

/// Each bad request exits 2 naming the flag or the problem, and writes nothing.
#[test]
fn bad_tiles_are_refused_before_any_work() {
    let dir = scratch("tiles", "bad");
    let input = samples_npy(&dir.join("s.npy"), 32, 24, 4 * 32 * 24, 1);
    let out = dir.join("o.npy");
    let base = reconstruct2d(&input, &out, "32x24");
    for (extra, needle) in [
        (vec!["--tile", "0"], "--tile"),
        (vec!["--tile", "25"], "larger than the 32 x 24 image"),
        (vec!["--tile", "8", "--halo", "9"], "--halo"),
        (vec!["--halo", "4"], "give --tile T too"),
        (vec!["--tile", "8", "--workers", "0"], "--workers 0"),
        (vec!["--tile", "8", "--method", "local"], "--method"),
        (vec!["--tile", "8", "--smoothing", "0.1"], "smoothing"),
    ] {
        let message = user_error(&with(base.clone(), &extra));
        assert!(message.contains(needle), "{extra:?}: {message}");
        assert!(!out.exists(), "{extra:?} left an output");
    }
    // samples outside the image: a 16 x 16 resolution for samples on 32 x 24
    let message = user_error(&with(
        reconstruct2d(&input, &out, "16x16"),
        &["--tile", "8"],
    ));
    assert!(message.contains("outside the 16 x 16 image"), "{message}");
    assert!(!out.exists());
    // an input that is not there
    let missing = dir.join("missing.npy");
    let message = user_error(&with(
        reconstruct2d(&missing, &out, "32x24"),
        &["--tile", "8"],
    ));
    assert!(message.contains("missing.npy"), "{message}");
    // --tile with --state, and the image flags with --dim 1
    let message = user_error(&with(base.clone(), &["--tile", "8", "--state", arg(&dir)]));
    assert!(
        message.contains("--tile") && message.contains("--state"),
        "{message}"
    );
    let one_d = [
        "reconstruct",
        "--input",
        arg(&input),
        "--output",
        arg(&out),
        "--tile",
        "8",
    ];
    assert!(user_error(&one_d).contains("--dim 2"));
    assert!(!out.exists());
}

/// `--rho`, `--ridge` and `--smoothing` reach the 2D fit (they used to be ignored); not
/// given, the image is the default fit's, bit for bit; out of range, refused.
#[test]
fn the_fit_flags_reach_the_image_plane() {
    let dir = scratch("tiles", "flags");
    let input = samples_npy(&dir.join("s.npy"), 32, 24, 4 * 32 * 24, 1);
    let n = 32 * 24;
    let run = |name: &str, extra: &[&str]| {
        let out = dir.join(name);
        succeeds(&with(reconstruct2d(&input, &out, "32x24"), extra));
        npy_pixels(&out, n)
    };
    let default = run("default.npy", &["--pixels", "fit"]);
    assert_eq!(default, run("rho4.npy", &["--rho", "4", "--ridge", "1e-9"]));
    assert_ne!(default, run("rho1.npy", &["--rho", "1"]));
    assert_ne!(default, run("ridge.npy", &["--ridge", "1e-3"]));
    assert_ne!(default, run("smooth.npy", &["--smoothing", "0.1"]));
    let out = dir.join("bad.npy");
    for (extra, needle) in [
        (["--rho", "0"], "--rho"),
        (["--ridge", "2"], "--ridge"),
        (["--smoothing=-1", "--p=2"], "--smoothing"),
    ] {
        let message = user_error(&with(reconstruct2d(&input, &out, "32x24"), &extra));
        assert!(message.contains(needle), "{extra:?}: {message}");
    }
    let out = rkwave(&with(reconstruct2d(&input, &out, "32x24"), &["--help"]));
    assert!(text(&out).contains("default 4"));
}
