//! The image plane: pixels of a reconstruction and their filters.

pub mod equivalent_filter;
pub mod pixels;
