//! The tensor basis and the 2D solves: identities with justified tolerances.
//!
//! Tolerances: every quantity below is a short sum of products of `O(1)` values (basis values
//! are at most `2^{J/2} (2p)` in size, coefficients `O(1)`), so exact identities hold to a few
//! hundred ulps (`1e-12`); least-squares solutions of consistent data are exact up to
//! `cond(A) eps` with `cond(A) <~ 1e4` for these well-sampled problems (`1e-9`).

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

use rkwave::basis::facts::orthonormality_error;
use rkwave::basis::tensor::{TensorBasis, TensorError};
use rkwave::basis::FilterFamily;
use rkwave::image::fit::{NormalSolver, StencilPreconditioner};
use rkwave::image::{fit_image, ImageFitError, ImageFitParams, ImageLevels};

const SEED: u64 = 0x1a2b_3c4d;

fn basis(p: usize, w: usize, h: usize, levels: (u32, u32)) -> TensorBasis {
    TensorBasis::new(p, FilterFamily::cdv_default(p), w, h, levels).unwrap()
}

/// `spp` uniform samples per pixel plus every corner and samples along the four edges.
fn samples(w: usize, h: usize, spp: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let mut rng = Pcg64::seed_from_u64(seed);
    let (wf, hf) = (w as f64, h as f64);
    let mut xs = Vec::new();
    let mut ys = Vec::new();
    for _ in 0..w * h * spp {
        xs.push(rng.random::<f64>() * wf);
        ys.push(rng.random::<f64>() * hf);
    }
    for (x, y) in [(0.0, 0.0), (wf, 0.0), (0.0, hf), (wf, hf)] {
        xs.push(x);
        ys.push(y);
    }
    for _ in 0..w + h {
        let (t, s) = (rng.random::<f64>(), rng.random::<f64>());
        xs.extend([t * wf, t * wf, 0.0, wf]);
        ys.extend([0.0, hf, s * hf, s * hf]);
    }
    (xs, ys)
}

fn params(p: usize, levels: (u32, u32), solver: NormalSolver) -> ImageFitParams {
    ImageFitParams {
        p,
        family: None,
        levels: ImageLevels::Fixed(levels.0, levels.1),
        solver,
        ridge: 0.0,
        ..ImageFitParams::default()
    }
}

#[test]
fn fwt_round_trip_and_orthogonality() {
    let mut rng = Pcg64::seed_from_u64(SEED);
    for (p, w, h, levels) in [(2, 20, 12, (5, 4)), (3, 16, 40, (5, 6)), (1, 8, 8, (3, 3))] {
        let b = basis(p, w, h, levels);
        let v: Vec<f64> = (0..b.len()).map(|_| rng.random::<f64>() - 0.5).collect();
        let c = b.analysis(&v);
        let back = b.synthesis(&c);
        let err = v
            .iter()
            .zip(&back)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-12, "p = {p}: round trip error {err:e}");
        let (n1, n2) = (
            v.iter().map(|x| x * x).sum::<f64>(),
            c.iter().map(|x| x * x).sum::<f64>(),
        );
        assert!((n1 - n2).abs() < 1e-12 * n1, "p = {p}: norm {n1} -> {n2}");
    }
}

/// The multilevel basis is orthonormal: its Gram matrix is `W (Gx (x) Gy) W^T` with `W` the
/// 2D FWT; `W` is orthogonal (checked column by column on unit vectors) and each axis' single
/// scale Gram deviation is measured exactly by `facts::orthonormality_error` (refinement
/// algebra, no quadrature), so `|G_2D - I| <= ex + ey + ex ey`.
#[test]
fn orthonormality_at_a_small_level() {
    for p in [2, 3] {
        let j = rkwave::basis::minimum_level(p) + 1;
        // 512 (p = 2) and 1024 (p = 3) functions: n^3 / 2 flops for the dot products
        let b = basis(p, 7, 5, (j, j + (p == 2) as u32));
        let n = b.len();
        let columns: Vec<Vec<f64>> = (0..n)
            .map(|k| {
                let mut e = vec![0.0; n];
                e[k] = 1.0;
                b.analysis(&e)
            })
            .collect();
        let mut worst: f64 = 0.0;
        for a in 0..n {
            for c in a..n {
                let dot: f64 = columns[a].iter().zip(&columns[c]).map(|(x, y)| x * y).sum();
                let target = if a == c { 1.0 } else { 0.0 };
                worst = worst.max((dot - target).abs());
            }
        }
        assert!(worst < 1e-12, "p = {p}: W W^T - I = {worst:e}");
        let ex = orthonormality_error(b.scale_x());
        let ey = orthonormality_error(b.scale_y());
        assert!(
            ex + ey + ex * ey < 1e-10,
            "p = {p}: axis Gram errors {ex:e} {ey:e}"
        );
    }
}

/// Synthesis followed by single-scale evaluation equals direct evaluation of the multilevel
/// basis (Mallat layout, from the 1D evaluations of each axis); the unordered row is the
/// sorted one permuted, bit for bit.
#[test]
fn multilevel_evaluation_matches_synthesis() {
    let mut rng = Pcg64::seed_from_u64(SEED + 1);
    for (p, w, h, levels) in [(2, 11, 6, (5, 4)), (3, 9, 9, (5, 6))] {
        let b = basis(p, w, h, levels);
        let c: Vec<f64> = (0..b.len()).map(|_| rng.random::<f64>() - 0.5).collect();
        let single = b.synthesis(&c);
        let mut ev = b.evaluator();
        let mut mev = b.multilevel_evaluator();
        let (mut r1, mut r2) = (Vec::new(), Vec::new());
        for i in 0..400 {
            let (x, y) = if i < 4 {
                ((i % 2) as f64 * w as f64, (i / 2) as f64 * h as f64)
            } else {
                (
                    rng.random::<f64>() * w as f64,
                    rng.random::<f64>() * h as f64,
                )
            };
            ev.eval_into(x, y, &mut r1).unwrap();
            mev.eval_into(x, y, &mut r2).unwrap();
            // the unordered row holds the same entries, bit for bit, each index once
            let mut r3 = Vec::new();
            mev.eval_unordered_into(x, y, &mut r3).unwrap();
            r3.sort_by_key(|v| v.index);
            assert!(r2.windows(2).all(|w| w[0].index < w[1].index));
            assert_eq!(r2.len(), r3.len());
            for (a, b) in r2.iter().zip(&r3) {
                assert_eq!((a.index, a.value.to_bits()), (b.index, b.value.to_bits()));
            }
            let f1: f64 = r1.iter().map(|v| single[v.index] * v.value).sum();
            let f2: f64 = r2.iter().map(|v| c[v.index] * v.value).sum();
            let scale = 1.0 + f1.abs();
            assert!(
                (f1 - f2).abs() < 1e-10 * scale,
                "p = {p} at ({x}, {y}): {f1} vs {f2}"
            );
        }
    }
}

/// Tensor polynomials `t^a s^b`, `a, b < p` (`t = x / W`, `s = y / H`) lie in the space: the
/// least-squares fit of their samples reproduces them everywhere, edges and corners included.
#[test]
fn exact_reconstruction_of_tensor_polynomials() {
    let mut rng = Pcg64::seed_from_u64(SEED + 2);
    for (p, w, h, levels) in [(2, 13, 10, (4, 4)), (3, 24, 34, (5, 5))] {
        let (xs, ys) = samples(w, h, 4, SEED + p as u64);
        let (wf, hf) = (w as f64, h as f64);
        let mut values = Vec::new();
        let mut exps = Vec::new();
        for a in 0..p {
            for bb in 0..p {
                exps.push((a as i32, bb as i32));
                values.push(
                    xs.iter()
                        .zip(&ys)
                        .map(|(x, y)| (x / wf).powi(a as i32) * (y / hf).powi(bb as i32))
                        .collect::<Vec<f64>>(),
                );
            }
        }
        let refs: Vec<&[f64]> = values.iter().map(|v| v.as_slice()).collect();
        let fit = fit_image(
            w,
            h,
            &xs,
            &ys,
            &refs,
            &params(p, levels, NormalSolver::Cholesky),
        )
        .unwrap();
        assert_eq!(fit.report.unsampled, 0);
        assert!(fit.report.pinned.is_none());
        for i in 0..500 {
            let (x, y) = match i {
                0..=3 => ((i % 2) as f64 * wf, (i / 2) as f64 * hf),
                4..=99 => (rng.random::<f64>() * wf, [0.0, hf][i % 2]),
                _ => (rng.random::<f64>() * wf, rng.random::<f64>() * hf),
            };
            let got = fit.evaluate(x, y).unwrap();
            for (c, &(a, bb)) in exps.iter().enumerate() {
                let want = (x / wf).powi(a) * (y / hf).powi(bb);
                assert!(
                    (got[c] - want).abs() < 1e-9,
                    "p = {p}, t^{a} s^{bb} at ({x}, {y}): {} vs {want}",
                    got[c]
                );
            }
        }
    }
}

/// Swapping the axes (samples `(y, x)` on an `H x W` image) transposes the solution.
#[test]
fn axis_swap_symmetry() {
    let (w, h) = (26, 13);
    let (xs, ys) = samples(w, h, 4, SEED + 3);
    let f: Vec<f64> = xs
        .iter()
        .zip(&ys)
        .map(|(x, y)| (0.7 * x).sin() + (x * y * 0.05).cos() + if x > y { 1.0 } else { 0.0 })
        .collect();
    let a = fit_image(
        w,
        h,
        &xs,
        &ys,
        &[&f],
        &params(2, (5, 4), NormalSolver::Cholesky),
    )
    .unwrap();
    let b = fit_image(
        h,
        w,
        &ys,
        &xs,
        &[&f],
        &params(2, (4, 5), NormalSolver::Cholesky),
    )
    .unwrap();
    let (nx, ny) = a.dims();
    for ky in 0..ny {
        for kx in 0..nx {
            let (u, v) = (
                a.coefficients[0][ky * nx + kx],
                b.coefficients[0][kx * ny + ky],
            );
            assert!(
                (u - v).abs() < 1e-9 * (1.0 + u.abs()),
                "({kx}, {ky}): {u} vs {v}"
            );
        }
    }
}

/// Cholesky and CG (every preconditioner, relative residual 1e-12) give the same
/// coefficients; `solve_normal(K^T f)` gives them back too.
#[test]
fn cg_and_cholesky_agree() {
    let (w, h) = (24, 20);
    let (xs, ys) = samples(w, h, 4, SEED + 4);
    let f: Vec<f64> = xs
        .iter()
        .zip(&ys)
        .map(|(x, y)| (0.3 * x + 0.2 * y).sin())
        .collect();
    let g: Vec<f64> = xs
        .iter()
        .map(|x| if *x > 10.3 { 1.0 } else { 0.0 })
        .collect();
    let chol = fit_image(
        w,
        h,
        &xs,
        &ys,
        &[&f, &g],
        &params(2, (5, 4), NormalSolver::Cholesky),
    )
    .unwrap();
    for pre in [
        StencilPreconditioner::None,
        StencilPreconditioner::Jacobi,
        StencilPreconditioner::Local,
    ] {
        let solver = NormalSolver::Cg {
            preconditioner: pre,
            tolerance: 1e-12,
            forward_error: None,
            max_iterations: 10_000,
        };
        let cg = fit_image(w, h, &xs, &ys, &[&f, &g], &params(2, (5, 4), solver)).unwrap();
        let report = cg.report.cg.as_ref().unwrap();
        assert!(report.converged, "{pre:?}: {report:?}");
        for c in 0..2 {
            let err = chol.coefficients[c]
                .iter()
                .zip(&cg.coefficients[c])
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            // residual 1e-12 times cond(G) <~ 1e4 times |z| ~ 10
            assert!(err < 1e-7, "{pre:?} channel {c}: {err:e}");
        }
    }
    // local inversion (rings 0) runs on the 2D kernel matrix: one group per sample pattern
    // (the single-scale cell of a sample), finite coefficients; its accuracy against the global solve is a
    // measured figure (reports), not an identity
    let local = rkwave::solve::LocalInversionParams {
        rings: 0,
        ..Default::default()
    };
    let li = fit_image(
        w,
        h,
        &xs,
        &ys,
        &[&f],
        &params(2, (5, 4), NormalSolver::Local(local)),
    )
    .unwrap();
    let stats = li.report.local.as_ref().unwrap();
    assert!(
        stats.n_patterns > 0 && stats.n_patterns <= li.basis().len(),
        "{}",
        stats.n_patterns
    );
    assert!(li.coefficients[0].iter().all(|v| v.is_finite()));
    // G z = K^T f  <=>  z = coefficients
    let n = chol.basis().len();
    let mut b = vec![0.0; n];
    for (i, (&x, &y)) in xs.iter().zip(&ys).enumerate() {
        for v in chol.sample_row(x, y).unwrap() {
            b[v.index] += v.value * f[i];
        }
    }
    let z = chol.solve_normal(&b).unwrap();
    let err = z
        .iter()
        .zip(&chol.coefficients[0])
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(err < 1e-9, "solve_normal: {err:e}");
}

/// A hole (no sample in a disc) and a sample-free border: detected, reported, finite.
#[test]
fn holes_are_reported_never_nan() {
    let (w, h) = (32, 32);
    let (xs0, ys0) = samples(w, h, 4, SEED + 5);
    let (xs, ys): (Vec<f64>, Vec<f64>) = xs0
        .iter()
        .zip(&ys0)
        .filter(|(x, y)| (*x - 12.0).powi(2) + (*y - 16.0).powi(2) > 36.0 && **x < 28.0)
        .map(|(x, y)| (*x, *y))
        .unzip();
    let f: Vec<f64> = xs.iter().map(|x| x * 0.1).collect();
    let mut prm = params(2, (5, 5), NormalSolver::Cholesky);
    prm.ridge = 1e-9;
    let fit = fit_image(w, h, &xs, &ys, &[&f], &prm).unwrap();
    assert!(fit.report.unsampled > 0, "{:?}", fit.report);
    // The pinned region: one function per 1 x 1 pixel cell at level 5 on 32 pixels, all of
    // them in the hole (x >= 12 - 6) or the sample-free strip x > 28.
    let pin = fit.report.pinned.expect("pinned region reported");
    assert_eq!(pin.area_px, fit.report.unsampled as f64);
    assert_eq!(pin.fraction, fit.report.unsampled as f64 / 1024.0);
    assert!(pin.x.0 >= 6.0 && pin.x.1 <= 32.0, "{pin:?}");
    assert!(fit.coefficients[0].iter().all(|v| v.is_finite()));
    let far = fit.evaluate(31.0, 5.0).unwrap();
    assert!(far[0].is_finite());
    // away from the hole the fit is still the linear function
    let v = fit.evaluate(20.0, 4.0).unwrap()[0];
    assert!((v - 2.0).abs() < 1e-6, "{v}");
}

#[test]
fn bad_input_is_a_typed_error() {
    let xs = [1.0, 2.0, 3.5];
    let ys = [1.0, 2.0, 1.0];
    let f = [1.0, 2.0, 3.0];
    let prm = ImageFitParams::default();
    assert!(matches!(
        fit_image(3, 4, &xs, &ys, &[&f], &prm),
        Err(ImageFitError::SampleOutside { index: 2, .. })
    ));
    assert!(matches!(
        fit_image(0, 4, &xs, &ys, &[&f], &prm),
        Err(ImageFitError::Tensor(TensorError::ZeroResolution {
            axis: "width",
            ..
        }))
    ));
    assert!(matches!(
        fit_image(8, 8, &xs, &ys, &[&[1.0, f64::NAN, 0.0]], &prm),
        Err(ImageFitError::NonFiniteValue { index: 1, .. })
    ));
    assert!(matches!(
        fit_image(8, 8, &xs, &ys, &[&[1.0]], &prm),
        Err(ImageFitError::LengthMismatch { .. })
    ));
    assert!(matches!(
        TensorBasis::new(2, FilterFamily::Extremal, 8, 8, (2, 5)),
        Err(TensorError::LevelOutOfRange { axis: "x", .. })
    ));
    let msg = fit_image(3, 4, &xs, &ys, &[&f], &prm)
        .unwrap_err()
        .to_string();
    assert!(msg.contains("3.5") && msg.contains("outside"), "{msg}");
}

/// `ImageFitParams::family` follows `p` as `FitParams::family` does in 1D (CDV's choice:
/// extremal phase for `p <= 3`, least asymmetric above) unless a family is given, and the fit
/// builds its basis from it.
#[test]
fn image_family_follows_p_unless_given() {
    use rkwave::reconstruct::FitParams;
    for p in 1..=6 {
        let image = ImageFitParams {
            p,
            ..ImageFitParams::default()
        };
        let one_d = FitParams {
            p,
            ..FitParams::default()
        };
        assert_eq!(image.family(), one_d.family(), "p = {p}");
    }
    let (w, h) = (24, 20);
    let (xs, ys) = samples(w, h, 4, SEED + 9);
    let f: Vec<f64> = xs
        .iter()
        .zip(&ys)
        .map(|(x, y)| (0.2 * x).sin() * y)
        .collect();
    let fit_with = |family| {
        let prm = ImageFitParams {
            p: 4,
            family,
            ..ImageFitParams::default()
        };
        fit_image(w, h, &xs, &ys, &[&f], &prm).unwrap()
    };
    let default = fit_with(None);
    assert_eq!(
        default.basis().bank().family(),
        FilterFamily::LeastAsymmetric
    );
    let sym = fit_with(Some(FilterFamily::LeastAsymmetric));
    assert_eq!(default.coefficients, sym.coefficients);
    let db = fit_with(Some(FilterFamily::Extremal));
    assert_eq!(db.basis().bank().family(), FilterFamily::Extremal);
    // A different basis gives different coefficients: the choice reaches the fit.
    assert_ne!(default.coefficients, db.coefficients);
}

/// A hole with the first-difference penalty: the coefficients of a linear function on the
/// interior grid are linear in the index, so the penalty vanishes on them and the harmonic
/// fill of the hole is the same linear function; only functions near the image border (edge
/// functions, other coefficients) feel the small relative weight 1e-3. Without the penalty the
/// hole is pinned to 0. Tolerance 1e-2 on values of size 1: the border bias, measured about
/// 1e-4, decays into the interior.
#[test]
fn smoothing_fills_holes_from_their_neighbours() {
    let (w, h) = (32, 32);
    let (xs0, ys0) = samples(w, h, 4, SEED + 5);
    let (xs, ys): (Vec<f64>, Vec<f64>) = xs0
        .iter()
        .zip(&ys0)
        .filter(|(x, y)| (*x - 12.0).powi(2) + (*y - 16.0).powi(2) > 36.0)
        .map(|(x, y)| (*x, *y))
        .unzip();
    let f: Vec<f64> = xs.iter().map(|x| x * 0.1).collect();
    let mut prm = params(2, (5, 5), NormalSolver::Cholesky);
    prm.ridge = 1e-9;
    let pinned = fit_image(w, h, &xs, &ys, &[&f], &prm).unwrap();
    assert!(pinned.report.unsampled > 0);
    assert!(pinned.evaluate(12.0, 16.0).unwrap()[0].abs() < 1e-6);
    prm.smoothing = 1e-3;
    let smooth = fit_image(w, h, &xs, &ys, &[&f], &prm).unwrap();
    assert_eq!(smooth.report.smoothing, 1e-3);
    for (x, y) in [(12.0, 16.0), (9.0, 14.0), (15.5, 18.0), (20.0, 4.0)] {
        let v = smooth.evaluate(x, y).unwrap()[0];
        assert!((v - 0.1 * x).abs() < 1e-2, "({x}, {y}): {v}");
    }
    prm.p = 1;
    prm.levels = ImageLevels::Fixed(5, 5);
    let e = fit_image(w, h, &xs, &ys, &[&f], &prm).unwrap_err();
    assert_eq!(e.kind(), rkwave::error::ErrorKind::InvalidInput, "{e}");
}

/// The 2D FWT (parallel, whole-row column pass) is the 1D steps of `basis::fwt` applied line
/// by line, rows then columns, level by level: the same sums in the same order, so equal bit
/// for bit (a reference written here from the 1D step alone), for p = 1..4 on non-square
/// images.
#[test]
fn fwt_2d_is_the_1d_steps_line_by_line_bit_for_bit() {
    use rkwave::basis::fwt::{analysis_step, synthesis_step};
    let reference = |b: &TensorBasis, data: &[f64], analysis: bool| -> Vec<f64> {
        let (nx, _) = b.dims();
        let (cx, cy) = b.coarse_levels();
        let bank = b.bank();
        let mut x = data.to_vec();
        let steps: Vec<u32> = if analysis {
            (0..b.steps()).rev().collect()
        } else {
            (0..b.steps()).collect()
        };
        for s in steps {
            let (jx, jy) = (cx + s, cy + s);
            let (lx, ly) = (2usize << jx, 2usize << jy);
            let step = |j, f: &[f64], o: &mut [f64]| {
                if analysis {
                    analysis_step(bank, j, f, o)
                } else {
                    synthesis_step(bank, j, f, o)
                }
            };
            let mut out = vec![0.0; lx.max(ly)];
            for ky in 0..ly {
                step(jx, &x[ky * nx..ky * nx + lx], &mut out[..lx]);
                x[ky * nx..ky * nx + lx].copy_from_slice(&out[..lx]);
            }
            for kx in 0..lx {
                let line: Vec<f64> = (0..ly).map(|ky| x[ky * nx + kx]).collect();
                step(jy, &line, &mut out[..ly]);
                for ky in 0..ly {
                    x[ky * nx + kx] = out[ky];
                }
            }
        }
        x
    };
    let mut rng = Pcg64::seed_from_u64(SEED ^ 77);
    for (p, w, h, levels) in [
        (1, 8, 4, (4, 3)),
        (2, 16, 8, (5, 5)),
        (3, 24, 40, (6, 7)),
        (4, 32, 32, (6, 6)),
    ] {
        let b = basis(p, w, h, levels);
        let v: Vec<f64> = (0..b.len()).map(|_| rng.random::<f64>() - 0.5).collect();
        assert_eq!(b.analysis(&v), reference(&b, &v, true), "analysis, p = {p}");
        assert_eq!(
            b.synthesis(&v),
            reference(&b, &v, false),
            "synthesis, p = {p}"
        );
    }
}
