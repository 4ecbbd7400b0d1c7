//! The tile grid of a `W x H` image: tile size `T`, halo `H_a` (pixels).
//!
//! Tile `t = ty nx_t + tx` (`nx_t = ceil(W / T)` tiles per row, row-major) has the interior
//! pixel rectangle `[tx T, min((tx + 1) T, W)) x [ty T, min((ty + 1) T, H))` (the last
//! column and row of tiles are clipped at the image border) and the fit window
//! `[max(x0 - H_a, 0), min(x1 + H_a, W)] x [max(y0 - H_a, 0), min(y1 + H_a, H)]`: the interior
//! grown by the halo on every side and clipped at the border. Every pixel is in exactly one
//! interior; a sample belongs to every window whose closed rectangle holds it.

use serde::Serialize;
use thiserror::Error;

use crate::image::ImagePlane;

/// A rectangle of pixels `[x0, x1) x [y0, y1)` (pixel units; as a region of the plane, the
/// closed `[x0, x1] x [y0, y1]`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct PixelRect {
    /// First column.
    pub x0: usize,
    /// One past the last column.
    pub x1: usize,
    /// First row.
    pub y0: usize,
    /// One past the last row.
    pub y1: usize,
}

impl PixelRect {
    /// Columns `x1 - x0`.
    pub fn width(&self) -> usize {
        self.x1 - self.x0
    }
    /// Rows `y1 - y0`.
    pub fn height(&self) -> usize {
        self.y1 - self.y0
    }
    /// Pixels `width height`.
    pub fn pixels(&self) -> usize {
        self.width() * self.height()
    }
    /// Whether `(x, y)` lies in the closed rectangle `[x0, x1] x [y0, y1]` (false for NaN).
    pub fn contains(&self, x: f64, y: f64) -> bool {
        (self.x0 as f64..=self.x1 as f64).contains(&x)
            && (self.y0 as f64..=self.y1 as f64).contains(&y)
    }
}

impl std::fmt::Display for PixelRect {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "[{}, {}) x [{}, {})", self.x0, self.x1, self.y0, self.y1)
    }
}

/// Why a tile grid is not usable: each names the value at fault and the way out.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum TileGeometryError {
    /// A tile of 0 pixels.
    #[error(
        "tile size 0: give a tile size of at least 1 pixel (for example {} 128)",
        crate::error::Fix::Set(crate::error::Param::Tile)
    )]
    ZeroTile,
    /// A tile larger than the image on one axis.
    #[error(
        "tile size {tile} is larger than the {width} x {height} image: give a tile size of at \
         most {} pixels, or fit the image untiled (no {})",
        (*width).min(*height),
        crate::error::Fix::Set(crate::error::Param::Tile)
    )]
    TileLargerThanImage {
        /// Tile size asked for.
        tile: usize,
        /// Image width.
        width: usize,
        /// Image height.
        height: usize,
    },
    /// A halo wider than the tile.
    #[error(
        "halo {halo} is larger than the tile size {tile}: give a halo of at most {tile} pixels"
    )]
    HaloLargerThanTile {
        /// Halo asked for.
        halo: usize,
        /// Tile size.
        tile: usize,
    },
    /// A tile index past the last tile.
    #[error("tile {index} does not exist: the grid has tiles 0..{count}")]
    TileIndex {
        /// Index asked for.
        index: usize,
        /// Number of tiles.
        count: usize,
    },
}

/// The tile grid of an image (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct TileGeometry {
    /// The image.
    pub plane: ImagePlane,
    /// Tile size `T` in pixels (square tiles; the last row and column are clipped).
    pub tile: usize,
    /// Halo `H_a` in pixels around each tile's interior.
    pub halo: usize,
}

impl TileGeometry {
    /// The grid of `tile`-pixel tiles with a `halo`-pixel halo on `plane`, validated.
    pub fn new(plane: ImagePlane, tile: usize, halo: usize) -> Result<Self, TileGeometryError> {
        let g = Self { plane, tile, halo };
        g.validate()?;
        Ok(g)
    }

    /// Checks `1 <= T <= min(W, H)` and `H_a <= T`.
    pub fn validate(&self) -> Result<(), TileGeometryError> {
        let (width, height) = (self.plane.width(), self.plane.height());
        if self.tile == 0 {
            return Err(TileGeometryError::ZeroTile);
        }
        if self.tile > width || self.tile > height {
            return Err(TileGeometryError::TileLargerThanImage {
                tile: self.tile,
                width,
                height,
            });
        }
        if self.halo > self.tile {
            return Err(TileGeometryError::HaloLargerThanTile {
                halo: self.halo,
                tile: self.tile,
            });
        }
        Ok(())
    }

    /// Tiles per row and per column `(ceil(W / T), ceil(H / T))`.
    pub fn grid(&self) -> (usize, usize) {
        (
            self.plane.width().div_ceil(self.tile),
            self.plane.height().div_ceil(self.tile),
        )
    }

    /// Number of tiles.
    pub fn count(&self) -> usize {
        let (nx, ny) = self.grid();
        nx * ny
    }

    /// Checks that `index` names a tile.
    pub fn check_index(&self, index: usize) -> Result<(), TileGeometryError> {
        let count = self.count();
        if index >= count {
            return Err(TileGeometryError::TileIndex { index, count });
        }
        Ok(())
    }

    /// `(tx, ty)` of tile `index` (not checked).
    pub fn position(&self, index: usize) -> (usize, usize) {
        let nx = self.grid().0;
        (index % nx, index / nx)
    }

    /// The interior pixels of tile `index` (not checked: see [`Self::check_index`]).
    pub fn interior(&self, index: usize) -> PixelRect {
        let (tx, ty) = self.position(index);
        let t = self.tile;
        PixelRect {
            x0: tx * t,
            x1: ((tx + 1) * t).min(self.plane.width()),
            y0: ty * t,
            y1: ((ty + 1) * t).min(self.plane.height()),
        }
    }

    /// The fit window of tile `index`: its interior grown by the halo, clipped to the image.
    pub fn window(&self, index: usize) -> PixelRect {
        let r = self.interior(index);
        let h = self.halo;
        PixelRect {
            x0: r.x0.saturating_sub(h),
            x1: (r.x1 + h).min(self.plane.width()),
            y0: r.y0.saturating_sub(h),
            y1: (r.y1 + h).min(self.plane.height()),
        }
    }

    /// The tile rows whose windows hold a sample at height `y` (in `[0, H]`): a contiguous
    /// range `lo..=hi`, at most three rows when `H_a <= T`.
    pub fn rows_of(&self, y: f64) -> (usize, usize) {
        Self::span(y, self.tile, self.halo, self.grid().1)
    }

    /// The tile columns whose windows hold a sample at `x` (in `[0, W]`).
    pub fn columns_of(&self, x: f64) -> (usize, usize) {
        Self::span(x, self.tile, self.halo, self.grid().0)
    }

    /// Tiles `k` with `k T - H_a <= v <= (k + 1) T + H_a` (clipped windows give the same set
    /// inside the image).
    fn span(v: f64, tile: usize, halo: usize, n: usize) -> (usize, usize) {
        let (t, h) = (tile as f64, halo as f64);
        let lo = ((v - h) / t).ceil() - 1.0;
        let hi = ((v + h) / t).floor();
        let clamp = |k: f64| (k.max(0.0) as usize).min(n - 1);
        (clamp(lo), clamp(hi))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn geometry(w: usize, h: usize, t: usize, halo: usize) -> TileGeometry {
        TileGeometry::new(ImagePlane::new(w, h).unwrap(), t, halo).unwrap()
    }

    #[test]
    fn interiors_partition_the_pixels() {
        let g = geometry(37, 23, 8, 3);
        let mut seen = vec![0u8; 37 * 23];
        for t in 0..g.count() {
            let r = g.interior(t);
            let w = g.window(t);
            assert!(w.x0 <= r.x0 && r.x1 <= w.x1 && w.y0 <= r.y0 && r.y1 <= w.y1);
            for y in r.y0..r.y1 {
                for x in r.x0..r.x1 {
                    seen[y * 37 + x] += 1;
                }
            }
        }
        assert!(seen.iter().all(|&s| s == 1));
    }

    /// The rows and columns from `rows_of` / `columns_of` are exactly the tiles whose window
    /// holds the point (brute force over all tiles, on grid points and in between).
    #[test]
    fn spans_are_the_windows_holding_a_point() {
        for (t, halo) in [(8, 0), (8, 3), (8, 8), (5, 2)] {
            let g = geometry(37, 23, t, halo);
            for i in 0..=4 * 37 {
                let x = i as f64 / 4.0;
                let (lo, hi) = g.columns_of(x);
                let expect: Vec<usize> = (0..g.grid().0)
                    .filter(|&tx| g.window(tx).contains(x, 0.0))
                    .collect();
                assert_eq!(
                    (lo..=hi).collect::<Vec<_>>(),
                    expect,
                    "t {t} halo {halo} x {x}"
                );
            }
        }
    }

    #[test]
    fn bad_grids_are_refused() {
        let plane = ImagePlane::new(64, 32).unwrap();
        assert_eq!(
            TileGeometry::new(plane, 0, 0),
            Err(TileGeometryError::ZeroTile)
        );
        assert!(matches!(
            TileGeometry::new(plane, 33, 0),
            Err(TileGeometryError::TileLargerThanImage { tile: 33, .. })
        ));
        assert_eq!(
            TileGeometry::new(plane, 8, 9),
            Err(TileGeometryError::HaloLargerThanTile { halo: 9, tile: 8 })
        );
        let g = TileGeometry::new(plane, 8, 8).unwrap();
        assert_eq!(
            g.check_index(32),
            Err(TileGeometryError::TileIndex {
                index: 32,
                count: 32
            })
        );
    }
}
