//! The image plane: 2D reconstruction from samples `(x, y, values)` in pixel units on
//! `[0, W] x [0, H]`.

pub mod fit;

pub use fit::{fit_image, ImageFit, ImageFitError, ImageFitParams, ImageLevels, ImageSolveReport};
