//! How many of a set of samples each pixel holds: the pixels without one, and what each
//! pixel lacks to hold `m` (the coverage rule's counts, used by the plan and by its rounds).

use crate::image::ImagePlane;

/// The pixels (row-major indices `py W + px`) that hold none of the samples `(xs, ys)`.
pub fn empty_pixels(plane: ImagePlane, xs: &[f64], ys: &[f64]) -> Vec<usize> {
    let w = plane.width();
    let mut hit = vec![false; plane.pixels()];
    for (&x, &y) in xs.iter().zip(ys) {
        let (px, py) = plane.pixel_of(x, y);
        hit[py * w + px] = true;
    }
    (0..hit.len()).filter(|&p| !hit[p]).collect()
}

/// The samples each pixel lacks to hold `m`: `(pixel, m - n_P)` for the pixels (row-major
/// indices `py W + px`) with `n_P < m` samples among `(xs, ys)`, in pixel order.
pub fn pixel_shortfall(plane: ImagePlane, xs: &[f64], ys: &[f64], m: usize) -> Vec<(usize, usize)> {
    let w = plane.width();
    let mut count = vec![0usize; plane.pixels()];
    for (&x, &y) in xs.iter().zip(ys) {
        let (px, py) = plane.pixel_of(x, y);
        count[py * w + px] += 1;
    }
    (0..count.len())
        .filter(|&p| count[p] < m)
        .map(|p| (p, m - count[p]))
        .collect()
}
