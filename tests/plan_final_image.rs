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

/// The stopping round's fit carried in `final.bin` (`FinalFit::to_bytes`, a mask of the
/// entries on, then their values) gives back every coefficient bit for bit whichever entries
/// are on: pseudo-random patterns over a basis whose size is not a multiple of the mask's
/// 64-bit words, `-0.0` entries kept as on (their bits are not all zero), one to three
/// channels.
#[test]
fn final_fit_bytes_give_back_every_entry() {
    use rkwave::image::adaptive::{TreeFit, TreeFitReport};
    use rkwave::image::plan::FinalFit;
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        state >> 33
    };
    for (n, channels) in [(1, 1), (63, 2), (64, 1), (1000, 3), (4097, 2)] {
        let coefficients: Vec<Vec<f64>> = (0..channels)
            .map(|_| {
                (0..n)
                    .map(|_| match next() % 8 {
                        0 => -0.0,
                        1 | 2 => (next() % 1000) as f64 / 7.0 - 50.0,
                        _ => 0.0,
                    })
                    .collect()
            })
            .collect();
        let fit = FinalFit {
            samples: 3 * n,
            channels,
            fingerprint: next(),
            sigma: 0.5,
            fit: TreeFit {
                coefficients: coefficients.clone(),
                report: TreeFitReport::default(),
            },
            solver_note: None,
        };
        let back = FinalFit::from_bytes(&fit.to_bytes(11), 11, n).unwrap();
        for (a, b) in back.fit.coefficients.iter().zip(&coefficients) {
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(a), bits(b), "n = {n}, {channels} channel(s)");
        }
    }
}
