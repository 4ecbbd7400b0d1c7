//! Pixels of a reconstruction (`rkwave::image::pixels`) and the equivalent reconstruction filter
//! (`rkwave::image::equivalent_filter`): box pixels reproduce the exact pixel integrals of
//! polynomials in the space, film-filter rows are checked against a fine quadrature of the
//! pointwise evaluator, and the equivalent filter against a dense pseudo-inverse.

use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng};
use rkwave::basis::facts::monomial_coefficients;
use rkwave::basis::{minimum_level, BasisValue, CdvBasis, FilterFamily};
use rkwave::image::equivalent_filter::{equivalent_filter, pixel_functional, NormalEquations};
use rkwave::image::filters::FilmFilter;
use rkwave::image::pixels::{filter_image, FilterQuadrature, PixelIntegrals};
use rkwave::sampling::Domain;

fn axis(p: usize, level: u32, pixels: usize) -> CdvBasis {
    CdvBasis::new(
        p,
        FilterFamily::cdv_default(p),
        level,
        level,
        Domain::new(0.0, pixels as f64).unwrap(),
    )
    .unwrap()
}

/// Coefficients of `(x / W)^d` on `[0, W]` (the unit coefficients times `sqrt(W)`).
fn monomial(b: &CdvBasis, d: usize) -> Vec<f64> {
    let root = b.domain().length().sqrt();
    monomial_coefficients(b, d)
        .into_iter()
        .map(|c| c * root)
        .collect()
}

/// `int_X^{X+1} (x / W)^d dx`.
fn pixel_moment(x: usize, w: usize, d: usize) -> f64 {
    let (a, b) = (x as f64 / w as f64, (x + 1) as f64 / w as f64);
    w as f64 * (b.powi(d as i32 + 1) - a.powi(d as i32 + 1)) / (d + 1) as f64
}

/// Box pixels of tensor polynomials `(x/W)^dx (y/H)^dy`, `dx, dy < p`, are their exact pixel
/// integrals: a non-power-of-two, non-square image, every pixel including the borders.
#[test]
fn box_pixels_integrate_tensor_polynomials_exactly() {
    for p in [1, 2, 3, 4, 6] {
        let (w, h) = (37, 20);
        let jx = (minimum_level(p)).max(6);
        let jy = (minimum_level(p)).max(5);
        let (ax, ay) = (axis(p, jx, w), axis(p, jy, h));
        let (bx, by) = (
            PixelIntegrals::new(&ax, w).unwrap(),
            PixelIntegrals::new(&ay, h).unwrap(),
        );
        for dx in 0..p.min(3) {
            for dy in 0..p.min(3) {
                let (cx, cy) = (monomial(&ax, dx), monomial(&ay, dy));
                let c: Vec<f64> = cy
                    .iter()
                    .flat_map(|a| cx.iter().map(move |b| a * b))
                    .collect();
                let image = filter_image(&by, &bx, &c).unwrap();
                for y in 0..h {
                    for x in 0..w {
                        let want = pixel_moment(x, w, dx) * pixel_moment(y, h, dy);
                        // Coefficients from facts.rs' moment recursion (relative rounding
                        // ~1e-13); the sum has O(p^2) terms of size O(1).
                        assert!(
                            (image[y * w + x] - want).abs() < 1e-11,
                            "p={p} d=({dx},{dy}) pixel ({x},{y}): {} vs {want}",
                            image[y * w + x]
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn pixel_axis_must_match_the_basis_domain() {
    let b = axis(2, 4, 10);
    for pixels in [11, 0] {
        let e = PixelIntegrals::new(&b, pixels).unwrap_err();
        assert_eq!(
            e.kind(),
            rkwave::error::ErrorKind::InvalidInput,
            "{pixels}: {e}"
        );
    }
    let bx = PixelIntegrals::new(&b, 10).unwrap();
    let e = filter_image(&bx, &bx, &[0.0; 3]).unwrap_err();
    assert_eq!(e.kind(), rkwave::error::ErrorKind::InvalidInput, "{e}");
}

/// Test copies of the film-filter shapes of `film-filters.md` (pbrt-v4 defaults).
enum Shape {
    Triangle,
    Gaussian,
    Mitchell,
    Lanczos,
}

impl FilmFilter for Shape {
    fn radius(&self) -> f64 {
        match self {
            Shape::Triangle | Shape::Mitchell => 2.0,
            Shape::Gaussian => 1.5,
            Shape::Lanczos => 4.0,
        }
    }
    fn eval(&self, x: f64) -> f64 {
        let r = self.radius();
        if x.abs() > r {
            return 0.0;
        }
        match self {
            Shape::Triangle => r - x.abs(),
            Shape::Gaussian => {
                let g = |x: f64| (-x * x / 0.5).exp() / (2.0 * std::f64::consts::PI * 0.25).sqrt();
                (g(x) - g(r)).max(0.0)
            }
            Shape::Mitchell => {
                let (b, c) = (1.0 / 3.0, 1.0 / 3.0);
                let t = (2.0 * x / r).abs();
                if t < 1.0 {
                    ((12.0 - 9.0 * b - 6.0 * c) * t.powi(3)
                        + (-18.0 + 12.0 * b + 6.0 * c) * t * t
                        + (6.0 - 2.0 * b))
                        / 6.0
                } else {
                    ((-b - 6.0 * c) * t.powi(3)
                        + (6.0 * b + 30.0 * c) * t * t
                        + (-12.0 * b - 48.0 * c) * t
                        + (8.0 * b + 24.0 * c))
                        / 6.0
                }
            }
            Shape::Lanczos => {
                let sinc = |x: f64| {
                    if x.abs() < 1e-12 {
                        1.0
                    } else {
                        (std::f64::consts::PI * x).sin() / (std::f64::consts::PI * x)
                    }
                };
                sinc(x) * sinc(x / 3.0)
            }
        }
    }
    fn cubic_pieces(&self) -> Option<Vec<f64>> {
        match self {
            Shape::Triangle => Some(vec![0.0]),
            Shape::Mitchell => Some(vec![-1.0, 0.0, 1.0]),
            _ => None,
        }
    }
}

/// Filter rows against a fine Gauss–Legendre quadrature of `phi_k(x) w(x - c)` (p = 6, Hölder
/// 2.2, so 64 cells of 5 points per pixel integrate to ~1e-9, measured ~1e-12 for the integrals),
/// and reproduction of constants (exact up to rounding by construction of the normalization).
#[test]
fn film_filter_rows_match_fine_quadrature() {
    let nodes = [
        (0.0, 128.0 / 225.0),
        (-0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
        (0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
        (-0.906_179_845_938_664, 0.236_926_885_056_189_1),
        (0.906_179_845_938_664, 0.236_926_885_056_189_1),
    ];
    let (p, w) = (6, 24);
    let b = axis(p, 5, w);
    let ones = monomial(&b, 0);
    for shape in [
        Shape::Triangle,
        Shape::Gaussian,
        Shape::Mitchell,
        Shape::Lanczos,
    ] {
        let f = PixelIntegrals::filtered(&b, w, &shape, FilterQuadrature::default()).unwrap();
        let piecewise_cubic = shape.cubic_pieces().is_some();
        if piecewise_cubic {
            assert!(f.weight_error() < 1e-13, "{}", f.weight_error());
        } else {
            // Chebyshev cubic on 1/32-pixel cells: 2 (h/4)^4 max|w''''| / 4! ~ 2e-8 (Gaussian).
            assert!(f.weight_error() < 1e-7, "{}", f.weight_error());
        }
        let one = f.apply(&ones);
        for (x, v) in one.iter().enumerate() {
            // Cubic moments in each function's own variable reach (2p - 1)^3 ~ 1.3e3 and cancel
            // in the normalized sum: rounding ~1e3 eps per term, O(10) terms.
            assert!((v - 1.0).abs() < 1e-10, "constant at pixel {x}: {v}");
        }
        let mut ev = b.evaluator();
        let mut vals: Vec<BasisValue> = Vec::new();
        for pixel in [0usize, 1, 11, 23] {
            let centre = pixel as f64 + 0.5;
            let (lo, hi) = (
                (centre - shape.radius()).max(0.0),
                (centre + shape.radius()).min(w as f64),
            );
            // Cells aligned with the filter's breakpoints (integers and half-integers).
            let cells = ((hi - lo) * 128.0).round() as usize;
            let hcell = (hi - lo) / cells as f64;
            let mut row = vec![0.0; 1 << 5];
            let mut norm = 0.0;
            for i in 0..cells {
                let mid = lo + (i as f64 + 0.5) * hcell;
                for &(t, wt) in &nodes {
                    let x = mid + 0.5 * hcell * t;
                    let weight = 0.5 * hcell * wt * shape.eval(x - centre);
                    norm += weight;
                    ev.eval_scaling_unit_into(x / w as f64, &mut vals);
                    for v in &vals {
                        row[v.index] += weight * v.value;
                    }
                }
            }
            let got = f.matrix().outer_view(pixel).unwrap().to_dense();
            for k in 0..row.len() {
                let tol = if piecewise_cubic { 1e-9 } else { 1e-7 };
                assert!(
                    (got[k] - row[k] / norm).abs() < tol,
                    "pixel {pixel} k {k}: {} vs {}",
                    got[k],
                    row[k] / norm
                );
            }
        }
    }
}

/// Dense least squares on a small tensor problem: `K` from two 1D evaluations, `G = K^T K`
/// solved by Cholesky.
struct Dense {
    k: DMatrix<f64>,
    chol: nalgebra::Cholesky<f64, nalgebra::Dyn>,
}

impl NormalEquations for Dense {
    fn unknowns(&self) -> usize {
        self.k.ncols()
    }
    fn samples(&self) -> usize {
        self.k.nrows()
    }
    fn solve_normal(&self, b: &[f64]) -> Vec<f64> {
        self.chol
            .solve(&DVector::from_column_slice(b))
            .iter()
            .copied()
            .collect()
    }
    fn apply_rows(&self, z: &[f64]) -> Vec<f64> {
        (&self.k * DVector::from_column_slice(z))
            .iter()
            .copied()
            .collect()
    }
}

/// The equivalent filter equals `(K^+)^T b` from an SVD pseudo-inverse (a different route from
/// the normal equations), sums to one, and its centroid is the pixel centre (p = 2 reproduces
/// linear functions).
#[test]
fn equivalent_filter_matches_dense_pseudo_inverse() {
    let (w, h, p) = (8, 6, 2);
    let (ax, ay) = (axis(p, 3, w), axis(p, 3, h));
    let (bx, by) = (
        PixelIntegrals::new(&ax, w).unwrap(),
        PixelIntegrals::new(&ay, h).unwrap(),
    );
    let (nx, ny) = (8, 8);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(85);
    let m = 4 * w * h;
    let xs: Vec<f64> = (0..m).map(|_| rng.random::<f64>() * w as f64).collect();
    let ys: Vec<f64> = (0..m).map(|_| rng.random::<f64>() * h as f64).collect();
    let mut k = DMatrix::zeros(m, nx * ny);
    let (mut ex, mut ey) = (ax.evaluator(), ay.evaluator());
    for i in 0..m {
        let vx = ex.eval(xs[i]).unwrap();
        let vy = ey.eval(ys[i]).unwrap();
        for a in vy.iter().filter(|v| v.index < ny) {
            for b in vx.iter().filter(|v| v.index < nx) {
                k[(i, a.index * nx + b.index)] = a.value * b.value;
            }
        }
    }
    let g = k.transpose() * &k;
    let dense = Dense {
        k: k.clone(),
        chol: g
            .cholesky()
            .expect("4 samples per pixel: G is positive definite"),
    };
    let pinv = k.clone().pseudo_inverse(1e-12).unwrap();
    for (px, py) in [(0, 0), (3, 2), (7, 5), (4, 0)] {
        let f = equivalent_filter(&dense, &by, &bx, px, py).unwrap();
        let b = DVector::from_vec(pixel_functional(&by, &bx, px, py));
        let reference = pinv.transpose() * b;
        let scale = reference.amax();
        for i in 0..m {
            // Both routes are backward stable; cond(K) is small here (4 samples per pixel).
            assert!(
                (f.weights[i] - reference[i]).abs() < 1e-10 * scale,
                "pixel ({px},{py}) sample {i}: {} vs {}",
                f.weights[i],
                reference[i]
            );
        }
        assert!((f.total - 1.0).abs() < 1e-10, "total {}", f.total);
        let cx: f64 = f.weights.iter().zip(&xs).map(|(w, x)| w * x).sum();
        let cy: f64 = f.weights.iter().zip(&ys).map(|(w, y)| w * y).sum();
        assert!((cx - (px as f64 + 0.5)).abs() < 1e-9, "centroid x {cx}");
        assert!((cy - (py as f64 + 0.5)).abs() < 1e-9, "centroid y {cy}");
    }
    let e = equivalent_filter(&dense, &by, &bx, 8, 0).unwrap_err();
    assert_eq!(e.kind(), rkwave::error::ErrorKind::InvalidInput, "{e}");
}

/// Wired to `ImageFit`: the weights of the fit's own solve reproduce its box pixel,
/// `sum_i w_i f_i = I[Y, X]` (both are `b . c`; tolerance: two solves of the same factored
/// system, relative rounding ~1e-12 of O(1) values), and sum to one.
#[test]
fn equivalent_filter_of_an_image_fit_reproduces_its_pixels() {
    use rkwave::image::equivalent_filter::FitNormalEquations;
    use rkwave::image::fit::{fit_image, ImageFitParams, ImageLevels};
    use rkwave::image::pixels::{fit_pixels, PixelFilter};
    let (w, h) = (12, 10);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(86);
    let m = 6 * w * h;
    let xs: Vec<f64> = (0..m).map(|_| rng.random::<f64>() * w as f64).collect();
    let ys: Vec<f64> = (0..m).map(|_| rng.random::<f64>() * h as f64).collect();
    let f: Vec<f64> = xs
        .iter()
        .zip(&ys)
        .map(|(x, y)| (0.7 * x).sin() + 0.1 * y)
        .collect();
    let params = ImageFitParams {
        p: 2,
        levels: ImageLevels::Fixed(4, 4),
        ridge: 0.0,
        ..ImageFitParams::default()
    };
    let fit = fit_image(w, h, &xs, &ys, &[&f], &params).unwrap();
    let image = fit_pixels(&fit, PixelFilter::Box).unwrap();
    let normal = FitNormalEquations::new(&fit, &xs, &ys).unwrap();
    let (bx, by) = (
        PixelIntegrals::new(fit.scale_x(), w).unwrap(),
        PixelIntegrals::new(fit.scale_y(), h).unwrap(),
    );
    for (px, py) in [(0, 0), (5, 4), (11, 9)] {
        let e = equivalent_filter(&normal, &by, &bx, px, py).unwrap();
        let value: f64 = e.weights.iter().zip(&f).map(|(w, v)| w * v).sum();
        assert!(
            (value - image[0][py * w + px]).abs() < 1e-9,
            "pixel ({px},{py}): {value} vs {}",
            image[0][py * w + px]
        );
        assert!((e.total - 1.0).abs() < 1e-9, "total {}", e.total);
    }
}
