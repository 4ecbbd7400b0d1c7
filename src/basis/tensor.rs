//! The tensor CDV basis on the image rectangle `[0, W] x [0, H]` (pixel units).
//!
//! Each axis has its own 1D CDV basis (so non-square and non-power-of-two images work), with
//! single-scale level `Jx` on `[0, W]` and `Jy` on `[0, H]`. The single-scale space is
//! `V_Jx (x) V_Jy`, of dimension `nx ny = 2^Jx 2^Jy`, with functions
//! `Phi_{ky,kx}(x, y) = phi_{Jx,kx}(x) phi_{Jy,ky}(y)`, laid out at `ky * nx + kx`; it is
//! orthonormal on the rectangle because each axis is orthonormal on its interval.
//!
//! The multilevel **non-standard** basis takes `L` steps per axis together:
//! `V_nx (x) V_ny`, then for each step `s = 0..L` (levels `jx = nx + s`, `jy = ny + s`)
//! `W_jx (x) V_jy`, `V_jx (x) W_jy` and `W_jx (x) W_jy`, with `nx = Jx - L`, `ny = Jy - L`,
//! `L = min(Jx, Jy) - j_min(p)`. Its coefficients use the Mallat layout of the same
//! `ny x nx` array: the x index of `phi_{j,k}` is `k`, that of `psi_{j,k}` is `2^j + k` (the
//! global index of [`CdvBasis`]), likewise in y. The 2D FWT between the two layouts applies
//! the orthogonal 1D step ([`fwt::analysis_step`]) to every row, then to every column, of the
//! shrinking low-low block: it is orthogonal, so the multilevel basis is orthonormal too.
//!
//! Pointwise evaluation is separable: the single-scale values at `(x, y)` are the products of
//! the two 1D one-pass evaluations of `V_Jx` and `V_Jy`
//! ([`Evaluator::eval_scaling_unit_into`]), `(2p - 1)^2` products inside the image (a few more
//! beside an edge).

use std::sync::Arc;

use serde::Serialize;
use thiserror::Error;

use super::digits::DigitChains;
use super::{fwt, minimum_level, BasisError, BasisValue, CdvBasis, Evaluator, FilterBank};
use super::{FilterFamily, MAX_LEVEL};
use crate::domain::Domain;

/// Errors of the tensor basis: each names the value at fault and the way out.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum TensorError {
    /// The image has no pixels along an axis.
    #[error("image {axis} is {value} pixels: give a width and height of at least 1 pixel")]
    ZeroResolution {
        /// `"width"` or `"height"`.
        axis: &'static str,
        /// The size given.
        value: usize,
    },
    /// A single-scale level below the smallest usable one for `p` (or above the maximum).
    #[error(
        "single-scale level J = {level} on the {axis} axis is outside {minimum}..={maximum} \
         for p = {p}: choose a level in that range (or ImageLevels::Auto, which stays in it)"
    )]
    LevelOutOfRange {
        /// `"x"` or `"y"`.
        axis: &'static str,
        /// The level asked for.
        level: u32,
        /// Vanishing moments.
        p: usize,
        /// `j_min(p) + 1`: one multilevel step needs a coarse level `>= j_min(p)`.
        minimum: u32,
        /// Largest level.
        maximum: u32,
    },
    /// A position outside the image rectangle (or not finite).
    #[error(
        "position ({}, {}) is outside the image [0, {width}] x [0, {height}] (or not \
         finite): give positions in pixel units within the image",
        crate::norms::show(*.x),
        crate::norms::show(*.y)
    )]
    PositionOutside {
        /// x.
        x: f64,
        /// y.
        y: f64,
        /// Image width.
        width: f64,
        /// Image height.
        height: f64,
    },
    /// The 1D basis could not be built.
    #[error(transparent)]
    Basis(#[from] BasisError),
}

/// Knobs of the automatic level choice per axis.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct TensorLevelParams {
    /// Target samples per single-scale function, `rho = m / (nx ny)`: larger is more stable
    /// (fewer locally undersampled functions), smaller resolves finer detail (docs/design.md
    /// §7 on the resolution of the image-plane basis).
    pub rho: f64,
    /// Highest single-scale resolution allowed, in functions per pixel along an axis
    /// (`2^J <= max_per_pixel * W`): bounds the cost when samples are very dense.
    pub max_per_pixel: f64,
}

impl Default for TensorLevelParams {
    fn default() -> Self {
        Self {
            rho: 4.0,
            max_per_pixel: 2.0,
        }
    }
}

/// Single-scale level of one axis of `size` pixels with `m` samples on the `W x H` image:
/// `J = round(log2(size * sqrt(m / (rho W H))))` (about `sqrt(samples per pixel / rho)`
/// functions per pixel, so `rho` samples per tensor function), clamped to
/// `j_min(p) + 1 ..= floor(log2(max_per_pixel * size))`.
pub fn auto_level(
    size: usize,
    samples: usize,
    pixels: usize,
    p: usize,
    params: TensorLevelParams,
) -> u32 {
    let per_pixel = (samples as f64 / (params.rho.max(1e-12) * pixels.max(1) as f64)).sqrt();
    let target = (size as f64 * per_pixel).max(1.0).log2().round();
    let low = minimum_level(p) + 1;
    let high = (params.max_per_pixel * size as f64)
        .max(1.0)
        .log2()
        .floor()
        .max(low as f64);
    target.clamp(low as f64, high.min(MAX_LEVEL as f64)) as u32
}

/// One nonzero tensor function and its value at a point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TensorValue {
    /// Index `ky * nx + kx` in the layout of the space evaluated.
    pub index: usize,
    /// The value `f_x(x) f_y(y)`.
    pub value: f64,
}

/// The tensor basis on `[0, W] x [0, H]`.
#[derive(Clone, Debug)]
pub struct TensorBasis {
    width: usize,
    height: usize,
    /// Single-scale `Psi(Jx, Jx)` on `[0, W]` (its scaling part is `V_Jx`).
    scale_x: CdvBasis,
    /// Single-scale `Psi(Jy, Jy)` on `[0, H]`.
    scale_y: CdvBasis,
    /// `V_j` bases (`Psi(j, j)`) for `j = nx..Jx` (x axis) and `ny..Jy` (y axis).
    levels_x: Vec<CdvBasis>,
    levels_y: Vec<CdvBasis>,
    /// Multilevel `Psi(nx, Jx - 1)` and `Psi(ny, Jy - 1)`.
    multi_x: CdvBasis,
    multi_y: CdvBasis,
}

fn axis_basis(
    bank: &Arc<FilterBank>,
    level: u32,
    size: usize,
    axis: &'static str,
) -> Result<CdvBasis, TensorError> {
    let minimum = minimum_level(bank.p()) + 1;
    if level < minimum || level > MAX_LEVEL {
        return Err(TensorError::LevelOutOfRange {
            axis,
            level,
            p: bank.p(),
            minimum,
            maximum: MAX_LEVEL,
        });
    }
    let domain = Domain::new(0.0, size as f64).expect("a positive size is a valid domain");
    Ok(CdvBasis::with_bank(bank.clone(), level, level, domain)?)
}

impl TensorBasis {
    /// The basis with single-scale levels `(Jx, Jy)` on a `width x height` image.
    pub fn new(
        p: usize,
        family: FilterFamily,
        width: usize,
        height: usize,
        levels: (u32, u32),
    ) -> Result<Self, TensorError> {
        for (axis, value) in [("width", width), ("height", height)] {
            if value == 0 {
                return Err(TensorError::ZeroResolution { axis, value });
            }
        }
        let bank = FilterBank::shared(p, family)?;
        let scale_x = axis_basis(&bank, levels.0, width, "x")?;
        let scale_y = axis_basis(&bank, levels.1, height, "y")?;
        let steps = levels.0.min(levels.1) - minimum_level(p);
        let (nx, ny) = (levels.0 - steps, levels.1 - steps);
        let per_level = |n: u32, top: u32, d: Domain| {
            (n..=top)
                .map(|j| CdvBasis::with_bank(bank.clone(), j, j, d))
                .collect::<Result<Vec<_>, _>>()
        };
        let (dx, dy) = (scale_x.domain(), scale_y.domain());
        Ok(Self {
            width,
            height,
            levels_x: per_level(nx, levels.0, dx)?,
            levels_y: per_level(ny, levels.1, dy)?,
            multi_x: CdvBasis::with_bank(bank.clone(), nx, levels.0 - 1, dx)?,
            multi_y: CdvBasis::with_bank(bank.clone(), ny, levels.1 - 1, dy)?,
            scale_x,
            scale_y,
        })
    }

    /// The basis with levels from the resolution and the sample count ([`auto_level`]).
    pub fn auto(
        p: usize,
        family: FilterFamily,
        width: usize,
        height: usize,
        samples: usize,
        params: TensorLevelParams,
    ) -> Result<Self, TensorError> {
        let pixels = width.saturating_mul(height);
        let jx = auto_level(width, samples, pixels, p, params);
        let jy = auto_level(height, samples, pixels, p, params);
        Self::new(p, family, width, height, (jx, jy))
    }

    /// Image width `W` in pixels.
    pub fn width(&self) -> usize {
        self.width
    }
    /// Image height `H` in pixels.
    pub fn height(&self) -> usize {
        self.height
    }
    /// Vanishing moments `p`.
    pub fn p(&self) -> usize {
        self.scale_x.p()
    }
    /// The shared filter bank.
    pub fn bank(&self) -> &Arc<FilterBank> {
        self.scale_x.bank()
    }
    /// Single-scale levels `(Jx, Jy)`.
    pub fn levels(&self) -> (u32, u32) {
        (self.scale_x.coarse(), self.scale_y.coarse())
    }
    /// Coarse levels `(nx, ny)` of the non-standard basis.
    pub fn coarse_levels(&self) -> (u32, u32) {
        (self.multi_x.coarse(), self.multi_y.coarse())
    }
    /// Non-standard steps `L` (levels of wavelets per axis).
    pub fn steps(&self) -> u32 {
        self.scale_x.coarse() - self.multi_x.coarse()
    }
    /// `(nx, ny) = (2^Jx, 2^Jy)`.
    pub fn dims(&self) -> (usize, usize) {
        (1usize << self.levels().0, 1usize << self.levels().1)
    }
    /// `nx ny`, the dimension of both the single-scale and the multilevel basis.
    pub fn len(&self) -> usize {
        let (nx, ny) = self.dims();
        nx * ny
    }
    /// Always false (a basis has at least `2^(2 j_min + 2)` functions).
    pub fn is_empty(&self) -> bool {
        false
    }
    /// The x axis single-scale basis `Psi(Jx, Jx)` on `[0, W]` (its scaling part is `V_Jx`).
    pub fn scale_x(&self) -> &CdvBasis {
        &self.scale_x
    }
    /// The y axis single-scale basis `Psi(Jy, Jy)` on `[0, H]`.
    pub fn scale_y(&self) -> &CdvBasis {
        &self.scale_y
    }

    /// Checks that `(x, y)` lies in the image (NaN fails).
    pub fn check(&self, x: f64, y: f64) -> Result<(), TensorError> {
        if self.scale_x.domain().contains(x) && self.scale_y.domain().contains(y) {
            Ok(())
        } else {
            Err(TensorError::PositionOutside {
                x,
                y,
                width: self.width as f64,
                height: self.height as f64,
            })
        }
    }

    /// An evaluator of the single-scale space with its own scratch (one per thread).
    pub fn evaluator(&self) -> TensorEvaluator<'_> {
        TensorEvaluator {
            basis: self,
            ex: self.scale_x.evaluator(),
            ey: self.scale_y.evaluator(),
            vx: Vec::with_capacity(16),
            vy: Vec::with_capacity(16),
        }
    }

    /// 2D non-standard FWT analysis: single-scale coefficients (`ny x nx`, row-major) to the
    /// multilevel coefficients in the Mallat layout.
    pub fn analysis(&self, single: &[f64]) -> Vec<f64> {
        self.transform(single, true)
    }

    /// 2D non-standard FWT synthesis (the transpose, hence the inverse, of [`Self::analysis`]).
    pub fn synthesis(&self, coefficients: &[f64]) -> Vec<f64> {
        self.transform(coefficients, false)
    }

    /// The 2D non-standard FWT, level by level: every row by the x step, then every column
    /// by the y step (they commute). Both passes run in parallel over rows, each entry summed
    /// in the order of the 1D step ([`fwt::StepMatrix`]), so the bits are those of
    /// [`fwt::analysis_step`] / [`fwt::synthesis_step`] applied line by line whatever the
    /// thread count. The column pass combines whole rows (`y_o = sum_i w_oi x_i`, contiguous).
    fn transform(&self, data: &[f64], analysis: bool) -> Vec<f64> {
        use rayon::prelude::*;
        let (nx, ny) = self.dims();
        assert_eq!(data.len(), nx * ny, "2D FWT input length");
        let bank = self.bank();
        let (cx, cy) = self.coarse_levels();
        let mut x = data.to_vec();
        // the column pass's output: a buffer kept per thread (a fresh one per call cost its
        // page faults every PCG iteration); every entry read is written first
        let mut y = FWT_SCRATCH.with(|b| b.take());
        y.resize(nx * ny, 0.0);
        let order: Vec<u32> = if analysis {
            (0..self.steps()).rev().collect()
        } else {
            (0..self.steps()).collect()
        };
        for s in order {
            let (jx, jy) = (cx + s, cy + s);
            let (lx, ly) = (2usize << jx, 2usize << jy);
            let step_x = fwt::StepMatrix::new(bank, jx, analysis);
            let step_y = fwt::StepMatrix::new(bank, jy, analysis);
            // the row pass `ROWS` rows at a time ([`fwt::StepMatrix::apply_rows`])
            x[..ly * nx].par_chunks_mut(ROWS * nx).for_each_init(
                || vec![0.0; ROWS * lx],
                |out, rows| {
                    if rows.len() == ROWS * nx {
                        step_x.apply_rows::<ROWS>(rows, nx, out);
                        for (row, o) in rows.chunks_mut(nx).zip(out.chunks(lx)) {
                            row[..lx].copy_from_slice(o);
                        }
                    } else {
                        for row in rows.chunks_mut(nx) {
                            step_x.apply(&row[..lx], &mut out[..lx]);
                            row[..lx].copy_from_slice(&out[..lx]);
                        }
                    }
                },
            );
            y[..ly * nx]
                .par_chunks_mut(nx)
                .enumerate()
                .for_each(|(o, out)| {
                    let out = &mut out[..lx];
                    out.iter_mut().for_each(|v| *v = 0.0);
                    let (input, weight) = step_y.entries(o);
                    for (&i, &w) in input.iter().zip(weight) {
                        for (v, &xv) in out.iter_mut().zip(&x[i * nx..i * nx + lx]) {
                            *v += w * xv;
                        }
                    }
                });
            if lx == nx && ly == ny {
                // the level covers the whole layout: the output is all of `y`
                std::mem::swap(&mut x, &mut y);
            } else {
                x[..ly * nx]
                    .par_chunks_mut(nx)
                    .zip(y[..ly * nx].par_chunks(nx))
                    .for_each(|(xr, yr)| xr[..lx].copy_from_slice(&yr[..lx]));
            }
        }
        FWT_SCRATCH.with(|b| b.replace(y));
        x
    }

    /// An evaluator of the multilevel non-standard basis (Mallat layout indices).
    pub fn multilevel_evaluator(&self) -> MultilevelEvaluator<'_> {
        MultilevelEvaluator {
            basis: self,
            wx: self.multi_x.evaluator(),
            wy: self.multi_y.evaluator(),
            sx: self.levels_x.iter().map(|b| b.evaluator()).collect(),
            sy: self.levels_y.iter().map(|b| b.evaluator()).collect(),
            buf_wx: Vec::new(),
            buf_wy: Vec::new(),
            buf_sx: vec![Vec::new(); self.levels_x.len()],
            buf_sy: vec![Vec::new(); self.levels_y.len()],
            chain_x: DigitChains::default(),
            chain_y: DigitChains::default(),
        }
    }
}

/// Rows of the 2D FWT's row pass summed together (independent sums interleaved).
const ROWS: usize = 4;

thread_local! {
    /// Scratch of [`TensorBasis`]'s 2D FWT, one per thread.
    static FWT_SCRATCH: std::cell::RefCell<Vec<f64>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Evaluates every nonzero single-scale tensor function at a point; one per thread.
pub struct TensorEvaluator<'a> {
    basis: &'a TensorBasis,
    ex: Evaluator<'a>,
    ey: Evaluator<'a>,
    vx: Vec<BasisValue>,
    vy: Vec<BasisValue>,
}

impl TensorEvaluator<'_> {
    /// The 1D values `phi_{Jx,kx}(x)` and `phi_{Jy,ky}(y)` (unchecked positions in pixel
    /// units), ascending indices: the two factors of the tensor row.
    pub fn factors_unchecked(&mut self, x: f64, y: f64) -> (&[BasisValue], &[BasisValue]) {
        let b = self.basis;
        self.ex
            .eval_scaling_unit_into(b.scale_x.domain().to_unit(x), &mut self.vx);
        self.ey
            .eval_scaling_unit_into(b.scale_y.domain().to_unit(y), &mut self.vy);
        (&self.vx, &self.vy)
    }

    /// Every nonzero single-scale function at `(x, y)`, ascending index, into `out`.
    pub fn eval_into(
        &mut self,
        x: f64,
        y: f64,
        out: &mut Vec<TensorValue>,
    ) -> Result<(), TensorError> {
        self.basis.check(x, y)?;
        let nx = self.basis.dims().0;
        let (fx, fy) = self.factors_unchecked(x, y);
        out.clear();
        for vy in fy {
            for vx in fx {
                out.push(TensorValue {
                    index: vy.index * nx + vx.index,
                    value: vy.value * vx.value,
                });
            }
        }
        Ok(())
    }
}

/// Evaluates every nonzero function of the multilevel non-standard basis at a point, from the
/// 1D evaluations of `Psi(nx, Jx - 1)` (all wavelets) and of `V_j`, `j = nx..Jx` (and y).
/// `L + 2` one-pass evaluations per axis: for tests, figures and a few points, not for the
/// solve (which works in the single-scale space).
pub struct MultilevelEvaluator<'a> {
    basis: &'a TensorBasis,
    wx: Evaluator<'a>,
    wy: Evaluator<'a>,
    sx: Vec<Evaluator<'a>>,
    sy: Vec<Evaluator<'a>>,
    buf_wx: Vec<BasisValue>,
    buf_wy: Vec<BasisValue>,
    buf_sx: Vec<Vec<BasisValue>>,
    buf_sy: Vec<Vec<BasisValue>>,
    chain_x: DigitChains,
    chain_y: DigitChains,
}

/// The wavelets of level `j` (global indices `2^j..2^{j+1}`) in a `Psi(n, N)` evaluation
/// (ascending indices, so a contiguous run).
fn wavelets_of(values: &[BasisValue], j: u32) -> &[BasisValue] {
    let (lo, hi) = (1usize << j, 2usize << j);
    let start = values.partition_point(|v| v.index < lo);
    let end = values.partition_point(|v| v.index < hi);
    &values[start..end]
}

impl MultilevelEvaluator<'_> {
    /// Every nonzero multilevel function at `(x, y)` (Mallat layout index), into `out`,
    /// ascending index.
    pub fn eval_into(
        &mut self,
        x: f64,
        y: f64,
        out: &mut Vec<TensorValue>,
    ) -> Result<(), TensorError> {
        self.eval_unordered_into(x, y, out)?;
        out.sort_unstable_by_key(|v| v.index);
        Ok(())
    }

    /// [`Self::eval_into`] without the sort: the same values, level by level (coarse
    /// scaling functions, then per level the wavelet-scaling, scaling-wavelet and
    /// wavelet-wavelet products). For sums over samples per function, where the order within
    /// a row does not matter (each index occurs once): sorting the ~`28 (2p - 1)^2` entries
    /// of a row was about half of evaluating it (p = 2, 8 levels).
    pub fn eval_unordered_into(
        &mut self,
        x: f64,
        y: f64,
        out: &mut Vec<TensorValue>,
    ) -> Result<(), TensorError> {
        self.eval_unordered_steps_into(x, y, self.basis.steps(), out)
    }

    /// [`Self::eval_unordered_into`] for the coarse scaling functions and the first `steps`
    /// steps' functions only (levels `c..c + steps` per axis; `steps` at most the basis's):
    /// the same values in the same order, a prefix of the whole row. The scaling functions
    /// of the deeper levels, which the products need and whose evaluation costs most, are
    /// not evaluated: for sums over a tree that is shallower than the basis around the point.
    pub fn eval_unordered_steps_into(
        &mut self,
        x: f64,
        y: f64,
        steps: u32,
        out: &mut Vec<TensorValue>,
    ) -> Result<(), TensorError> {
        out.clear();
        self.for_each_steps(x, y, steps, |index, value| {
            out.push(TensorValue { index, value })
        })
    }

    /// Calls `visit(index, value)` for the values of
    /// [`Self::eval_unordered_steps_into`], in its order, without collecting them (for
    /// sums over samples per function). Each axis's evaluations of the point share their
    /// digit states ([`DigitChains`]): one digit walk per axis instead of one per level, the
    /// same values bit for bit.
    pub(crate) fn for_each_steps(
        &mut self,
        x: f64,
        y: f64,
        steps: u32,
        mut visit: impl FnMut(usize, f64),
    ) -> Result<(), TensorError> {
        let b = self.basis;
        b.check(x, y)?;
        let steps = steps.min(b.steps());
        let nx = b.dims().0;
        let (tx, ty) = (b.scale_x.domain().to_unit(x), b.scale_y.domain().to_unit(y));
        let (chain_x, chain_y) = (&mut self.chain_x, &mut self.chain_y);
        self.wx
            .eval_unit_sharing_into(tx, chain_x, &mut self.buf_wx);
        self.wy
            .eval_unit_sharing_into(ty, chain_y, &mut self.buf_wy);
        // levels `c..c + steps` (the coarse one at least); the finest, `V_J`, is never a
        // factor of a multilevel function
        let used = steps.max(1) as usize;
        for (e, buf) in self.sx.iter_mut().zip(&mut self.buf_sx).take(used) {
            e.eval_scaling_unit_sharing_into(tx, chain_x, buf);
        }
        for (e, buf) in self.sy.iter_mut().zip(&mut self.buf_sy).take(used) {
            e.eval_scaling_unit_sharing_into(ty, chain_y, buf);
        }
        let mut products = |fy: &[BasisValue], fx: &[BasisValue]| {
            for vy in fy {
                for vx in fx {
                    visit(vy.index * nx + vx.index, vy.value * vx.value);
                }
            }
        };
        products(&self.buf_sy[0], &self.buf_sx[0]);
        let (cx, cy) = b.coarse_levels();
        for s in 0..steps {
            let wxs = wavelets_of(&self.buf_wx, cx + s);
            let wys = wavelets_of(&self.buf_wy, cy + s);
            products(&self.buf_sy[s as usize], wxs);
            products(wys, &self.buf_sx[s as usize]);
            products(wys, wxs);
        }
        Ok(())
    }
}

impl TensorError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            TensorError::ZeroResolution { .. }
            | TensorError::LevelOutOfRange { .. }
            | TensorError::PositionOutside { .. } => crate::error::ErrorKind::InvalidInput,
            TensorError::Basis(e) => e.kind(),
        }
    }
}

crate::error::classified!(TensorError);
