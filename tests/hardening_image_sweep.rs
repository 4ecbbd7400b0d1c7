//! The hostile sweep of the image-plane surface (issue 27, item 4), through the binary:
//! sizes, values, files, state, paths and concurrency, each case with the exit code and
//! message it must give (0 success, 1 a failure of the machine, 2 a user error; never a
//! panic or an abort). The failure classes of the issue are in `tests/hardening_image.rs`.

mod common;

use std::path::Path;

use common::image_cli::{
    arg, plan_round, reconstruct2d, samples_npy, started_plan, write_npy_unchecked,
};
use common::{rkwave, text, user_error, Scratch};
use rkwave::io::{write_npy, SampleSet};

fn scratch(name: &str) -> Scratch {
    common::scratch("hardening-image-sweep", name)
}

// ---------------------------------------------------------------------------------------
// The hostile sweep.

/// Sizes: resolutions of 0, beyond 65,536, garbage, and more samples than fit are refused
/// with the flag named; none panics.
#[test]
fn sweep_sizes() {
    let d = scratch("sizes");
    let s = samples_npy(&d.join("S.npy"), 16, 16, 256, 1);
    let out = d.join("o.npy");
    for res in [
        "0x16", "16x0", "70000x1", "16", "axb", "1e3x1e3", "16x16x16",
    ] {
        let e = user_error(&reconstruct2d(&s, &out, res));
        assert!(
            e.contains("--resolution") || e.contains("resolution"),
            "{res}: {e}"
        );
    }
    // samples outside a smaller image
    let e = user_error(&reconstruct2d(&s, &out, "8x8"));
    assert!(e.contains("outside") || e.contains("lie"), "{e}");
    for spp in ["0", "-1", "1e30", "nan"] {
        let out = rkwave(&[
            "plan",
            "--resolution",
            "16x16",
            "--spp",
            spp,
            "--state",
            arg(&d.join("p")),
            "--out",
            arg(&d.join("n.npy")),
        ]);
        assert_eq!(out.status.code(), Some(2), "{spp}: {}", text(&out));
    }
    assert!(!out.exists());
}

/// Values: infinite values, too few or too many columns, an empty table: refused with the
/// row and column or the shape named.
#[test]
fn sweep_values() {
    let d = scratch("values");
    let out = d.join("o.npy");
    let f = d.join("v.npy");
    let inf = SampleSet::new(
        vec![1.0, 2.0],
        vec![vec![1.0, 1.0], vec![0.5, f64::INFINITY]],
    )
    .unwrap();
    write_npy_unchecked(&f, &inf);
    let e = user_error(&reconstruct2d(&f, &out, "4x4"));
    assert!(e.contains("not finite") && e.contains("row 2"), "{e}");
    let two = SampleSet::new(vec![1.0, 2.0], vec![vec![1.0, 1.0]]).unwrap();
    write_npy(&f, &two).unwrap();
    let e = user_error(&reconstruct2d(&f, &out, "4x4"));
    assert!(e.contains("column"), "{e}");
    let seven = SampleSet::new(vec![1.0], vec![vec![1.0]; 6]).unwrap();
    write_npy(&f, &seven).unwrap();
    let e = user_error(&reconstruct2d(&f, &out, "4x4"));
    assert!(e.contains("column"), "{e}");
    let csv = d.join("h.csv");
    std::fs::write(&csv, "x,y,v\n").unwrap();
    user_error(&reconstruct2d(&csv, &out, "4x4"));
    std::fs::write(&csv, "x,y,v\n1,1,inf\n").unwrap();
    let e = user_error(&reconstruct2d(&csv, &out, "4x4"));
    assert!(e.contains("row 1") && e.contains("--drop-nonfinite"), "{e}");
    assert!(!out.exists());
}

/// Files: a folder, a missing file, garbage bytes, a truncated `.npy`, a forged header with
/// a huge shape: each a typed error (exit 2), never an allocation of the forged size.
#[test]
fn sweep_files() {
    let d = scratch("files");
    let out = d.join("o.npy");
    user_error(&reconstruct2d(&d, &out, "4x4"));
    user_error(&reconstruct2d(&d.join("missing.npy"), &out, "4x4"));
    let g = d.join("g.npy");
    std::fs::write(&g, b"\x00\x01garbage\xff").unwrap();
    user_error(&reconstruct2d(&g, &out, "4x4"));
    let s = samples_npy(&d.join("s.npy"), 4, 4, 64, 1);
    let bytes = std::fs::read(&s).unwrap();
    std::fs::write(&g, &bytes[..bytes.len() - 5]).unwrap();
    let e = user_error(&reconstruct2d(&g, &out, "4x4"));
    assert!(
        e.contains("short") || e.contains("truncated") || e.contains("needs"),
        "{e}"
    );
    let header_end = 10 + u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let dict = "{'descr': '<f8', 'fortran_order': False, 'shape': (99999999999999, 3), }";
    let len = header_end - 10;
    let mut forged = bytes[..10].to_vec();
    forged.extend_from_slice(format!("{dict:<width$}\n", width = len - 1).as_bytes());
    forged.extend_from_slice(&bytes[header_end..]);
    std::fs::write(&g, forged).unwrap();
    user_error(&reconstruct2d(&g, &out, "4x4"));
    assert!(!out.exists());
}

/// State: a damaged, truncated or foreign `state.json`, a missing plan, another resolution:
/// refused (exit 2) with the state named, the state file left as it was.
#[test]
fn sweep_state() {
    let d = scratch("state");
    let s0 = started_plan(&d, "16x16", "4");
    let good = std::fs::read(d.join("state.json")).unwrap();
    let n1 = d.join("n1.npy");
    let call = |state: &Path| user_error(&plan_round(state, &s0, &n1));
    for bad in [
        &b"{"[..],
        b"",
        b"[]",
        &good[..good.len() / 2],
        br#"{"format":"rkwave-image-plan","version":99}"#,
    ] {
        std::fs::write(d.join("state.json"), bad).unwrap();
        let e = call(&d);
        assert!(e.contains("state"), "{e}");
        assert_eq!(std::fs::read(d.join("state.json")).unwrap(), bad);
    }
    std::fs::write(d.join("state.json"), &good).unwrap();
    let e = call(&d.join("elsewhere"));
    assert!(e.contains("no plan"), "{e}");
    let e = user_error(&[
        "plan",
        "--state",
        arg(&d),
        "--resolution",
        "32x32",
        "--samples",
        arg(&s0),
        "--out",
        arg(&n1),
    ]);
    assert!(e.contains("resolution"), "{e}");
    assert!(!n1.exists());
}

/// Paths: an output that is a folder, an unknown extension, an existing file without
/// `--force`, `image --out` naming its scene file: refused before any work.
#[test]
fn sweep_paths() {
    let d = scratch("paths");
    let s = samples_npy(&d.join("S.npy"), 8, 8, 256, 1);
    let folder = d.join("folder.npy");
    std::fs::create_dir(&folder).unwrap();
    let e = user_error(&reconstruct2d(&s, &folder, "8x8"));
    assert!(e.contains("directory"), "{e}");
    let e = user_error(&reconstruct2d(&s, &d.join("o.jpg"), "8x8"));
    assert!(e.contains(".png"), "{e}");
    let existing = d.join("e.npy");
    std::fs::write(&existing, b"keep").unwrap();
    let e = user_error(&reconstruct2d(&s, &existing, "8x8"));
    assert!(e.contains("--force"), "{e}");
    assert_eq!(std::fs::read(&existing).unwrap(), b"keep");
    // a scene file whose name is the output's (a .npy scene is no scene, but the output
    // check comes first and names the clash)
    let scene = d.join("scene.npy");
    std::fs::copy(
        rkwave::image::scene::Scene::builtin_dir().join("shapes.json"),
        &scene,
    )
    .unwrap();
    let e = user_error(&[
        "image",
        "--scene",
        arg(&scene),
        "--resolution",
        "8x8",
        "--out",
        arg(&scene),
        "--force",
    ]);
    assert!(e.contains("is the input"), "{e}");
}

/// Concurrency: two `plan` calls on one state at once each exit 0 or 2 (never a panic or a
/// torn file); the state afterwards is a plan state the next call reads.
#[test]
fn sweep_concurrent_plan_calls() {
    let d = scratch("concurrent");
    let s0 = started_plan(&d, "32x32", "4");
    let spawn = |name: &str| {
        common::command()
            .args([
                "plan",
                "--state",
                arg(&d),
                "--samples",
                arg(&s0),
                "--out",
                arg(&d.join(name)),
            ])
            .output()
            .unwrap()
    };
    let (a, b) = std::thread::scope(|s| {
        let a = s.spawn(|| spawn("a.npy"));
        let b = s.spawn(|| spawn("b.npy"));
        (a.join().unwrap(), b.join().unwrap())
    });
    for out in [&a, &b] {
        assert!(matches!(out.status.code(), Some(0 | 2)), "{}", text(out));
        assert!(!text(out).contains("panicked"));
    }
    assert!(a.status.success() || b.status.success());
    let state = std::fs::read_to_string(d.join("state.json")).unwrap();
    rkwave::image::plan::PlanState::from_json(&state, Path::new("state.json")).unwrap();
}
