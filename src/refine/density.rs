//! Trees from sample density, for samples we did not choose (seed supplement §4: "decide on
//! the local depth of the wavelet tree based on the number of samples in a neighborhood"): the
//! tree ([`density_tree`], [`empty_regions`]) lives in the adaptive core
//! ([`crate::adaptive::density`]), the fit on it ([`fit_density_tree`]) beside the uniform fit
//! that falls back to it ([`crate::reconstruct::fit`]); both are re-exported here.

pub use crate::adaptive::density::{density_tree, empty_regions};
pub use crate::reconstruct::density::{
    fit_density_tree, fit_density_tree_with, strongly_non_uniform, DensityOptions,
};
