//! Film filters as renderers ship them (pbrt-v4 defaults), the baselines rkwave is compared
//! against.
//!
//! Every filter is separable: `w(dx, dy) = f(dx) f(dy)` with `dx, dy` the offsets in pixels
//! from the pixel centre, and vanishes for `|dx| > r` or `|dy| > r`. In one dimension
//! (`t = |x|`):
//!
//! | filter | parameters | `f(x)` for `t <= r` |
//! | --- | --- | --- |
//! | [`BoxFilter`] | `r = 1/2` | `1` |
//! | [`TriangleFilter`] | `r = 2` | `r - t` |
//! | [`GaussianFilter`] | `r = 3/2`, `sigma = 1/2` | `max(0, g(x) - g(r))`, `g(x) = exp(-x^2 / (2 sigma^2)) / sqrt(2 pi sigma^2)` |
//! | [`MitchellFilter`] | `r = 2`, `B = C = 1/3` | the Mitchell–Netravali cubic `k(2x / r)` |
//! | [`LanczosFilter`] | `r = 4`, `tau = 3` | `sinc(x) sinc(x / tau)`, `sinc(x) = sin(pi x) / (pi x)` |
//!
//! with the Mitchell–Netravali cubic `k(s)` (`s = |s|`)
//! `((12 - 9B - 6C) s^3 + (-18 + 12B + 6C) s^2 + (6 - 2B)) / 6` for `s < 1`,
//! `((-B - 6C) s^3 + (6B + 30C) s^2 + (-12B - 48C) s + (8B + 24C)) / 6` for `1 <= s < 2`.
//!
//! The filters are not normalised (as in pbrt-v4): the weighted average of the splat (the
//! `splat` module beside this one) divides by the sum of weights, so a constant factor
//! cancels.
//! [`FilmFilter::integral`] gives `int f` for users who need the normalised `f / int f`.

use std::f64::consts::PI;
use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// A separable film filter: a 1D profile `f` with support `[-r, r]`.
pub trait FilmFilter: Sync + Send {
    /// The radius `r`: `f(x) = 0` for `|x| > r`.
    fn radius(&self) -> f64;

    /// The 1D profile `f(x)`, `x` in pixels from the pixel centre.
    fn eval(&self, x: f64) -> f64;

    /// Interior breakpoints in `(-r, r)` between which `f` is a polynomial of degree `<= 3`,
    /// or `None` if `f` is not piecewise cubic. Pixel integrals of a reconstruction against
    /// the filter (`PixelIntegrals::filtered` of the `pixels` module) are exact on such
    /// pieces; other filters are replaced by cubic interpolants on sub-cells, with the error
    /// measured and reported.
    fn cubic_pieces(&self) -> Option<Vec<f64>> {
        None
    }

    /// The 2D weight `w(dx, dy) = f(dx) f(dy)`.
    fn eval_2d(&self, dx: f64, dy: f64) -> f64 {
        self.eval(dx) * self.eval(dy)
    }

    /// `int_{-r}^{r} f(x) dx`, by default by 2000-panel composite Gauss–Legendre quadrature
    /// (3 nodes per panel; exact for the piecewise polynomials, error far below `1e-12` for
    /// the smooth profiles). The 2D integral is its square.
    fn integral(&self) -> f64 {
        let r = self.radius();
        let panels = 2000;
        let h = 2.0 * r / panels as f64;
        let nodes = [-(0.6f64).sqrt(), 0.0, (0.6f64).sqrt()];
        let weights = [5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0];
        let mut sum = 0.0;
        for k in 0..panels {
            let mid = -r + (k as f64 + 0.5) * h;
            for (t, w) in nodes.iter().zip(weights) {
                sum += w * self.eval(mid + 0.5 * h * t);
            }
        }
        0.5 * h * sum
    }
}

/// The box filter `f(x) = 1` for `|x| <= r` (pbrt-v4 default `r = 1/2`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BoxFilter {
    /// Radius `r` in pixels.
    pub radius: f64,
}

impl Default for BoxFilter {
    fn default() -> Self {
        Self { radius: 0.5 }
    }
}

impl FilmFilter for BoxFilter {
    fn radius(&self) -> f64 {
        self.radius
    }
    fn eval(&self, x: f64) -> f64 {
        if x.abs() <= self.radius {
            1.0
        } else {
            0.0
        }
    }
    /// Constant on `[-r, r]`.
    fn cubic_pieces(&self) -> Option<Vec<f64>> {
        Some(vec![])
    }
    fn integral(&self) -> f64 {
        2.0 * self.radius
    }
}

/// The triangle (tent) filter `f(x) = max(0, r - |x|)` (pbrt-v4 default `r = 2`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TriangleFilter {
    /// Radius `r` in pixels.
    pub radius: f64,
}

impl Default for TriangleFilter {
    fn default() -> Self {
        Self { radius: 2.0 }
    }
}

impl FilmFilter for TriangleFilter {
    fn radius(&self) -> f64 {
        self.radius
    }
    fn eval(&self, x: f64) -> f64 {
        (self.radius - x.abs()).max(0.0)
    }
    /// Linear on `[-r, 0]` and `[0, r]`.
    fn cubic_pieces(&self) -> Option<Vec<f64>> {
        Some(vec![0.0])
    }
    fn integral(&self) -> f64 {
        self.radius * self.radius
    }
}

/// The Gaussian filter with pbrt-v4's offset, `f(x) = max(0, g(x) - g(r))`,
/// `g(x) = exp(-x^2 / (2 sigma^2)) / sqrt(2 pi sigma^2)` (default `r = 3/2`, `sigma = 1/2`:
/// pbrt-v4's scene default).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GaussianFilter {
    /// Radius `r` in pixels.
    pub radius: f64,
    /// Standard deviation `sigma` in pixels.
    pub sigma: f64,
}

impl Default for GaussianFilter {
    fn default() -> Self {
        Self {
            radius: 1.5,
            sigma: 0.5,
        }
    }
}

impl GaussianFilter {
    /// The unclipped normal density `g(x)`.
    pub fn gaussian(&self, x: f64) -> f64 {
        (-x * x / (2.0 * self.sigma * self.sigma)).exp()
            / (2.0 * PI * self.sigma * self.sigma).sqrt()
    }
}

impl FilmFilter for GaussianFilter {
    fn radius(&self) -> f64 {
        self.radius
    }
    fn eval(&self, x: f64) -> f64 {
        if x.abs() > self.radius {
            return 0.0;
        }
        (self.gaussian(x) - self.gaussian(self.radius)).max(0.0)
    }
}

/// The Mitchell–Netravali filter `f(x) = k(2x / r)` with the cubic `k` of the module docs
/// (default `r = 2`, `B = C = 1/3`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MitchellFilter {
    /// Radius `r` in pixels.
    pub radius: f64,
    /// The parameter `B`.
    pub b: f64,
    /// The parameter `C`.
    pub c: f64,
}

impl Default for MitchellFilter {
    fn default() -> Self {
        Self {
            radius: 2.0,
            b: 1.0 / 3.0,
            c: 1.0 / 3.0,
        }
    }
}

impl MitchellFilter {
    /// The Mitchell–Netravali cubic `k(s)` on its own support `[-2, 2]`.
    pub fn cubic(&self, s: f64) -> f64 {
        let (b, c) = (self.b, self.c);
        let s = s.abs();
        if s < 1.0 {
            ((12.0 - 9.0 * b - 6.0 * c) * s.powi(3)
                + (-18.0 + 12.0 * b + 6.0 * c) * s * s
                + (6.0 - 2.0 * b))
                / 6.0
        } else if s < 2.0 {
            ((-b - 6.0 * c) * s.powi(3)
                + (6.0 * b + 30.0 * c) * s * s
                + (-12.0 * b - 48.0 * c) * s
                + (8.0 * b + 24.0 * c))
                / 6.0
        } else {
            0.0
        }
    }
}

impl FilmFilter for MitchellFilter {
    fn radius(&self) -> f64 {
        self.radius
    }
    fn eval(&self, x: f64) -> f64 {
        self.cubic(2.0 * x / self.radius)
    }
    /// Cubic between `-r, -r/2, 0, r/2, r` (`k` is cubic on `|s| < 1` and `1 <= |s| < 2`).
    fn cubic_pieces(&self) -> Option<Vec<f64>> {
        let h = self.radius / 2.0;
        Some(vec![-h, 0.0, h])
    }
    /// `int k = 1` on `[-2, 2]` for every `B, C`, so `int f = r / 2`.
    fn integral(&self) -> f64 {
        self.radius / 2.0
    }
}

/// The Lanczos windowed sinc `f(x) = sinc(x) sinc(x / tau)` for `|x| <= r`
/// (default `r = 4`, `tau = 3`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LanczosFilter {
    /// Radius `r` in pixels.
    pub radius: f64,
    /// The window's period parameter `tau`.
    pub tau: f64,
}

impl Default for LanczosFilter {
    fn default() -> Self {
        Self {
            radius: 4.0,
            tau: 3.0,
        }
    }
}

/// `sinc(x) = sin(pi x) / (pi x)`, `sinc(0) = 1`.
pub fn sinc(x: f64) -> f64 {
    if x.abs() < 1e-5 {
        // Taylor: 1 - (pi x)^2 / 6, error below (pi x)^4 / 120 < 1e-19.
        1.0 - (PI * x).powi(2) / 6.0
    } else {
        (PI * x).sin() / (PI * x)
    }
}

impl FilmFilter for LanczosFilter {
    fn radius(&self) -> f64 {
        self.radius
    }
    fn eval(&self, x: f64) -> f64 {
        if x.abs() > self.radius {
            return 0.0;
        }
        sinc(x) * sinc(x / self.tau)
    }
}

/// The film filters by name, each with pbrt-v4's default parameters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FilmFilterKind {
    /// [`BoxFilter`], `r = 1/2`.
    Box,
    /// [`TriangleFilter`], `r = 2`.
    Triangle,
    /// [`GaussianFilter`], `r = 3/2`, `sigma = 1/2` (pbrt-v4's default).
    Gaussian,
    /// [`MitchellFilter`], `r = 2`, `B = C = 1/3`.
    Mitchell,
    /// [`LanczosFilter`], `r = 4`, `tau = 3`.
    Lanczos,
}

impl FilmFilterKind {
    /// Every film filter, in table order.
    pub const ALL: [FilmFilterKind; 5] = [
        FilmFilterKind::Box,
        FilmFilterKind::Triangle,
        FilmFilterKind::Gaussian,
        FilmFilterKind::Mitchell,
        FilmFilterKind::Lanczos,
    ];

    /// The lowercase name (`box`, `triangle`, ...).
    pub fn name(self) -> &'static str {
        match self {
            FilmFilterKind::Box => "box",
            FilmFilterKind::Triangle => "triangle",
            FilmFilterKind::Gaussian => "gaussian",
            FilmFilterKind::Mitchell => "mitchell",
            FilmFilterKind::Lanczos => "lanczos",
        }
    }

    /// The filter with its default parameters.
    pub fn build(self) -> Box<dyn FilmFilter> {
        match self {
            FilmFilterKind::Box => Box::new(BoxFilter::default()),
            FilmFilterKind::Triangle => Box::new(TriangleFilter::default()),
            FilmFilterKind::Gaussian => Box::new(GaussianFilter::default()),
            FilmFilterKind::Mitchell => Box::new(MitchellFilter::default()),
            FilmFilterKind::Lanczos => Box::new(LanczosFilter::default()),
        }
    }
}

impl fmt::Display for FilmFilterKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A film filter name that is not one of [`FilmFilterKind::ALL`].
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("unknown film filter `{name}`: expected one of box, triangle, gaussian, mitchell, lanczos")]
pub struct ParseFilmFilterError {
    /// The name as given.
    pub name: String,
}

impl FromStr for FilmFilterKind {
    type Err = ParseFilmFilterError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        FilmFilterKind::ALL
            .into_iter()
            .find(|k| k.name().eq_ignore_ascii_case(s.trim()))
            .ok_or_else(|| ParseFilmFilterError {
                name: s.to_string(),
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Independent reference: midpoint rule with `n` cells on `[-r, r]`. For the profiles
    /// here (Lipschitz, piecewise smooth with finitely many kinks) the error is `O(r^3 / n^2)`
    /// away from kinks plus `O(r / n)` at the box's jumps; `n = 400_000` keeps it below 1e-9
    /// for the continuous ones.
    fn midpoint(f: &dyn FilmFilter, n: usize) -> f64 {
        let r = f.radius();
        let h = 2.0 * r / n as f64;
        (0..n)
            .map(|k| f.eval(-r + (k as f64 + 0.5) * h))
            .sum::<f64>()
            * h
    }

    /// `erf` by its Maclaurin series (converges fast for |x| <= 3; terms decay like x^2n / n!).
    fn erf(x: f64) -> f64 {
        let mut term = x;
        let mut sum = x;
        for n in 1..80 {
            term *= -x * x / n as f64;
            sum += term / (2 * n + 1) as f64;
        }
        2.0 / PI.sqrt() * sum
    }

    #[test]
    fn normalised_filters_integrate_to_one() {
        for kind in FilmFilterKind::ALL {
            let f = kind.build();
            let integral = f.integral();
            let reference = midpoint(f.as_ref(), 400_000);
            // The box jumps at +-r: the midpoint grid hits no jump, so it is exact there too.
            assert!(
                (integral - reference).abs() < 1e-9 * reference.abs().max(1.0),
                "{kind}: integral {integral} against midpoint {reference}"
            );
            // Normalised 2D filter f(x) f(y) / (int f)^2 integrates to one: a 2D midpoint rule.
            let n = 800;
            let r = f.radius();
            let h = 2.0 * r / n as f64;
            let mut s = 0.0;
            for i in 0..n {
                for j in 0..n {
                    s += f.eval_2d(-r + (i as f64 + 0.5) * h, -r + (j as f64 + 0.5) * h);
                }
            }
            let s = s * h * h / (integral * integral);
            // 2D midpoint error O(h^2) relative, h = 2r/800 <= 0.01: below 1e-4.
            assert!((s - 1.0).abs() < 1e-4, "{kind}: 2D normalised integral {s}");
        }
        // Closed forms against independent facts.
        assert_eq!(BoxFilter::default().integral(), 1.0);
        assert_eq!(TriangleFilter::default().integral(), 4.0);
        assert!((MitchellFilter::default().integral() - 1.0).abs() < 1e-15);
        let g = GaussianFilter::default();
        // int_{-r}^{r} (g(x) - g(r)) dx = erf(r / (sigma sqrt 2)) - 2 r g(r).
        let exact = erf(g.radius / (g.sigma * 2f64.sqrt())) - 2.0 * g.radius * g.gaussian(g.radius);
        assert!(
            (g.integral() - exact).abs() < 1e-12,
            "{} {exact}",
            g.integral()
        );
    }

    #[test]
    fn filters_match_their_formulas_at_known_points() {
        let t = TriangleFilter::default();
        assert_eq!(t.eval(0.5), 1.5);
        assert_eq!(t.eval(-2.5), 0.0);
        let b = BoxFilter::default();
        assert_eq!((b.eval(0.5), b.eval(0.51)), (1.0, 0.0));
        let g = GaussianFilter::default();
        // g(0) = 1 / sqrt(2 pi / 4) = sqrt(2 / pi); g(1.5) = sqrt(2 / pi) e^{-4.5}.
        let g0 = (2.0 / PI).sqrt();
        assert!((g.eval(0.0) - (g0 - g0 * (-4.5f64).exp())).abs() < 1e-15);
        assert!((g.eval(1.0) - (g0 * (-2.0f64).exp() - g0 * (-4.5f64).exp())).abs() < 1e-15);
        assert_eq!(g.eval(1.5), 0.0);
        assert_eq!(g.eval(1.6), 0.0);
        let m = MitchellFilter::default();
        // k(0) = (6 - 2B) / 6 = 8/9; k(1) = B / 6 = 1/18 (both pieces agree there); k(2) = 0.
        assert!((m.eval(0.0) - 8.0 / 9.0).abs() < 1e-15);
        assert!((m.eval(1.0) - 1.0 / 18.0).abs() < 1e-15);
        assert!((m.cubic(1.0 - 1e-12) - 1.0 / 18.0).abs() < 1e-10);
        assert!(m.eval(2.0).abs() < 1e-15);
        let l = LanczosFilter::default();
        // sinc(1/2) sinc(1/6) = (2/pi) (3/pi); zeros at the integers.
        assert!((l.eval(0.0) - 1.0).abs() < 1e-15);
        assert!((l.eval(0.5) - 6.0 / (PI * PI)).abs() < 1e-15);
        assert!(l.eval(1.0).abs() < 1e-15 && l.eval(2.0).abs() < 1e-15);
        assert_eq!(l.eval(4.5), 0.0);
        assert_eq!(l.eval_2d(0.5, 0.5), l.eval(0.5) * l.eval(0.5));
        assert_eq!(
            "Gaussian".parse::<FilmFilterKind>(),
            Ok(FilmFilterKind::Gaussian)
        );
        assert!("cubic".parse::<FilmFilterKind>().is_err());
    }
}
