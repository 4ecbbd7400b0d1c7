//! Non-finite radiance from a renderer (issue 28, item 3): samples whose value is NaN or
//! infinite are refused by default with their count and the first one's row, position and
//! channel, or dropped with `--drop-nonfinite` and counted in the text report and `--json`;
//! in `reconstruct --dim 2` (uniform and `--state`) and in `plan`, whose state survives a
//! refused round (the same round can be answered again) and recognises a round with dropped
//! samples as the round it handed out.

mod common;

use std::path::{Path, PathBuf};

use common::image_cli::{
    arg, plan_round, plan_start, reconstruct2d, render, samples_npy, write_npy_unchecked,
};
use common::{succeeds, user_error, Scratch};
use rkwave::image::adaptive::AdaptiveParams;
use rkwave::image::plan::{PlanState, ProtocolError};
use rkwave::image::{split_finite, ImageError, ImagePlane, NonFinitePolicy};
use rkwave::io::{read_npy, SampleSet};

fn scratch(name: &str) -> Scratch {
    common::scratch("nonfinite-radiance", name)
}

/// The samples of `file` with channel 0 of the rows `rows` (0-based) set to `values`,
/// written by hand to `out` (the crate's writer refuses non-finite values).
fn poisoned(file: &Path, rows: &[usize], values: &[f64], out: &Path) -> PathBuf {
    let mut set = read_npy(file).unwrap();
    for (&i, &v) in rows.iter().zip(values) {
        set.values[1][i] = v;
    }
    write_npy_unchecked(out, &set);
    out.to_path_buf()
}

fn with(mut args: Vec<String>, more: &[&str]) -> Vec<String> {
    args.extend(more.iter().map(|s| s.to_string()));
    args
}

/// Uniform path: refused with the count (2), the first row (1-based: 4) and its position;
/// the message names `--drop-nonfinite`. With it, the image is the reconstruction of the
/// other samples, bit for bit, and the drop is counted in the text and the JSON report.
#[test]
fn uniform_refuses_then_drops_and_counts() {
    let d = scratch("uniform");
    let clean = samples_npy(&d.join("clean.npy"), 16, 16, 1024, 1);
    let bad = poisoned(
        &clean,
        &[3, 700],
        &[f64::NAN, f64::INFINITY],
        &d.join("bad.npy"),
    );
    let out = d.join("o.npy");
    let e = user_error(&reconstruct2d(&bad, &out, "16x16"));
    let first = read_npy(&clean).unwrap();
    assert!(
        e.contains("2 samples") && e.contains("row 4") && e.contains("--drop-nonfinite"),
        "{e}"
    );
    assert!(e.contains(&format!("{}", first.positions[3])), "{e}");
    assert!(!out.exists(), "a refused file writes no image");

    let text = succeeds(&with(
        reconstruct2d(&bad, &out, "16x16"),
        &["--drop-nonfinite"],
    ));
    assert!(text.contains("2 samples with a non-finite value"), "{text}");
    let json = succeeds(&with(
        reconstruct2d(&bad, &d.join("o2.npy"), "16x16"),
        &["--drop-nonfinite", "--json"],
    ));
    let report: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(report["nonfinite"]["count"], 2);
    assert_eq!(report["nonfinite"]["first"]["row"], 4);
    assert_eq!(report["nonfinite"]["first"]["value"], "NaN");
    assert_eq!(report["samples"], 1022);

    // The same image as the file without those two rows.
    let mut kept = first.clone();
    kept.positions = without_rows(&first.positions, &[3, 700]);
    kept.values = first
        .values
        .iter()
        .map(|v| without_rows(v, &[3, 700]))
        .collect();
    let kept_file = d.join("kept.npy");
    rkwave::io::write_npy(&kept_file, &kept).unwrap();
    let expected = d.join("expected.npy");
    succeeds(&reconstruct2d(&kept_file, &expected, "16x16"));
    assert_eq!(
        std::fs::read(&out).unwrap(),
        std::fs::read(&expected).unwrap()
    );
}

/// `v` without the entries at `rows`.
fn without_rows(v: &[f64], rows: &[usize]) -> Vec<f64> {
    v.iter()
        .enumerate()
        .filter(|(i, _)| !rows.contains(i))
        .map(|(_, x)| *x)
        .collect()
}

/// CSV too: `nan` and `inf` are read as values and refused with the count.
#[test]
fn csv_values_are_counted() {
    let d = scratch("csv");
    let f = d.join("s.csv");
    let mut text = String::from("x,y,v\n");
    for i in 0..64 {
        let (x, y) = (0.5 + (i % 8) as f64, 0.5 + (i / 8) as f64);
        let v = match i {
            5 => "nan".to_string(),
            9 | 10 => "-inf".to_string(),
            _ => "0.5".to_string(),
        };
        text.push_str(&format!("{x},{y},{v}\n"));
    }
    std::fs::write(&f, text).unwrap();
    let e = user_error(&reconstruct2d(&f, &d.join("o.npy"), "8x8"));
    assert!(e.contains("3 samples") && e.contains("row 6"), "{e}");
    // a non-finite position is no radiance: refused with or without the flag
    std::fs::write(&f, "x,y,v\nnan,0.5,1\n0.5,0.5,1\n").unwrap();
    let e = user_error(&with(
        reconstruct2d(&f, &d.join("o.npy"), "8x8"),
        &["--drop-nonfinite"],
    ));
    assert!(e.contains("not finite") && e.contains("`x`"), "{e}");
}

/// The plan: a round with a NaN is refused and leaves the state and the positions file as
/// they were; the same round is answered again with `--drop-nonfinite` (recognised by all
/// its positions, the drop counted in the text and the JSON), and the final reconstruction
/// takes the flag too.
#[test]
fn plan_state_survives_a_refused_round() {
    let d = scratch("plan");
    let n0 = d.join("n0.npy");
    succeeds(&plan_start("24x24", "4", &d, &n0));
    let s0 = d.join("s0.npy");
    render(None, &n0, &s0);
    let bad = poisoned(&s0, &[10], &[f64::NAN], &d.join("bad0.npy"));
    let state_before = std::fs::read(PlanState::path(&d)).unwrap();
    let n1 = d.join("n1.npy");
    let e = user_error(&plan_round(&d, &bad, &n1));
    assert!(e.contains("1 samples") && e.contains("row 11"), "{e}");
    assert_eq!(std::fs::read(PlanState::path(&d)).unwrap(), state_before);
    assert!(!n1.exists(), "a refused round writes no positions");

    let json = succeeds(&with(
        plan_round(&d, &bad, &n1),
        &["--drop-nonfinite", "--json"],
    ));
    let report: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(report["step"]["dropped"]["count"], 1, "{json}");
    assert_ne!(std::fs::read(PlanState::path(&d)).unwrap(), state_before);

    // Play the plan to its end with the poisoned sample kept in the file.
    let (mut samples, mut next) = (bad.clone(), n1.clone());
    for k in 1.. {
        if read_npy(&next).map_or(true, |s| s.is_empty()) {
            break;
        }
        assert!(k < 64, "the plan stops");
        let s = d.join(format!("s{k}.npy"));
        render_after(&samples, &next, &s);
        let n = d.join(format!("n{}.npy", k + 1));
        let text = succeeds(&with(plan_round(&d, &s, &n), &["--drop-nonfinite"]));
        assert!(text.contains("1 samples with a non-finite value"), "{text}");
        (samples, next) = (s, n);
    }
    let out = d.join("img.npy");
    let rec = |extra: &[&str]| {
        with(
            vec![
                "reconstruct".into(),
                "--dim".into(),
                "2".into(),
                "--state".into(),
                arg(&d).into(),
                "--input".into(),
                arg(&samples).into(),
                "--output".into(),
                arg(&out).into(),
            ],
            extra,
        )
    };
    let e = user_error(&rec(&[]));
    assert!(e.contains("--drop-nonfinite"), "{e}");
    let json = succeeds(&rec(&["--drop-nonfinite", "--json"]));
    let report: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(report["nonfinite"]["count"], 1, "{json}");
    assert!(report["notes"].to_string().contains("non-finite"), "{json}");
}

/// The renderer of `common::image_cli::render`, keeping the rows of `previous` as they are
/// (its NaN included).
fn render_after(previous: &Path, next: &Path, out: &Path) {
    let fresh = out.with_extension("fresh.npy");
    render(None, next, &fresh);
    let (prev, new) = (read_npy_lenient(previous), read_npy(&fresh).unwrap());
    let join = |a: &[f64], b: &[f64]| [a, b].concat();
    let all = SampleSet::new(
        join(&prev.positions, &new.positions),
        vec![
            join(&prev.values[0], &new.values[0]),
            join(&prev.values[1], &new.values[1]),
        ],
    )
    .unwrap();
    write_npy_unchecked(out, &all);
}

/// A `.npy` sample file whose values may be non-finite.
fn read_npy_lenient(path: &Path) -> SampleSet {
    let plane = ImagePlane::new(64, 64).unwrap();
    let (s, dropped) =
        rkwave::io::read_image_samples_with(path, plane, NonFinitePolicy::Drop).unwrap();
    assert!(dropped.count <= 1);
    // put the dropped rows back in their places (as NaN) in the file's order
    let n = s.len() + dropped.count;
    let row = dropped.first.map(|f| f.row - 1);
    let (mut xs, mut ys, mut vs) = (Vec::new(), Vec::new(), Vec::new());
    let mut k = 0;
    for i in 0..n {
        if Some(i) == row {
            let f = dropped.first.unwrap();
            xs.push(f.x);
            ys.push(f.y);
            vs.push(f.value);
        } else {
            xs.push(s.xs()[k]);
            ys.push(s.ys()[k]);
            vs.push(s.channel(0)[k]);
            k += 1;
        }
    }
    SampleSet::new(xs, vec![ys, vs]).unwrap()
}

/// The library: a refused advance leaves the state equal to what it was; a dropped sample
/// keeps the round recognised; the split is the identity on finite samples.
#[test]
fn library_advance_with_dropped_samples() {
    let plane = ImagePlane::new(16, 16).unwrap();
    let params = AdaptiveParams {
        stop: rkwave::image::adaptive::StopParams {
            budget: 16 * 16 * 4,
            ..AdaptiveParams::default().stop
        },
        ..AdaptiveParams::default()
    };
    let (mut state, base) = PlanState::start(plane, &params).unwrap();
    let f = |x: f64, y: f64| 0.3 + 0.01 * x + if x + y < 14.0 { 0.5 } else { 0.0 };
    let mut v: Vec<f64> = base
        .xs
        .iter()
        .zip(&base.ys)
        .map(|(x, y)| f(*x, *y))
        .collect();
    v[7] = f64::NEG_INFINITY;
    let e = split_finite(
        plane,
        base.xs.clone(),
        base.ys.clone(),
        vec![v.clone()],
        NonFinitePolicy::Refuse,
    )
    .unwrap_err();
    assert!(matches!(
        e,
        ImageError::NonFiniteSamples {
            count: 1,
            row: 8,
            ..
        }
    ));
    let before = state.clone();
    let (kept, dropped) = split_finite(
        plane,
        base.xs.clone(),
        base.ys.clone(),
        vec![v],
        NonFinitePolicy::Drop,
    )
    .unwrap();
    // Without the dropped positions the round is not the one handed out: refused, unchanged.
    let e = state.advance(&kept).unwrap_err();
    assert!(matches!(e, ProtocolError::Mismatch { .. }), "{e}");
    assert_eq!(state, before);
    let step = state.advance_dropped(&kept, dropped).unwrap();
    assert_eq!(step.dropped.count, 1);
    assert_eq!(step.log.samples, base.len() - 1);
}
