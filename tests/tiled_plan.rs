//! The plan on tiles (issue 40, item 2): against the untiled plan on analytic scenes, a
//! state written and read back, refusals. The figures of docs/measurements/scale-out.md come
//! from `examples/tiled_plan_figure.rs`.

mod common;

use rkwave::image::adaptive::{ImageOracle, NoisyOracle, SceneOracle};
use rkwave::image::job::tiled_plan::{
    plan_window, TiledPlanError, TiledPlanOptions, TiledPlanStart, TiledPlanState,
};
use rkwave::image::job::{PlanBudget, PlanFinal, PlanOptions, PlanStart};
use rkwave::image::metrics::{compare, ImageMetrics};
use rkwave::image::plan::ProtocolError;
use rkwave::image::scene::Scene;
use rkwave::image::tiles::TileGeometry;
use rkwave::image::truth::box_truth;
use rkwave::image::{DroppedSamples, ImagePlane, ImageSamples, PixelImage};

use common::rendered::RenderedChannels;

fn options(spp: usize) -> PlanOptions {
    PlanOptions {
        budget: Some(PlanBudget::PerPixel(spp)),
        ..PlanOptions::default()
    }
}

/// The untiled plan to its stop through its jobs; its final image.
fn untiled(oracle: &dyn ImageOracle, plane: ImagePlane, spp: usize) -> PixelImage {
    let (mut state, base) = PlanStart::new(plane, &options(spp)).unwrap().run().unwrap();
    let mut r = RenderedChannels::new(oracle.channels());
    r.render(oracle, &base);
    loop {
        let step = state
            .advance_imaging(&r.samples(plane), DroppedSamples::default(), false)
            .unwrap();
        if step.stop.is_some() {
            break;
        }
        r.render(oracle, &step.next);
    }
    PlanFinal::of(&state, false)
        .run(&r.samples(plane), DroppedSamples::default(), None)
        .unwrap()
        .image
}

/// The tiled plan to its stop; its final image and state.
fn tiled(
    oracle: &dyn ImageOracle,
    plane: ImagePlane,
    spp: usize,
    tile: usize,
    halo: Option<usize>,
) -> (PixelImage, TiledPlanState, usize) {
    let tiles = TiledPlanOptions {
        tile,
        halo,
        workers: Some(2),
    };
    let start = TiledPlanStart::new(plane, &options(spp), &tiles).unwrap();
    let (mut state, base) = start.run(oracle.channels()).unwrap();
    let mut r = RenderedChannels::new(oracle.channels());
    r.render(oracle, &base);
    let mut rounds = 0;
    loop {
        let step = state.advance(&r.samples(plane)).unwrap();
        assert!(step.total_positions <= step.budget, "{step:?}");
        if step.stop.is_some() {
            break;
        }
        rounds += 1;
        r.render(oracle, &step.next);
    }
    let fin = state.final_image(&r.samples(plane), None).unwrap();
    assert!(fin.complete);
    (fin.image, state, rounds)
}

fn scene(name: &str) -> Scene {
    Scene::from_file(Scene::builtin_dir().join(format!("{name}.json"))).unwrap()
}

/// The tiled plan against the untiled plan (issue 40's target: PSNR within 0.2 dB and relMSE
/// within 5 %, relative), on three analytic scenes at 128², 8 spp, noise sigma 0.05 (a
/// renderer's Monte Carlo noise in miniature), tiles of 64 with the tiled plan's default halo
/// (0: each tile's window is its interior, a power of two), both against the scene's box
/// truth (16² strata a pixel); one-sided (the tiled plan may be better). Recorded at the
/// fourteenth session with the windows alone: shapes +0.09 dB, relMSE -2.0 %; slanted_edge
/// -0.08 dB, -9.0 %; zone_plate +0.78 dB, -14.0 %; after that session's merge (one probe
/// channel, the floor in the base of both plans): shapes -0.04 dB, +1.8 %; slanted_edge
/// +0.44 dB, -12.2 %; zone_plate +0.77 dB, -15.6 %. Before (windows of 88 pixels, the uniform tiles' halo 12):
/// shapes -2.65 dB / +29.8 %, slanted_edge -1.95 / +12.0 %, zone_plate -1.05 / +28.0 %.
#[test]
fn tiled_plan_is_within_tolerance_of_the_untiled_plan() {
    let plane = ImagePlane::new(128, 128).unwrap();
    let mut failures = Vec::new();
    for name in ["shapes", "slanted_edge", "zone_plate"] {
        let s = scene(name);
        let clean = SceneOracle { scene: &s, plane };
        let oracle = NoisyOracle {
            inner: &clean,
            sigma: 0.05,
            seed: 7,
        };
        let truth = box_truth(&s, plane, 16);
        let a: ImageMetrics = compare(&untiled(&oracle, plane, 8), &truth);
        let (image, _, _) = tiled(&oracle, plane, 8, 64, None);
        let b = compare(&image, &truth);
        let dpsnr = b.psnr - a.psnr;
        let drel = b.rel_mse / a.rel_mse - 1.0;
        println!(
            "{name}: untiled {:.3} dB relMSE {:.4e}; tiled {:.3} dB relMSE {:.4e}; \
             {dpsnr:+.3} dB, relMSE {:+.2} %",
            a.psnr,
            a.rel_mse,
            b.psnr,
            b.rel_mse,
            100.0 * drel
        );
        // the target: at most 0.2 dB and 5 % relMSE worse than the untiled plan
        let (floor, ceiling) = (-0.2, 0.05);
        if dpsnr < floor || drel > ceiling {
            failures.push(format!(
                "{name}: {dpsnr:+.3} dB, relMSE {:+.2} % (allowed {floor:+.2} dB, {:+.1} %)",
                100.0 * drel,
                100.0 * ceiling
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:?}");
}

/// A tiled plan's state written to JSON and read back gives the identical round: the same
/// next positions and the same state after it, bit for bit (PCG's start is kept as bits).
#[test]
fn a_state_read_back_gives_the_identical_round() {
    let plane = ImagePlane::new(96, 80).unwrap();
    let s = scene("shapes");
    let clean = SceneOracle { scene: &s, plane };
    let oracle = NoisyOracle {
        inner: &clean,
        sigma: 0.05,
        seed: 3,
    };
    let tiles = TiledPlanOptions {
        tile: 32,
        halo: Some(8),
        workers: Some(2),
    };
    let start = TiledPlanStart::new(plane, &options(6), &tiles).unwrap();
    let (mut state, base) = start.run(3).unwrap();
    let mut r = RenderedChannels::new(3);
    r.render(&oracle, &base);
    for _ in 0..3 {
        let step = state.advance(&r.samples(plane)).unwrap();
        assert!(step.stop.is_none());
        r.render(&oracle, &step.next);
    }
    let json = state.to_json();
    let mut back = TiledPlanState::from_json(&json, "state.json".as_ref()).unwrap();
    assert_eq!(back, state);
    let samples = r.samples(plane);
    let a = state.advance(&samples).unwrap();
    let b = back.advance(&samples).unwrap();
    assert_eq!(a.next, b.next);
    assert_eq!(state, back);
    assert!(!a.next.is_empty());
    // and the round is refused once planned, the state unchanged
    let before = state.clone();
    match state.advance(&samples) {
        Err(TiledPlanError::Protocol(ProtocolError::AlreadyPlanned { .. })) => {}
        other => panic!("expected AlreadyPlanned, got {other:?}"),
    }
    assert_eq!(state, before);
    // samples that are not the positions handed out: refused, state unchanged
    let mut moved = r.samples(plane).xs().to_vec();
    moved[0] = (moved[0] + 0.25).min(95.0);
    let forged = ImageSamples::new(
        plane,
        moved,
        samples.ys().to_vec(),
        samples.values().to_vec(),
    )
    .unwrap();
    let mut other = back.clone();
    assert!(matches!(
        other.advance(&forged),
        Err(TiledPlanError::Protocol(ProtocolError::Mismatch { .. }))
    ));
    assert_eq!(other, back);
}

/// Every position handed out lies in exactly one tile's interior, none twice, and the plan
/// spends the budget no more than once.
#[test]
fn positions_are_owned_once_and_the_budget_holds() {
    let plane = ImagePlane::new(100, 72).unwrap();
    let s = scene("zone_plate");
    let oracle = SceneOracle { scene: &s, plane };
    let (_, state, rounds) = tiled(&oracle, plane, 4, 24, Some(6));
    assert!(rounds >= 2, "{rounds} rounds");
    assert!(state.positions() <= 4 * 100 * 72);
}

/// A tile's window (`plan_window`) holds its interior and at least the halo on each side away
/// from the image border, lies inside the image, and is a power of two on each axis unless the
/// image's side is smaller (then it is the whole side); with no halo a power-of-two tile is
/// its own window.
#[test]
fn windows_are_powers_of_two_holding_interior_and_halo() {
    for (w, h, tile, halo) in [
        (128, 128, 64, 0),
        (128, 128, 64, 12),
        (100, 72, 24, 6),
        (1920, 1080, 128, 0),
        (1920, 1080, 104, 12),
        (40, 33, 16, 16),
    ] {
        let g = TileGeometry::new(ImagePlane::new(w, h).unwrap(), tile, halo).unwrap();
        for t in 0..g.count() {
            let (r, win) = (g.interior(t), plan_window(&g, t));
            let what = format!("{w}x{h} tile {tile} halo {halo}: tile {t} {r} window {win}");
            assert!(win.x1 <= w && win.y1 <= h, "{what}");
            assert!(win.x0 <= r.x0.saturating_sub(halo), "{what}");
            assert!(win.y0 <= r.y0.saturating_sub(halo), "{what}");
            assert!(win.x1 >= (r.x1 + halo).min(w), "{what}");
            assert!(win.y1 >= (r.y1 + halo).min(h), "{what}");
            assert!(win.width().is_power_of_two() || win.width() == w, "{what}");
            assert!(
                win.height().is_power_of_two() || win.height() == h,
                "{what}"
            );
            if halo == 0 && r.width() == tile && tile.is_power_of_two() {
                assert_eq!((win.x0, win.x1), (r.x0, r.x1), "{what}");
            }
        }
    }
}

/// Bad grids and workers are refused, naming the parameter.
#[test]
fn bad_tiles_are_refused() {
    let plane = ImagePlane::new(64, 48).unwrap();
    let with = |tile, halo, workers| {
        TiledPlanStart::new(
            plane,
            &options(4),
            &TiledPlanOptions {
                tile,
                halo,
                workers,
            },
        )
    };
    use rkwave::error::Param;
    assert_eq!(with(0, None, None).unwrap_err().param(), Some(Param::Tile));
    assert_eq!(with(49, None, None).unwrap_err().param(), Some(Param::Tile));
    assert_eq!(
        with(16, Some(17), None).unwrap_err().param(),
        Some(Param::Halo)
    );
    assert_eq!(
        with(16, None, Some(0)).unwrap_err().param(),
        Some(Param::Workers)
    );
    assert!(matches!(
        TiledPlanStart::new(
            plane,
            &PlanOptions::default(),
            &TiledPlanOptions {
                tile: 16,
                ..Default::default()
            }
        ),
        Err(TiledPlanError::Job(_))
    ));
}

/// The tiled plan to its stop with each tile's PCG diagonal kept between rounds up to
/// `bound` bytes (`None`: rebuilt every round); its final image, every round's positions and
/// the largest count of tiles kept and over the bound in a round.
fn tiled_keeping(
    oracle: &dyn ImageOracle,
    plane: ImagePlane,
    bound: Option<u64>,
) -> (PixelImage, Vec<Vec<f64>>, usize, usize) {
    let tiles = TiledPlanOptions {
        tile: 64,
        halo: None,
        workers: Some(2),
    };
    let start = TiledPlanStart::new(plane, &options(8), &tiles).unwrap();
    let (mut state, base) = start.run(oracle.channels()).unwrap();
    state.keep_diagonals(bound);
    let mut r = RenderedChannels::new(oracle.channels());
    r.render(oracle, &base);
    let mut rounds = vec![base.xs.clone()];
    let (mut kept, mut over) = (0, 0);
    loop {
        let step = state.advance(&r.samples(plane)).unwrap();
        kept = kept.max(step.diagonals_kept);
        over = over.max(step.diagonals_over);
        if step.stop.is_some() {
            break;
        }
        rounds.push(step.next.xs.clone());
        r.render(oracle, &step.next);
    }
    let fin = state.final_image(&r.samples(plane), None).unwrap();
    (fin.image, rounds, kept, over)
}

/// Keeping each tile's PCG diagonal between rounds (`TiledPlanState::keep_diagonals`)
/// changes only the order of the diagonal's sums: with a bound of 0 nothing is kept and the
/// plan is the rebuilt plan bit for bit; kept, the diagonal preconditions the same systems,
/// each solved to PCG's tolerance, so the plan hands out the same number of positions every
/// round and its final image differs from the rebuilt plan's by at most `1e-9` of the
/// rebuilt plan's own RMS error against the truth (rounding: recorded `3.6e-15` on shapes,
/// `9.6e-16` on zone_plate, with every round's positions identical; the bound leaves six
/// orders for PCG's iterates to amplify the rounding of another machine) and PSNR within
/// `1e-6` dB. 128², 8 spp, noise 0.05, tiles of 64, on two analytic scenes.
#[test]
fn kept_diagonals_change_the_plan_only_by_rounding() {
    let plane = ImagePlane::new(128, 128).unwrap();
    for name in ["shapes", "zone_plate"] {
        let s = scene(name);
        let clean = SceneOracle { scene: &s, plane };
        let oracle = NoisyOracle {
            inner: &clean,
            sigma: 0.05,
            seed: 7,
        };
        let truth = box_truth(&s, plane, 16);
        let (rebuilt, rebuilt_rounds, k0, _) = tiled_keeping(&oracle, plane, None);
        assert_eq!(k0, 0);
        let (zero, zero_rounds, k, over) = tiled_keeping(&oracle, plane, Some(0));
        assert_eq!(
            (k, over > 0),
            (0, true),
            "{name}: a bound of 0 keeps nothing"
        );
        assert_eq!(zero_rounds, rebuilt_rounds, "{name}");
        assert_eq!(
            zero, rebuilt,
            "{name}: nothing kept is the rebuilt plan bit for bit"
        );
        let (kept, kept_rounds, k, over) = tiled_keeping(&oracle, plane, Some(u64::MAX));
        assert_eq!((k, over), (4, 0), "{name}: every tile kept");
        let counts = |r: &[Vec<f64>]| r.iter().map(Vec::len).collect::<Vec<_>>();
        assert_eq!(counts(&kept_rounds), counts(&rebuilt_rounds), "{name}");
        let same = kept_rounds == rebuilt_rounds;
        let (a, b) = (compare(&rebuilt, &truth), compare(&kept, &truth));
        let diff = compare(&kept, &rebuilt);
        let err = |m: &ImageMetrics| m.rmse;
        let ratio = err(&diff) / err(&a);
        println!(
            "{name}: positions identical {same}; kept - rebuilt RMS {:.3e} = {:.3e} of the \
             rebuilt plan's RMS error {:.3e}; PSNR {:.4} vs {:.4} dB",
            err(&diff),
            ratio,
            err(&a),
            b.psnr,
            a.psnr
        );
        assert!(ratio <= 1e-9, "{name}: {ratio:.3e}");
        assert!((b.psnr - a.psnr).abs() <= 1e-6, "{name}");
    }
}
