//! The pixel share of the plan's rounds (`GrowthParams::pixel_share`, the hybrid of the tree
//! and the pixels' own spread): the budget is spent exactly, the share goes to noisy pixels
//! and not to noise-free ones, and a pixel the tree never deepened holds a prefix of its own
//! (0, 2)-sequence however many rounds added to it; above 4 samples a pixel (the share's
//! budgets) the plan is the tree's alone, sample for sample, and a note says so.

use rkwave::adaptive::Cell;
use rkwave::image::adaptive::{
    refine_image, slot_sobol, AdaptiveImage, AdaptiveParams, GrowthParams, ImageOracle, StopParams,
};
use rkwave::image::ImagePlane;

mod common;
use common::scenes::HalfNoisy;

/// The noisy half of the plane: deviation 0.1 on `x < 16`.
const HALF_NOISY: HalfNoisy = HalfNoisy {
    sigma: 0.1,
    seed: 5,
};

fn run(oracle: &dyn ImageOracle, plane: ImagePlane, budget: usize, share: f64) -> AdaptiveImage {
    let d = AdaptiveParams::renderer_plan();
    let params = AdaptiveParams {
        growth: GrowthParams {
            pixel_share: share,
            ..d.growth
        },
        stop: StopParams { budget, ..d.stop },
        ..d
    };
    refine_image(oracle, plane, &params).unwrap()
}

/// Per pixel (row-major) the positions inside it, relative to the pixel's corner.
fn per_pixel(plane: ImagePlane, xs: &[f64], ys: &[f64]) -> Vec<Vec<(f64, f64)>> {
    let mut out = vec![Vec::new(); plane.pixels()];
    for (&x, &y) in xs.iter().zip(ys) {
        let (px, py) = plane.pixel_of(x, y);
        out[py * plane.width() + px].push((x, y));
    }
    out
}

fn sorted(mut v: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    v.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    v
}

/// On a 32 x 32 plane at 3 and 4 samples a pixel (the share's budgets) with the pixel share at 1: the budget is
/// spent exactly; the rounds give samples to the pixels (the report counts them, a note says
/// so); the noise-free band `x >= 20` (pooled spreads of exactly 0: its samples are all 0.5,
/// and its 3 x 3 pools stay right of `x = 19`) holds no more samples than the same run
/// without the share gives it (the share takes none there, only the tree's marking does);
/// and every pixel the tree never deepened holds exactly the first `n_P` points of its own
/// sequence (`slot_sobol` of the pixel's cell), bit for bit as a set.
#[test]
fn the_pixel_share_follows_the_noise_and_continues_each_pixels_sequence() {
    let plane = ImagePlane::new(32, 32).unwrap();
    for spp in [3usize, 4] {
        let budget = spp * plane.pixels();
        let hybrid = run(&HALF_NOISY, plane, budget, 1.0);
        let tree_only = run(&HALF_NOISY, plane, budget, 0.0);
        let what = format!("{spp} spp");
        assert_eq!(
            hybrid.xs.len(),
            budget,
            "{what}: the budget is spent exactly"
        );
        let by_pixel: usize = hybrid.report.rounds.iter().map(|r| r.pixel_spread).sum();
        assert!(by_pixel > 0, "{what}: no sample went to the pixels");
        assert!(
            hybrid
                .report
                .notes
                .iter()
                .any(|n| n.contains("pixel share")),
            "{what}: the notes do not say so"
        );
        let band = |xs: &[f64]| xs.iter().filter(|&&x| x >= 20.0).count();
        assert!(
            band(&hybrid.xs) <= band(&tree_only.xs),
            "{what}: the noise-free band got {} samples with the share, {} without",
            band(&hybrid.xs),
            band(&tree_only.xs)
        );
        let left = |xs: &[f64]| xs.iter().filter(|&&x| x < 16.0).count();
        assert!(
            left(&hybrid.xs) > left(&tree_only.xs),
            "{what}: the noisy half did not gain samples"
        );
        // the step whose cells are the pixels
        let tree = &hybrid.tree;
        let step = (0..=tree.steps())
            .find(|&s| tree.cell_dims(s) == (32, 32))
            .unwrap();
        let seed = AdaptiveParams::renderer_plan().sampling.seed;
        for (p, pts) in per_pixel(plane, &hybrid.xs, &hybrid.ys)
            .into_iter()
            .enumerate()
        {
            let (px, py) = (p % 32, p / 32);
            let cell = Cell {
                step,
                kx: px,
                ky: py,
            };
            if tree.is_active(cell) {
                continue; // deepened: its children's points
            }
            let (x0, y0) = (px as f64, py as f64);
            let own = slot_sobol(seed, cell, [x0, x0 + 1.0, y0, y0 + 1.0], 0, pts.len());
            let own: Vec<(f64, f64)> = own.xs.into_iter().zip(own.ys).collect();
            assert_eq!(sorted(pts), sorted(own), "{what}: pixel {p}");
        }
    }
}

/// A noise-free flat image: no pixel's samples spread, so the share gives nothing to the
/// pixels and the run is the tree's alone, sample for sample.
#[test]
fn a_flat_noise_free_image_gives_the_pixels_nothing() {
    let plane = ImagePlane::new(32, 32).unwrap();
    let flat = |_: f64, _: f64| 0.25;
    let budget = 8 * plane.pixels();
    let hybrid = run(&flat, plane, budget, 1.0);
    let tree_only = run(&flat, plane, budget, 0.0);
    let by_pixel: usize = hybrid.report.rounds.iter().map(|r| r.pixel_spread).sum();
    assert_eq!(by_pixel, 0);
    assert_eq!(hybrid.xs, tree_only.xs);
    assert_eq!(hybrid.ys, tree_only.ys);
}

/// Above 4 samples a pixel the share does not apply: with the share at 1 the run is the tree's
/// alone, position for position, no round gives the pixels a sample, and a note says why; at 4
/// samples a pixel the same scene's rounds do give the pixels samples (so the cut is where the
/// notes say). On the half-noisy plane, whose noisy half draws the share whenever it applies.
#[test]
fn above_four_samples_a_pixel_the_plan_is_the_trees_alone() {
    let plane = ImagePlane::new(32, 32).unwrap();
    let at = |spp: usize| spp * plane.pixels();
    let by_pixel = |r: &AdaptiveImage| {
        r.report
            .rounds
            .iter()
            .map(|r| r.pixel_spread)
            .sum::<usize>()
    };
    let four = run(&HALF_NOISY, plane, at(4), 1.0);
    assert!(
        by_pixel(&four) > 0,
        "4 spp: the share gave the pixels nothing"
    );
    for budget in [at(4) + 1, at(8), at(16)] {
        let hybrid = run(&HALF_NOISY, plane, budget, 1.0);
        let tree_only = run(&HALF_NOISY, plane, budget, 0.0);
        assert_eq!(by_pixel(&hybrid), 0, "budget {budget}");
        assert_eq!(hybrid.xs, tree_only.xs, "budget {budget}");
        assert_eq!(hybrid.ys, tree_only.ys, "budget {budget}");
        assert!(
            hybrid
                .report
                .notes
                .iter()
                .any(|n| n.contains("above 4 samples a pixel")),
            "budget {budget}: no note says the share is off: {:?}",
            hybrid.report.notes
        );
    }
}

/// Texture past Nyquist: on a 32 x 32 plane, `0.5 + a(x) sin(2 pi (k1 x + k2 y))` with
/// `k1 = 5.37`, `k2 = 3.71` cycles a pixel (far above what half-pixel slots at the depth limit
/// resolve) and an amplitude `a` of 0.4 on `x < 12`, 0.1 on `12 <= x < 22` and 0 beyond (a
/// flat band). Where the tree cannot follow the signal the final image is close to each
/// pixel's mean, of squared error about `s_P^2 / n_P` (`s_P = a / sqrt(2)`, one sample's
/// deviation), and Neyman's allocation above the floor `f` (`n_P = max(f, lambda s_P)`, the
/// mean `n_P` the budget's) minimises `E = mean_P s_P^2 / n_P`. At 4 samples a pixel (the
/// share's budgets, floor 2) with the pixel share at 0.5 and 1: every pixel holds a sample,
/// the plan's counts give `E` within 10 % of that optimum (measured: 1.035 and 1.027 x) and
/// below the tree alone's `E` (1.71 x the optimum, above uniform counts' 1.62 x: the tree's
/// marking is no allocation for the pixel integrals of texture it cannot resolve).
#[test]
fn on_texture_past_nyquist_the_share_follows_neymans_allocation() {
    let plane = ImagePlane::new(32, 32).unwrap();
    let amp = |x: f64| {
        if x < 12.0 {
            0.4
        } else if x < 22.0 {
            0.1
        } else {
            0.0
        }
    };
    let texture = move |x: f64, y: f64| {
        0.5 + amp(x) * (2.0 * std::f64::consts::PI * (5.37 * x + 3.71 * y)).sin()
    };
    let spp = 4usize;
    let budget = spp * plane.pixels();
    // s_P^2 of one sample in each pixel (the amplitude is constant over a pixel)
    let var: Vec<f64> = (0..plane.pixels())
        .map(|p| amp((p % 32) as f64 + 0.5).powi(2) / 2.0)
        .collect();
    let model = |n: &[f64]| var.iter().zip(n).map(|(v, n)| v / n).sum::<f64>() / n.len() as f64;
    // Neyman above the floor: n_P = max(2, lambda s_P) with mean 4 (bisection on lambda)
    let (mut lo, mut hi) = (0.0f64, 1e6f64);
    let at = |l: f64| -> Vec<f64> { var.iter().map(|v| (l * v.sqrt()).max(2.0)).collect() };
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if at(mid).iter().sum::<f64>() < budget as f64 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let optimum = model(&at(lo));
    let uniform = model(&vec![spp as f64; plane.pixels()]);
    assert!(
        (uniform / optimum - 1.62).abs() < 0.01,
        "{}",
        uniform / optimum
    );
    let counts = |r: &AdaptiveImage| {
        let mut n = vec![0.0; plane.pixels()];
        for (&x, &y) in r.xs.iter().zip(&r.ys) {
            let (px, py) = plane.pixel_of(x, y);
            n[py * 32 + px] += 1.0;
        }
        n
    };
    let tree_only = model(&counts(&run(&texture, plane, budget, 0.0)));
    for share in [0.5, 1.0] {
        let r = run(&texture, plane, budget, share);
        let n = counts(&r);
        assert!(
            n.iter().all(|&c| c >= 1.0),
            "share {share}: a pixel without a sample"
        );
        let e = model(&n);
        assert!(
            e <= 1.10 * optimum,
            "share {share}: E {e:.3e} against Neyman's {optimum:.3e}"
        );
        assert!(
            e < tree_only,
            "share {share}: E {e:.3e}, the tree alone {tree_only:.3e}"
        );
    }
}
