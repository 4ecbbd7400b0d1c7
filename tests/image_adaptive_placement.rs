//! Where the adaptive image refiner puts its samples: the per-slot continued Sobol pattern
//! (stratification of every batch and of their union, continuation equal to one draw) and the
//! uncertainty spread rule (a noisy flat region is sampled more densely, a noise-free flat
//! one is not; the budget is spent exactly).

use rkwave::adaptive::marking::SpreadRule;
use rkwave::adaptive::Cell;
use rkwave::image::adaptive::{
    refine_image, slot_sobol, AdaptiveParams, GrowthParams, ImageOracle, ImageSampling,
    PositionPattern, SamplePositions, StopParams,
};
use rkwave::image::ImagePlane;
use rkwave::refine::StopReason;

mod common;
use common::nets::is_net;
use common::scenes::HalfNoisy;

fn slice(p: &SamplePositions, a: usize, b: usize) -> SamplePositions {
    SamplePositions {
        xs: p.xs[a..b].to_vec(),
        ys: p.ys[a..b].to_vec(),
    }
}

/// A slot's sequence in a non-square rectangle: the first 2, 4, ..., 64 points are a
/// `(0, m, 2)`-net (one point in every elementary interval of the rectangle: a property of
/// the (0, 2)-sequence that Owen scrambling keeps), and so is every batch that is an aligned
/// block of `2^k` indices (4..8, 8..16, 16..32, 32..64, 48..64) — the batches later rounds
/// add. Drawn in batches of 3, 5, 11 and 45 points the positions are those of one draw of 64,
/// bit for bit (continuation across calls is one long call). Another cell or seed gives
/// other points.
#[test]
fn a_slot_sequence_is_a_net_in_every_aligned_batch_and_continues() {
    let rect = [2.0, 6.0, 1.0, 3.0];
    let cell = Cell {
        step: 3,
        kx: 5,
        ky: 2,
    };
    let all = slot_sobol(7, cell, rect, 0, 64);
    for m in 1..=6 {
        assert!(is_net(&slice(&all, 0, 1 << m), rect, m), "prefix 2^{m}");
    }
    for (a, b) in [
        (4usize, 8usize),
        (8, 16),
        (16, 32),
        (32, 64),
        (48, 64),
        (60, 64),
    ] {
        let m = (b - a).trailing_zeros();
        assert!(is_net(&slice(&all, a, b), rect, m), "batch {a}..{b}");
    }
    let mut parts = SamplePositions::default();
    let mut start = 0;
    for n in [3, 5, 11, 45] {
        let part = slot_sobol(7, cell, rect, start, n);
        parts.xs.extend(part.xs);
        parts.ys.extend(part.ys);
        start += n;
    }
    assert_eq!(parts, all);
    assert!(all
        .xs
        .iter()
        .zip(&all.ys)
        .all(|(x, y)| (2.0..=6.0).contains(x) && (1.0..=3.0).contains(y)));
    assert_ne!(slot_sobol(8, cell, rect, 0, 4), slice(&all, 0, 4));
    let other = Cell { kx: 6, ..cell };
    assert_ne!(slot_sobol(7, other, rect, 0, 4), slice(&all, 0, 4));
}

/// The base positions of a plan under the Sobol pattern: each base slot holds `ceil(rho) = 4`
/// of them, a `(0, 2, 2)`-net of the slot (one point in each quadrant, each 1/4-column and
/// each 1/4-row).
#[test]
fn base_positions_are_a_net_in_every_slot() {
    let plane = ImagePlane::new(32, 32).unwrap();
    let params = AdaptiveParams {
        tree: rkwave::adaptive::TreeParams { p: 2, rho: 4.0 },
        stop: StopParams {
            budget: 8 * plane.pixels(),
            ..AdaptiveParams::default().stop
        },
        ..AdaptiveParams::default()
    };
    assert_eq!(params.sampling.pattern, PositionPattern::Sobol);
    let plan = rkwave::image::adaptive::ImagePlan::new(plane, &params).unwrap();
    let base = plan.base_positions();
    let tree = plan.tree();
    let slots = tree.leaves();
    assert_eq!(base.len(), 4 * slots.len());
    for slot in slots {
        let rect = tree.rect(slot);
        let inside = |i: usize| tree.leaf_at(base.xs[i], base.ys[i]) == slot;
        let idx: Vec<usize> = (0..base.len()).filter(|&i| inside(i)).collect();
        let p = SamplePositions {
            xs: idx.iter().map(|&i| base.xs[i]).collect(),
            ys: idx.iter().map(|&i| base.ys[i]).collect(),
        };
        assert!(is_net(&p, rect, 2), "slot {slot:?}");
    }
}

/// The noisy half of the plane: deviation 0.05 on `x < 16`.
const HALF_NOISY: HalfNoisy = HalfNoisy {
    sigma: 0.05,
    seed: 11,
};

fn params(budget: usize, spread: SpreadRule, pattern: PositionPattern) -> AdaptiveParams {
    let d = AdaptiveParams::default();
    AdaptiveParams {
        growth: GrowthParams { spread, ..d.growth },
        sampling: ImageSampling {
            pattern,
            ..d.sampling
        },
        stop: StopParams { budget, ..d.stop },
        ..d
    }
}

/// Samples in the noisy half (`x < 16`) and in the noise-free band `x >= 20` (away from the
/// middle, where functions whose support crosses it carry some of the left's noise).
fn halves(xs: &[f64]) -> (usize, usize) {
    let left = xs.iter().filter(|&&x| x < 16.0).count();
    let right = xs.iter().filter(|&&x| x >= 20.0).count();
    (left, right)
}

/// Under the uncertainty rule the refiner spends the budget on the noisy flat half, where the
/// mean of a slot is uncertain (the spread of its residuals), and none beyond the base on the
/// noise-free band `x >= 20`, whose residuals vanish (0.5 is in the fit's space: its residuals
/// are the round-off of a fit that also carries the left's noise, orders below `0.05`; the
/// weights follow, so the band may get a few samples of their share: 2 % of its base, 2 per
/// pixel, is allowed). The indicator rule densifies both halves alike. The budget is spent
/// exactly, by both patterns.
#[test]
fn the_uncertainty_rule_samples_noise_not_flat_regions() {
    let plane = ImagePlane::new(32, 32).unwrap();
    let budget = 8 * plane.pixels() + 5;
    for pattern in PositionPattern::ALL {
        let run = refine_image(
            &HALF_NOISY,
            plane,
            &params(budget, SpreadRule::Uncertainty, pattern),
        )
        .unwrap();
        let base = run.report.base_samples;
        assert_eq!(base, 2 * plane.pixels());
        let (left, right) = halves(&run.xs);
        let what = format!("{pattern}: {left} left, {right} right, base {base}");
        assert_eq!(run.xs.len(), budget, "{what}");
        assert_eq!(run.report.stop, StopReason::Budget, "{what}");
        assert!(
            right as f64 <= 1.02 * (2 * 12 * 32) as f64,
            "{what}: the noise-free half sampled beyond its base"
        );
        assert!(left >= 5 * right, "{what}");
        let ind = refine_image(
            &HALF_NOISY,
            plane,
            &params(budget, SpreadRule::Indicator, pattern),
        )
        .unwrap();
        let (l, r) = halves(&ind.xs);
        assert!(
            r > 2 * right && l < left,
            "{pattern}: indicator {l} left, {r} right"
        );
    }
}

/// The uncertainty rule spends the budget exactly on noise-free scenes too (an edge, and a
/// chirp whose detail reaches the depth limit: the tree stops deepening and the rule keeps
/// densifying instead of stopping at the depth limit), every sampling round adding samples.
#[test]
fn the_uncertainty_rule_spends_the_budget_exactly() {
    let plane = ImagePlane::new(32, 32).unwrap();
    let chirp = |x: f64, y: f64| 0.5 + 0.4 * ((x * x + y * y) * 0.09).sin();
    let edge = |x: f64, y: f64| if x < 0.37 * 32.0 + 0.2 * y { 0.2 } else { 0.9 };
    let scenes: [(&str, &dyn ImageOracle); 2] = [("chirp", &chirp), ("edge", &edge)];
    for (name, scene) in scenes {
        for budget in [4 * 1024, 8 * 1024 + 3] {
            let p = params(budget, SpreadRule::Uncertainty, PositionPattern::Sobol);
            let run = refine_image(scene, plane, &p).unwrap();
            assert_eq!(run.xs.len(), budget, "{name}, budget {budget}");
            for pair in run.report.rounds.windows(2) {
                assert!(pair[1].samples > pair[0].samples, "{name}: an empty round");
            }
        }
    }
}
