//! The stratification of sample positions: `(0, m, 2)`-nets of a rectangle.

use std::collections::HashSet;

use rkwave::image::adaptive::SamplePositions;

/// Whether the points are one per elementary interval `2^-j x 2^-(m-j)` of `rect` for every
/// `j in 0..=m` (`2^m` points: a `(0, m, 2)`-net of the rectangle).
pub fn is_net(p: &SamplePositions, rect: [f64; 4], m: u32) -> bool {
    let n = 1usize << m;
    if p.len() != n {
        return false;
    }
    (0..=m).all(|j| {
        let (bx, by) = (1usize << j, 1usize << (m - j));
        let boxes: HashSet<(usize, usize)> =
            p.xs.iter()
                .zip(&p.ys)
                .map(|(x, y)| {
                    let u = (x - rect[0]) / (rect[1] - rect[0]);
                    let v = (y - rect[2]) / (rect[3] - rect[2]);
                    (
                        ((u * bx as f64) as usize).min(bx - 1),
                        ((v * by as f64) as usize).min(by - 1),
                    )
                })
                .collect();
        boxes.len() == n
    })
}
