//! Tiles with halos: the image-plane least-squares fit ([`crate::image::fit`]) computed tile
//! by tile in bounded memory.
//!
//! **The untiled fit.** On a `W x H` image with `m` samples the fit lives in the single-scale
//! space `V_Jx (x) V_Jy` of CDV interval bases on `[0, W]` and `[0, H]`, with
//! `J = auto_level(size, m, W H, p, rho)` per axis ([`crate::basis::tensor::auto_level`]):
//! `2^Jx` functions on cells of width `W / 2^Jx` pixels, and it solves
//! `G z = K^T f`, `G = K^T K` over all samples.
//!
//! **A tile.** The grid ([`TileGeometry`]) gives tile `t` its interior pixels `R_t` and its
//! window `R_t^+` (the interior grown by the halo, clipped at the border). The tile's basis
//! is **the untiled basis restricted to the window**: the same levels (from the whole
//! image's `m`, never from the tile's own samples), the same functions
//! `phi_{Jx,kx} (x) phi_{Jy,ky}` (the image's edge functions at the image border, interior
//! translates elsewhere, on the same cells), keeping those whose support meets `R_t^+`. The
//! tile solves the untiled normal equations restricted to those functions and to the samples
//! in `R_t^+`:
//! `G_t z_t = K_t^T f_t`, `K_t[i, k] = Phi_k(x_i, y_i)`, `(x_i, y_i) in R_t^+`,
//! with the same equilibration and relative ridge, and keeps the box (or film-filtered)
//! pixels `I = B_y Z_t B_x^T` of its interior. Functions near the window's edge are only
//! partly sampled; their error, like the local inversion's, decays away from the edge, so the
//! interior's difference to the untiled fit falls with the halo; a window that covers the
//! whole image is the untiled fit (up to summation order). Every tile is solved by the sparse
//! Cholesky, so "the untiled fit" here is its exact solution: the untiled default's CG
//! iterate (relative residual `1e-6`) differs from it by up to `cond(G) 1e-6`, which near
//! Nyquist is `1e-4` to `1e-2` of the value range, for every halo ([`TiledReport::solver`]).
//!
//! **Purity.** [`fit_tile`] reads nothing but its arguments and sums samples in the order
//! given, on the calling thread: the same samples give the same bits whatever the worker
//! count or the order tiles run in.

pub mod fit;
pub mod geometry;
pub mod spill;

pub use fit::{fit_tile, window_samples, TileBasis, TileError, TileImage, TileParams, TileReport};
pub use geometry::{PixelRect, TileGeometry, TileGeometryError};
pub mod tiled;

pub use tiled::{
    reconstruct_tiled, tiled_estimate, TiledError, TiledInput, TiledOutput, TiledParams,
    TiledReport,
};

use crate::error::ErrorKind;

/// The halo of `reconstruct --dim 2 --tile` when none is given, in pixels: the smallest
/// halo of the halo study (docs/measurements/image-plane.md) whose tiled image is within `1e-6` of
/// the value range of the untiled one.
pub const DEFAULT_HALO: usize = 12;

impl TileGeometryError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> ErrorKind {
        ErrorKind::InvalidInput
    }
}

crate::error::classified!(TileGeometryError);

impl TileError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> ErrorKind {
        match self {
            TileError::Geometry(e) => e.kind(),
            TileError::Basis(e) => e.kind(),
            TileError::Pixels(e) => e.kind(),
            TileError::Unsolvable { .. } => ErrorKind::Numerical,
            TileError::Thread { .. } => ErrorKind::ResourceLimit,
            _ => ErrorKind::InvalidInput,
        }
    }
}

crate::error::classified!(TileError);

impl TiledError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> ErrorKind {
        match self {
            TiledError::Io(e) => e.kind(),
            TiledError::Tile(e) => e.kind(),
            TiledError::Resources(e) => e.kind(),
            TiledError::Scratch(_) => ErrorKind::WriteFailed,
            _ => ErrorKind::InvalidInput,
        }
    }
}

crate::error::classified!(TiledError);
