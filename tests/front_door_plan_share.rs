//! The plan's pixel share at the front door (`PlanOptions::pixel_share`, the refiner's
//! `GrowthParams::pixel_share`): the tiled plan refuses it at both of its entries (a new plan,
//! a later call) with one message, spelled in the library's terms here and as flags by the
//! command line; the untiled plan says each round how many of its next positions the share
//! placed (`PlanRound::notes`), so the share is never a silent decision. Python's side:
//! `python/tests/test_front_door_plan.py`.

mod common;

use rkwave::error::{ErrorKind, Fix, Param};
use rkwave::image::adaptive::AdaptiveParams;
use rkwave::image::job::tiled_plan::{TiledPlanOptions, TiledPlanStart};
use rkwave::image::job::{PlanBudget, PlanOptions, PlanRound, PlanStart};
use rkwave::image::{DroppedSamples, ImagePlane};

use common::image_cli::{arg, plan_start};
use common::rendered::Rendered;
use common::scenes::HalfNoisy;
use common::{scratch, succeeds, user_error};

/// The noisy half of the plane: deviation 0.1 on `x < 16` (`tests/plan_pixel_share.rs`'s).
const HALF_NOISY: HalfNoisy = HalfNoisy {
    sigma: 0.1,
    seed: 5,
};

fn options(spp: usize, share: Option<f64>) -> PlanOptions {
    PlanOptions {
        budget: Some(PlanBudget::PerPixel(spp)),
        pixel_share: share,
        ..PlanOptions::default()
    }
}

/// The message of the command line's `error: ...` line in `text`.
fn error_line(text: &str) -> String {
    let lines: Vec<&str> = text.lines().filter(|l| l.starts_with("error: ")).collect();
    assert_eq!(lines.len(), 1, "{text}");
    lines[0]["error: ".len()..].to_string()
}

fn tiles() -> TiledPlanOptions {
    TiledPlanOptions {
        tile: 16,
        halo: None,
        workers: Some(1),
    }
}

/// A new tiled plan with a pixel share `q > 0` is refused (kind `InvalidInput`) naming the
/// share and the tile as the library spells them; `q = 0` (the default, the plan without a
/// share) is accepted; a share out of its range is refused by its range first. A later call
/// on a tiled plan that gives a share is refused with the same message.
#[test]
fn the_tiled_plan_refuses_a_pixel_share_at_both_entries() {
    let plane = ImagePlane::new(32, 32).unwrap();
    let refused = TiledPlanStart::new(plane, &options(4, Some(0.5)), &tiles())
        .expect_err("a tiled plan with a pixel share is refused");
    assert_eq!(refused.kind(), ErrorKind::InvalidInput);
    let message = refused.to_string();
    let (share, tile) = (Fix::Set(Param::PixelShare), Fix::Set(Param::Tile));
    assert!(
        message.starts_with(&format!("{share} is not available with the tiled plan"))
            && message.ends_with(&format!(": drop {share} or {tile}")),
        "{message}"
    );
    // the range of the share is checked first: a share of 1.5 is out of range on any plan
    let range = TiledPlanStart::new(plane, &options(4, Some(1.5)), &tiles())
        .expect_err("out of range")
        .to_string();
    assert!(
        range.contains("pixel_share") && !range.contains("tiled plan"),
        "{range}"
    );
    // without a share (given as 0, or not given) the tiled plan starts
    let start = TiledPlanStart::new(plane, &options(4, Some(0.0)), &tiles()).unwrap();
    assert_eq!(start.params().growth.pixel_share, 0.0);
    let (state, _) = start.run(1).unwrap();
    assert!(state.check_options(None, &options(4, None)).is_ok());
    let later = state
        .check_options(
            None,
            &PlanOptions {
                pixel_share: Some(0.5),
                ..PlanOptions::default()
            },
        )
        .expect_err("a later call with a share is refused");
    assert_eq!(later.to_string(), message);
    // the untiled plan takes the same options
    assert!(PlanStart::new(plane, &options(4, Some(0.5))).is_ok());
}

/// The command line refuses `--pixel-share` with `--tile` (exit 2) before anything is
/// written, naming both flags, and a later call on a tiled plan with `--pixel-share` with the
/// same words; `--pixel-share 0` is the plan without a share and is taken.
#[test]
fn plan_tile_with_pixel_share_is_refused_by_the_command_line() {
    let dir = scratch("front-door-plan-share", "cli");
    let state = dir.join("state");
    let start = |extra: &[&str]| {
        let mut args = plan_start("32x32", "4", &state, &dir.join("n0.npy"));
        args.extend(extra.iter().map(|s| s.to_string()));
        args
    };
    let e = error_line(&user_error(&start(&[
        "--tile",
        "16",
        "--pixel-share",
        "0.5",
    ])));
    assert_eq!(
        e,
        "--pixel-share is not available with the tiled plan (its tiles would give the pixels a \
         share the rounds do not report, and the tiled plan would no longer follow the untiled \
         one): drop --pixel-share or --tile"
    );
    assert!(!dir.join("n0.npy").exists() && !state.exists());
    succeeds(&start(&["--tile", "16", "--pixel-share", "0"]));
    let base = rkwave::io::read_npy(dir.join("n0.npy")).unwrap();
    let value = vec![0.5; base.positions.len()];
    let set =
        rkwave::io::SampleSet::new(base.positions.clone(), vec![base.values[0].clone(), value])
            .unwrap();
    rkwave::io::write_npy(dir.join("s0.npy"), &set).unwrap();
    let later = error_line(&user_error(&[
        "plan",
        "--state",
        arg(&state),
        "--samples",
        arg(&dir.join("s0.npy")),
        "--out",
        arg(&dir.join("n1.npy")),
        "--pixel-share",
        "0.5",
    ]));
    assert_eq!(later, e);
    assert!(!dir.join("n1.npy").exists());
}

/// Each round of an untiled plan with a pixel share says how many of its next positions the
/// share placed, that count being the round's log (`pixel_spread`, also in `--json` and
/// Python's report); on a power-of-two plane whose left half is noisy it places some at 4
/// samples a pixel. On a plane whose base slots are not the pixels (24 x 20), or above the
/// share's budget cut (8 samples a pixel), the share places none and the note says so; without
/// a share no note speaks of one.
#[test]
fn each_round_says_what_the_pixel_share_placed() {
    // The share applies at budgets of at most `SHARE_MAX_SPP` (4) samples a pixel: at 8 it
    // places none on the plane where it places some at 4.
    let cases = [
        (32, 32, 4, Some(0.5)),
        (24, 20, 4, Some(0.5)),
        (32, 32, 4, None),
        (32, 32, 8, Some(0.5)),
    ];
    for (w, h, spp, share) in cases {
        let plane = ImagePlane::new(w, h).unwrap();
        let start = PlanStart::new(plane, &options(spp, share)).unwrap();
        let params: AdaptiveParams = *start.params();
        let (mut state, base) = start.run().unwrap();
        let mut r = Rendered::default();
        r.render(&HALF_NOISY, &base);
        let (mut placed, mut rounds) = (0, 0);
        loop {
            let round = PlanRound::new(&mut state, None, &PlanOptions::default()).unwrap();
            let step = round
                .run(&r.samples(plane), DroppedSamples::default())
                .unwrap();
            let notes = PlanRound::notes(&params, &step);
            let said: Vec<&String> = notes.iter().filter(|n| n.contains("pixel share")).collect();
            if step.stop.is_some() {
                assert!(said.is_empty(), "no next positions, no share: {notes:?}");
                break;
            }
            rounds += 1;
            match share {
                None => assert!(said.is_empty(), "{notes:?}"),
                Some(q) => {
                    assert_eq!(said.len(), 1, "{notes:?}");
                    let n = step.log.pixel_spread;
                    let expected = if n == 0 {
                        format!("pixel share {q}: none of the {} next", step.next_positions)
                    } else {
                        format!("pixel share {q}: {n} of the {} next", step.next_positions)
                    };
                    assert!(said[0].starts_with(&expected), "{}", said[0]);
                    placed += n;
                }
            }
            r.render(&HALF_NOISY, &step.next);
            assert!(rounds < 100, "the plan did not stop");
        }
        assert!(rounds > 1, "{w}x{h}: {rounds} rounds");
        match (w, spp, share) {
            (32, 4, Some(_)) => assert!(placed > 0, "the share placed nothing on 32x32"),
            _ => assert_eq!(placed, 0, "{w}x{h} {spp} spp {share:?}"),
        }
    }
}
