//! The domain `[a, b]` of a reconstruction: a validated finite interval with an exact affine
//! map to and from the unit interval `[0, 1]` on which the CDV basis is built. Shared by the
//! basis (which maps positions to `[0, 1]`) and the sample layouts (which place positions in
//! it); re-exported from both. It depends on neither.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::norms::show;

/// Why a [`Domain`] could not be built.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum DomainError {
    /// An endpoint is NaN or infinite.
    #[error(
        "invalid domain [{}, {}]: both endpoints must be finite numbers; \
         pass finite bounds such as a = 0 and b = 1",
        show(*.a),
        show(*.b)
    )]
    NotFinite {
        /// The left endpoint as given.
        a: f64,
        /// The right endpoint as given.
        b: f64,
    },
    /// `a >= b`: the interval is empty or reversed.
    #[error(
        "invalid domain [{a}, {b}]: the left endpoint a = {a} must be strictly less than \
         the right endpoint b = {b}; swap the endpoints or widen the interval",
        a = show(*.a),
        b = show(*.b)
    )]
    NotIncreasing {
        /// The left endpoint as given.
        a: f64,
        /// The right endpoint as given.
        b: f64,
    },
    /// `b - a` overflows to infinity in `f64`.
    #[error(
        "invalid domain [{}, {}]: its width b - a overflows f64 (it exceeds {:e}); \
         rescale the positions (and the domain with them) to a smaller range",
        show(*.a),
        show(*.b),
        f64::MAX
    )]
    TooWide {
        /// The left endpoint as given.
        a: f64,
        /// The right endpoint as given.
        b: f64,
    },
    /// `b - a` is subnormal (below `f64::MIN_POSITIVE`): positions in it have only a few
    /// significant bits relative to the width, and their map to `[0, 1]` loses them.
    #[error(
        "invalid domain [{}, {}]: its width b - a = {:e} is subnormal (below {:e}), so \
         positions in it keep only a few significant bits; rescale the positions (and the \
         domain with them), e.g. multiply them by 1e300",
        show(*.a),
        show(*.b),
        .b - .a,
        f64::MIN_POSITIVE
    )]
    TooNarrow {
        /// The left endpoint as given.
        a: f64,
        /// The right endpoint as given.
        b: f64,
    },
    /// A string given to [`Domain::from_str`] is not of the form `a,b`.
    #[error(
        "cannot read a domain from `{input}`: expected two numbers `a,b` \
         (for example `0,1` or `-2.5,4`)"
    )]
    Parse {
        /// The text that failed to parse.
        input: String,
    },
}

/// A finite closed interval `[a, b]` with `a < b`, the domain of the
/// reconstructed function.
///
/// The fields are private so that every `Domain` is valid; build one with
/// [`Domain::new`] and read the endpoints with [`Domain::a`] and [`Domain::b`].
/// It serialises as `{"a": .., "b": ..}` and deserialisation validates.
///
/// ```
/// use rkwave::sampling::Domain;
///
/// let d = Domain::new(-2.0, 2.0)?;
/// assert_eq!(d.to_unit(0.0), 0.5);
/// assert_eq!(d.from_unit(0.25), -1.0);
/// assert!(Domain::new(1.0, 0.0).is_err()); // reversed: an error, not a panic
/// # Ok::<(), rkwave::sampling::DomainError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RawDomain")]
pub struct Domain {
    a: f64,
    b: f64,
}

/// Unvalidated form used to deserialise a [`Domain`].
#[derive(Deserialize)]
struct RawDomain {
    a: f64,
    b: f64,
}

impl TryFrom<RawDomain> for Domain {
    type Error = DomainError;

    fn try_from(raw: RawDomain) -> Result<Self, Self::Error> {
        Domain::new(raw.a, raw.b)
    }
}

impl Default for Domain {
    fn default() -> Self {
        Domain::UNIT
    }
}

impl Domain {
    /// The unit interval `[0, 1]`.
    pub const UNIT: Domain = Domain { a: 0.0, b: 1.0 };

    /// Builds the interval `[a, b]`.
    ///
    /// Fails if an endpoint is NaN or infinite, if `a >= b`, or if `b - a`
    /// overflows or is subnormal.
    pub fn new(a: f64, b: f64) -> Result<Domain, DomainError> {
        if !a.is_finite() || !b.is_finite() {
            return Err(DomainError::NotFinite { a, b });
        }
        if a >= b {
            return Err(DomainError::NotIncreasing { a, b });
        }
        if !(b - a).is_finite() {
            return Err(DomainError::TooWide { a, b });
        }
        if b - a < f64::MIN_POSITIVE {
            return Err(DomainError::TooNarrow { a, b });
        }
        Ok(Domain { a, b })
    }

    /// The left endpoint `a`.
    pub fn a(&self) -> f64 {
        self.a
    }

    /// The right endpoint `b`.
    pub fn b(&self) -> f64 {
        self.b
    }

    /// The length `b - a` (always finite and positive).
    pub fn length(&self) -> f64 {
        self.b - self.a
    }

    /// Whether `a <= x <= b` (false for NaN).
    pub fn contains(&self, x: f64) -> bool {
        self.a <= x && x <= self.b
    }

    /// The uniform grid of `points` positions `x_g = a + (b - a) g / (G - 1)`, both ends
    /// included (`a` alone for one point, nothing for none): the crate's one grid for
    /// plots, outputs and error measurements.
    ///
    /// ```
    /// use rkwave::domain::Domain;
    ///
    /// let g = Domain::new(-1.0, 3.0)?.uniform_grid(5);
    /// assert_eq!(g, vec![-1.0, 0.0, 1.0, 2.0, 3.0]);
    /// # Ok::<(), rkwave::domain::DomainError>(())
    /// ```
    pub fn uniform_grid(&self, points: usize) -> Vec<f64> {
        (0..points).map(|g| self.grid_point(points, g)).collect()
    }

    /// Point `g` of [`Domain::uniform_grid`]`(points)`, for grids made block by block.
    pub fn grid_point(&self, points: usize, g: usize) -> f64 {
        let last = points.saturating_sub(1).max(1) as f64;
        self.from_unit(g as f64 / last)
    }

    /// Maps `x` to the unit interval: `(x - a) / (b - a)`.
    ///
    /// `a` maps to exactly `0.0` and `b` to exactly `1.0`, and every `x` in
    /// `[a, b]` maps into `[0, 1]` (rounding overshoot is clamped). Points
    /// outside the domain are extrapolated linearly, so they land outside
    /// `[0, 1]`.
    pub fn to_unit(&self, x: f64) -> f64 {
        let t = (x - self.a) / self.length();
        if self.contains(x) {
            t.clamp(0.0, 1.0)
        } else {
            t
        }
    }

    /// Maps `t` from the unit interval to the domain: `a + t (b - a)`.
    ///
    /// `0.0` maps to exactly `a` and `1.0` to exactly `b`, and every `t` in
    /// `[0, 1]` maps into `[a, b]` (clamped). The left half is computed from
    /// `a` and the right half from `b`, which keeps both ends exact. Values of
    /// `t` outside `[0, 1]` are extrapolated linearly.
    pub fn from_unit(&self, t: f64) -> f64 {
        let len = self.length();
        let x = if t <= 0.5 {
            self.a + t * len
        } else {
            // 1 - t is exact for t in [0.5, 2] (Sterbenz), so t = 1 gives b.
            self.b - (1.0 - t) * len
        };
        if (0.0..=1.0).contains(&t) {
            x.clamp(self.a, self.b)
        } else {
            x
        }
    }
}

impl fmt::Display for Domain {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "[{}, {}]", show(self.a), show(self.b))
    }
}

impl FromStr for Domain {
    type Err = DomainError;

    /// Parses `a,b`, optionally wrapped in brackets: `0,1`, `[-1, 2.5]`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let parse_err = || DomainError::Parse {
            input: s.to_string(),
        };
        let inner = s.trim();
        let inner = inner
            .strip_prefix('[')
            .and_then(|r| r.strip_suffix(']'))
            .unwrap_or(inner);
        let (a, b) = inner.split_once(',').ok_or_else(parse_err)?;
        let a: f64 = a.trim().parse().map_err(|_| parse_err())?;
        let b: f64 = b.trim().parse().map_err(|_| parse_err())?;
        Domain::new(a, b)
    }
}

impl DomainError {
    /// The kind of this error ([`crate::error`]): always `ErrorKind::InvalidInput`.
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            DomainError::NotFinite { .. }
            | DomainError::NotIncreasing { .. }
            | DomainError::TooWide { .. }
            | DomainError::TooNarrow { .. }
            | DomainError::Parse { .. } => crate::error::ErrorKind::InvalidInput,
        }
    }
}

crate::error::classified!(DomainError);
