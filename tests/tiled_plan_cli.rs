//! `rkwave plan --tile`: the tiled plan through the round files (positions out, every sample
//! so far in) to its stop and its final image; the command line's refusals name the flags.

mod common;

use rkwave::io::{write_npy, SampleSet};

use common::scenes::straight_edge;

/// The tiled plan driven through files to its stop writes its positions and, on the stopping
/// call, the final image; the positions are those the library hands out (each call's count
/// is the state's record).
#[test]
fn tiled_plan_through_files_to_its_stop() {
    let dir = common::scratch("tiledplan", "loop");
    let state = dir.join("state");
    let (w, h) = (48usize, 40usize);
    let s = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let mut set = SampleSet::default();
    let image = dir.join("image.npy");
    let mut call = 0;
    loop {
        let next = dir.join(format!("next{call}.npy"));
        let mut args = vec![
            "plan".to_string(),
            "--state".into(),
            s(&state),
            "--spp".into(),
            "3".into(),
            "--out".into(),
            s(&next),
            "--final-image".into(),
            s(&image),
        ];
        if call == 0 {
            args.extend([
                "--resolution".into(),
                format!("{w}x{h}"),
                "--tile".into(),
                "16".into(),
                "--halo".into(),
                "4".into(),
            ]);
        } else {
            args.extend([
                "--samples".into(),
                s(&dir.join(format!("samples{}.npy", call - 1))),
            ]);
        }
        let out = common::rkwave(&args);
        assert!(out.status.success(), "{}", common::text(&out));
        if common::text(&out).contains("the tiled plan stopped") {
            assert!(image.exists(), "{}", common::text(&out));
            break;
        }
        assert!(!image.exists());
        common::image_cli::append_rendered(&mut set, &next, straight_edge);
        write_npy(dir.join(format!("samples{call}.npy")), &set).unwrap();
        call += 1;
        assert!(call < 60, "the plan did not stop");
    }
    assert!(set.positions.len() <= 3 * w * h);
}

/// The command line's refusals of the tile grid name the flag at fault (the library's
/// parameter spelled as the flag), before anything is written; a halo without tiles is
/// refused by the library's check (`PlanStart::check_halo`), as Python's `Plan(halo=...)` is.
#[test]
fn bad_tiles_are_refused_naming_the_flag() {
    let dir = common::scratch("tiledplan", "refusals");
    let out_file = dir.join("next.npy");
    let run = |extra: &[&str]| {
        let mut args: Vec<String> = ["plan", "--resolution", "64x48", "--spp", "4", "--state"]
            .map(String::from)
            .to_vec();
        args.push(dir.join("state").to_str().unwrap().into());
        args.push("--out".into());
        args.push(out_file.to_str().unwrap().into());
        args.extend(extra.iter().map(|e| e.to_string()));
        common::rkwave(&args)
    };
    for (extra, flag) in [
        (
            &["--halo", "4"][..],
            "error: --halo is the halo of the tiles of a tiled plan: set --tile with it, or \
             drop --halo",
        ),
        (&["--tile", "0"][..], "--tile"),
        (&["--tile", "49"][..], "--tile"),
        (&["--tile", "16", "--halo", "17"][..], "--halo"),
    ] {
        let out = run(extra);
        assert!(!out.status.success(), "{extra:?}");
        let text = common::text(&out);
        assert!(text.contains(flag), "{extra:?}: {text}");
        assert!(!out_file.exists(), "{extra:?}: positions written");
    }
}

/// `--drop-nonfinite` on a tiled plan is refused (exit 2) by the library's one check
/// (`PlanRound::check_tiled_samples`), naming the flag and `--tile`, on a new plan and on a
/// later call, before anything is read or written.
#[test]
fn drop_nonfinite_is_refused_on_tiles_naming_the_flags() {
    let dir = common::scratch("tiledplan", "nonfinite");
    let s = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let state = dir.join("state");
    let start = |extra: &[&str]| {
        let mut args: Vec<String> = ["plan", "--resolution", "32x32", "--spp", "4", "--tile"]
            .map(String::from)
            .to_vec();
        args.extend(["16".into(), "--state".into(), s(&state), "--out".into()]);
        args.push(s(&dir.join("n0.npy")));
        args.extend(extra.iter().map(|e| e.to_string()));
        args
    };
    let said = "the tiled plan refuses non-finite samples (its rounds do not count dropped \
                samples): do not ask for --drop-nonfinite with a plan on tiles (--tile); remove \
                them from the samples, or plan untiled";
    let first = common::user_error(&start(&["--drop-nonfinite"]));
    assert!(first.contains(&format!("error: {said}\n")), "{first}");
    assert!(!dir.join("n0.npy").exists());
    common::succeeds(&start(&[]));
    let mut set = SampleSet::default();
    common::image_cli::append_rendered(&mut set, &dir.join("n0.npy"), straight_edge);
    write_npy(dir.join("s0.npy"), &set).unwrap();
    let later = common::user_error(&[
        "plan".to_string(),
        "--state".into(),
        s(&state),
        "--samples".into(),
        s(&dir.join("s0.npy")),
        "--out".into(),
        s(&dir.join("n1.npy")),
        "--drop-nonfinite".into(),
    ]);
    assert!(later.contains(&format!("error: {said}\n")), "{later}");
    assert!(!dir.join("n1.npy").exists());
}
