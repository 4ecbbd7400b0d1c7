//! The plan loop without its last refit (issue 28, item 5): the call of `plan` that stops the
//! plan fits every sample on the final tree already, so `plan --final-image` writes the image
//! `reconstruct --dim 2 --state` would compute from the same samples, bit for bit under the
//! direct solve (`--solver direct`; under PCG, the plan's default, the stopping round's fit
//! is continued to the solver's tolerance with the rounds' noise estimate), and the loop saves
//! one fit of every sample.

mod common;

use common::image_cli::{arg, plan_round, plan_start, plan_to_stop, render};
use common::{succeeds, user_error, Scratch};

fn scratch(name: &str) -> Scratch {
    common::scratch("plan-final-image", name)
}

#[test]
fn final_image_is_the_reconstruction_bit_for_bit() {
    let d = scratch("loop");
    let (samples, _) = plan_to_stop(&d, &["--solver", "direct"]);
    let fin = d.join("final.npy");
    let out = d.join("reconstructed.npy");
    succeeds(&[
        "reconstruct",
        "--dim",
        "2",
        "--state",
        arg(&d),
        "--input",
        arg(&samples),
        "--output",
        arg(&out),
    ]);
    assert_eq!(std::fs::read(&fin).unwrap(), std::fs::read(&out).unwrap());
}

#[test]
fn final_image_is_checked_before_the_round() {
    let d = scratch("checked");
    let n0 = d.join("n0.npy");
    succeeds(&plan_start("16x16", "4", &d, &n0));
    let s0 = d.join("s0.npy");
    render(None, &n0, &s0);
    let mut args = plan_round(&d, &s0, &d.join("n1.npy"));
    args.extend(["--final-image".into(), arg(&d.join("image.txt")).into()]);
    let e = user_error(&args);
    assert!(e.contains("--final-image"), "{e}");
    assert!(!d.join("n1.npy").exists(), "a refused call writes nothing");
}
