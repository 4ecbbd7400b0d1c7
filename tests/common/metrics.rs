//! Image metrics the tests compare by, written once.

/// PSNR in dB of `image` against `reference`, both clipped to `[0, 1]` (peak 1), the mean
/// squared error taken over every pixel of every channel: the harness's definition
/// (`benches/mitsuba/metrics.py`), `10 log10(n / sum (clip(x) - clip(r))^2)`. Channels are
/// compared pairwise; `+inf` for equal images.
pub fn psnr(image: &[Vec<f64>], reference: &[Vec<f64>]) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for (a, b) in image.iter().zip(reference) {
        for (&x, &r) in a.iter().zip(b) {
            let d = x.clamp(0.0, 1.0) - r.clamp(0.0, 1.0);
            sum += d * d;
            n += 1;
        }
    }
    10.0 * (n as f64 / sum).log10()
}

/// relMSE of the unclipped (HDR) values, `mean((x - r)^2 / (r^2 + 0.01))` over every pixel of
/// every channel: the harness's definition (`benches/mitsuba/metrics.py`, eps = 0.01).
pub fn relmse(image: &[Vec<f64>], reference: &[Vec<f64>]) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for (a, b) in image.iter().zip(reference) {
        for (&x, &r) in a.iter().zip(b) {
            sum += (x - r) * (x - r) / (r * r + 0.01);
            n += 1;
        }
    }
    sum / n as f64
}
