//! Axes in plot space (log10 of the data on log axes): ranges, tick positions ("nice" steps
//! of 1, 2, 2.5 or 5 times a power of ten; decades on log axes) and tick labels.

use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint};
use plotters::prelude::*;

use super::spec::Scale;

pub(super) type Axis = AxisSpec;

/// How tick values are turned into labels.
#[derive(Debug, Clone, Copy)]
enum TickFmt {
    /// Plain values with the given tick step; scientific notation if `sci`.
    Linear { step: f64, sci: bool },
    /// Log-space values `v` labelled as `10^v` rounded to one significant digit.
    Powers,
    /// Log-space values labelled as `10^v` on a linear grid of the given step.
    LogLinear { step: f64, sci: bool },
    /// Row indices drawn upside down: the label of `v` is `-v`.
    NegatedIndex { step: f64 },
}

/// One resolved axis, in plot space (log10 of the data on log axes).
#[derive(Debug, Clone)]
pub(super) struct AxisSpec {
    pub(super) lo: f64,
    pub(super) hi: f64,
    major: Vec<f64>,
    minor: Vec<f64>,
    fmt: TickFmt,
}

/// Plotters coordinate: a linear map of `[lo, hi]` with our own tick positions
/// (bold grid lines and labels at `major`, light grid lines at `minor`).
impl Ranged for AxisSpec {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, v: &f64, limit: (i32, i32)) -> i32 {
        let t = (v - self.lo) / (self.hi - self.lo);
        let len = f64::from(limit.1 - limit.0);
        if !t.is_finite() {
            return limit.0;
        }
        let pixel = (len * t).round().clamp(-1e7, 1e7);
        limit.0 + pixel as i32
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            self.minor.clone()
        } else {
            self.major.clone()
        }
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.lo..self.hi
    }
}

impl AxisSpec {
    pub(super) fn coord(&self) -> Axis {
        self.clone()
    }

    pub(super) fn contains(&self, v: f64) -> bool {
        let eps = (self.hi - self.lo) * 1e-9;
        v >= self.lo - eps && v <= self.hi + eps
    }

    pub(super) fn label(&self, v: f64) -> String {
        match self.fmt {
            TickFmt::Linear { step, sci } => fmt_tick(v, step, sci),
            TickFmt::Powers => fmt_power(v),
            TickFmt::LogLinear { step, sci } => fmt_tick(10f64.powf(v), step, sci),
            TickFmt::NegatedIndex { step } => fmt_tick(-v, step, false),
        }
    }

    /// An axis over `[lo, hi]` in plot space with about `target` labelled ticks.
    pub(super) fn new(lo: f64, hi: f64, scale: Scale, target: usize) -> Self {
        match scale {
            Scale::Linear => {
                let (major, step) = linear_ticks(lo, hi, target, false);
                let m = lo.abs().max(hi.abs());
                let sci = !(1e-3..1e5).contains(&m);
                AxisSpec {
                    lo,
                    hi,
                    major,
                    minor: Vec::new(),
                    fmt: TickFmt::Linear { step, sci },
                }
            }
            Scale::Log10 => log_axis(lo, hi, target),
        }
    }

    /// An axis of integer indices `0..n` centred on the cells, with the
    /// direction flipped (index `i` at `-i`) when `negate` is set.
    pub(super) fn index(n: usize, target: usize, negate: bool) -> Self {
        let (lo, hi) = (-0.5, n.max(1) as f64 - 0.5);
        let (ticks, step) = linear_ticks(lo, hi, target, true);
        if negate {
            AxisSpec {
                lo: -hi,
                hi: -lo,
                major: ticks.iter().map(|t| -t).collect(),
                minor: Vec::new(),
                fmt: TickFmt::NegatedIndex { step },
            }
        } else {
            AxisSpec {
                lo,
                hi,
                major: ticks,
                minor: Vec::new(),
                fmt: TickFmt::Linear { step, sci: false },
            }
        }
    }
}

/// "Nice" tick step (1, 2, 2.5 or 5 times a power of ten) for about `target` ticks.
fn nice_step(span: f64, target: usize) -> f64 {
    let raw = span / target.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let f = raw / mag;
    let nice = if f <= 1.0 {
        1.0
    } else if f <= 2.0 {
        2.0
    } else if f <= 2.5 {
        2.5
    } else if f <= 5.0 {
        5.0
    } else {
        10.0
    };
    nice * mag
}

/// Multiples of a nice step inside `[lo, hi]`, and the step.
pub(super) fn linear_ticks(lo: f64, hi: f64, target: usize, integer: bool) -> (Vec<f64>, f64) {
    let span = hi - lo;
    if !(span.is_finite() && span > 0.0) {
        return (vec![lo], 1.0);
    }
    let mut step = nice_step(span, target);
    if integer {
        step = step.max(1.0).round();
    }
    let start = (lo / step - 1e-9).ceil();
    let end = (hi / step + 1e-9).floor();
    let count = (end - start).clamp(-1.0, 200.0);
    let ticks = (0..=count as i64)
        .map(|k| {
            let v = (start + k as f64) * step;
            if v.abs() < step * 1e-9 {
                0.0
            } else {
                v
            }
        })
        .collect();
    (ticks, step)
}

/// A log10 axis over `[lo, hi]` (already in log space).
fn log_axis(lo: f64, hi: f64, target: usize) -> AxisSpec {
    let decades = hi - lo;
    let inside = |v: &f64| *v >= lo - 1e-9 && *v <= hi + 1e-9;
    let (first, last) = (lo.floor() as i64, hi.ceil() as i64);
    let mantissas = |ms: &[f64]| -> Vec<f64> {
        (first..=last)
            .flat_map(|k| ms.iter().map(move |m| k as f64 + m.log10()))
            .filter(inside)
            .collect()
    };
    if decades >= 2.0 {
        let step = nice_step(decades, target).max(1.0).round() as i64;
        let (major, minor): (Vec<f64>, Vec<f64>) = (first..=last)
            .map(|k| k as f64)
            .filter(inside)
            .partition(|k| (*k as i64).rem_euclid(step) == 0);
        let minor = if step == 1 && decades <= 12.0 {
            mantissas(&[2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0])
        } else if minor.len() <= 30 {
            minor
        } else {
            Vec::new()
        };
        AxisSpec {
            lo,
            hi,
            major,
            minor,
            fmt: TickFmt::Powers,
        }
    } else if decades >= 0.6 {
        AxisSpec {
            lo,
            hi,
            major: mantissas(&[1.0, 2.0, 5.0]),
            minor: mantissas(&[3.0, 4.0, 6.0, 7.0, 8.0, 9.0]),
            fmt: TickFmt::Powers,
        }
    } else {
        let (vlo, vhi) = (10f64.powf(lo), 10f64.powf(hi));
        let (ticks, step) = linear_ticks(vlo, vhi, target, false);
        AxisSpec {
            lo,
            hi,
            major: ticks
                .into_iter()
                .filter(|t| *t > 0.0)
                .map(f64::log10)
                .collect(),
            minor: Vec::new(),
            fmt: TickFmt::LogLinear {
                step,
                sci: !(1e-3..1e5).contains(&vhi),
            },
        }
    }
}

/// Formats a tick value with as many digits as the tick step needs.
pub(super) fn fmt_tick(v: f64, step: f64, sci: bool) -> String {
    if !v.is_finite() {
        return String::new();
    }
    if v.abs() < step.abs() * 1e-6 {
        return "0".into();
    }
    // Decimals needed to represent multiples of `step` exactly.
    let decimals = (0..=12)
        .find(|&d| {
            let s = step * 10f64.powi(d);
            (s - s.round()).abs() < 1e-6 * s.max(1.0)
        })
        .unwrap_or(12);
    if sci {
        let sig = (v.abs().log10().floor() as i32 + decimals + 1).clamp(1, 12) as usize;
        trim_sci(&format!("{:.*e}", sig - 1, v))
    } else {
        format!("{:.*}", decimals as usize, v)
    }
}

/// Formats `10^v` rounded to one significant digit (`v` is near `log10(m 10^k)`).
pub(super) fn fmt_power(v: f64) -> String {
    let mut k = v.floor();
    let mut m = 10f64.powf(v - k).round();
    if m >= 10.0 {
        m = 1.0;
        k += 1.0;
    }
    let k = k as i32;
    if (-3..=4).contains(&k) {
        format!("{:.*}", (-k).max(0) as usize, m * 10f64.powi(k))
    } else if m == 1.0 {
        format!("1e{k}")
    } else {
        format!("{m}e{k}")
    }
}

/// Removes trailing zeros of a mantissa: `"2.50e-5"` → `"2.5e-5"`, `"1.0e3"` → `"1e3"`.
fn trim_sci(s: &str) -> String {
    match s.split_once('e') {
        Some((mant, exp)) if mant.contains('.') => {
            let mant = mant.trim_end_matches('0').trim_end_matches('.');
            format!("{mant}e{exp}")
        }
        _ => s.to_string(),
    }
}

/// Maps a data value to plot space; `None` if it cannot be shown on `scale`.
pub(super) fn to_plot(v: f64, scale: Scale) -> Option<f64> {
    let t = match scale {
        Scale::Linear => v,
        Scale::Log10 if v > 0.0 => v.log10(),
        Scale::Log10 => return None,
    };
    t.is_finite().then_some(t)
}

/// Resolves an axis interval in plot space from an optional explicit range
/// and the data values, padding auto ranges by `pad` of their span.
pub(super) fn resolve_range(
    explicit: Option<(f64, f64)>,
    scale: Scale,
    data: impl Iterator<Item = f64>,
    pad: f64,
) -> (f64, f64) {
    let fixed = explicit.and_then(|(a, b)| Some((to_plot(a, scale)?, to_plot(b, scale)?)));
    let (lo, hi, auto) = match fixed {
        Some((a, b)) => (a.min(b), a.max(b), false),
        None => {
            let (lo, hi) = data.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            });
            if lo > hi {
                return (0.0, 1.0);
            }
            (lo, hi, true)
        }
    };
    let span = hi - lo;
    if span <= lo.abs().max(hi.abs()).max(1e-300) * 1e-12 {
        let d = if lo == 0.0 { 0.5 } else { lo.abs() * 0.05 };
        return (lo - d, hi + d);
    }
    if auto {
        (lo - pad * span, hi + pad * span)
    } else {
        (lo, hi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels() {
        assert_eq!(fmt_tick(0.2, 0.2, false), "0.2");
        assert_eq!(fmt_tick(7.5, 2.5, false), "7.5");
        assert_eq!(fmt_tick(1e-17, 0.5, false), "0");
        assert_eq!(fmt_tick(2e5, 1e5, true), "2e5");
        assert_eq!(fmt_power(-2.0), "0.01");
        assert_eq!(fmt_power(2f64.log10() + 6.0), "2e6");
        assert_eq!(fmt_power(3.0), "1000");
        let (ticks, step) = linear_ticks(-0.5, 39.5, 5, true);
        assert_eq!(step, 10.0);
        assert_eq!(ticks, vec![0.0, 10.0, 20.0, 30.0]);
    }
}
