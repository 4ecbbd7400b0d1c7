//! Resource guards: what a request will need, estimated before anything large is allocated,
//! against a memory limit derived from the machine.
//!
//! Every estimate is a lower bound of the bytes the request holds at its peak, computed in
//! `f64` (so `2^61` functions or `u64::MAX` samples do not overflow the estimate itself):
//!
//! - a uniform basis `Psi(n, N)`: `P = 2^{N+1}` functions, one coefficient vector per
//!   channel plus the single-scale band of the normal equations,
//!   `8 P ((2p - 1) + 2 channels)` bytes;
//! - a kernel matrix `K` (`m` samples): at most `(2p - 1)(N - n + 2)` nonzeros per row,
//!   stored with its transpose, 16 bytes each (value and index), twice;
//! - a dense local block `r x n` (local inversion): the block, its factor and the `n x g`
//!   result, `8 (2 r n + n^2 + n g)` bytes per block and one block per thread;
//! - a grid of `G` positions: `8 G (1 + channels)` bytes.
//!
//! On the image plane one estimate serves every path ([`ImageRequest`] →
//! [`ImageEstimate`]: the uniform fit, local inversion, the adaptive tree fit by the direct
//! solve or PCG, the plan's rounds, `image` and `compare`), by part, from sizes alone
//! (samples `m`, channels `c`, pixels, `p`, functions `P`, tree levels `L`), in bytes:
//!
//! - samples: `8 m (2 + c)` held, three times while a file is read (its bytes, the decoded
//!   table, the samples);
//! - positions handed out or generated: `16 n`;
//! - the uniform fit's normal matrix on the `(4p - 3)^2` stencil, upper triangle, values and
//!   indices, twice (the matrix and the copy factored): `16 P (4p - 3)^2`; its sparse Cholesky
//!   factor under nested dissection, `nnz(L) ~ kappa (2p - 1)^2 P log2 P` entries of 8 bytes
//!   (the top separators of a 2D grid; `kappa` = [`FACTOR_FILL`]), up to `64²` functions; above,
//!   the fit is PCG (the image fit's `NormalSolver::Auto`): no factor, `64 P c` of vectors;
//! - local inversion: the kernel matrix and its transpose, `32 m (2p - 1)^2`;
//! - the tree fit on `L` levels: kernel rows of `r = 2 (2p - 1)^2 L` entries per sample
//!   (`32 m r` with the transpose, the direct solve; `8 m r` for the matrix-free PCG), the
//!   normal matrix with `g = (4p - 3)^2 (2L + 1)` entries per function (48 bytes each: the
//!   matrix continued between rounds and the copy factored), its factor `f = 2.1 g` entries
//!   per function (8 bytes); `P = m / rho` functions at most (`rho` samples per leaf);
//! - output images `8 W H c` each, and one more for the encoded file;
//! - scratch: right-hand sides and coefficients, `24 P c`.
//!
//! The stencil and row counts follow from the supports (`2p - 1` cells per axis); the fill
//! constants are calibrated against the solver's own counts (`normal_nnz`, `factor_nnz` of
//! `--json`) and the child's peak resident memory is checked against the total in
//! `tests/hardening_image.rs` (docs/measurements/image-plane.md, "Image plane: resource
//! estimates").
//!
//! The limit is three quarters of `MemTotal` in `/proc/meminfo` (8 GiB where that file
//! does not exist), or what [`set_memory_limit`] set (the command line's `--memory-limit`).
//! A request above it is refused with [`ResourceError::TooLarge`], which says what it would
//! need and which parameter to change.

use std::sync::atomic::{AtomicU64, Ordering};

use thiserror::Error;

use crate::error::Fix;

/// The largest uniform image fit (functions) that the image fit's `NormalSolver::Auto` solves by
/// the sparse Cholesky; above it, Jacobi PCG (no factor). Defined here, where the memory
/// estimate needs it, and used by the image fit (`image::fit::CHOLESKY_MAX_FUNCTIONS`).
pub const UNIFORM_CHOLESKY_MAX_FUNCTIONS: usize = 64 * 64;

/// The limit when the machine's memory cannot be read: 8 GiB.
pub const FALLBACK_LIMIT: u64 = 8 << 30;

/// Zero = not set (derive from the machine).
static LIMIT: AtomicU64 = AtomicU64::new(0);

/// A request refused before allocating.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum ResourceError {
    /// The estimated memory exceeds the limit.
    #[error(
        "{what} would need about {} of memory, above the limit of {}: {fix} \
         (or raise the memory limit)",
        format_bytes(*needed),
        format_bytes(*limit as f64)
    )]
    TooLarge {
        /// What was requested, with its size.
        what: String,
        /// Estimated bytes.
        needed: f64,
        /// The limit in bytes.
        limit: u64,
        /// Which parameter to change, and how.
        fix: Advice,
    },
    /// A memory limit that cannot be read.
    #[error(
        "memory limit {value:?} is not a size: give bytes or a number with K, M, G or T, e.g. 4G"
    )]
    BadLimit {
        /// The text given.
        value: String,
    },
}

/// Which parameters to change to fit a request in memory: words made where the error was
/// made, or words with typed fixes ([`Fix`]) spelled where the error is printed (each front
/// end's flags or keywords, [`crate::error::spelled`]), so a library message names no flag.
#[derive(Debug, Clone, PartialEq)]
pub enum Advice {
    /// Words, as given.
    Words(String),
    /// A template whose `{}` are replaced by the fixes in order.
    Fixes(&'static str, Vec<Fix>),
}

impl std::fmt::Display for Advice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Advice::Words(words) => f.write_str(words),
            Advice::Fixes(template, fixes) => {
                let mut fixes = fixes.iter();
                let mut parts = template.split("{}");
                f.write_str(parts.next().unwrap_or(""))?;
                for part in parts {
                    match fixes.next() {
                        Some(fix) => write!(f, "{fix}")?,
                        None => f.write_str("{}")?,
                    }
                    f.write_str(part)?;
                }
                Ok(())
            }
        }
    }
}

/// Sets the process-wide memory limit in bytes (`None`: derive it from the machine again).
pub fn set_memory_limit(bytes: Option<u64>) {
    LIMIT.store(bytes.unwrap_or(0), Ordering::Relaxed);
}

/// `MemTotal` of `/proc/meminfo` in bytes, if readable.
pub fn machine_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kb.checked_mul(1024)
}

/// The limit in bytes: [`set_memory_limit`]'s, or 3/4 of the machine's memory, or
/// [`FALLBACK_LIMIT`].
pub fn memory_limit() -> u64 {
    match LIMIT.load(Ordering::Relaxed) {
        0 => machine_memory().map_or(FALLBACK_LIMIT, |t| t / 4 * 3),
        l => l,
    }
}

/// Parses a size: plain bytes, or a number followed by `K`, `M`, `G` or `T` (powers of
/// 1024, an optional trailing `B`/`iB`), e.g. `512M`, `4G`, `1.5T`.
pub fn parse_size(text: &str) -> Result<u64, ResourceError> {
    let bad = || ResourceError::BadLimit {
        value: text.to_string(),
    };
    let t = text.trim();
    let t = t
        .strip_suffix("iB")
        .or_else(|| t.strip_suffix('B'))
        .unwrap_or(t);
    let (num, mult) = match t.chars().last() {
        Some(c @ ('K' | 'k' | 'M' | 'm' | 'G' | 'g' | 'T' | 't')) => {
            let e = match c.to_ascii_uppercase() {
                'K' => 10,
                'M' => 20,
                'G' => 30,
                _ => 40,
            };
            (&t[..t.len() - 1], (1u64 << e) as f64)
        }
        _ => (t, 1.0),
    };
    let v: f64 = num.trim().parse().map_err(|_| bad())?;
    let bytes = v * mult;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64) {
        return Err(bad());
    }
    Ok(bytes as u64)
}

/// `1.5 GB`-style text (powers of 1024, three significant digits; `{:e}` beyond exabytes).
pub fn format_bytes(bytes: f64) -> String {
    const UNITS: [&str; 7] = ["B", "KB", "MB", "GB", "TB", "PB", "EB"];
    if !bytes.is_finite() || bytes >= 1024f64.powi(7) {
        return format!("{bytes:.2e} bytes");
    }
    let mut v = bytes.max(0.0);
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{v:.0} B")
    } else {
        format!("{v:.1} {}", UNITS[u])
    }
}

/// Refuses `needed` bytes above [`memory_limit`]; `what` names the request and its size,
/// `fix` the parameter to change.
pub fn check(
    what: impl FnOnce() -> String,
    needed: f64,
    fix: impl FnOnce() -> String,
) -> Result<(), ResourceError> {
    check_advised(what, needed, || Advice::Words(fix()))
}

/// [`check`] with the fix as [`Advice`] (typed fixes spelled where the error is printed).
pub fn check_advised(
    what: impl FnOnce() -> String,
    needed: f64,
    fix: impl FnOnce() -> Advice,
) -> Result<(), ResourceError> {
    let limit = memory_limit();
    if needed.is_nan() || needed > limit as f64 {
        return Err(ResourceError::TooLarge {
            what: what(),
            needed,
            limit,
            fix: fix(),
        });
    }
    Ok(())
}

/// Functions of a uniform `Psi(n, N)`: `2^{N+1}` (as `f64`, exact for every level).
pub fn dimension(fine: u32) -> f64 {
    2f64.powi(fine as i32 + 1)
}

/// Bytes of a uniform basis with `channels` coefficient vectors and the single-scale band
/// of the normal equations: `8 P ((2p - 1) + 2 channels)`.
pub fn uniform_basis_bytes(p: usize, fine: u32, channels: usize) -> f64 {
    8.0 * dimension(fine) * ((2 * p).saturating_sub(1) as f64 + 2.0 * channels as f64)
}

/// Bytes of a kernel matrix of `m` samples on levels `n..=N` (with its transpose):
/// `2 * 16 * m (2p - 1)(N - n + 2)`.
pub fn kernel_bytes(m: usize, p: usize, coarse: u32, fine: u32) -> f64 {
    let per_row = (2 * p).saturating_sub(1) as f64 * (fine.saturating_sub(coarse) as f64 + 2.0);
    32.0 * m as f64 * per_row
}

/// Bytes of one dense local block `r x n` serving `g` pivots: `8 (2 r n + n^2 + n g)`.
pub fn dense_block_bytes(rows: usize, cols: usize, pivots: usize) -> f64 {
    let (r, n, g) = (rows as f64, cols as f64, pivots as f64);
    8.0 * (2.0 * r * n + n * n + n * g)
}

/// Bytes of `len` positions with `channels` values each: `8 len (1 + channels)`.
pub fn grid_bytes(len: usize, channels: usize) -> f64 {
    8.0 * len as f64 * (1.0 + channels as f64)
}

/// Nested-dissection fill of the uniform image fit's factor: `nnz(L) = FACTOR_FILL (2p -
/// 1)^2 P log2 P` (module docs).
pub const FACTOR_FILL: f64 = 1.3;

/// Factor entries per normal-matrix entry of the tree fit (module docs).
pub const TREE_FACTOR_PER_NORMAL: f64 = 2.1;

/// How an image-plane request fits its samples: what decides the large parts of
/// [`ImageEstimate`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum ImageSolve {
    /// No basis: film filters or positions alone.
    None,
    /// The uniform tensor fit on `functions` single-scale functions by sparse Cholesky.
    Uniform {
        /// Vanishing moments.
        p: usize,
        /// Functions `P = 2^{Jx + Jy}`.
        functions: f64,
    },
    /// Local inversion of the uniform kernel matrix.
    Local {
        /// Vanishing moments.
        p: usize,
        /// Functions `P`.
        functions: f64,
    },
    /// The adaptive tree fit by the direct solve (its largest fit).
    TreeDirect {
        /// Vanishing moments.
        p: usize,
        /// Levels of the tree, coarse to deepest.
        levels: u32,
        /// Samples per leaf `rho`: the tree has at most `m / rho` functions.
        rho: f64,
    },
    /// The adaptive tree fit by matrix-free PCG (its largest fit).
    TreePcg {
        /// Vanishing moments.
        p: usize,
        /// Levels of the tree, coarse to deepest.
        levels: u32,
        /// Samples per leaf.
        rho: f64,
    },
}

/// The sizes of an image-plane request, all an [`ImageEstimate`] needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageRequest {
    /// Pixels `W H`.
    pub pixels: f64,
    /// Value channels `c`.
    pub channels: usize,
    /// Samples fitted `m`.
    pub samples: f64,
    /// Whether the samples are read from a file (three copies while reading).
    pub from_file: bool,
    /// Positions handed out or generated besides the samples.
    pub positions: f64,
    /// The fit.
    pub solve: ImageSolve,
    /// Output images held at once (each `8 W H c`, one more for the encoded file).
    pub images: usize,
}

/// What an image-plane request holds at its peak, by part, in bytes (module docs).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct ImageEstimate {
    /// Sample positions and values (and the file being read).
    pub samples: f64,
    /// Positions handed out or generated.
    pub positions: f64,
    /// Kernel rows (and their transpose).
    pub kernel_rows: f64,
    /// The normal matrix.
    pub normal_matrix: f64,
    /// The sparse Cholesky factor.
    pub factor: f64,
    /// Output images and the encoded file.
    pub output_images: f64,
    /// Right-hand sides and coefficients.
    pub scratch: f64,
}

impl ImageRequest {
    /// The estimate of this request (module docs), computed from the sizes alone.
    pub fn estimate(&self) -> ImageEstimate {
        let m = self.samples;
        let c = self.channels as f64;
        let copies = if self.from_file { 3.0 } else { 1.0 };
        let mut e = ImageEstimate {
            samples: copies * 8.0 * m * (2.0 + c),
            positions: 16.0 * self.positions,
            output_images: if self.images == 0 {
                0.0
            } else {
                8.0 * self.pixels * c * (self.images as f64 + 1.0)
            },
            ..ImageEstimate::default()
        };
        let stencil = |p: usize| ((4 * p).saturating_sub(3) as f64).powi(2);
        let support = |p: usize| ((2 * p).saturating_sub(1) as f64).powi(2);
        match self.solve {
            ImageSolve::None => {}
            ImageSolve::Uniform { p, functions } => {
                e.normal_matrix = 16.0 * functions * stencil(p);
                if functions <= UNIFORM_CHOLESKY_MAX_FUNCTIONS as f64 {
                    e.factor =
                        8.0 * FACTOR_FILL * support(p) * functions * functions.max(2.0).log2();
                    e.scratch = 24.0 * functions * c;
                } else {
                    // PCG (`NormalSolver::Auto`): five vectors a channel and their
                    // interleaved copies, no factor (its rare fallback is not counted)
                    e.scratch = 64.0 * functions * c;
                }
            }
            ImageSolve::Local { p, functions } => {
                e.kernel_rows = 32.0 * m * support(p);
                e.scratch = 24.0 * functions * c;
            }
            ImageSolve::TreeDirect { p, levels, rho } | ImageSolve::TreePcg { p, levels, rho } => {
                let l = levels as f64;
                let functions = m / rho.max(1.0);
                let row = 2.0 * support(p) * l;
                e.scratch = 24.0 * functions * c;
                if matches!(self.solve, ImageSolve::TreeDirect { .. }) {
                    let g = stencil(p) * (2.0 * l + 1.0);
                    e.kernel_rows = 32.0 * m * row;
                    e.normal_matrix = 48.0 * functions * g;
                    e.factor = 8.0 * functions * TREE_FACTOR_PER_NORMAL * g;
                } else {
                    e.kernel_rows = 8.0 * m * row;
                }
            }
        }
        e
    }
}

impl ImageEstimate {
    /// The sum of the parts.
    pub fn total(&self) -> f64 {
        self.samples
            + self.positions
            + self.kernel_rows
            + self.normal_matrix
            + self.factor
            + self.output_images
            + self.scratch
    }

    /// The nonzero parts as `samples 42 MB, factor 1.2 GB, ...`.
    pub fn parts(&self) -> String {
        [
            ("samples", self.samples),
            ("positions", self.positions),
            ("kernel rows", self.kernel_rows),
            ("normal matrix", self.normal_matrix),
            ("factor", self.factor),
            ("output images", self.output_images),
            ("scratch", self.scratch),
        ]
        .iter()
        .filter(|(_, b)| *b > 0.0)
        .map(|(name, b)| format!("{name} {}", format_bytes(*b)))
        .collect::<Vec<_>>()
        .join(", ")
    }

    /// Refuses the request above [`memory_limit`]: `what` names it and its size, `fix` the
    /// flag to change; the message lists the parts.
    pub fn check(
        &self,
        what: impl FnOnce() -> String,
        fix: impl FnOnce() -> String,
    ) -> Result<(), ResourceError> {
        self.check_advised(what, || Advice::Words(fix()))
    }

    /// [`ImageEstimate::check`] with the fix as [`Advice`].
    pub fn check_advised(
        &self,
        what: impl FnOnce() -> String,
        fix: impl FnOnce() -> Advice,
    ) -> Result<(), ResourceError> {
        check_advised(
            || format!("{} ({})", what(), self.parts()),
            self.total(),
            fix,
        )
    }
}

/// Functions `P = 2^{Jx + Jy}` of the uniform image fit of `samples` samples on a `width x
/// height` image at `rho` samples per function ([`crate::basis::tensor::auto_level`]).
pub fn uniform_image_functions(
    p: usize,
    width: usize,
    height: usize,
    samples: f64,
    rho: f64,
) -> f64 {
    let params = crate::basis::tensor::TensorLevelParams {
        rho,
        ..Default::default()
    };
    let pixels = width.saturating_mul(height);
    let m = samples.min(usize::MAX as f64) as usize;
    let jx = crate::basis::tensor::auto_level(width, m, pixels, p, params);
    let jy = crate::basis::tensor::auto_level(height, m, pixels, p, params);
    2f64.powi((jx + jy) as i32)
}

/// Levels of the adaptive tree at its depth limit on a `width x height` image: from
/// `j_min(p)` to `ceil(log2 max(W, H)) + below_pixel`.
pub fn tree_levels(p: usize, width: usize, height: usize, below_pixel: u32) -> u32 {
    let fine = (width.max(height).max(1) as f64).log2().ceil() as u32 + below_pixel;
    let coarse = crate::basis::minimum_level(p);
    fine.saturating_sub(coarse) + 1
}

/// The requests of the image-plane paths, built from their sizes (the command line, the
/// Python module and the tile code call these, so every path is estimated alike).
impl ImageRequest {
    /// `samples` samples of `channels` on a `width x height` image (generated, not read from
    /// a file), fitted by `solve`, `images` output images held.
    pub fn new(
        (width, height): (usize, usize),
        channels: usize,
        samples: f64,
        solve: ImageSolve,
        images: usize,
    ) -> Self {
        ImageRequest {
            pixels: width as f64 * height as f64,
            channels,
            samples,
            from_file: false,
            positions: 0.0,
            solve,
            images,
        }
    }

    /// The uniform fit (the sparse Cholesky, or local inversion with `local`) at `rho`
    /// samples per function ([`uniform_image_functions`]).
    pub fn uniform(
        (width, height): (usize, usize),
        channels: usize,
        samples: f64,
        p: usize,
        rho: f64,
        local: bool,
        images: usize,
    ) -> Self {
        let functions = uniform_image_functions(p, width, height, samples, rho);
        let solve = if local {
            ImageSolve::Local { p, functions }
        } else {
            ImageSolve::Uniform { p, functions }
        };
        Self::new((width, height), channels, samples, solve, images)
    }

    /// The adaptive tree fit at its depth limit ([`tree_levels`]): the assembled normal
    /// matrix and its factor with `direct`, matrix-free otherwise.
    #[allow(clippy::too_many_arguments)]
    pub fn tree(
        (width, height): (usize, usize),
        channels: usize,
        samples: f64,
        p: usize,
        below_pixel: u32,
        rho: f64,
        direct: bool,
        images: usize,
    ) -> Self {
        let levels = tree_levels(p, width, height, below_pixel);
        let solve = if direct {
            ImageSolve::TreeDirect { p, levels, rho }
        } else {
            ImageSolve::TreePcg { p, levels, rho }
        };
        Self::new((width, height), channels, samples, solve, images)
    }

    /// The larger (by estimated total) of two requests: a run whose parts come one after
    /// the other needs the larger part's memory.
    pub fn larger(self, other: Self) -> Self {
        if other.estimate().total() > self.estimate().total() {
            other
        } else {
            self
        }
    }
}

/// Memory a sample file of `bytes` bytes needs while it is read: its bytes, the decoded
/// table and the samples; three copies of an `.npy` file's data (`npy`), and for CSV four
/// times its bytes each for the table and the samples (a number takes at least two bytes
/// of text and eight in memory).
pub fn reading_bytes(bytes: f64, npy: bool) -> f64 {
    if npy {
        3.0 * bytes
    } else {
        9.0 * bytes
    }
}

/// Refuses to read the sample file `path` above the memory limit ([`reading_bytes`]),
/// before reading it, `fix` saying what to change; a file that cannot be inspected passes
/// (its reader names the problem).
pub fn check_reading(
    path: &std::path::Path,
    fix: impl FnOnce() -> String,
) -> Result<(), ResourceError> {
    let Ok(meta) = std::fs::metadata(path) else {
        return Ok(());
    };
    let bytes = meta.len() as f64;
    let npy = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("npy"));
    check(
        || format!("reading {} ({})", path.display(), format_bytes(bytes)),
        reading_bytes(bytes, npy),
        fix,
    )
}

impl ResourceError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            ResourceError::TooLarge { .. } => crate::error::ErrorKind::ResourceLimit,
            ResourceError::BadLimit { .. } => crate::error::ErrorKind::InvalidInput,
        }
    }
}

crate::error::classified!(ResourceError);

#[cfg(test)]
mod tests {
    use super::*;

    /// The builders fill every field from the sizes; `larger` keeps the larger estimate.
    #[test]
    fn image_requests_are_built_from_sizes() {
        let uniform = ImageRequest::uniform((64, 32), 3, 8192.0, 2, 4.0, false, 2);
        assert_eq!(uniform.pixels, 2048.0);
        assert!(!uniform.from_file);
        let functions = uniform_image_functions(2, 64, 32, 8192.0, 4.0);
        assert_eq!(uniform.solve, ImageSolve::Uniform { p: 2, functions });
        let local = ImageRequest::uniform((64, 32), 3, 8192.0, 2, 4.0, true, 2);
        assert_eq!(local.solve, ImageSolve::Local { p: 2, functions });
        let tree = ImageRequest::tree((64, 32), 3, 8192.0, 2, 1, 2.0, true, 2);
        let levels = tree_levels(2, 64, 32, 1);
        assert_eq!(
            tree.solve,
            ImageSolve::TreeDirect {
                p: 2,
                levels,
                rho: 2.0
            }
        );
        let (a, b) = (uniform.estimate().total(), tree.estimate().total());
        assert_ne!(a, b);
        let larger = if a > b { uniform } else { tree };
        assert_eq!(uniform.larger(tree), larger);
        assert_eq!(tree.larger(uniform), larger);
        assert_eq!(reading_bytes(100.0, true), 300.0);
        assert_eq!(reading_bytes(100.0, false), 900.0);
    }

    #[test]
    fn sizes_parse_and_refuse_garbage() {
        assert_eq!(parse_size("4G").unwrap(), 4 << 30);
        assert_eq!(parse_size("512MiB").unwrap(), 512 << 20);
        assert_eq!(parse_size("1000").unwrap(), 1000);
        assert_eq!(parse_size("1.5k").unwrap(), 1536);
        for bad in ["", "G", "-1G", "nan", "1e30T", "0"] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn estimates_do_not_overflow_and_the_check_refuses() {
        // 2^61 functions: the estimate is finite and far above any machine.
        let b = uniform_basis_bytes(3, 60, 1);
        assert!(b.is_finite() && b > 1e18);
        assert!(kernel_bytes(usize::MAX, 10, 0, 60).is_finite());
        let e = check(|| "a test".into(), b, || "lower N".into()).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("a test") && msg.contains("lower N"), "{msg}");
        assert!(msg.len() < 300, "{msg}");
        check(|| "small".into(), 1024.0, String::new).unwrap();
        assert_eq!(format_bytes(1536.0 * 1024.0 * 1024.0), "1.5 GB");
    }

    /// The parts follow their formulas: a uniform fit's factor grows as `P log2 P`, the
    /// tree's direct fit holds more than its PCG fit, files are counted three times, and a
    /// request of `u64::MAX` samples stays finite and is refused.
    #[test]
    fn image_estimates_follow_the_formulas() {
        let uniform = |functions: f64| ImageRequest {
            pixels: 65536.0,
            channels: 3,
            samples: 4.0 * 65536.0,
            from_file: false,
            positions: 0.0,
            solve: ImageSolve::Uniform { p: 2, functions },
            images: 1,
        };
        let (a, b) = (uniform(1024.0).estimate(), uniform(4096.0).estimate());
        let ratio = b.factor / a.factor;
        assert!((ratio - 4.0 * 12.0 / 10.0).abs() < 1e-12, "{ratio}");
        assert_eq!(a.normal_matrix, 16.0 * 1024.0 * 25.0);
        // above 64² functions the fit is PCG: no factor
        assert_eq!(uniform(65536.0).estimate().factor, 0.0);
        let file = ImageRequest {
            from_file: true,
            ..uniform(65536.0)
        };
        assert_eq!(file.estimate().samples, 3.0 * a.samples);
        let tree = |solve| ImageRequest {
            solve,
            ..uniform(0.0)
        };
        let direct = tree(ImageSolve::TreeDirect {
            p: 2,
            levels: 7,
            rho: 2.0,
        });
        let pcg = tree(ImageSolve::TreePcg {
            p: 2,
            levels: 7,
            rho: 2.0,
        });
        assert!(direct.estimate().total() > 4.0 * pcg.estimate().total());
        assert_eq!(pcg.estimate().factor, 0.0);
        let huge = ImageRequest {
            samples: u64::MAX as f64,
            ..uniform(2f64.powi(60))
        }
        .estimate();
        assert!(huge.total().is_finite());
        let e = huge
            .check(|| "a test".into(), || "fewer samples".into())
            .unwrap_err();
        assert!(e.to_string().contains("normal matrix"), "{e}");
        assert_eq!(uniform_image_functions(2, 256, 256, 262144.0, 4.0), 65536.0);
        assert_eq!(tree_levels(2, 256, 256, 1), 7);
        assert_eq!(tree_levels(2, 128, 128, 1), 6);
    }
}
