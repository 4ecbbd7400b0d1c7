//! Which pixel estimate the uniform path makes, by name.

use std::fmt;
use std::str::FromStr;

use serde::Serialize;
use thiserror::Error;

/// How a pixel's value is estimated from the samples on the uniform path (the adaptive
/// engine's output has its own choice, [`crate::image::adaptive::PixelEstimate`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize)]
#[serde(into = "String")]
pub enum UniformEstimate {
    /// Per pixel the candidate of least SURE against the box over the window's pixels at its
    /// level (films, SureShrink, mixtures, a robust candidate, the box), projected onto the
    /// local sample range.
    #[default]
    Auto,
    /// The least-squares fit's box pixels (the reconstruction method's output, unchanged).
    Fit,
    /// The fit clamped per pixel to the range of the pixel's samples.
    FitClamped,
    /// The mean of the pixel's samples (the box film).
    Box,
    /// The box pixels, shrunk in cycle-spun Haar at the universal threshold of the samples'
    /// own noise level.
    Shrunk,
}

impl UniformEstimate {
    /// Every estimate, the default first.
    pub const ALL: [UniformEstimate; 5] = [
        UniformEstimate::Auto,
        UniformEstimate::Fit,
        UniformEstimate::FitClamped,
        UniformEstimate::Box,
        UniformEstimate::Shrunk,
    ];

    /// The name on the command line (`auto`, `fit`, `fit-clamped`, `box`, `shrunk`).
    pub fn name(self) -> &'static str {
        match self {
            UniformEstimate::Auto => "auto",
            UniformEstimate::Fit => "fit",
            UniformEstimate::FitClamped => "fit-clamped",
            UniformEstimate::Box => "box",
            UniformEstimate::Shrunk => "shrunk",
        }
    }

    /// Whether the estimate uses the least-squares fit (otherwise only the pixels' samples).
    pub fn uses_fit(self) -> bool {
        matches!(self, UniformEstimate::Fit | UniformEstimate::FitClamped)
    }
}

impl From<UniformEstimate> for String {
    fn from(e: UniformEstimate) -> String {
        e.name().to_string()
    }
}

impl fmt::Display for UniformEstimate {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A pixel-estimate name that is not one of [`UniformEstimate::ALL`].
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("unknown pixel estimate `{name}`: expected auto, fit, fit-clamped, box or shrunk")]
pub struct ParseUniformEstimateError {
    /// The name as given.
    pub name: String,
}

impl FromStr for UniformEstimate {
    type Err = ParseUniformEstimateError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let t = s.trim().to_ascii_lowercase();
        UniformEstimate::ALL
            .into_iter()
            .find(|e| e.name() == t)
            .ok_or_else(|| ParseUniformEstimateError {
                name: s.to_string(),
            })
    }
}
