//! `rkwave plan --new-samples` (issue 40, item 1): a round given only the samples of the
//! positions just handed out is the round `--samples` with every sample so far (the earlier
//! rounds' samples in the order given, then the new ones) gives, bit for bit: every positions
//! file and the final image; the two flags mix across calls. New samples that are not the
//! round handed out (an earlier round, every sample so far, another count, moved positions)
//! are refused naming the round and count expected, and a refused call changes nothing; the
//! plan's file of the samples read (`samples.bin`) missing or damaged is a refusal naming
//! the fix.

mod common;

use std::path::{Path, PathBuf};

use common::image_cli::{arg, plan_start, write_npy_unchecked};
use common::{succeeds, user_error, Scratch};
use rkwave::io::{read_npy, SampleSet};

fn scratch(name: &str) -> Scratch {
    common::scratch("plan-new-samples", name)
}

/// The samples of the positions in `next` (a positions file), in reverse order (a renderer
/// may return them in any order): channels `y`-ramp and a disc, with `nan_at` (a row) given a
/// NaN value.
fn render_new(next: &Path, nan_at: Option<usize>) -> SampleSet {
    let p = read_npy(next).unwrap();
    let (mut xs, mut ys) = (p.positions.clone(), p.values[0].clone());
    xs.reverse();
    ys.reverse();
    let a: Vec<f64> = ys.iter().map(|y| 0.1 + y / 40.0).collect();
    let mut b: Vec<f64> = xs
        .iter()
        .zip(&ys)
        .map(|(x, y)| {
            if (x - 9.0).powi(2) + (y - 8.0).powi(2) < 30.0 {
                1.0
            } else {
                0.25
            }
        })
        .collect();
    if let Some(i) = nan_at.filter(|&i| i < b.len()) {
        b[i] = f64::NAN;
    }
    SampleSet::new(xs, vec![ys, a, b]).unwrap()
}

fn append(all: &mut Option<SampleSet>, new: &SampleSet) {
    match all {
        None => *all = Some(new.clone()),
        Some(s) => {
            s.positions.extend(&new.positions);
            for (c, v) in s.values.iter_mut().zip(&new.values) {
                c.extend(v);
            }
        }
    }
}

fn save(path: &Path, set: &SampleSet) -> PathBuf {
    write_npy_unchecked(path, set);
    path.to_path_buf()
}

/// How each round's samples are given.
#[derive(Clone, Copy, PartialEq)]
enum Give {
    All,
    New,
    /// `--new-samples` on odd rounds, `--samples` on even ones.
    Mixed,
}

/// A 24x20 plan at 4 spp started with `start` flags and run to its stop in `dir`, each round
/// given as `give` says, with `flags` on every round; the bytes of every positions file and of
/// the final image.
fn run_loop(
    dir: &Path,
    give: Give,
    (start, flags): (&[&str], &[&str]),
    nan_round: Option<usize>,
) -> Vec<Vec<u8>> {
    let n0 = dir.join("n0.npy");
    let mut first = plan_start("24x20", "4", dir, &n0);
    first.extend(start.iter().map(|f| f.to_string()));
    succeeds(&first);
    let fin = dir.join("final.npy");
    let mut out = vec![std::fs::read(&n0).unwrap()];
    let (mut all, mut next) = (None, n0);
    for k in 1.. {
        assert!(k < 64, "the plan stops");
        let new = render_new(&next, (nan_round == Some(k)).then_some(3));
        append(&mut all, &new);
        let new_file = save(&dir.join(format!("new{k}.npy")), &new);
        let all_file = save(&dir.join(format!("all{k}.npy")), all.as_ref().unwrap());
        let by_new = give == Give::New || (give == Give::Mixed && k % 2 == 1);
        let (flag, file) = match by_new {
            true => ("--new-samples", new_file),
            false => ("--samples", all_file),
        };
        let n = dir.join(format!("n{k}.npy"));
        let mut args: Vec<String> = ["plan", "--state", arg(dir), flag, arg(&file), "--out"]
            .map(String::from)
            .to_vec();
        args.extend([arg(&n).into(), "--final-image".into(), arg(&fin).into()]);
        args.extend(flags.iter().map(|f| f.to_string()));
        let text = succeeds(&args);
        assert!(!text.contains("could not be kept"), "{text}");
        out.push(std::fs::read(&n).unwrap());
        next = n;
        if text.contains("stopped") {
            out.push(std::fs::read(&fin).unwrap());
            return out;
        }
    }
    unreachable!()
}

#[test]
fn new_samples_give_the_rounds_of_every_sample_bit_for_bit() {
    for flags in [&[][..], &["--solver", "direct"][..]] {
        let all = run_loop(&scratch("all"), Give::All, (flags, &[]), None);
        assert!(all.len() >= 4, "a plan of several rounds: {}", all.len());
        let new = run_loop(&scratch("new"), Give::New, (flags, &[]), None);
        let mixed = run_loop(&scratch("mixed"), Give::Mixed, (flags, &[]), None);
        assert!(
            all == new,
            "--new-samples: the same positions and image ({flags:?})"
        );
        assert!(
            all == mixed,
            "mixed calls: the same positions and image ({flags:?})"
        );
    }
}

#[test]
fn dropped_nonfinite_samples_count_as_with_every_sample() {
    let flags = ["--drop-nonfinite"];
    let all = run_loop(&scratch("nan-all"), Give::All, (&[], &flags), Some(2));
    let new = run_loop(&scratch("nan-new"), Give::New, (&[], &flags), Some(2));
    assert!(all.len() >= 4);
    assert!(all == new, "a dropped sample in round 2: the same rounds");
}

/// A plan in `dir` advanced by `--new-samples` through round 2; returns the new samples of
/// rounds 1, 2 and 3 (the last not given yet) and every sample through round 3.
fn plan_at_round_three(dir: &Path) -> (Vec<SampleSet>, SampleSet) {
    let n0 = dir.join("n0.npy");
    succeeds(&plan_start("24x20", "8", dir, &n0));
    let (mut news, mut all, mut next) = (Vec::new(), None, n0);
    for k in 1..=3 {
        let new = render_new(&next, None);
        append(&mut all, &new);
        news.push(new.clone());
        if k == 3 {
            break;
        }
        let file = save(&dir.join(format!("new{k}.npy")), &new);
        let n = dir.join(format!("n{k}.npy"));
        let text = succeeds(&round(dir, "--new-samples", &file, &n));
        assert!(!text.contains("stopped"), "the plan goes on: {text}");
        next = n;
    }
    (news, all.unwrap())
}

fn round(dir: &Path, flag: &str, file: &Path, out: &Path) -> Vec<String> {
    [
        "plan",
        "--state",
        arg(dir),
        flag,
        arg(file),
        "--out",
        arg(out),
    ]
    .map(String::from)
    .to_vec()
}

/// Refuses `file` as the new round of the plan in `dir`, changing nothing; the message.
fn refused(dir: &Path, file: &Path) -> String {
    let state = std::fs::read(dir.join("state.json")).unwrap();
    let kept = std::fs::read(dir.join("samples.bin")).ok();
    let out = dir.join("refused.npy");
    let e = user_error(&round(dir, "--new-samples", file, &out));
    assert!(!out.exists(), "a refused call writes no positions: {e}");
    assert_eq!(std::fs::read(dir.join("state.json")).unwrap(), state, "{e}");
    assert_eq!(std::fs::read(dir.join("samples.bin")).ok(), kept, "{e}");
    e
}

#[test]
fn new_samples_of_another_round_are_refused_naming_the_round_expected() {
    let d = scratch("refusals");
    let (news, all) = plan_at_round_three(&d);
    let expected = news[2].len();
    let want = format!("{expected} positions");
    // an earlier round again (repeated; or the last one lost)
    let e = refused(&d, &save(&d.join("again.npy"), &news[1]));
    assert!(
        e.contains("round 1, which this plan has read already"),
        "{e}"
    );
    assert!(e.contains(&want) && e.contains("round 2"), "{e}");
    // every sample so far as the new round
    let e = refused(&d, &save(&d.join("all.npy"), &all));
    assert!(e.contains("every sample of rounds 0..=2"), "{e}");
    assert!(e.contains(&format!("{expected} samples")), "{e}");
    // one sample lost
    let mut short = news[2].clone();
    short.positions.pop();
    short.values.iter_mut().for_each(|v| {
        v.pop();
    });
    let e = refused(&d, &save(&d.join("short.npy"), &short));
    assert!(
        e.contains(&format!("{} samples given as the new round", expected - 1)),
        "{e}"
    );
    assert!(e.contains(&want) && e.contains("round 2"), "{e}");
    // positions rounded to float32 on the way, or moved
    let mut rounded = news[2].clone();
    rounded
        .positions
        .iter_mut()
        .chain(rounded.values[0].iter_mut())
        .for_each(|v| *v = *v as f32 as f64);
    assert!(rounded.positions != news[2].positions || rounded.values != news[2].values);
    let e = refused(&d, &save(&d.join("f32.npy"), &rounded));
    assert!(
        e.contains("not the positions this plan handed out for round 2"),
        "{e}"
    );
    assert!(e.contains("float32"), "{e}");
    // the round as handed out is then taken
    let file = save(&d.join("new3.npy"), &news[2]);
    succeeds(&round(&d, "--new-samples", &file, &d.join("n3.npy")));
}

#[test]
fn the_samples_read_missing_or_damaged_refuse_naming_the_fix() {
    let d = scratch("kept");
    let (news, all) = plan_at_round_three(&d);
    let new3 = save(&d.join("new3.npy"), &news[2]);
    let kept = d.join("samples.bin");
    let bytes = std::fs::read(&kept).unwrap();
    // damaged: one bit flipped in the last piece
    let mut flipped = bytes.clone();
    let at = flipped.len() - 24;
    flipped[at] ^= 1;
    std::fs::write(&kept, &flipped).unwrap();
    let e = refused(&d, &new3);
    assert!(e.contains("samples.bin") && e.contains("damaged"), "{e}");
    assert!(e.contains("--samples"), "the fix is named: {e}");
    // missing
    std::fs::remove_file(&kept).unwrap();
    let out = d.join("n3.npy");
    let e = user_error(&round(&d, "--new-samples", &new3, &out));
    assert!(e.contains("not found") && e.contains("--samples"), "{e}");
    assert!(!out.exists());
    // every sample so far works, and writes the file again for the next round's new samples
    let all_file = save(&d.join("all3.npy"), &all);
    let text = succeeds(&round(&d, "--samples", &all_file, &out));
    assert!(kept.exists(), "{text}");
    if !text.contains("stopped") {
        let new4 = render_new(&out, None);
        let file = save(&d.join("new4.npy"), &new4);
        succeeds(&round(&d, "--new-samples", &file, &d.join("n4.npy")));
    }
}

#[test]
fn new_samples_are_refused_on_the_tiled_plan_naming_the_fix() {
    let d = scratch("tiled");
    let n0 = d.join("n0.npy");
    let mut start = plan_start("32x32", "4", &d, &n0);
    start.extend(["--tile".into(), "16".into()]);
    succeeds(&start);
    let new = save(&d.join("new1.npy"), &render_new(&n0, None));
    let e = user_error(&round(&d, "--new-samples", &new, &d.join("n1.npy")));
    assert!(e.contains("tiled plan") && e.contains("--samples"), "{e}");
    assert!(!d.join("n1.npy").exists());
}
