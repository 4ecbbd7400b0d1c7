//! Counts on the command line, parsed with their range: `u64::MAX`, `1e308` or `0` where it
//! makes no sense are refused by the parser (exit 2) before anything is allocated. The
//! memory a request needs is checked again by the library (`rkwave::resources`).

/// Largest grid, sample count, point count or budget a flag accepts (1e8: 0.8 GB per
/// channel of `f64`s).
pub const MAX_POINTS: u64 = 100_000_000;

/// Most residual probes per leaf and round.
pub const MAX_PROBES: u64 = 64;

/// Most value channels.
pub const MAX_CHANNELS: u64 = 64;

/// An integer in `lo..=hi` (plain or `1e6`-style scientific notation of an integer).
pub fn count_in(text: &str, lo: u64, hi: u64) -> Result<usize, String> {
    let t = text.trim();
    let v: f64 = match t.parse::<u64>() {
        Ok(v) => v as f64,
        Err(_) => t
            .parse::<f64>()
            .map_err(|_| format!("`{t}` is not a whole number"))?,
    };
    if !(v.is_finite() && v.fract() == 0.0) {
        return Err(format!("`{t}` is not a whole number"));
    }
    if v < lo as f64 || v > hi as f64 {
        return Err(format!(
            "{} is outside {lo}..={}",
            rkwave::norms::show(v),
            rkwave::norms::show(hi as f64)
        ));
    }
    Ok(v as usize)
}

/// Neighbourhood rings of local inversion: `0..=10` (`rkwave::solve::MAX_RINGS`).
pub fn rings(text: &str) -> Result<usize, String> {
    count_in(text, 0, rkwave::solve::MAX_RINGS as u64)
}

/// Grid points: `2..=1e8`.
pub fn grid(text: &str) -> Result<usize, String> {
    count_in(text, 2, MAX_POINTS)
}

/// Grid points where 0 has a meaning (off, or "as many as samples"): `0..=1e8`.
pub fn grid_or_zero(text: &str) -> Result<usize, String> {
    count_in(text, 0, MAX_POINTS)
}

/// Samples, points or a budget: `1..=1e8`.
pub fn samples(text: &str) -> Result<usize, String> {
    count_in(text, 1, MAX_POINTS)
}

/// Residual probes per leaf and round: `1..=64`.
pub fn probes(text: &str) -> Result<usize, String> {
    count_in(text, 1, MAX_PROBES)
}

/// Value channels: `1..=64`.
pub fn channels(text: &str) -> Result<usize, String> {
    count_in(text, 1, MAX_CHANNELS)
}

/// A whole count bounded later (by the command's own checks or the memory estimate, which
/// name the flag and what would fit): `0..=u64::MAX`, plain or in `1e9` notation, as every
/// count flag of the command line.
pub fn count(text: &str) -> Result<usize, String> {
    count_in(text, 0, u64::MAX)
}

/// A sample count given as a number (`1e6`): `1..=1e8`, whole.
pub fn size(text: &str) -> Result<f64, String> {
    count_in(text, 1, MAX_POINTS).map(|v| v as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_refuse_the_absurd() {
        assert_eq!(grid("1000").unwrap(), 1000);
        assert_eq!(samples("1e6").unwrap(), 1_000_000);
        for bad in [
            "18446744073709551615",
            "1e308",
            "0",
            "1.5",
            "nan",
            "-3",
            "inf",
            "",
        ] {
            assert!(samples(bad).is_err(), "{bad}");
        }
        assert!(channels("0").is_err());
        assert_eq!(grid_or_zero("0").unwrap(), 0);
        assert_eq!(count("1e9").unwrap(), 1_000_000_000);
        assert_eq!(count("0").unwrap(), 0);
        for bad in ["1e30", "2.5", "-1", "nan", "x"] {
            assert!(count(bad).is_err(), "{bad}");
        }
    }
}
