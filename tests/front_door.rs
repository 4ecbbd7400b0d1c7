//! The image plane's front door through the binary: the failure classes of issue 39 that
//! the library call ([`rkwave::image::job`]) now decides once for the command line and Python
//! (Python's side: `python/tests/test_front_door.py`).

mod common;

use std::time::Duration;

use common::image_cli::{arg, samples_npy};
use common::{rkwave, rkwave_bounded, scratch, text, user_error};
use rkwave::image::job::text::NOTE_WIDTH;

/// The default pixel estimate at the largest resolution is refused by the memory check
/// before its per-pixel statistics are allocated: exit 2 with the estimate, the limit and
/// the flags to change, where the command used to abort allocating `65536^2` pixel counts.
/// (Bounded: an abort or a swap storm fails the test instead of hanging it.)
#[test]
fn the_default_estimate_is_checked_before_it_allocates() {
    let dir = scratch("front-door", "largest");
    let input = samples_npy(&dir.join("s.npy"), 16, 16, 4 * 256, 3);
    let output = dir.join("out.npy");
    for limit in ["8G", "64G"] {
        let args = [
            "--memory-limit",
            limit,
            "reconstruct",
            "--dim",
            "2",
            "--resolution",
            "65536x65536",
            "--input",
            arg(&input),
            "--output",
            arg(&output),
        ];
        let (code, err) =
            rkwave_bounded(&args, Duration::from_secs(60)).expect("refused at once, not hung");
        assert_eq!(code, 2, "{err}");
        assert!(err.contains("above the limit"), "{err}");
        assert!(err.contains("--pixels auto"), "{err}");
        assert!(err.contains("--resolution"), "{err}");
        assert!(
            !err.contains("ImageParams"),
            "a library path in a flag's place: {err}"
        );
        assert!(!output.exists());
    }
}

/// Every `note:` line of the text output fits [`NOTE_WIDTH`] characters: a fit-only flag
/// given without `--pixels` (the longest decision note) with dropped non-finite samples.
#[test]
fn notes_are_wrapped_at_a_readable_width() {
    let dir = scratch("front-door", "notes");
    let input = samples_npy(&dir.join("s.npy"), 16, 16, 4 * 256, 1);
    let output = dir.join("out.npy");
    let args = [
        "reconstruct",
        "--dim",
        "2",
        "--resolution",
        "16x16",
        "--input",
        arg(&input),
        "--output",
        arg(&output),
        "--p",
        "2",
        "--rho",
        "4",
        "--smoothing",
        "0",
    ];
    let out = rkwave(&args);
    let all = text(&out);
    assert!(out.status.success(), "{all}");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("note: pixels: the least-squares fit"),
        "{stdout}"
    );
    // A note's lines: its `note:` line and the continuation lines indented under it.
    let mut in_note = false;
    for line in stdout.lines() {
        in_note = line.starts_with("note: ") || (in_note && line.starts_with("      "));
        if in_note {
            assert!(
                line.chars().count() <= NOTE_WIDTH,
                "{} chars: {line}",
                line.len()
            );
        }
    }
    // Unwrapped, the note says which flags made the fit the default.
    let joined = stdout.split_whitespace().collect::<Vec<_>>().join(" ");
    assert!(
        joined.contains("because --p, --rho, --smoothing (read by the fit only)"),
        "{joined}"
    );
}

/// Parameter ranges are the library's, named as flags: each refusal names the flag given.
#[test]
fn ranges_are_refused_by_flag() {
    let dir = scratch("front-door", "ranges");
    let input = samples_npy(&dir.join("s.npy"), 16, 16, 4 * 256, 1);
    let output = dir.join("out.npy");
    for (flag, value) in [
        ("--p", "7"),
        ("--rho", "0"),
        ("--ridge", "1"),
        ("--smoothing", "-1"),
    ] {
        let mut args = vec![
            "reconstruct".to_string(),
            "--dim".into(),
            "2".into(),
            "--resolution".into(),
            "16x16".into(),
            "--input".into(),
            arg(&input).into(),
            "--output".into(),
            arg(&output).into(),
        ];
        args.push(format!("{flag}={value}"));
        let err = user_error(&args);
        assert!(err.contains(&format!("{flag} {value}")), "{flag}: {err}");
        assert!(!err.contains("::"), "{flag}: {err}");
    }
}
