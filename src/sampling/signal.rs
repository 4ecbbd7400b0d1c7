//! Built-in test signals on the unit interval.

use std::f64::consts::PI;
use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::Domain;

/// A test function `f(t)` on the unit interval `t ∈ [0, 1]`.
///
/// On a [`Domain`] `[a, b]` the signal is `x ↦ f((x − a) / (b − a))`; see
/// [`Signal::value_in`] and [`Signal::sample`]. Outside `[0, 1]` the formulas
/// are evaluated as they are (which gives NaN for [`Signal::Doppler`]).
///
/// The last four are the test signals of D. L. Donoho and I. M. Johnstone,
/// *Ideal spatial adaptation by wavelet shrinkage*, Biometrika 81(3):425–455,
/// 1994 (Table 1 and Fig. 1), with the constants of WaveLab's `MakeSignal`,
/// unscaled (the paper rescales them to a given signal-to-noise ratio).
///
/// Names (for [`FromStr`], [`fmt::Display`] and serde): `smooth`,
/// `polynomialN` (e.g. `polynomial3`), `jumps`, `kink`, `cusp`, `blocks`,
/// `bumps`, `heavisine`, `doppler`. Parsing ignores case, `-`, `_`, `:`,
/// brackets and spaces, accepts `poly` for `polynomial`, and takes degree 3
/// when the degree is left out.
///
/// ```
/// use rkwave::sampling::{Domain, Signal};
///
/// let s: Signal = "doppler".parse().unwrap();
/// let ys = s.sample(Domain::UNIT, &[0.25, 0.5]);
/// assert_eq!(ys.len(), 2);
/// assert!(ys.iter().all(|y| y.is_finite()));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum Signal {
    /// `sin(2πt) + 0.5 cos(5πt)`.
    Smooth,
    /// The degree-`d` polynomial `1 + s + s² + … + s^d` with `s = 2t − 1`
    /// (every monomial present, values in `[0, d + 1]` on `[0, 1]`),
    /// evaluated by Horner's rule.
    Polynomial(u32),
    /// `0.5 sin(2πt) + #{p ∈ JUMP_POINTS : p ≤ t}`: smooth pieces with three
    /// upward jumps of size exactly 1 at [`Signal::JUMP_POINTS`]; right
    /// continuous.
    Jumps,
    /// `|t − 0.41|`: continuous with a jump of the derivative at
    /// [`Signal::KINK_POINT`].
    Kink,
    /// `sqrt(|t − 0.37|)`: continuous, infinite derivative at
    /// [`Signal::CUSP_POINT`].
    Cusp,
    /// Donoho–Johnstone *Blocks*: `Σ_j h_j (1 + sgn(t − p_j)) / 2`, piecewise
    /// constant with eleven jumps (`sgn(0) = 0`, so the value at a jump is the
    /// mean of the one-sided limits).
    Blocks,
    /// Donoho–Johnstone *Bumps*: `Σ_j h_j (1 + |t − p_j| / w_j)^(−4)`, eleven
    /// sharp peaks at the *Blocks* positions.
    Bumps,
    /// Donoho–Johnstone *HeaviSine*:
    /// `4 sin(4πt) − sgn(t − 0.3) − sgn(0.72 − t)`.
    HeaviSine,
    /// Donoho–Johnstone *Doppler*:
    /// `sqrt(t(1 − t)) sin(2π(1 + ε) / (t + ε))`, `ε = 0.05`.
    Doppler,
}

/// The error for an unknown signal name; it lists the valid names.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error(
    "unknown signal `{name}`{detail}; valid signals are: smooth, polynomialN (degree N = 0..={max}, \
     e.g. polynomial3), jumps, kink, cusp, blocks, bumps, heavisine, doppler",
    max = Signal::MAX_PARSED_DEGREE
)]
pub struct ParseSignalError {
    /// The name that was not recognised.
    pub name: String,
    /// Extra explanation (empty, or starting with `: `).
    pub detail: String,
}

/// Jump and peak positions of *Blocks* and *Bumps*.
const DJ_POSITIONS: [f64; 11] = [
    0.10, 0.13, 0.15, 0.23, 0.25, 0.40, 0.44, 0.65, 0.76, 0.78, 0.81,
];
/// Jump heights of *Blocks*.
const BLOCKS_HEIGHTS: [f64; 11] = [4.0, -5.0, 3.0, -4.0, 5.0, -4.2, 2.1, 4.3, -3.1, 2.1, -4.2];
/// Peak heights of *Bumps*.
const BUMPS_HEIGHTS: [f64; 11] = [4.0, 5.0, 3.0, 4.0, 5.0, 4.2, 2.1, 4.3, 3.1, 5.1, 4.2];
/// Peak widths of *Bumps*.
const BUMPS_WIDTHS: [f64; 11] = [
    0.005, 0.005, 0.006, 0.01, 0.01, 0.03, 0.01, 0.01, 0.005, 0.008, 0.005,
];
/// Jump positions of *HeaviSine*.
const HEAVISINE_JUMPS: [f64; 2] = [0.3, 0.72];
/// The `ε` of *Doppler*.
const DOPPLER_EPS: f64 = 0.05;

/// The sign function with `sgn(0) = 0` (unlike [`f64::signum`]).
fn sgn(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

impl Signal {
    /// Where [`Signal::Jumps`] jumps up by exactly 1.
    pub const JUMP_POINTS: [f64; 3] = [0.29, 0.53, 0.81];
    /// Where [`Signal::Kink`] has its kink.
    pub const KINK_POINT: f64 = 0.41;
    /// Where [`Signal::Cusp`] has its cusp.
    pub const CUSP_POINT: f64 = 0.37;
    /// The largest polynomial degree accepted by name parsing.
    pub const MAX_PARSED_DEGREE: u32 = 64;

    /// One signal of each kind (the polynomial with degree 3), in a fixed
    /// order.
    pub fn all() -> &'static [Signal] {
        &[
            Signal::Smooth,
            Signal::Polynomial(3),
            Signal::Jumps,
            Signal::Kink,
            Signal::Cusp,
            Signal::Blocks,
            Signal::Bumps,
            Signal::HeaviSine,
            Signal::Doppler,
        ]
    }

    /// The value `f(t)` at `t` on the unit interval.
    pub fn value(&self, t: f64) -> f64 {
        match *self {
            Signal::Smooth => (2.0 * PI * t).sin() + 0.5 * (5.0 * PI * t).cos(),
            Signal::Polynomial(d) => {
                let s = 2.0 * t - 1.0;
                (0..d).fold(1.0, |p, _| p * s + 1.0)
            }
            Signal::Jumps => {
                let steps = Self::JUMP_POINTS.iter().filter(|&&p| p <= t).count();
                0.5 * (2.0 * PI * t).sin() + steps as f64
            }
            Signal::Kink => (t - Self::KINK_POINT).abs(),
            Signal::Cusp => (t - Self::CUSP_POINT).abs().sqrt(),
            Signal::Blocks => DJ_POSITIONS
                .iter()
                .zip(BLOCKS_HEIGHTS)
                .map(|(&p, h)| h * (1.0 + sgn(t - p)) / 2.0)
                .sum(),
            Signal::Bumps => DJ_POSITIONS
                .iter()
                .zip(BUMPS_HEIGHTS)
                .zip(BUMPS_WIDTHS)
                .map(|((&p, h), w)| h * (1.0 + (t - p).abs() / w).powi(-4))
                .sum(),
            Signal::HeaviSine => {
                4.0 * (4.0 * PI * t).sin()
                    - sgn(t - HEAVISINE_JUMPS[0])
                    - sgn(HEAVISINE_JUMPS[1] - t)
            }
            Signal::Doppler => {
                (t * (1.0 - t)).sqrt() * (2.0 * PI * (1.0 + DOPPLER_EPS) / (t + DOPPLER_EPS)).sin()
            }
        }
    }

    /// The value at `x` in `domain`: `value(domain.to_unit(x))`.
    pub fn value_in(&self, domain: Domain, x: f64) -> f64 {
        self.value(domain.to_unit(x))
    }

    /// The values at `positions` in `domain`.
    pub fn sample(&self, domain: Domain, positions: &[f64]) -> Vec<f64> {
        positions
            .iter()
            .map(|&x| self.value_in(domain, x))
            .collect()
    }

    /// Points of `(0, 1)` where the signal or its first derivative is
    /// discontinuous or unbounded (jumps, kinks, cusps, the Bumps peaks).
    /// Empty for the smooth signals; Doppler's oscillation near 0 is not
    /// listed.
    pub fn singular_points(&self) -> &'static [f64] {
        match self {
            Signal::Smooth | Signal::Polynomial(_) | Signal::Doppler => &[],
            Signal::Jumps => &Self::JUMP_POINTS,
            Signal::Kink => &[Self::KINK_POINT],
            Signal::Cusp => &[Self::CUSP_POINT],
            Signal::Blocks | Signal::Bumps => &DJ_POSITIONS,
            Signal::HeaviSine => &HEAVISINE_JUMPS,
        }
    }

    /// Whether the signal is discontinuous (has jumps) in `(0, 1)`.
    pub fn has_jumps(&self) -> bool {
        matches!(self, Signal::Jumps | Signal::Blocks | Signal::HeaviSine)
    }
}

impl fmt::Display for Signal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Signal::Smooth => f.write_str("smooth"),
            Signal::Polynomial(d) => write!(f, "polynomial{d}"),
            Signal::Jumps => f.write_str("jumps"),
            Signal::Kink => f.write_str("kink"),
            Signal::Cusp => f.write_str("cusp"),
            Signal::Blocks => f.write_str("blocks"),
            Signal::Bumps => f.write_str("bumps"),
            Signal::HeaviSine => f.write_str("heavisine"),
            Signal::Doppler => f.write_str("doppler"),
        }
    }
}

impl FromStr for Signal {
    type Err = ParseSignalError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let err = |detail: String| ParseSignalError {
            name: s.to_string(),
            detail,
        };
        let key: String = s
            .trim()
            .chars()
            .filter(|c| !matches!(c, '-' | '_' | ' ' | ':' | '(' | ')' | '[' | ']'))
            .flat_map(char::to_lowercase)
            .collect();
        let simple = match key.as_str() {
            "smooth" => Some(Signal::Smooth),
            "jumps" => Some(Signal::Jumps),
            "kink" => Some(Signal::Kink),
            "cusp" => Some(Signal::Cusp),
            "blocks" => Some(Signal::Blocks),
            "bumps" => Some(Signal::Bumps),
            "heavisine" => Some(Signal::HeaviSine),
            "doppler" => Some(Signal::Doppler),
            _ => None,
        };
        if let Some(signal) = simple {
            return Ok(signal);
        }
        let degree = key
            .strip_prefix("polynomial")
            .or_else(|| key.strip_prefix("poly"))
            .ok_or_else(|| err(String::new()))?;
        if degree.is_empty() {
            return Ok(Signal::Polynomial(3));
        }
        if !degree.bytes().all(|b| b.is_ascii_digit()) {
            return Err(err(format!(": `{degree}` is not a polynomial degree")));
        }
        match degree.parse::<u32>() {
            Ok(d) if d <= Self::MAX_PARSED_DEGREE => Ok(Signal::Polynomial(d)),
            _ => Err(err(format!(": polynomial degree {degree} is too large"))),
        }
    }
}

impl TryFrom<String> for Signal {
    type Error = ParseSignalError;

    fn try_from(s: String) -> Result<Self, Self::Error> {
        s.parse()
    }
}

impl From<Signal> for String {
    fn from(signal: Signal) -> String {
        signal.to_string()
    }
}
