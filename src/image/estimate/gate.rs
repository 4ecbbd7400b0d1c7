//! The risk gate: per pixel, the candidate estimate of least estimated risk against the box
//! pixels, the box itself among the candidates.
//!
//! **Risk.** The box pixel `m_P` (the mean of the pixel's samples) is unbiased for the pixel
//! integral `mu_P` with variance `v_P` (estimated from the strata, [`super::noise`]): its risk is
//! `v_P`. A candidate `x_P = f_P(m)` whose derivative in its own pixel's mean is `div_P` has, for
//! Gaussian `m_P` independent across pixels (Stein's lemma, per coordinate),
//!
//! `E (x_P - mu_P)² = E [(x_P - m_P)² - v_P + 2 v_P div_P]`,
//!
//! the per-pixel SURE (summed over channels). A linear film has `div_P = A_P`, the weight of
//! the pixel's own samples ([`super::sure`]); the SureShrink pixels their exact divergence
//! ([`super::sureshrink`]); a convex combination the combination of the divergences; the box
//! `div_P = 1`, SURE `v_P`.
//!
//! **Gate.** One pixel's SURE is too noisy to choose by; each pixel takes the candidate of
//! least SURE summed over the `(2 h + 1)²` window around it (ties to the box, which is
//! candidate 0). With levels `L` (the caller's smooth estimate of each pixel's brightness),
//! the window of `P` keeps only the pixels `Q` of the square at `P`'s level,
//! `|ln((L_Q + 0.1) / (L_P + 0.1))| <= ln 2` ([`LEVEL_RATIO`], [`LEVEL_EPS`]): a dark pixel
//! beside bright ones is judged by the pixels as dark as it, not carried by a decision its
//! bright neighbours' risks made (where relMSE weighs it most; measured on the suite's
//! texture scenes, `docs/measurements/estimators.md`). `P` is always in its own window, and
//! the window still depends on the data only through the smooth level. So no pixel takes a candidate whose estimated risk over its window exceeds
//! the box's there: the estimate never takes a step its estimate says raises the risk. The
//! summed SURE of the output is reported next to the box's (both per pixel, averaged over the
//! image) so a user sees the estimated gain.

use serde::Serialize;

use super::sure::window_sum;
use crate::image::PixelImage;

/// Half the side of the gate's window: `(2 h + 1)²` = 9 x 9 pixels (chosen on the suite's
/// tuning half against 5 x 5, 17 x 17 and 25 x 25: `docs/measurements/estimators.md`).
pub const GATE_HALF: usize = 4;

/// The largest ratio of levels `(L_Q + eps) / (L_P + eps)` (either way) of a pixel `Q` in
/// `P`'s window (chosen on the suite's tuning half against 1.5 and no limit:
/// `docs/measurements/estimators.md`).
pub const LEVEL_RATIO: f64 = 2.0;

/// `eps` of the level ratio: levels below about 0.1 count as one (dark) level.
pub const LEVEL_EPS: f64 = 0.1;

/// One candidate: its pixels and their divergence in their own pixel's mean, per channel.
#[derive(Debug, Clone)]
pub struct GateCandidate {
    /// A short name for the report.
    pub name: String,
    /// The pixels.
    pub image: PixelImage,
    /// `div_{P,c}` per channel and pixel.
    pub divergence: Vec<Vec<f64>>,
}

/// Pixels that took one candidate.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GateCount {
    /// The candidate.
    pub candidate: String,
    /// Its pixels.
    pub pixels: usize,
}

/// The gated pixels and what the gate did.
#[derive(Debug, Clone)]
pub struct Gated {
    /// Each pixel from its candidate.
    pub image: PixelImage,
    /// The index of each pixel's candidate.
    pub choice: Vec<usize>,
    /// Pixels per candidate.
    pub counts: Vec<GateCount>,
    /// The chosen candidate's SURE (unweighted) averaged over each pixel's window.
    pub window_risk: Vec<f64>,
    /// Mean over pixels of the chosen candidate's own SURE (summed over channels).
    pub risk: f64,
    /// Mean over pixels of the box's risk `sum_c v_{P,c}`.
    pub box_risk: f64,
}

/// Per-pixel SURE of `candidate` against the box pixels `mean` with variances `variance`
/// (both per channel), summed over channels with the weights `weight` (per channel and pixel;
/// `None`: 1).
pub fn pixel_sure(
    candidate: &GateCandidate,
    mean: &[Vec<f64>],
    variance: &[Vec<f64>],
    weight: Option<&[Vec<f64>]>,
) -> Vec<f64> {
    let pixels = candidate.image.plane.pixels();
    (0..pixels)
        .map(|p| {
            (0..mean.len())
                .map(|c| {
                    let d = candidate.image.channels[c][p] - mean[c][p];
                    let v = variance[c][p];
                    let wt = weight.map_or(1.0, |w| w[c][p]);
                    wt * (d * d - v + 2.0 * v * candidate.divergence[c][p])
                })
                .sum()
        })
        .collect()
}

/// Each pixel from the candidate of least window-summed SURE (`(2 half + 1)²` window, each
/// pixel and channel weighted by `weight`; with `level`, only the window's pixels at the
/// centre's level, [`level_window_sum`]), candidate 0 on ties; `candidates[0]` should be the
/// box (`image = mean`, divergence 1). The reported risks are unweighted.
pub fn gate(
    candidates: &[GateCandidate],
    mean: &[Vec<f64>],
    variance: &[Vec<f64>],
    weight: Option<&[Vec<f64>]>,
    level: Option<&[f64]>,
    half: usize,
) -> Gated {
    let plane = candidates[0].image.plane;
    let (w, h) = (plane.width(), plane.height());
    let sures: Vec<Vec<f64>> = candidates
        .iter()
        .map(|c| pixel_sure(c, mean, variance, None))
        .collect();
    let sum = |s: &[f64]| match level {
        None => window_sum(s, w, h, half),
        Some(l) => level_window_sum(s, l, w, h, half),
    };
    let windows: Vec<Vec<f64>> = candidates
        .iter()
        .zip(&sures)
        .map(|(c, s)| match weight {
            None => sum(s),
            Some(_) => sum(&pixel_sure(c, mean, variance, weight)),
        })
        .collect();
    let choice: Vec<usize> = (0..plane.pixels())
        .map(|p| {
            let mut best = 0;
            for k in 1..candidates.len() {
                if windows[k][p] < windows[best][p] {
                    best = k;
                }
            }
            best
        })
        .collect();
    let area = sum(&vec![1.0; plane.pixels()]);
    let channels = mean.len();
    let mut image = PixelImage::zeros(plane, channels);
    for (p, &k) in choice.iter().enumerate() {
        for c in 0..channels {
            image.channels[c][p] = candidates[k].image.channels[c][p];
        }
    }
    let n = plane.pixels().max(1) as f64;
    let risk = choice
        .iter()
        .enumerate()
        .map(|(p, &k)| sures[k][p])
        .sum::<f64>()
        / n;
    let box_risk = (0..plane.pixels())
        .map(|p| variance.iter().map(|v| v[p]).sum::<f64>())
        .sum::<f64>()
        / n;
    let counts = candidates
        .iter()
        .enumerate()
        .map(|(k, c)| GateCount {
            candidate: c.name.clone(),
            pixels: choice.iter().filter(|&&x| x == k).count(),
        })
        .collect();
    let window_risk = choice
        .iter()
        .enumerate()
        .map(|(p, &k)| windows[k][p] / area[p])
        .collect();
    Gated {
        image,
        choice,
        counts,
        window_risk,
        risk,
        box_risk,
    }
}

/// `sum_Q values_Q` over the pixels `Q` of the `(2 half + 1)²` square around each pixel `P`
/// (clipped at the borders) at `P`'s level: `|ln((L_Q + eps) / (L_P + eps))| <= ln r`, `eps`
/// = [`LEVEL_EPS`], `r` = [`LEVEL_RATIO`]. With every level equal it is
/// [`window_sum`].
pub fn level_window_sum(
    values: &[f64],
    level: &[f64],
    width: usize,
    height: usize,
    half: usize,
) -> Vec<f64> {
    let log_level: Vec<f64> = level.iter().map(|l| (l + LEVEL_EPS).ln()).collect();
    let reach = LEVEL_RATIO.ln();
    (0..width * height)
        .map(|p| {
            let (x, y) = (p % width, p / width);
            let mut total = 0.0;
            for qy in y.saturating_sub(half)..(y + half + 1).min(height) {
                for qx in x.saturating_sub(half)..(x + half + 1).min(width) {
                    let q = qy * width + qx;
                    if (log_level[q] - log_level[p]).abs() <= reach {
                        total += values[q];
                    }
                }
            }
            total
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::super::sure::window_sum;
    use super::*;
    use crate::image::ImagePlane;

    /// The box pixels `mean` as a candidate (divergence 1: each pixel is its own samples' mean).
    fn box_candidate(plane: ImagePlane, mean: &[Vec<f64>]) -> GateCandidate {
        GateCandidate {
            name: "box".into(),
            image: PixelImage {
                plane,
                channels: mean.to_vec(),
            },
            divergence: vec![vec![1.0; plane.pixels()]; mean.len()],
        }
    }

    /// The box's own SURE is its variance, exactly; a candidate far from the box everywhere
    /// never wins; a candidate equal to the box with divergence 0 (a constant, say) wins
    /// where its SURE `-v` is less than `v`.
    #[test]
    fn the_box_wins_ties_and_far_candidates_lose() {
        let plane = ImagePlane::new(6, 4).unwrap();
        let n = plane.pixels();
        let mean = vec![(0..n).map(|p| p as f64 * 0.1).collect::<Vec<_>>()];
        let variance = vec![vec![0.01; n]];
        let boxed = box_candidate(plane, &mean);
        let s = pixel_sure(&boxed, &mean, &variance, None);
        assert!(s.iter().all(|&x| (x - 0.01).abs() <= 1e-15));
        let far = GateCandidate {
            name: "far".into(),
            image: PixelImage {
                plane,
                channels: vec![mean[0].iter().map(|m| m + 1.0).collect()],
            },
            divergence: vec![vec![0.0; n]],
        };
        let same = GateCandidate {
            name: "same".into(),
            divergence: vec![vec![0.0; n]],
            ..boxed.clone()
        };
        let g = gate(
            &[boxed.clone(), far.clone()],
            &mean,
            &variance,
            None,
            None,
            1,
        );
        assert!(g.choice.iter().all(|&k| k == 0));
        let g = gate(&[boxed, far, same], &mean, &variance, None, None, 1);
        assert!(g.choice.iter().all(|&k| k == 2));
        assert!((g.risk + 0.01).abs() <= 1e-15 && (g.box_risk - 0.01).abs() <= 1e-15);
    }

    /// With every level equal the level window is the square window; levels more than a
    /// factor `LEVEL_RATIO` apart (with `LEVEL_EPS`) are left out, nearer ones kept.
    #[test]
    fn level_windows_keep_the_centres_level() {
        let (w, h) = (7, 5);
        let values: Vec<f64> = (0..w * h).map(|p| ((p * 37) % 11) as f64 - 4.0).collect();
        let same = level_window_sum(&values, &vec![0.3; w * h], w, h, 2);
        let square = window_sum(&values, w, h, 2);
        assert!(same
            .iter()
            .zip(&square)
            .all(|(a, b)| (a - b).abs() <= 1e-12));
        // pixel 0 at level 0 (0.1 with eps); pixel 1 at 0.09 (ratio 1.9: kept), pixel 2 at
        // 0.11 (ratio 2.1: left out), the rest at 10
        let mut level = vec![10.0; w * h];
        level[0] = 0.0;
        level[1] = 0.09;
        level[2] = 0.11;
        let ones = vec![1.0; w * h];
        let counts = level_window_sum(&ones, &level, w, h, 2);
        assert_eq!(counts[0], 2.0);
    }

    /// A dark row beside a bright field where a smooth candidate gains: without levels the
    /// dark pixels ride on the bright pixels' decision; with levels each takes the candidate its
    /// own level's pixels favour (the box, where the smooth candidate's SURE is positive).
    #[test]
    fn dark_pixels_are_not_carried_by_bright_neighbours() {
        let plane = ImagePlane::new(9, 9).unwrap();
        let n = plane.pixels();
        let dark = |p: usize| p / 9 == 4;
        let mean = vec![(0..n)
            .map(|p| if dark(p) { 0.0 } else { 1.0 })
            .collect::<Vec<_>>()];
        let variance = vec![vec![0.01; n]];
        let boxed = box_candidate(plane, &mean);
        // the smooth candidate: equal to the box on the bright pixels with divergence 0
        // (SURE -v), 0.3 above the dark ones (SURE 0.09 - v > v)
        let smooth = GateCandidate {
            name: "smooth".into(),
            image: PixelImage {
                plane,
                channels: vec![mean[0]
                    .iter()
                    .map(|&m| if m == 0.0 { 0.3 } else { m })
                    .collect()],
            },
            divergence: vec![vec![0.0; n]],
        };
        let level: Vec<f64> = mean[0].clone();
        let candidates = [boxed, smooth];
        let plain = gate(&candidates, &mean, &variance, None, None, 4);
        let levelled = gate(&candidates, &mean, &variance, None, Some(&level), 4);
        for p in 0..n {
            assert_eq!(levelled.choice[p], usize::from(!dark(p)), "pixel {p}");
        }
        assert!((0..n).filter(|&p| dark(p)).all(|p| plain.choice[p] == 1));
    }
}
