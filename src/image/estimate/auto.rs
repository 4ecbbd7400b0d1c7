//! `--pixels auto`: per pixel, the candidate estimate of least estimated risk against the box
//! pixels `m_P` (the mean of the pixel's own samples), the box itself among the candidates, so
//! no pixel takes a step its risk estimate says raises the risk ([`super::gate`]).
//!
//! 1. **Noise per pixel**, not a global level: `v_P`, the variance of `m_P`, the least of
//!    three difference estimates of the strata (2D second differences, successive differences
//!    along `x` and along `y`, [`super::noise`]), each cancelling a class of the signal's
//!    variation between strata (an edge or gradient across the pixel, texture coarser than a
//!    stratum) and keeping what the stratified mean really varies by; then checked against
//!    the box pixels' own differences across pixels and lowered wherever it says more than
//!    twice the noise they show (texture inside the strata, a sampler that stratifies more
//!    than the model knows; never raised, [`super::spatial`]).
//! 2. **Films**: the film filter of least SURE over the window around each pixel
//!    ([`super::sure`]; the box film `F = m`, `A = 1`, is one of the five).
//! 3. **SureShrink of the box pixels**: cycle-spun Haar, heteroscedastic coefficient variances
//!    propagated exactly from `v_P`, a SURE-chosen threshold per level with "no shrinkage"
//!    among the candidates ([`super::sureshrink`]).
//! 4. **Gate**: candidates box, films, SureShrink, the convex combinations
//!    `alpha F + (1 - alpha) S` (`alpha` in `1/4, 1/2, 3/4`) and the robust candidate, each
//!    with its exact per-pixel divergence; each pixel takes the one of least SURE over its
//!    9 x 9 window ([`super::gate`]), the window's pixels weighted by `1 / (x² + 0.01)` (`x`
//!    the half-and-half candidate), the relative error that relMSE measures, so that the
//!    bright pixels of an HDR window (an emitter, a firefly) do not decide for the dark ones,
//!    and only the window's pixels at the pixel's level counted (within a factor 2 of its
//!    level `L = (1/C) sum_c |x_c|`, [`super::gate::LEVEL_RATIO`]), so that a dark pixel is
//!    not carried by a decision its brighter neighbours made. The weights and the levels
//!    depend on the data only through a smooth candidate; the per-pixel estimates stay
//!    unbiased. (Candidates projected onto each pixel's own sample range were candidates
//!    before: with them the gate's window choice carried the unclamped pixels of texture,
//!    `docs/measurements/estimators.md`; the range step 5 stays.)
//! 5. **Range**: each pixel is projected onto the range of the samples in it and its eight
//!    neighbours (the samples that shaped it at the finest scale): no negative radiance, no
//!    overshoot beside an emitter (a film with negative lobes, or a shrunk coefficient).
//!    The box pixel lies in its own samples' range and never moves; the pixels moved are
//!    counted in the report.
//!
//! It needs a sample in every pixel (the box pixels `m_P` are SURE's observation) and the
//! noise of at least half the pixels (two samples or more each); otherwise
//! [`estimate`] returns the reason and the caller falls back.

use serde::Serialize;

use super::clamp::clamp_to_local_range;
use super::gate::{gate, GateCandidate, GateCount, GATE_HALF, LEVEL_EPS, LEVEL_RATIO};
use super::noise::{CountCalibration, DifferenceCount, PixelNoise};
use super::robust::{robust_estimate, RobustReport, KAPPA, ROBUST_HALF};
use super::shrink::ShrinkParams;
use super::spatial::{apply_factors, spatial_factors, SpatialCheck};
use super::statistics::median;
use super::sure::{choose_films, FilmRisks};
use super::sureshrink::sure_shrink_channel;
use crate::image::filters::FilmFilterKind;
use crate::image::splat::PixelBins;
use crate::image::{ImageSamples, PixelImage};

/// Half the side of SURE's window: `(2 h + 1)²` pixels, 17 x 17 (chosen on the Mitsuba
/// renders direct, cornell and thinlens against 9 x 9 and 33 x 33,
/// `docs/measurements/real-renders.md`; those three are in the suite's tuning half, and the
/// validation half's figures are in `docs/measurements/estimators.md`).
pub const WINDOW_HALF: usize = 8;

/// Pixels that took one film.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct FilmCount {
    /// The film.
    pub film: FilmFilterKind,
    /// Its pixels.
    pub pixels: usize,
}

/// The weights `alpha` of the films in the candidates `alpha F + (1 - alpha) S`.
pub const MIX_WEIGHTS: [f64; 3] = [0.25, 0.5, 0.75];

/// `eps` of the relative weights `1 / (x² + eps)` of the gate's window sums (the relMSE's).
pub const RELATIVE_EPS: f64 = 0.01;

/// What `auto` found and did.
#[derive(Debug, Clone, PartialEq)]
pub struct AutoReport {
    /// Pixels per film.
    pub films: Vec<FilmCount>,
    /// Estimated risks of the films.
    pub risk: FilmRisks,
    /// The output's SURE per pixel, averaged over the window (before the range projection).
    pub window_risk: Vec<f64>,
    /// The noise of a pixel's mean `sigma_c` ([`PixelNoise::sigma`]; reported, not used: every
    /// step uses each pixel's own `v_P`).
    pub sigma: Vec<f64>,
    /// Pixels whose noise was estimated.
    pub pixels_with_blocks: usize,
    /// Pixels per difference estimate of the noise.
    pub noise_estimators: Vec<DifferenceCount>,
    /// `c`, the least of three's expectation on pure noise relative to the noise at these
    /// positions ([`PixelNoise::pure_noise_ratio`]).
    pub pure_noise_ratio: Option<f64>,
    /// The equalisation of the noise across sample counts ([`PixelNoise::equalise_counts`]),
    /// when [`ShrinkParams::equalise_counts`] asks for it.
    pub counts: Option<CountCalibration>,
    /// The check of `v_P` against the box pixels' differences across pixels
    /// ([`super::spatial`]).
    pub spatial: SpatialCheck,
    /// Pixels per gate candidate.
    pub gate: Vec<GateCount>,
    /// Mean estimated risk per pixel of the output (summed over channels).
    pub estimated_risk: f64,
    /// Mean estimated risk per pixel of the box (`sum_c v_{P,c}`).
    pub box_risk: f64,
    /// The robust candidate's report.
    pub robust: RobustReport,
    /// The median SureShrink `lambda` per channel (over shifts and levels).
    pub lambda: Vec<f64>,
    /// The fraction of Haar detail coefficients SureShrink killed, per channel.
    pub killed: Vec<f64>,
    /// Pixels the range projection moved.
    pub range_clamped: usize,
    /// Its largest move.
    pub largest_clamp: f64,
    /// The shrinkage's parameters.
    pub shrink: ShrinkParams,
    /// `v_{P,c}`, the noise of each pixel's mean every step used (per channel and pixel,
    /// after the check against the box pixels' differences across pixels).
    pub pixel_variance: Vec<Vec<f64>>,
    /// The gate's level ratio: a window's pixels within this factor of the centre's level
    /// count ([`LEVEL_RATIO`]).
    pub level_ratio: f64,
}

impl AutoReport {
    /// The report in words.
    pub fn describe(&self) -> String {
        let films = self
            .films
            .iter()
            .map(|f| format!("{} {}", f.film, f.pixels))
            .collect::<Vec<_>>()
            .join(", ");
        let noise = self
            .noise_estimators
            .iter()
            .map(|d| format!("{} {}", d.estimator.name(), d.pixels))
            .collect::<Vec<_>>()
            .join(", ");
        let gate = self
            .gate
            .iter()
            .map(|g| format!("{} {}", g.candidate, g.pixels))
            .collect::<Vec<_>>()
            .join(", ");
        // SURE is unbiased but not positive: where the output's estimated risk is at or below
        // 0 (its own noise exceeds the risk left), a ratio in dB would be meaningless.
        let gain = if self.box_risk <= 0.0 {
            "none (no noise)".into()
        } else if self.estimated_risk <= 0.0 {
            "not resolved: the estimated risk is not above 0, within SURE's own noise".into()
        } else {
            format!(
                "{:.2} dB",
                10.0 * (self.box_risk / self.estimated_risk).log10()
            )
        };
        let calibration = match self.pure_noise_ratio {
            Some(c) => format!(
                "; on pure noise at these positions that estimate is {c:.2} of the noise \
                 (simulated), so the estimated risks are low by about that factor where pixels \
                 hold noise only"
            ),
            None => String::new(),
        };
        format!(
            "pixels: auto, per pixel the candidate of least SURE against the box over the \
             pixels of the {gside} x {gside} window within a factor {ratio} of its level (eps \
             {LEVEL_EPS}), each pixel weighted by 1 / (x² + {RELATIVE_EPS}) (pixels \
             per candidate: {gate}); films by SURE: {films}; SureShrink of the box pixels ({} \
             shifts, heteroscedastic per-pixel noise, median lambda {} per channel, {} of the \
             coefficients killed); noise of each pixel's mean from the least of three difference \
             estimates of its strata ({} pixels: {noise}; median sigma {}{calibration}; {}; {}); estimated risk per pixel {:.3e} \
             against the box's {:.3e} (gain {gain}); {} pixels projected onto the range of the \
             samples in their 3x3 neighbourhood (largest move {:.3e}); {}",
            self.shrink.shifts * self.shrink.shifts,
            super::list(&self.lambda),
            self.killed
                .iter()
                .map(|k| format!("{:.1}%", 100.0 * k))
                .collect::<Vec<_>>()
                .join(", "),
            self.pixels_with_blocks,
            super::list(&self.sigma),
            self.counts.as_ref().map_or_else(
                || "noise not equalised across sample counts".to_string(),
                CountCalibration::describe
            ),
            self.spatial.describe(),
            self.estimated_risk,
            self.box_risk,
            self.range_clamped,
            self.largest_clamp,
            self.robust.describe(),
            gside = 2 * GATE_HALF + 1,
            ratio = self.level_ratio,
        )
    }
}

/// The `auto` pixels of `samples`, or why the samples do not permit them.
pub fn estimate(
    samples: &ImageSamples,
    shrink: &ShrinkParams,
) -> Result<(PixelImage, AutoReport), String> {
    let plane = samples.plane();
    let (w, h) = (plane.width(), plane.height());
    let bins = PixelBins::new(samples);
    let pixels = plane.pixels();
    let channels = samples.channels();
    let empty: Vec<usize> = (0..pixels)
        .filter(|&p| bins.in_pixel(p).is_empty())
        .collect();
    if let Some(&first) = empty.first() {
        return Err(format!(
            "{} pixels have no sample (the first at ({}, {})), and SURE compares each film with \
             the mean of the pixel's own samples",
            empty.len(),
            first % w,
            first / w
        ));
    }
    let mut noise = PixelNoise::new(samples, &bins)
        .filter(|n| 2 * n.pixels_with_blocks() >= pixels)
        .ok_or_else(|| {
            let two = (0..pixels).filter(|&p| bins.in_pixel(p).len() >= 2).count();
            format!(
                "only {two} of {pixels} pixels have two samples or more, so the noise of a \
                 pixel's mean is unknown (render at least 2 samples per pixel)"
            )
        })?;
    // 1a. with `shrink.equalise_counts`, every count's noise brought to the most common
    // count's bias (`noise`, "Counts")
    let counts = shrink
        .equalise_counts
        .then(|| noise.equalise_counts(samples, &bins));
    let mean: Vec<Vec<f64>> = samples
        .values()
        .iter()
        .map(|v| {
            (0..pixels)
                .map(|p| {
                    let idx = bins.in_pixel(p);
                    idx.iter().map(|&i| v[i]).sum::<f64>() / idx.len() as f64
                })
                .collect()
        })
        .collect();
    let mut variance: Vec<Vec<f64>> = (0..channels)
        .map(|c| (0..pixels).map(|p| noise.pixel_variance(c, p)).collect())
        .collect();
    // 1b. the strata's noise checked against the box pixels' own differences across pixels,
    // lowered where it says more than twice the noise they show (`super::spatial`)
    let factors = spatial_factors(&mean, &variance, w, h, GATE_HALF);
    apply_factors(&mut noise.mean_variance, &factors, GATE_HALF);
    let spatial = apply_factors(&mut variance, &factors, GATE_HALF);
    let choice = choose_films(
        samples,
        &bins,
        &noise,
        &mean,
        &FilmFilterKind::ALL,
        WINDOW_HALF,
    );
    let shrunk: Vec<_> = (0..channels)
        .map(|c| sure_shrink_channel(&mean[c], &variance[c], w, h, shrink.shifts))
        .collect();
    let boxed = GateCandidate {
        name: "box".into(),
        image: PixelImage {
            plane,
            channels: mean.clone(),
        },
        divergence: vec![vec![1.0; pixels]; channels],
    };
    let films = GateCandidate {
        name: "films".into(),
        image: choice.image.clone(),
        divergence: vec![choice.own_weight.clone(); channels],
    };
    let sure_shrunk = GateCandidate {
        name: "sureshrink".into(),
        image: PixelImage {
            plane,
            channels: shrunk.iter().map(|s| s.image.clone()).collect(),
        },
        divergence: shrunk.iter().map(|s| s.divergence.clone()).collect(),
    };
    let mut candidates = vec![boxed, films.clone(), sure_shrunk.clone()];
    for alpha in MIX_WEIGHTS {
        let mix = |a: &[Vec<f64>], b: &[Vec<f64>]| -> Vec<Vec<f64>> {
            a.iter()
                .zip(b)
                .map(|(x, y)| {
                    x.iter()
                        .zip(y)
                        .map(|(u, v)| alpha * u + (1.0 - alpha) * v)
                        .collect()
                })
                .collect()
        };
        candidates.push(GateCandidate {
            name: format!("{alpha} films + {} sureshrink", 1.0 - alpha),
            image: PixelImage {
                plane,
                channels: mix(&films.image.channels, &sure_shrunk.image.channels),
            },
            divergence: mix(&films.divergence, &sure_shrunk.divergence),
        });
    }
    // the robust candidate for heavy tails (its bias estimated and reported, `robust`)
    let (robust_image, robust_divergence, mut robust) =
        robust_estimate(samples, &bins, KAPPA, ROBUST_HALF);
    let robust_index = candidates.len();
    candidates.push(GateCandidate {
        name: "robust".into(),
        image: robust_image,
        divergence: robust_divergence,
    });
    // relative weights 1 / (x² + eps) and levels from the half-and-half candidate (module
    // docs, 4.): the mixtures follow the box, the films and SureShrink
    let half_and_half = 3 + MIX_WEIGHTS
        .iter()
        .position(|&a| a == 0.5)
        .expect("1/2 is one of the mixing weights");
    let weight: Vec<Vec<f64>> = candidates[half_and_half]
        .image
        .channels
        .iter()
        .map(|ch| ch.iter().map(|x| 1.0 / (x * x + RELATIVE_EPS)).collect())
        .collect();
    let level: Vec<f64> = (0..pixels)
        .map(|p| {
            candidates[half_and_half]
                .image
                .channels
                .iter()
                .map(|ch| ch[p].abs())
                .sum::<f64>()
                / channels as f64
        })
        .collect();
    let gated = gate(
        &candidates,
        &mean,
        &variance,
        Some(&weight),
        Some(&level),
        GATE_HALF,
    );
    robust.gated_pixels = gated
        .choice
        .iter()
        .filter(|&&k| {
            candidates[k]
                .name
                .starts_with(&candidates[robust_index].name)
        })
        .count();
    let mut image = gated.image;
    let (range_clamped, largest_clamp) = clamp_to_local_range(
        &mut image.channels,
        plane,
        samples.xs(),
        samples.ys(),
        samples.values(),
    );
    let films = choice
        .counts()
        .into_iter()
        .map(|(film, pixels)| FilmCount { film, pixels })
        .collect();
    let lambda = shrunk
        .iter()
        .map(|s| median(&mut s.lambdas.clone()))
        .collect();
    Ok((
        image,
        AutoReport {
            films,
            risk: choice.risk,
            window_risk: gated.window_risk,
            sigma: noise.sigma.clone(),
            pixels_with_blocks: noise.pixels_with_blocks(),
            noise_estimators: noise.estimator_counts(),
            pure_noise_ratio: noise.pure_noise_ratio,
            counts,
            spatial,
            gate: gated.counts,
            estimated_risk: gated.risk,
            box_risk: gated.box_risk,
            robust,
            lambda,
            killed: shrunk.iter().map(|s| s.killed_fraction).collect(),
            range_clamped,
            largest_clamp,
            shrink: *shrink,
            pixel_variance: variance,
            level_ratio: LEVEL_RATIO,
        },
    ))
}
