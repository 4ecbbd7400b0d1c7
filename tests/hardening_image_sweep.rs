//! The hostile sweep of the image-plane surface (issue 27, item 4), through the binary:
//! sizes, values, files, state, paths and concurrency, each case with the exit code and
//! message it must give (0 success, 1 a failure of the machine, 2 a user error; never a
//! panic or an abort). The failure classes of the issue are in `tests/hardening_image.rs`.

mod common;

use std::path::{Path, PathBuf};

use common::{rkwave, succeeds, text, user_error, Scratch};
use rkwave::io::{write_npy, SampleSet};

fn scratch(name: &str) -> Scratch {
    common::scratch("hardening-image-sweep", name)
}

fn arg(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `n` image samples on `w x h` (positions by a fixed additive recurrence, a disc of value 1
/// on a ramp), `channels` equal channels, as `.npy` `n x (2 + channels)`.
fn samples_npy(path: &Path, w: usize, h: usize, n: usize, channels: usize) -> PathBuf {
    let xs: Vec<f64> = (0..n)
        .map(|i| w as f64 * (i as f64 * 0.754_877_666_2).fract())
        .collect();
    let ys: Vec<f64> = (0..n)
        .map(|i| h as f64 * (i as f64 * 0.569_840_290_9).fract())
        .collect();
    let v: Vec<f64> = xs
        .iter()
        .zip(&ys)
        .map(|(x, y)| {
            let (dx, dy) = (x - w as f64 / 3.0, y - h as f64 / 2.0);
            if dx * dx + dy * dy < (w as f64 / 4.0).powi(2) {
                1.0
            } else {
                0.2 + 0.5 * x / w as f64
            }
        })
        .collect();
    let mut values = vec![ys];
    values.extend(std::iter::repeat_n(v, channels));
    write_npy(path, &SampleSet::new(xs, values).unwrap()).unwrap();
    path.to_path_buf()
}

/// `reconstruct --dim 2` arguments on `w x h`.
fn reconstruct2d(input: &Path, output: &Path, resolution: &str) -> Vec<String> {
    [
        "reconstruct",
        "--dim",
        "2",
        "--input",
        arg(input),
        "--resolution",
        resolution,
        "--output",
        arg(output),
    ]
    .map(String::from)
    .to_vec()
}

/// `plan` continuing the plan in `state` with `samples`, the next positions to `out`.
fn plan_round(state: &Path, samples: &Path, out: &Path) -> Vec<String> {
    [
        "plan",
        "--state",
        arg(state),
        "--samples",
        arg(samples),
        "--out",
        arg(out),
    ]
    .map(String::from)
    .to_vec()
}

/// `plan` starting a plan at `resolution` and `spp` in `state`, the base positions to `out`.
fn plan_start(resolution: &str, spp: &str, state: &Path, out: &Path) -> Vec<String> {
    [
        "plan",
        "--resolution",
        resolution,
        "--spp",
        spp,
        "--state",
        arg(state),
        "--out",
        arg(out),
    ]
    .map(String::from)
    .to_vec()
}

/// The renderer of the plan loop: the positions of `next` (n x 2) with the value of the
/// disc scene appended to `previous` samples, written to `out`.
fn render(previous: Option<&Path>, next: &Path, out: &Path) {
    let pos = rkwave::io::read_npy(next).unwrap();
    let (mut xs, mut ys, mut vs) = match previous {
        Some(p) => {
            let s = rkwave::io::read_npy(p).unwrap();
            (
                s.positions.clone(),
                s.values[0].clone(),
                s.values[1].clone(),
            )
        }
        None => (Vec::new(), Vec::new(), Vec::new()),
    };
    for (x, y) in pos.positions.iter().zip(&pos.values[0]) {
        xs.push(*x);
        ys.push(*y);
        vs.push(if (x - 40.0).powi(2) + (y - 30.0).powi(2) < 400.0 {
            1.0
        } else {
            0.2
        });
    }
    write_npy(out, &SampleSet::new(xs, vec![ys, vs]).unwrap()).unwrap();
}

/// Starts a plan at `resolution`, `spp` in `dir`, renders its base and returns the samples.
fn started_plan(dir: &Path, resolution: &str, spp: &str) -> PathBuf {
    let n0 = dir.join("n0.npy");
    succeeds(&plan_start(resolution, spp, dir, &n0));
    let s0 = dir.join("s0.npy");
    render(None, &n0, &s0);
    s0
}

/// `.npy` bytes of `set` written by hand (the crate's writer refuses non-finite values).
fn write_npy_unchecked(path: &Path, set: &SampleSet) {
    let (m, k) = (set.len(), 1 + set.channels());
    let mut header = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': ({m}, {k}), }}");
    let unpadded = 10 + header.len() + 1;
    header.push_str(&" ".repeat((64 - unpadded % 64) % 64));
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    for i in 0..m {
        bytes.extend_from_slice(&set.positions[i].to_le_bytes());
        for c in &set.values {
            bytes.extend_from_slice(&c[i].to_le_bytes());
        }
    }
    std::fs::write(path, bytes).unwrap();
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
    assert!(e.contains("line 2"), "{e}");
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
        std::process::Command::new(env!("CARGO_BIN_EXE_rkwave"))
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
    rkwave::image::adaptive::protocol::PlanState::from_json(&state, Path::new("state.json"))
        .unwrap();
}
