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
//! The limit is three quarters of `MemTotal` in `/proc/meminfo` (8 GiB where that file
//! does not exist), or what [`set_memory_limit`] set (the command line's `--memory-limit`).
//! A request above it is refused with [`ResourceError::TooLarge`], which says what it would
//! need and which parameter to change.

use std::sync::atomic::{AtomicU64, Ordering};

use thiserror::Error;

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
        fix: String,
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
