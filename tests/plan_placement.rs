//! Where the plan puts its samples on texture (issue 38): the uniform floor
//! (`ImageSampling::pixel_floor`) holds in every pixel at the end, within the budget, on
//! planes whose sides are powers of two and on others, and the fill that gives it is said in
//! the notes; with no floor the plan is the one before. (The stratification of the draws is
//! checked by the unit tests of the refiner's `positions` and `coverage` modules.)

use rkwave::image::adaptive::{pixel_shortfall, refine_image, AdaptiveParams};
use rkwave::image::ImagePlane;

mod common;
use common::scenes::StripesAndDisc;

fn params(budget: usize, floor: f64) -> AdaptiveParams {
    let mut p = AdaptiveParams::default();
    p.stop.budget = budget;
    p.sampling.pixel_floor = floor;
    p
}

/// At 16 samples a pixel with the floor at half of them, every pixel ends with at least 8
/// samples (exact counts, no tolerance), the plan spends at most its budget, and a round that
/// filled (if any: the rounds may reach the floor themselves) says so in its log and the
/// run's notes. (The check fails if the floor is not held: the reserve or the fill
/// miscounted, or the budget ran out first.)
#[test]
fn the_floor_holds_in_every_pixel() {
    // (30 x 20: base slots that are not the pixels, no floor: the coverage rule's 2 hold)
    for (w, h, m) in [(32usize, 32usize, 8usize), (30, 20, 2)] {
        let plane = ImagePlane::new(w, h).unwrap();
        let oracle = StripesAndDisc {
            w: w as f64,
            h: h as f64,
        };
        let budget = 16 * w * h;
        let run = refine_image(&oracle, plane, &params(budget, 0.5)).unwrap();
        assert!(run.xs.len() <= budget, "{w}x{h}: {} samples", run.xs.len());
        let short = pixel_shortfall(plane, &run.xs, &run.ys, m);
        assert!(
            short.is_empty(),
            "{w}x{h}: {} pixels below the floor of {m}",
            short.len()
        );
        // the rounds may reach the floor themselves (their samples in a pixel below it are
        // paid from the reserve); a round that filled says so
        for r in run.report.rounds.iter().filter(|r| r.filled > 0) {
            let said = r.coverage.as_deref().unwrap_or("");
            assert!(said.contains(&format!("up to {m} samples")), "{said}");
            assert!(run.report.notes.iter().any(|n| n == said));
        }
    }
}

/// A floor no higher than the coverage rule's two samples a pixel changes nothing: the same
/// positions, bit for bit, as no floor (4 samples a pixel, floor 0.5 gives 2).
#[test]
fn a_floor_at_the_coverage_count_changes_nothing() {
    let plane = ImagePlane::new(32, 32).unwrap();
    let oracle = StripesAndDisc { w: 32.0, h: 32.0 };
    let budget = 4 * 32 * 32;
    let a = refine_image(&oracle, plane, &params(budget, 0.5)).unwrap();
    let b = refine_image(&oracle, plane, &params(budget, 0.0)).unwrap();
    assert_eq!(a.xs, b.xs);
    assert_eq!(a.ys, b.ys);
}
