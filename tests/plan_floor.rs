//! The plan's uniform floor in its first round (issue 38): with `ImageSampling::pixel_floor
//! = f`, the base positions already give every pixel `floor(f N / (W H))` samples, drawn
//! from the pixel's own (0, 2)-sequence where the pixel is a base slot, so no round holds
//! samples back for the floor and none tops pixels up at the end: the rounds are no more
//! than without the floor. (Before, the floor was held back from the rounds and filled at
//! the end: the loop's rounds doubled on the suite, docs/measurements/plan-quality-history.md.)

use rkwave::image::adaptive::{
    pixel_shortfall, refine_image, AdaptiveParams, ImagePlan, SamplePositions,
};
use rkwave::image::ImagePlane;

mod common;
use common::nets::is_net;
use common::scenes::StripesAndDisc;

fn params(budget: usize, floor: f64) -> AdaptiveParams {
    let mut p = AdaptiveParams::default();
    p.stop.budget = budget;
    p.sampling.pixel_floor = floor;
    p
}

/// The first round gives every pixel its floor share: at 16 samples a pixel and floors
/// 0.25, 0.5, 1 (4, 8, 16 samples a pixel), every pixel of a 32 x 32 plane holds exactly that
/// many base positions (the base's two a pixel topped up), and they are a `(0, k, 2)`-net of
/// the pixel (one point in every elementary interval of area `2^-k`, all `k + 1` shapes): the
/// pixel's own (0, 2)-sequence, not jittered strata. On a 30 x 20 plane (base slots are not
/// pixels) every pixel holds at least the floor. Exact counts, no tolerance: a floor left to
/// later rounds, or drawn from another sequence, fails.
#[test]
fn the_first_round_gives_every_pixel_its_floor_share() {
    let plane = ImagePlane::new(32, 32).unwrap();
    for (f, m) in [(0.25, 4usize), (0.5, 8), (1.0, 16)] {
        let plan = ImagePlan::new(plane, &params(16 * plane.pixels(), f)).unwrap();
        assert_eq!(plan.floor(), m, "f = {f}");
        let base = plan.base_positions();
        assert_eq!(
            base.len(),
            m * plane.pixels(),
            "f = {f}: the base is the floor"
        );
        let mut per_pixel = vec![SamplePositions::default(); plane.pixels()];
        for (&x, &y) in base.xs.iter().zip(&base.ys) {
            let (px, py) = plane.pixel_of(x, y);
            let pixel = &mut per_pixel[py * 32 + px];
            pixel.xs.push(x);
            pixel.ys.push(y);
        }
        let k = m.trailing_zeros();
        for (p, pts) in per_pixel.iter().enumerate() {
            let (px, py) = ((p % 32) as f64, (p / 32) as f64);
            assert_eq!(pts.len(), m, "f = {f}, pixel {p}");
            assert!(
                is_net(pts, [px, px + 1.0, py, py + 1.0], k),
                "f = {f}, pixel {p}: not a (0, {k}, 2)-net"
            );
        }
    }
    // base slots that are not the pixels: no floor, and the notes say so
    let plane = ImagePlane::new(30, 20).unwrap();
    let plan = ImagePlan::new(plane, &params(16 * plane.pixels(), 0.5)).unwrap();
    assert_eq!(plan.floor(), 0, "30x20: the base slots are not the pixels");
    let oracle = StripesAndDisc { w: 30.0, h: 20.0 };
    let run = refine_image(&oracle, plane, &params(16 * plane.pixels(), 0.5)).unwrap();
    assert!(
        run.report
            .notes
            .iter()
            .any(|n| n.contains("the base slots are not the pixels")),
        "{:?}",
        run.report.notes
    );
}

/// The floor costs no rounds: on stripes beside a disc (texture the tree cannot follow, so
/// the old floor, held back and filled at the end, added rounds), at 8 and 16 samples a pixel
/// and floors 0.25 to 0.75 above the coverage rule's two samples a pixel, the run with the
/// floor takes no more rounds than without, no round tops pixels up (`filled` 0: the base
/// holds the floor, and with it the coverage rule's count), it spends at most its budget and
/// every pixel ends with at least the floor. Exact counts.
#[test]
fn the_floor_costs_no_rounds() {
    for (w, h) in [(32usize, 32usize)] {
        let plane = ImagePlane::new(w, h).unwrap();
        let oracle = StripesAndDisc {
            w: w as f64,
            h: h as f64,
        };
        for spp in [8usize, 16] {
            let budget = spp * w * h;
            let none = refine_image(&oracle, plane, &params(budget, 0.0)).unwrap();
            for f in [0.25, 0.5, 0.75] {
                let m = (f * spp as f64).floor() as usize;
                if m <= 2 {
                    continue; // the coverage rule's count: no floor (tests/plan_placement.rs)
                }
                let run = refine_image(&oracle, plane, &params(budget, f)).unwrap();
                let at = format!("{w}x{h}, {spp} spp, floor {f}");
                assert!(
                    run.report.rounds.len() <= none.report.rounds.len(),
                    "{at}: {} rounds against {} without the floor",
                    run.report.rounds.len(),
                    none.report.rounds.len()
                );
                assert!(
                    run.report.rounds.iter().all(|r| r.filled == 0),
                    "{at}: a round topped pixels up"
                );
                assert!(run.xs.len() <= budget, "{at}: {} samples", run.xs.len());
                let short = pixel_shortfall(plane, &run.xs, &run.ys, m);
                assert!(short.is_empty(), "{at}: {} pixels below {m}", short.len());
            }
        }
    }
}
