//! The single-scale least squares out of core: `min_v ||K_J v - f||` accumulated chunk by
//! chunk, the samples never held whole.
//!
//! The banded QR `K_J = Q R`, `z = Q^T f` ([`super::single_scale_qr`]) is a reduction over the
//! rows of `K_J`: the triangle of the rows `A` stacked on `B` is the QR of the stacked
//! triangles `[R_A; R_B]` (TSQR). A [`SingleScaleAccumulator`] rotates the rows of one chunk
//! into its triangle ([`SingleScaleAccumulator::add_chunk`]), two accumulators of
//! consecutive chunks merge ([`SingleScaleAccumulator::merge`]), and
//! [`SingleScaleAccumulator::finish`] back-substitutes `R v = z` and applies the FWT. The
//! rows must come in ascending cell order at level `J` (each row then ends where the rows
//! before it end or later, `O(w^2)` per row): samples sorted by position.
//!
//! Bit for bit: [`fit_streamed`] splits the samples into the consecutive ranges the in-memory
//! QR splits them into (`super::single_scale::qr_parts`, one per thread), rotates each range
//! into its own accumulator in file order and merges them left to right, the rotations of
//! [`super::fit`] on samples already in cell order, in the same order: the coefficients are
//! identical. Merging in another tree (a Dask reduction) gives another rounding of the same
//! orthogonal reduction: backward stable, the coefficients within `O(eps cond(K_J))` relative.

use std::ops::Range;
use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;
use thiserror::Error;

use super::single_scale::{qr_parts, solve_triangle};
use super::{
    cell_of, check_values, choose_levels, density, guard_uniform, min_support_of_counts,
    single_scale_fit, undersampled, Fit, FitParams, Levels, Method, ReconstructError,
    SingleScaleReport, SingleScaleSolver,
};
use crate::basis::CdvBasis;
use crate::kernel::{check_positions, KernelError, LevelChoice};
use crate::sampling::Domain;
use crate::solve::band::GivensTriangle;

/// Errors of the streamed single-scale fit.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum StreamError {
    /// Parameters, values or positions (as in [`super::fit`]).
    #[error(transparent)]
    Reconstruct(#[from] ReconstructError),
    /// A sample in an earlier cell than the one before it.
    #[error(
        "sample {row} (1-based) at x = {x} comes after a sample at a larger position: the \
         streamed single-scale QR takes the samples in ascending order of position; sort them \
         by x (numpy: `a[a[:, 0].argsort(kind=\"stable\")]`) or fit them in memory"
    )]
    OutOfOrder {
        /// 1-based sample.
        row: usize,
        /// Its position.
        x: f64,
    },
    /// Two accumulators that cannot merge.
    #[error("these partial fits cannot merge: {problem}")]
    Mismatch {
        /// What differs, and the fix.
        problem: String,
    },
    /// What the streamed path cannot do (the in-memory fit would fall back to a method that
    /// needs the samples in memory).
    #[error("{reason}: the streamed single-scale fit cannot continue; {fix}")]
    NotStreamable {
        /// Why.
        reason: String,
        /// What to do instead.
        fix: String,
    },
    /// Bytes that are not an accumulator's ([`SingleScaleAccumulator::from_bytes`]).
    #[error("not the bytes of a partial fit: {problem}")]
    BadBytes {
        /// What is wrong with them.
        problem: String,
    },
    /// The sample source failed (reading, parsing).
    #[error(transparent)]
    Source(Box<dyn std::error::Error + Send + Sync>),
}

impl StreamError {
    /// The kind of this error ([`crate::error`]): that of the fit's error, else the caller's
    /// input (the samples' order, the partials, the source).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            StreamError::Reconstruct(e) => e.kind(),
            _ => crate::error::ErrorKind::InvalidInput,
        }
    }
}

crate::error::classified!(StreamError);

/// The banded QR triangle of the samples seen so far, at the single-scale level `J = N + 1`
/// of a basis `Psi(n, N)` (module docs).
///
/// ```
/// use rkwave::reconstruct::stream::SingleScaleAccumulator;
/// use rkwave::reconstruct::{single_scale_qr, FitParams};
/// use rkwave::sampling::Domain;
///
/// let xs: Vec<f64> = (0..4000).map(|i| (i as f64 + 0.5) / 4000.0).collect();
/// let f: Vec<f64> = xs.iter().map(|x| (5.0 * x).sin()).collect();
/// let basis = FitParams::default().basis(4, 8, Domain::UNIT)?;
/// let mut left = SingleScaleAccumulator::new(&basis, 1);
/// left.add_chunk(&xs[..1500], &[&f[..1500]])?;
/// let mut right = SingleScaleAccumulator::new(&basis, 1).starting_at(1500);
/// right.add_chunk(&xs[1500..], &[&f[1500..]])?;
/// left.merge(right)?;
/// let (c, _) = left.finish(&basis, 0.0)?;
/// let (whole, _) = single_scale_qr(&basis, &xs, &[&f], 0.0)?;
/// let err = c[0].iter().zip(&whole[0]).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
/// assert!(err < 1e-12);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone)]
pub struct SingleScaleAccumulator {
    scale: CdvBasis,
    channels: usize,
    tri: Option<GivensTriangle>,
    /// 0-based index of this accumulator's first sample in the whole set (errors name rows).
    start: usize,
    samples: usize,
    /// Cells at level `J` of the first and the last sample.
    cells: Option<(usize, usize)>,
}

impl SingleScaleAccumulator {
    /// An empty accumulator for `basis = Psi(n, N)` with `channels` right-hand sides.
    ///
    /// Panics if `basis`'s single-scale level cannot be built (a basis that exists has one).
    pub fn new(basis: &CdvBasis, channels: usize) -> Self {
        let top = basis.fine() + 1;
        let scale = CdvBasis::with_bank(basis.bank().clone(), top, top, basis.domain())
            .expect("the single-scale level of a valid basis");
        Self {
            scale,
            channels,
            tri: None,
            start: 0,
            samples: 0,
            cells: None,
        }
    }

    /// The same accumulator for samples that start at 0-based index `start` of the whole set
    /// (only the rows errors name depend on it).
    pub fn starting_at(mut self, start: usize) -> Self {
        self.start = start;
        self
    }

    /// Samples added so far (merged ones included).
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// Columns of `V_J`: `2^J`.
    fn columns(&self) -> usize {
        self.scale.dimension() / 2
    }

    fn width(&self) -> usize {
        if self.scale.bank().edge_count() == 0 {
            1
        } else {
            3 * self.scale.p() - 2
        }
    }

    /// Rotates the samples `(positions[i], values[c][i])` into the triangle, in order. They
    /// must lie in the domain, follow the samples added before in ascending cell order at
    /// level `J`, and have finite values, one per position in each of the `channels`.
    pub fn add_chunk(&mut self, positions: &[f64], values: &[&[f64]]) -> Result<(), StreamError> {
        let rows = |i: usize| self.start + self.samples + i + 1;
        if values.len() != self.channels {
            return Err(StreamError::Mismatch {
                problem: format!(
                    "a chunk with {} channels for an accumulator of {}: give every chunk the \
                     same channels",
                    values.len(),
                    self.channels
                ),
            });
        }
        check_values(positions.len(), values).map_err(|e| match e {
            ReconstructError::NonFiniteValue {
                row,
                channel,
                value,
            } => ReconstructError::NonFiniteValue {
                row: rows(row - 1),
                channel,
                value,
            },
            other => other,
        })?;
        let domain = self.scale.domain();
        check_positions(domain, positions).map_err(|e| match e {
            KernelError::PositionOutside { row, x, a, b } => {
                ReconstructError::Kernel(KernelError::PositionOutside {
                    row: rows(row - 1),
                    x,
                    a,
                    b,
                })
            }
            other => ReconstructError::Kernel(other),
        })?;
        if positions.is_empty() {
            return Ok(());
        }
        let cells = self.columns();
        let mut last = self.cells.map_or(0, |c| c.1);
        for (i, &x) in positions.iter().enumerate() {
            let c = cell_of(domain.to_unit(x), cells);
            if c < last {
                return Err(StreamError::OutOfOrder { row: rows(i), x });
            }
            last = c;
        }
        let first_cell = cell_of(domain.to_unit(positions[0]), cells);
        self.cells = Some((self.cells.map_or(first_cell, |c| c.0), last));
        let (w, channels) = (self.width(), self.channels);
        let mut ev = self.scale.single_level_evaluator();
        let mut f = vec![0.0; channels];
        for (i, &x) in positions.iter().enumerate() {
            for (fc, vc) in f.iter_mut().zip(values) {
                *fc = vc[i];
            }
            let (first, row) = ev.row_unit(domain.to_unit(x));
            let end = first + row.len();
            let tri = self
                .tri
                .get_or_insert_with(|| GivensTriangle::new(first, 0, w, channels));
            if end > tri.columns().end {
                tri.cover(first, end);
            }
            tri.add_row(first, row, &f);
        }
        self.samples += positions.len();
        Ok(())
    }

    /// Merges the accumulator of the samples that follow this one's (QR of the stacked
    /// triangles). Both must belong to the same basis and channels, and `later`'s samples
    /// must not lie in an earlier cell than this one's last.
    pub fn merge(&mut self, later: SingleScaleAccumulator) -> Result<(), StreamError> {
        if (later.columns(), later.width(), later.channels)
            != (self.columns(), self.width(), self.channels)
        {
            return Err(StreamError::Mismatch {
                problem: format!(
                    "{} columns of band width {} and {} channels against {}, {} and {}: build \
                     every partial with the same basis and channels",
                    self.columns(),
                    self.width(),
                    self.channels,
                    later.columns(),
                    later.width(),
                    later.channels
                ),
            });
        }
        let (Some(other), Some((first, last))) = (later.tri, later.cells) else {
            return Ok(());
        };
        let Some(tri) = self.tri.as_mut() else {
            self.tri = Some(other);
            self.cells = later.cells;
            self.samples = later.samples;
            return Ok(());
        };
        let ours = self.cells.map_or(0, |c| c.1);
        if first < ours {
            return Err(StreamError::Mismatch {
                problem: format!(
                    "the later partial starts in cell {first}, before the earlier one's last \
                     cell {ours}: merge partials of consecutive sorted chunks, earlier first"
                ),
            });
        }
        let span = other.columns();
        tri.cover(span.start, span.end);
        tri.absorb(&other);
        self.cells = self.cells.map(|c| (c.0, last));
        self.samples += later.samples;
        Ok(())
    }

    /// The `Psi(n, N)` coefficients per channel (`basis` the one of [`Self::new`]) and the
    /// solve's report, as [`super::single_scale_qr`] finds them.
    pub fn finish(
        self,
        basis: &CdvBasis,
        ridge: f64,
    ) -> Result<(Vec<Vec<f64>>, SingleScaleReport), StreamError> {
        if basis.fine() + 1 != self.scale.coarse() || basis.domain() != self.scale.domain() {
            return Err(StreamError::Mismatch {
                problem: "finish with the basis the accumulator was built for".into(),
            });
        }
        let (n, w, channels) = (self.columns(), self.width(), self.channels);
        let mut tri = self
            .tri
            .unwrap_or_else(|| GivensTriangle::new(0, n, w, channels));
        tri.cover(0, n);
        Ok(solve_triangle(basis, tri, ridge, self.samples))
    }

    /// The [`Fit`] of the samples accumulated, on `basis = Psi(n, N)` (the one of
    /// [`Self::new`]) with the relative `ridge`: [`Self::finish`], refused with
    /// [`StreamError::NotStreamable`] when the samples leave single-scale directions
    /// undetermined (the in-memory fit would lower the level or invert locally, both of
    /// which need the samples again). The fit's levels are `(n, N)` with the oversampling
    /// `m / 2^{N+1}` of the samples accumulated.
    pub fn finish_fit(self, basis: &CdvBasis, ridge: f64) -> Result<Fit, StreamError> {
        let t0 = Instant::now();
        let m = self.samples;
        let (coefficients, rep) = self.finish(basis, ridge)?;
        if rep.deficient > 0 {
            return Err(deficient(&rep));
        }
        let levels = LevelChoice {
            coarse: basis.coarse(),
            fine: basis.fine(),
            oversampling: m as f64 / 2f64.powi(basis.fine() as i32 + 1),
        };
        Ok(single_scale_fit(
            basis.clone(),
            coefficients,
            levels,
            t0,
            rep,
            0,
        ))
    }

    /// The accumulator as bytes (little-endian), to move between processes;
    /// [`Self::from_bytes`] reads them back with the basis.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = MAGIC.to_vec();
        let mut word = |v: u64| out.extend_from_slice(&v.to_le_bytes());
        let (first, last) = self.cells.unwrap_or((0, 0));
        let head = [
            self.columns() as u64,
            self.width() as u64,
            self.channels as u64,
            self.start as u64,
            self.samples as u64,
            u64::from(self.cells.is_some()),
            first as u64,
            last as u64,
            u64::from(self.tri.is_some()),
        ];
        head.into_iter().for_each(&mut word);
        if let Some(tri) = &self.tri {
            let (sizes, arrays, len) = tri.parts();
            sizes.into_iter().for_each(|s| word(s as u64));
            for a in arrays {
                a.iter().for_each(|v| word(v.to_bits()));
            }
            len.iter().for_each(|&l| word(u64::from(l)));
        }
        out
    }

    /// The accumulator of [`Self::to_bytes`] for `basis` (the one it was built with).
    pub fn from_bytes(bytes: &[u8], basis: &CdvBasis) -> Result<Self, StreamError> {
        let bad = |problem: &str| StreamError::BadBytes {
            problem: problem.to_string(),
        };
        let body = bytes
            .strip_prefix(MAGIC)
            .ok_or_else(|| bad("they do not start with the partial fit's tag"))?;
        if body.len() % 8 != 0 {
            return Err(bad("their length is not a whole number of words"));
        }
        let mut words = body
            .chunks_exact(8)
            .map(|c| u64::from_le_bytes(c.try_into().expect("8 bytes")));
        let mut next = || words.next().ok_or_else(|| bad("they end early"));
        let mut head = [0u64; 9];
        for h in &mut head {
            *h = next()?;
        }
        let [columns, width, channels, start, samples, has_cells, first, last, has_tri] =
            head.map(|v| v as usize);
        let mut acc = Self::new(basis, channels).starting_at(start);
        if (columns, width) != (acc.columns(), acc.width()) {
            return Err(bad(&format!(
                "they hold {columns} columns of band width {width}, the basis has {} and {}",
                acc.columns(),
                acc.width()
            )));
        }
        acc.samples = samples;
        acc.cells = (has_cells == 1).then_some((first, last));
        if has_tri == 1 {
            let mut sizes = [0usize; 4];
            for s in &mut sizes {
                *s = next()? as usize;
            }
            let [_, n, w, ch] = sizes;
            let lens = [n.saturating_mul(w), n.saturating_mul(ch), n, ch];
            if lens.iter().sum::<usize>().saturating_add(n) != body.len() / 8 - 13 {
                return Err(bad("their length does not match the triangle's size"));
            }
            let arrays = lens.map(|l| {
                (0..l)
                    .map(|_| f64::from_bits(next().unwrap_or(0)))
                    .collect()
            });
            let len = (0..n).map(|_| next().unwrap_or(0) as u16).collect();
            let tri = GivensTriangle::from_parts(sizes, arrays, len)
                .ok_or_else(|| bad("the triangle's arrays are inconsistent"))?;
            if tri.columns().end > columns || ch != channels || w != width {
                return Err(bad("the triangle does not fit the basis"));
            }
            acc.tri = Some(tri);
        }
        Ok(acc)
    }
}

/// The tag that starts an accumulator's bytes (format version 1).
const MAGIC: &[u8; 8] = b"RKWSSQ1\n";

/// What [`SampleChunks::read`] calls with each chunk: positions and values per channel.
pub type ChunkSink<'a> = dyn FnMut(&[f64], &[&[f64]]) -> Result<(), StreamError> + 'a;

/// Samples read in consecutive chunks of rows (a `.npy` or CSV file, or any other source).
pub trait SampleChunks: Sync {
    /// Number of samples `m`.
    fn len(&self) -> usize;
    /// Whether there are no samples.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Number of value channels.
    fn channels(&self) -> usize;
    /// Calls `each` with consecutive chunks of the samples `rows` in order: positions and one
    /// slice of values per channel.
    fn read(&self, rows: Range<usize>, each: &mut ChunkSink<'_>) -> Result<(), StreamError>;
}

/// What the streamed fit did besides the fit.
#[derive(Clone, Debug, Default, Serialize)]
pub struct StreamReport {
    /// The passes over the samples, in order, one sentence each.
    pub passes: Vec<String>,
}

/// [`super::fit`] with the single-scale QR on samples read chunk by chunk: the same levels,
/// level drops and coefficients (bit for bit, module docs), the samples never held whole.
/// Needs the samples in ascending order of position ([`StreamError::OutOfOrder`]), and
/// refuses what the in-memory fit answers with a method that needs them all in memory
/// (strongly non-uniform samples: the density tree; undetermined directions: local
/// inversion) with [`StreamError::NotStreamable`].
pub fn fit_streamed(
    source: &dyn SampleChunks,
    domain: Domain,
    params: &FitParams,
) -> Result<(Fit, StreamReport), StreamError> {
    let (m, channels) = (source.len(), source.channels());
    let Method::SingleScale {
        ridge,
        solver: SingleScaleSolver::Qr,
    } = params.method
    else {
        return Err(StreamError::NotStreamable {
            reason: "only the single-scale QR streams its samples".into(),
            fix: "use the single-scale method with the QR solver".into(),
        });
    };
    let mut levels = choose_levels(m, params);
    guard_uniform(m, channels, params, &levels)?;
    crate::resources::check(
        || {
            format!(
                "the streamed banded QR of {m} samples on levels {}..{}",
                levels.coarse, levels.fine
            )
        },
        stream_bytes(params.p, levels.fine, channels),
        || "lower the fine level N (automatic levels: raise rho)".to_string(),
    )
    .map_err(ReconstructError::from)?;
    let auto = matches!(params.levels, Levels::Auto(_));
    let mut report = StreamReport::default();
    let mut dropped = 0u32;
    if auto {
        // The sample count per cell at V_{N+1}; coarser levels add pairs of cells.
        let mut counts = vec![0usize; 1 << (levels.fine + 1)];
        let cells = counts.len();
        let mut seen = 0;
        source.read(0..m, &mut |xs, _| {
            check_positions(domain, xs)
                .map_err(|e| match e {
                    KernelError::PositionOutside { row, x, a, b } => KernelError::PositionOutside {
                        row: seen + row,
                        x,
                        a,
                        b,
                    },
                    other => other,
                })
                .map_err(ReconstructError::from)?;
            for &x in xs {
                counts[cell_of(domain.to_unit(x), cells)] += 1;
            }
            seen += xs.len();
            Ok(())
        })?;
        report
            .passes
            .push("sample counts per cell (automatic levels)".into());
        let coarser =
            |counts: &[usize]| -> Vec<usize> { counts.chunks(2).map(|c| c.iter().sum()).collect() };
        let mut at = vec![counts];
        while at.len() < 4 + 2 && at.last().is_some_and(|c| c.len() > 1) {
            let next = coarser(at.last().expect("one level"));
            at.push(next);
        }
        let top = levels.fine + 1;
        let min_support = |level: u32| -> Option<usize> {
            let k = top.checked_sub(level)? as usize;
            at.get(k).map(|c| min_support_of_counts(c, params.p))
        };
        if let Some(level) = density::inspected_level(m, &levels, params.p) {
            let least = min_support(level).unwrap_or_else(|| {
                let mut c = at.last().expect("one level").clone();
                while c.len() > 1 << level {
                    c = coarser(&c);
                }
                min_support_of_counts(&c, params.p)
            });
            if least < 2 {
                return Err(StreamError::NotStreamable {
                    reason: format!(
                        "the samples are strongly non-uniform (a support of level {level} \
                         holds {least})"
                    ),
                    fix: format!(
                        "the density tree that fits them needs the samples in memory: fit \
                         them in memory (a larger {}) or give fixed levels",
                        crate::error::Fix::Set(crate::error::Param::MemoryLimit)
                    ),
                });
            }
        }
        while dropped < 3
            && levels.fine > levels.coarse
            && min_support(levels.fine + 1).is_some_and(|s| s < 2)
        {
            levels.lower_finest();
            dropped += 1;
        }
    }
    let basis = params
        .basis(levels.coarse, levels.fine, domain)
        .map_err(ReconstructError::from)?;
    if m < basis.dimension() {
        return Err(undersampled(
            m,
            basis.dimension(),
            params.p,
            levels.fine,
            Some(&params.levels),
        )
        .into());
    }
    let t0 = Instant::now();
    while dropped <= 3 && levels.fine >= levels.coarse {
        let basis = params
            .basis(levels.coarse, levels.fine, domain)
            .map_err(ReconstructError::from)?;
        let acc = accumulate(source, &basis)?;
        report.passes.push(format!(
            "banded QR at level {} ({} parts merged in order)",
            levels.fine + 1,
            qr_parts(m).len()
        ));
        let (coefficients, rep) = acc.finish(&basis, ridge)?;
        if rep.deficient == 0 {
            let fit = single_scale_fit(basis, coefficients, levels, t0, rep, dropped);
            return Ok((fit, report));
        }
        if !auto || levels.fine == levels.coarse {
            return Err(deficient(&rep));
        }
        levels.lower_finest();
        dropped += 1;
    }
    Err(StreamError::NotStreamable {
        reason: "the samples leave directions undetermined at every level tried".into(),
        fix: "fit them in memory (local inversion decides them) or give fixed, lower levels".into(),
    })
}

/// Peak bytes of [`fit_streamed`] on levels `..=fine` with `channels`, independent of the
/// number of samples: the triangle over the `P = 2^{N+1}` columns of `V_{N+1}` (band width
/// `w = 3p - 2`, right-hand sides, column norms, row lengths), the parts of the threads
/// before they merge (at most one more triangle), and the solution and FWT vectors.
pub fn stream_bytes(p: usize, fine: u32, channels: usize) -> f64 {
    let columns = crate::resources::dimension(fine);
    let w = (3 * p).saturating_sub(2) as f64;
    let triangle = columns * (8.0 * (w + channels as f64 + 1.0) + 2.0);
    2.0 * triangle + columns * 16.0 * channels as f64
}

fn deficient(rep: &SingleScaleReport) -> StreamError {
    StreamError::NotStreamable {
        reason: format!(
            "{} single-scale directions are undetermined ({} functions without a sample)",
            rep.deficient, rep.unsampled
        ),
        fix: format!(
            "local inversion, which decides them, needs the samples in memory: fit them in \
             memory (a larger {}) or lower the fine level",
            crate::error::Fix::Set(crate::error::Param::MemoryLimit)
        ),
    }
}

/// The triangle of all samples: each range of [`qr_parts`] rotated into its own accumulator
/// (in parallel, each reading its own rows), merged left to right.
fn accumulate(
    source: &dyn SampleChunks,
    basis: &CdvBasis,
) -> Result<SingleScaleAccumulator, StreamError> {
    let channels = source.channels();
    let parts: Vec<Result<SingleScaleAccumulator, StreamError>> = qr_parts(source.len())
        .into_par_iter()
        .map(|rows| {
            let mut acc = SingleScaleAccumulator::new(basis, channels).starting_at(rows.start);
            source.read(rows, &mut |xs, vs| acc.add_chunk(xs, vs))?;
            Ok(acc)
        })
        .collect();
    let mut parts = parts.into_iter();
    let mut acc = parts.next().expect("at least one part")?;
    for part in parts {
        acc.merge(part?)?;
    }
    Ok(acc)
}

/// The samples of slices in memory as [`SampleChunks`] of `chunk` rows (tests, and callers
/// that hold a part of the samples).
pub struct SliceChunks<'a> {
    /// Positions.
    pub positions: &'a [f64],
    /// Values per channel.
    pub values: &'a [&'a [f64]],
    /// Rows per chunk.
    pub chunk: usize,
}

impl SampleChunks for SliceChunks<'_> {
    fn len(&self) -> usize {
        self.positions.len()
    }
    fn channels(&self) -> usize {
        self.values.len()
    }
    fn read(&self, rows: Range<usize>, each: &mut ChunkSink<'_>) -> Result<(), StreamError> {
        let step = self.chunk.max(1);
        for s in rows.clone().step_by(step) {
            let r = s..(s + step).min(rows.end);
            let vs: Vec<&[f64]> = self.values.iter().map(|v| &v[r.clone()]).collect();
            each(&self.positions[r], &vs)?;
        }
        Ok(())
    }
}
