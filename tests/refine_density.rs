//! Trees from sample density (issue 9 item 3): `fit` with automatic levels on samples we did
//! not choose. Clustered samples get a tree whose local depth follows the sample count (every
//! leaf a wavelet creates holds `ceil(rho)` samples), accurate in the clusters and bounded in
//! the gaps, with the gaps reported; uniform samples keep the uniform levels and the
//! single-scale path.

mod common;

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rkwave::basis::{FilterBank, FilterFamily};
use rkwave::kernel::{kernel_matrix, LevelChoice, LevelParams};
use rkwave::reconstruct::{fit, Fallback, FitParams, SolveReport};
use rkwave::refine::density::density_tree;
use rkwave::sampling::{Domain, Layout};
use rkwave::solve::dense_pinv;

/// Named seeds.
const SEED_A: u64 = 11;
const SEED_B: u64 = 12;

const CENTRES: [f64; 3] = [0.2, 0.5, 0.8];
const SIGMA: f64 = 0.03;

/// `m` samples from three normal clusters `N(0.2 / 0.5 / 0.8, 0.03)` (Box–Muller), kept in
/// `[0, 1]`, values `sin(6x)`.
fn clusters(m: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let mut rng = Pcg64::seed_from_u64(seed);
    let mut xs = Vec::with_capacity(m);
    while xs.len() < m {
        let (u, v): (f64, f64) = (rng.random(), rng.random());
        let z = (-2.0 * (1.0 - u).ln()).sqrt() * (std::f64::consts::TAU * v).cos();
        let x = CENTRES[xs.len() % 3] + SIGMA * z;
        if (0.0..=1.0).contains(&x) {
            xs.push(x);
        }
    }
    let ys = xs.iter().map(|x| (6.0 * x).sin()).collect();
    (xs, ys)
}

/// Largest `|f~ - sin(6x)|` on a fine grid, inside the clusters (`|x - c| <= 2 sigma`) and in
/// the gaps (`|x - c| >= 4 sigma` for every centre), and the largest `|f~|` in the gaps.
fn errors(f: &rkwave::reconstruct::Fit) -> (f64, f64, f64) {
    let grid: Vec<f64> = (0..=20_000).map(|i| i as f64 / 20_000.0).collect();
    let v = f.evaluate(&grid).unwrap().swap_remove(0);
    let (mut inside, mut gap, mut gap_value) = (0.0f64, 0.0f64, 0.0f64);
    for (x, y) in grid.iter().zip(&v) {
        assert!(y.is_finite(), "x = {x}");
        let e = (y - (6.0 * x).sin()).abs();
        let d = CENTRES
            .iter()
            .map(|c| (x - c).abs())
            .fold(f64::MAX, f64::min);
        if d <= 2.0 * SIGMA {
            inside = inside.max(e);
        }
        if d >= 4.0 * SIGMA {
            gap = gap.max(e);
            gap_value = gap_value.max(y.abs());
        }
    }
    (inside, gap, gap_value)
}

/// Three clusters of 3,000 samples: the density tree replaces the uniform levels. In the
/// clusters (`|x - c| <= 2 sigma`) the error is at the approximation level of the local depth
/// (measured 3.4e-4, at the flanks where the tree is shallowest; bound 1e-3); in the gaps the reconstruction stays within the data's range `[-1, 1]` plus the
/// interpolation error of the coarse level (bound 0.5 on the error against `sin(6x)`; the
/// uniform levels gave values of `~5e3` there). The coefficients equal the dense SVD
/// solution on the same `K` to `1e-8` (the Cholesky's `cond^2 eps` is small on the tree).
#[test]
fn clustered_samples_are_accurate_in_the_clusters_and_bounded_in_the_gaps() {
    let (xs, ys) = clusters(3000, SEED_A);
    let f = fit(&xs, &[&ys], Domain::UNIT, &FitParams::default()).unwrap();
    let Some(Fallback::DensityTree {
        coarse,
        fine,
        empty,
        ..
    }) = f.fallbacks.first()
    else {
        panic!("no density tree: {:?}", f.fallbacks);
    };
    assert!(fine > coarse);
    assert!(f.warnings()[0].contains("strongly non-uniform"));
    // The two gaps between the clusters (and the ends) hold no sample: reported.
    for (a, b) in [(0.35, 0.36), (0.65, 0.66)] {
        assert!(
            empty.iter().any(|r| r[0] <= a && r[1] >= b),
            "gap around {a}: {empty:?}"
        );
    }
    let (inside, gap, gap_value) = errors(&f);
    assert!(inside < 1e-3, "max error in the clusters {inside:e}");
    assert!(gap < 0.5, "max error in the gaps {gap:e}");
    assert!(gap_value < 1.5, "largest value in the gaps {gap_value:e}");
    // The solve against the dense SVD on the same active set.
    let k = kernel_matrix(&f.active, &xs).unwrap();
    let reference = dense_pinv(&k, 1e-13).unwrap().apply(&ys).unwrap();
    let scale = reference.iter().fold(0.0f64, |m, c| m.max(c.abs()));
    for (a, (x, y)) in f.coefficients[0].iter().zip(&reference).enumerate() {
        assert!(
            (x - y).abs() <= 1e-8 * scale,
            "coefficient {a}: {x} against {y}"
        );
    }
}

/// The tree's local depth is deeper in the clusters than in the gaps, the tree is closed, and
/// it is minimal: every wavelet passes the cell test (`ceil(rho)` samples in every cell of
/// its support one level down) or is an ancestor of one that does.
#[test]
fn the_density_tree_is_closed_minimal_and_deep_where_samples_are() {
    let (xs, _) = clusters(3000, SEED_B);
    let mut sorted = xs.clone();
    sorted.sort_by(f64::total_cmp);
    for per_leaf in [2usize, 3, 5] {
        let bank = FilterBank::shared(3, FilterFamily::cdv_default(3)).unwrap();
        let tree = density_tree(bank, Domain::UNIT, &sorted, per_leaf, 52).unwrap();
        for a in tree.wavelets() {
            let parent = tree.parent(a).unwrap();
            assert!(tree.contains(parent), "parent of {a} missing");
        }
        assert!(tree.local_depth(0.5) >= tree.local_depth(0.35) + 4);
        // Every wavelet passes the cell test or is an ancestor of one that does.
        let count = |level: u32, cell: u64| {
            sorted
                .iter()
                .filter(|&&t| rkwave::refine::cell_of(t, level) == cell)
                .count()
        };
        let passes = |a: usize| {
            let (level, lo, hi) = tree.support(a);
            (2 * lo..=2 * hi + 1).all(|c| count(level + 1, c) >= per_leaf)
        };
        for a in tree.wavelets() {
            let needed = passes(a)
                || tree.wavelets().any(|d| {
                    let mut up = tree.parent(d);
                    while let Some(u) = up.filter(|&u| u >= a) {
                        if u == a {
                            return passes(d);
                        }
                        up = tree.parent(u);
                    }
                    false
                });
            assert!(
                needed,
                "wavelet {a} neither passes nor is an ancestor of one that does"
            );
        }
        assert!(tree.len() * per_leaf <= xs.len() + (1 << tree.coarse()) * per_leaf);
    }
}

/// Uniform, jittered and random samples keep today's automatic levels and the single-scale
/// fast path, with no fallback.
#[test]
fn uniform_samples_keep_uniform_levels_and_the_single_scale_path() {
    for layout in [Layout::Uniform, Layout::Jittered, Layout::Random] {
        for (m, p) in [
            (300usize, 2usize),
            (1000, 3),
            (3000, 3),
            (20_000, 4),
            (5000, 1),
        ] {
            for seed in [SEED_A, SEED_B] {
                let xs = layout.generate(m, Domain::UNIT, seed);
                let ys: Vec<f64> = xs.iter().map(|x| (6.0 * x).sin()).collect();
                let params = FitParams {
                    p,
                    ..FitParams::default()
                };
                let f = fit(&xs, &[&ys], Domain::UNIT, &params).unwrap();
                let auto = LevelChoice::auto(m, p, LevelParams::default());
                assert!(
                    !f.fallbacks
                        .iter()
                        .any(|x| matches!(x, Fallback::DensityTree { .. })),
                    "{layout:?} m = {m} p = {p}: {:?}",
                    f.fallbacks
                );
                if f.fallbacks.is_empty() {
                    assert_eq!(f.levels, auto, "{layout:?} m = {m} p = {p}");
                    assert!(matches!(f.solve, SolveReport::SingleScale(_)));
                }
            }
        }
    }
}

/// Two blocks of samples with nothing in `[0.3, 0.7]`: the gap is reported (its extent, in the
/// library, the text output and the JSON), and the values there stay within the data's range
/// plus the coarse level's interpolation error.
#[test]
fn empty_regions_are_reported_in_text_and_json() {
    let xs: Vec<f64> = (0..2000)
        .map(|i| {
            let u = (i % 1000) as f64 / 1000.0 * 0.3;
            if i < 1000 {
                u
            } else {
                0.7 + u
            }
        })
        .collect();
    let ys: Vec<f64> = xs.iter().map(|x| (6.0 * x).sin()).collect();
    let f = fit(&xs, &[&ys], Domain::UNIT, &FitParams::default()).unwrap();
    let Some(Fallback::DensityTree { empty, .. }) = f.fallbacks.first() else {
        panic!("{:?}", f.fallbacks);
    };
    let gap = empty
        .iter()
        .find(|r| r[0] < 0.31 && r[1] > 0.69)
        .unwrap_or_else(|| panic!("{empty:?}"));
    assert!((gap[0] - 0.2997).abs() < 1e-3 && (gap[1] - 0.7).abs() < 1e-12);
    let mid: Vec<f64> = (0..=100).map(|i| 0.3 + 0.4 * i as f64 / 100.0).collect();
    let v = f.evaluate(&mid).unwrap().swap_remove(0);
    let worst = v.iter().fold(0.0f64, |m, y| m.max(y.abs()));
    assert!(worst < 1.5, "{worst}");

    let dir = common::scratch("density", "gaps");
    let input = dir.join("in.csv");
    let mut body = String::from("x,y\n");
    for (x, y) in xs.iter().zip(&ys) {
        body.push_str(&format!("{x},{y}\n"));
    }
    std::fs::write(&input, body).unwrap();
    let run = |json: bool, name: &str| {
        let out = dir.join(name);
        let mut args = vec![
            "reconstruct".to_string(),
            "--input".into(),
            input.to_str().unwrap().into(),
            "--output".into(),
            out.to_str().unwrap().into(),
            "--levels".into(),
            "auto".into(),
        ];
        if json {
            args.push("--json".into());
        }
        common::succeeds(&args)
    };
    let text = run(false, "a.csv");
    assert!(text.contains("no samples in [0.2997"), "{text}");
    let json = run(true, "b.csv");
    let v: serde_json::Value = serde_json::from_str(&json).expect("one JSON object");
    let fallback = &v["fallbacks"][0]["fallback"];
    assert_eq!(fallback["kind"], "density_tree", "{json}");
    let region = &fallback["empty"][0];
    assert!(region[0].as_f64().unwrap() < 0.31 && region[1].as_f64().unwrap() > 0.69);
}
