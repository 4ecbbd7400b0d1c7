//! The plan's front door through the binary: `rkwave plan` and `rkwave reconstruct --dim 2
//! --state` call the library's plan jobs ([`rkwave::image::job`]: start, round, final image)
//! and only parse and print. Python's side: `python/tests/test_front_door.py`.

mod common;

use std::path::Path;
use std::time::Duration;

use common::image_cli::{arg, plan_start, plan_to_stop};
use common::{rkwave_bounded, scratch, succeeds, user_error};

/// A new plan's arguments on 16x16 at 4 spp, writing into `dir`, with `extra` flags.
fn start_args(dir: &Path, extra: &[String]) -> Vec<String> {
    let mut args = plan_start("16x16", "4", &dir.join("state"), &dir.join("n0.npy"));
    args.extend(extra.iter().cloned());
    args
}

/// Each range of a new plan is refused with exit 2, the parameter named as the command line
/// spells it (the library's range of `p` names `--p`; the refiner's ranges name the
/// parameter itself, `rho = 0.5 is invalid`), and no state is written.
#[test]
fn plan_ranges_are_refused_before_a_state_is_written() {
    let dir = scratch("front-door-plan", "ranges");
    for (flag, value, said) in [
        ("--p", "7", "--p 7"),
        ("--rho", "0.5", "rho = 0.5"),
        ("--false-alarm", "2", "false_alarm = 2"),
        ("--below-pixel", "9", "below_pixel = 9"),
        ("--min-growth", "-1", "min_growth"),
    ] {
        let e = user_error(&start_args(&dir, &[format!("{flag}={value}")]));
        assert!(e.contains(said), "{flag}: {e}");
        assert!(!e.contains("::"), "a library path in a flag's place: {e}");
        assert!(!dir.join("state").join("state.json").exists(), "{flag}");
    }
    // a new plan without a budget: the library names the parameter, as the flag here
    let e = user_error(&[
        "plan",
        "--resolution",
        "16x16",
        "--state",
        arg(&dir.join("state")),
        "--out",
        arg(&dir.join("n0.npy")),
    ]);
    assert!(
        e.contains("a new plan needs a sample budget: set --budget"),
        "{e}"
    );
}

/// A plan whose basis at the depth limit cannot be held is refused from the sizes alone,
/// before the basis is built: exit 2 naming the estimate, the limit and the flags to change,
/// where the start used to abort allocating the tree's flags of a 65536² image. (Bounded: an
/// abort or a swap storm fails the test instead of hanging it.)
#[test]
fn a_plan_too_large_is_refused_before_it_allocates() {
    let dir = scratch("front-door-plan", "largest");
    let out = dir.join("n0.npy");
    let state = dir.join("state");
    let args = [
        "--memory-limit",
        "8G",
        "plan",
        "--resolution",
        "65536x65536",
        "--budget",
        "100000",
        "--state",
        arg(&state),
        "--out",
        arg(&out),
    ];
    let (code, err) =
        rkwave_bounded(&args, Duration::from_secs(60)).expect("refused at once, not hung");
    assert_eq!(code, 2, "{err}");
    for said in [
        "would need about",
        "above the limit",
        "--budget",
        "--below-pixel",
    ] {
        assert!(err.contains(said), "{said}: {err}");
    }
    assert!(!out.exists());
    assert!(!dir.join("state").join("state.json").exists());
}

/// Runs a 24x20 plan at 4 spp to its stop with `--final-image` (`plan_to_stop`), the first
/// call with `flags`; returns the state folder, the last samples and the text of the stopping
/// call.
fn stopped_plan(name: &str, flags: &[&str]) -> (common::Scratch, std::path::PathBuf, String) {
    let d = scratch("front-door-plan", name);
    let (samples, text) = plan_to_stop(&d, flags);
    (d, samples, text)
}

/// `plan --final-image` and `reconstruct --dim 2 --state` are the same library call: the
/// same pixels bit for bit under the plan's default solver (PCG) and under the direct one,
/// and the stopping call, having written the image, does not send the user to the other.
#[test]
fn the_final_image_is_one_library_call() {
    for (name, flags) in [("pcg", &[][..]), ("direct", &["--solver", "direct"][..])] {
        let (d, samples, text) = stopped_plan(name, flags);
        assert!(text.contains("wrote the final image"), "{name}: {text}");
        assert!(!text.contains("reconstruct"), "{name}: {text}");
        let again = d.join("again.npy");
        succeeds(&[
            "reconstruct",
            "--dim",
            "2",
            "--state",
            arg(&d),
            "--input",
            arg(&samples),
            "--output",
            arg(&again),
        ]);
        assert_eq!(
            std::fs::read(d.join("final.npy")).unwrap(),
            std::fs::read(&again).unwrap(),
            "{name}: the two final images differ"
        );
    }
}

/// The uniform path's parameters are refused with a plan's state, naming the flag and
/// `--state`; the plan's image size is checked.
#[test]
fn the_final_image_refuses_the_uniform_parameters() {
    let (d, samples, _) = stopped_plan("refusals", &[]);
    let base = |extra: &[&str]| {
        let mut args: Vec<String> = [
            "reconstruct",
            "--dim",
            "2",
            "--state",
            arg(&d),
            "--input",
            arg(&samples),
            "--output",
            arg(&d.join("o.npy")),
        ]
        .map(String::from)
        .to_vec();
        args.extend(extra.iter().map(|s| s.to_string()));
        args
    };
    for (flag, value) in [
        ("--pixels", "box"),
        ("--rho", "4"),
        ("--ridge", "0.1"),
        ("--smoothing", "1"),
        ("--tile", "16"),
    ] {
        let e = user_error(&base(&[flag, value]));
        assert!(e.contains(flag) && e.contains("--state"), "{flag}: {e}");
    }
    let e = user_error(&base(&["--resolution", "32x32"]));
    assert!(e.contains("the plan is for 24x20"), "{e}");
    assert!(!d.join("o.npy").exists());
}

/// A folder that holds a plan (its state file, or another kind's, e.g. the tiled plan's)
/// refuses a new one through the one library check, `PlanState::check_new`, whose fixes are
/// parameters in the library's words (the command line spells them as flags:
/// `image_adaptive_protocol`); `overwrite` lets the new plan in.
#[test]
fn a_folder_holding_a_plan_refuses_a_new_one() {
    use rkwave::error::ErrorKind;
    use rkwave::image::plan::{PlanState, ProtocolError};
    let dir = scratch("front-door-plan", "holds");
    let state = dir.join("state");
    std::fs::create_dir_all(&state).expect("scratch folder");
    let tiled = state.join("tiled-state.json");
    assert!(PlanState::check_new(&state, std::slice::from_ref(&tiled), false).is_ok());
    for file in [PlanState::path(&state), tiled.clone()] {
        std::fs::write(&file, "{}").expect("scratch file");
        let e = PlanState::check_new(&state, std::slice::from_ref(&tiled), false)
            .expect_err("a folder with a plan refuses a new one");
        assert!(matches!(e, ProtocolError::HoldsPlan { .. }), "{e}");
        assert_eq!(e.kind(), ErrorKind::InvalidInput);
        let text = e.to_string();
        assert!(
            text.contains("holds a plan already") && text.contains("(overwrite)"),
            "{text}"
        );
        assert!(
            !text.contains("--"),
            "a library message names no flag: {text}"
        );
        assert!(PlanState::check_new(&state, std::slice::from_ref(&tiled), true).is_ok());
        std::fs::remove_file(&file).expect("scratch file");
    }
}
