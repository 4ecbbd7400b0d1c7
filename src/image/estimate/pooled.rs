//! The noise of a pixel's mean pooled over its 3 x 3 neighbourhood where its own samples lie
//! within its neighbours' samples: SURE's `v_P` decoupled from the draw it judges.
//!
//! **Why.** SURE's risk of a candidate `x_P`, `(x_P - m_P)² - v_P + 2 v_P div_P`
//! ([`super::gate`]), is unbiased when `v_P` is the variance of `m_P` *independently of the
//! draw*. The strata's estimate ([`super::noise`]) comes from the pixel's own samples, so it is
//! correlated with the box's error wherever the samples are skewed: in a dark glyph stroke
//! (a few percent of the pixel bright) or at a thin bright line, the draws that hit the bright
//! part have both a mean `m_P` too high and a large `v_P`, and the draws that miss it a mean
//! too low and `v_P` near 0. SURE then rewards smoothing exactly where the box is already
//! pulled toward the bright neighbours (`- v_P (1 - 2 div)` is most negative there) and the
//! gate smooths the stroke further toward them (suite: text 4 spp, relMSE 1.16 x the box's,
//! its excess in pixels of reference 0.05-0.2 beside bright paper).
//!
//! **The pooled estimate.** `vbar_P = (1 / |N_P|) sum_{Q in N_P} v_Q` over the 3 x 3
//! neighbourhood `N_P` (clipped at the border): where the noise varies slowly across pixels
//! it has the same expectation as `v_P` and depends on the pixel's own draw through one term
//! of nine, and it is less noisy (about nine times the difference blocks). Two exceptions
//! keep `v_P`:
//!
//! - **Outliers keep their own.** A pixel with a sample above the largest, or below the
//!   least, sample of its eight neighbours in some channel (a firefly, an emitter's edge, a
//!   caustic's peak) keeps `v_P`: there the large `v_P` is the evidence that the pixel holds
//!   a rare value its neighbours did not see, and lowering it to theirs would keep the firefly.
//!   (Texture's rare samples are values the neighbours hold too: the bright paper beside a
//!   glyph.)
//! - **A cap.** `v'_P = min(vbar_P, POOL_CAP v_P)` where the pixel is within range, so a
//!   quiet pixel beside a noisy or bright one (a dark pixel beside an emitter, in relMSE's
//!   most weighted place) does not take its neighbour's noise and get smoothed with it.
//!
//! Unlike [`super::spatial`]'s check this can *raise* a pixel's `v` (up to `POOL_CAP` times
//! its own), so the gate may smooth more there; what keeps the estimate's promise is the
//! gate itself, which still compares every candidate with the box by SURE over its window.
//! `POOL_CAP` was chosen on the suite's tuning half against 1, 1.5, 2 and no cap, and against
//! pooling without the outlier rule, a median or trimmed mean of the nine, and leaving out the
//! pixel's own `v_P` (`docs/measurements/estimators.md`).

use serde::Serialize;

use super::PixelStatistics;

/// The cap of the pooled noise relative to the pixel's own estimate (module docs).
pub const POOL_CAP: f64 = 4.0;

/// What the pooling did.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PooledNoise {
    /// [`POOL_CAP`].
    pub cap: f64,
    /// Pixels whose samples lie within their neighbours' range in every channel (pooled).
    pub pooled_pixels: usize,
    /// Of those, pixels where the cap bound (`vbar_P > POOL_CAP v_P` in some channel).
    pub capped_pixels: usize,
    /// Pixels that kept their own `v_P` (a sample outside their neighbours' range).
    pub own_pixels: usize,
    /// `sum_P v'_P / sum_P v_P` over the image and channels (1: unchanged on the whole).
    pub total_factor: f64,
}

impl PooledNoise {
    /// The pooling in words.
    pub fn describe(&self) -> String {
        format!(
            "then pooled over each pixel's 3x3 neighbourhood where its samples lie within its \
             neighbours' (at most {} times its own): pooled on {} pixels ({} at the cap), own \
             kept on {} with a sample outside their neighbours' range, total factor {:.2}",
            self.cap, self.pooled_pixels, self.capped_pixels, self.own_pixels, self.total_factor
        )
    }
}

/// Whether every sample of each pixel lies within the range of the samples of its (up to
/// eight) neighbours, in every channel (module docs). A pixel without neighbours holding
/// samples is not within.
pub fn within_neighbours(stats: &PixelStatistics) -> Vec<bool> {
    let (w, h) = (stats.plane.width(), stats.plane.height());
    (0..w * h)
        .map(|p| {
            let (x, y) = (p % w, p / w);
            stats.min.iter().zip(&stats.max).all(|(lo_c, hi_c)| {
                let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
                for yy in y.saturating_sub(1)..(y + 2).min(h) {
                    for xx in x.saturating_sub(1)..(x + 2).min(w) {
                        if (xx, yy) != (x, y) {
                            lo = lo.min(lo_c[yy * w + xx]);
                            hi = hi.max(hi_c[yy * w + xx]);
                        }
                    }
                }
                lo <= lo_c[p] && hi_c[p] <= hi
            })
        })
        .collect()
}

/// `v'_P = min(vbar_P, POOL_CAP v_P)` where `within[P]`, else `v_P`, per channel
/// (`variance[c]` row-major on a `w x h` plane; module docs). Non-finite `v_Q` are left out of
/// the means; a non-finite `v_P` stays.
pub fn pool_variance(
    variance: &mut [Vec<f64>],
    within: &[bool],
    w: usize,
    h: usize,
) -> PooledNoise {
    let before: f64 = variance.iter().flatten().filter(|x| x.is_finite()).sum();
    let mut capped = vec![false; w * h];
    for v in variance.iter_mut() {
        let own = v.clone();
        for p in (0..w * h).filter(|&p| within[p] && own[p].is_finite()) {
            let (x, y) = (p % w, p / w);
            let (mut sum, mut count) = (0.0, 0usize);
            for yy in y.saturating_sub(1)..(y + 2).min(h) {
                for xx in x.saturating_sub(1)..(x + 2).min(w) {
                    let q = own[yy * w + xx];
                    if q.is_finite() {
                        sum += q;
                        count += 1;
                    }
                }
            }
            let pooled = sum / count as f64;
            if pooled > POOL_CAP * own[p] {
                capped[p] = true;
            }
            v[p] = pooled.min(POOL_CAP * own[p]);
        }
    }
    let after: f64 = variance.iter().flatten().filter(|x| x.is_finite()).sum();
    let pooled_pixels = within.iter().filter(|&&x| x).count();
    PooledNoise {
        cap: POOL_CAP,
        pooled_pixels,
        capped_pixels: capped.iter().filter(|&&x| x).count(),
        own_pixels: within.len() - pooled_pixels,
        total_factor: if before > 0.0 { after / before } else { 1.0 },
    }
}
