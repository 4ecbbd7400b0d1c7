//! The dyadic trees of the adaptive core: [`interval`], the 1D tree of CDV wavelets on
//! `[0, 1]` (two children per wavelet); [`quad`], the 2D tree of the non-standard tensor
//! basis (four children per cell). Both are closed under "parent present", and their leaves
//! (1D) and slots (2D) partition the domain into the cells of the local space.

pub mod interval;
pub mod quad;
