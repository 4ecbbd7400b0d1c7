//! The tiled plan's rounds split into bands of tile rows (issue 40, item 4; the seam of
//! `rkwave.dask.TiledPlan`): against the local round, bit for bit, through the bands' tasks
//! serialised as a scheduler sends them; a commit refused with the state unchanged.

mod common;

use rkwave::image::adaptive::{ImageOracle, NoisyOracle, SceneOracle};
use rkwave::image::job::tiled_plan::{
    BandError, BandOutcome, BandTask, BandedRound, FinalBandTask, TiledPlanOptions, TiledPlanStart,
    TiledPlanState,
};
use rkwave::image::job::{PlanBudget, PlanOptions};
use rkwave::image::scene::Scene;
use rkwave::image::{ImagePlane, ImageSamples, PixelImage};

use common::rendered::RenderedChannels;

fn options(spp: usize) -> PlanOptions {
    PlanOptions {
        budget: Some(PlanBudget::PerPixel(spp)),
        ..PlanOptions::default()
    }
}

fn start(plane: ImagePlane, spp: usize, tile: usize, halo: usize) -> TiledPlanStart {
    let tiles = TiledPlanOptions {
        tile,
        halo: Some(halo),
        workers: Some(2),
    };
    TiledPlanStart::new(plane, &options(spp), &tiles).unwrap()
}

/// One band's task run as a remote worker runs it: the task and its outcome through JSON.
fn run_remote(task: &BandTask, samples: &ImageSamples) -> BandOutcome {
    let task: BandTask = serde_json::from_str(&serde_json::to_string(task).unwrap()).unwrap();
    let outcome = task.run(samples).unwrap();
    serde_json::from_str(&serde_json::to_string(&outcome).unwrap()).unwrap()
}

/// The banded final image, the final tasks through JSON.
fn banded_final(state: &TiledPlanState, samples: &ImageSamples, rows: usize) -> PixelImage {
    let tasks = state.final_bands(samples, None, rows, 1).unwrap();
    let strips = tasks
        .iter()
        .rev()
        .map(|(task, s)| {
            let task: FinalBandTask =
                serde_json::from_str(&serde_json::to_string(task).unwrap()).unwrap();
            task.run(s).unwrap()
        })
        .collect();
    state
        .stitch_bands(strips, samples.channels())
        .unwrap()
        .image
}

/// The local tiled plan and the banded one (bands of `rows` tile rows, one tile at a time
/// per task, tasks run in reverse order) in lock step on a noisy analytic scene: every
/// round's positions and the whole state after it equal bit for bit, and the final image
/// too (`f64` compared by bits through `PartialEq` on the exact values; no tolerance: the
/// same function on the same inputs).
fn lock_step(plane: ImagePlane, tile: usize, halo: usize, rows: usize) {
    let scene = Scene::from_file(Scene::builtin_dir().join("shapes.json")).unwrap();
    let clean = SceneOracle {
        scene: &scene,
        plane,
    };
    let oracle = NoisyOracle {
        inner: &clean,
        sigma: 0.05,
        seed: 11,
    };
    let s = start(plane, 6, tile, halo);
    let (mut local, base) = s.run(oracle.channels()).unwrap();
    let mut banded = local.clone();
    let mut r = RenderedChannels::new(oracle.channels());
    r.render(&oracle, &base);
    let mut rounds = 0;
    loop {
        let samples = r.samples(plane);
        let a = local.advance(&samples).unwrap();
        let b = match banded.begin_round(&samples, rows, 1).unwrap() {
            BandedRound::Stopped(step) => step,
            BandedRound::Steps(plan) => {
                assert!(plan.tasks.len() <= plane.height().div_ceil(tile).div_ceil(rows));
                let outcomes = plan.tasks.iter().rev().map(|(t, s)| run_remote(t, s));
                banded.commit_round(&plan, outcomes.collect()).unwrap()
            }
        };
        assert_eq!(a.next, b.next, "round {rounds}");
        assert_eq!(a.stop, b.stop);
        assert_eq!(local, banded, "round {rounds}");
        if a.stop.is_some() {
            break;
        }
        rounds += 1;
        r.render(&oracle, &a.next);
    }
    assert!(rounds >= 2, "{rounds} rounds");
    let samples = r.samples(plane);
    let a = local.final_image(&samples, None).unwrap().image;
    assert_eq!(a, banded_final(&banded, &samples, rows));
}

#[test]
fn bands_of_one_tile_row_give_the_local_plan_bit_for_bit() {
    lock_step(ImagePlane::new(64, 64).unwrap(), 16, 0, 1);
}

#[test]
fn bands_of_two_rows_with_a_halo_and_a_ragged_grid_give_the_local_plan_bit_for_bit() {
    // 80 x 72 in tiles of 16 with halo 4: windows of 32 overlapping their neighbours, the
    // last band of one tile row (5 rows in bands of 2)
    lock_step(ImagePlane::new(80, 72).unwrap(), 16, 4, 2);
}

/// A commit with a band's outcome missing, given twice or of another round is refused and
/// changes nothing; the complete one is then taken.
#[test]
fn a_round_commits_whole_or_not_at_all() {
    let plane = ImagePlane::new(64, 48).unwrap();
    let scene = Scene::from_file(Scene::builtin_dir().join("zone_plate.json")).unwrap();
    let oracle = SceneOracle {
        scene: &scene,
        plane,
    };
    let (mut state, base) = start(plane, 4, 16, 0).run(oracle.channels()).unwrap();
    let mut r = RenderedChannels::new(oracle.channels());
    r.render(&oracle, &base);
    let samples = r.samples(plane);
    let BandedRound::Steps(plan) = state.begin_round(&samples, 1, 1).unwrap() else {
        panic!("the first round stopped");
    };
    let outcomes: Vec<BandOutcome> = plan.tasks.iter().map(|(t, s)| t.run(s).unwrap()).collect();
    assert!(outcomes.len() >= 2);
    let before = state.clone();
    let refused = |e: Result<_, BandError>, what: &str| match e {
        Err(BandError::Foreign { problem, .. }) => {
            assert!(problem.contains(what), "{problem}")
        }
        other => panic!("expected a refusal naming {what:?}, got {other:?}"),
    };
    refused(state.commit_round(&plan, outcomes[1..].to_vec()), "missing");
    assert_eq!(state, before);
    let mut twice = outcomes.clone();
    twice.push(outcomes[0].clone());
    refused(state.commit_round(&plan, twice), "twice");
    assert_eq!(state, before);
    let mut stale = outcomes.clone();
    stale[0].round += 1;
    refused(state.commit_round(&plan, stale), "round");
    assert_eq!(state, before);
    let step = state.commit_round(&plan, outcomes.clone()).unwrap();
    assert!(step.next_positions > 0 && state.round() == 1);
    // the same outcomes again: the plan has moved on, refused, unchanged
    let after = state.clone();
    refused(state.commit_round(&plan, outcomes), "begin the round again");
    assert_eq!(state, after);
}
