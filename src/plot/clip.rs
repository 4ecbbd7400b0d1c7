//! Lines broken at unplottable points and clipped to the axes box (Liang–Barsky: the segment
//! `p + t (q - p)`, `t ∈ [0, 1]`, is cut to the `t` interval inside all four half-planes).

use super::axes::AxisSpec;

/// Clips the segment `p`–`q` to the box (Liang–Barsky); returns the clipped
/// segment and whether its start/end were moved.
#[allow(clippy::type_complexity)]
fn clip_segment(
    p: (f64, f64),
    q: (f64, f64),
    x: &AxisSpec,
    y: &AxisSpec,
) -> Option<((f64, f64), (f64, f64), bool, bool)> {
    let (dx, dy) = (q.0 - p.0, q.1 - p.1);
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (num, den) in [
        (p.0 - x.lo, -dx),
        (x.hi - p.0, dx),
        (p.1 - y.lo, -dy),
        (y.hi - p.1, dy),
    ] {
        if den == 0.0 {
            if num < 0.0 {
                return None;
            }
        } else {
            let t = num / den;
            if den < 0.0 {
                t0 = t0.max(t);
            } else {
                t1 = t1.min(t);
            }
        }
    }
    if t0 > t1 {
        return None;
    }
    let at = |t: f64| (p.0 + t * dx, p.1 + t * dy);
    Some((
        if t0 > 0.0 { at(t0) } else { p },
        if t1 < 1.0 { at(t1) } else { q },
        t0 > 0.0,
        t1 < 1.0,
    ))
}

/// Splits a series into visible polylines: broken at unplottable points and
/// clipped to the axes box.
pub(super) fn polylines(
    points: &[Option<(f64, f64)>],
    x: &AxisSpec,
    y: &AxisSpec,
) -> Vec<Vec<(f64, f64)>> {
    let mut lines = Vec::new();
    let mut current: Vec<(f64, f64)> = Vec::new();
    for pair in points.windows(2) {
        let (Some(p), Some(q)) = (pair[0], pair[1]) else {
            if current.len() > 1 {
                lines.push(std::mem::take(&mut current));
            }
            current.clear();
            continue;
        };
        match clip_segment(p, q, x, y) {
            None => {
                if current.len() > 1 {
                    lines.push(std::mem::take(&mut current));
                }
                current.clear();
            }
            Some((a, b, a_moved, b_moved)) => {
                if current.is_empty() || a_moved {
                    if current.len() > 1 {
                        lines.push(std::mem::take(&mut current));
                    }
                    current = vec![a];
                }
                current.push(b);
                if b_moved {
                    lines.push(std::mem::take(&mut current));
                }
            }
        }
    }
    if current.len() > 1 {
        lines.push(current);
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plot::Scale;

    #[test]
    fn lines_break_at_gaps_and_clip() {
        let axis = AxisSpec::new(0.0, 1.0, Scale::Linear, 5);
        let pts = [
            Some((0.1, 0.5)),
            Some((0.2, 0.5)),
            None,
            Some((0.3, 0.5)),
            Some((0.5, 0.5)),
            Some((1.5, 0.5)),
            Some((2.0, 0.5)),
            Some((0.9, 0.5)),
        ];
        let lines = polylines(&pts, &axis, &axis);
        assert_eq!(
            lines,
            vec![
                vec![(0.1, 0.5), (0.2, 0.5)],
                vec![(0.3, 0.5), (0.5, 0.5), (1.0, 0.5)],
                vec![(1.0, 0.5), (0.9, 0.5)],
            ]
        );
        assert!(polylines(&[], &axis, &axis).is_empty());
        assert!(polylines(&[Some((0.5, 0.5))], &axis, &axis).is_empty());
    }
}
