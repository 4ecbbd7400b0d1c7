//! The job of the lab's image commands (`image`, `compare`): methods on a sampled scene,
//! checked as one request against the memory limit before a sample is drawn.
//!
//! The request's peak is the larger of (bytes by [`crate::resources::ImageRequest`], sizes
//! alone): each method's reconstruction of `m = s W H` samples with `k + 1` images held (the
//! `k` methods' results, one after the other, and the truth), `2 m` samples when one
//! pixel's equivalent filter resamples the scene; and, when the adaptive rows run beside
//! them, the adaptive tree fit of a budget `B = s W H` ([`adaptive_request`]). A request above
//! the limit is refused ([`ImageRunError::Resources`]) naming the parameters to lower.

use crate::error::{Fix, Param};
use crate::image::adaptive::AdaptiveParams;
use crate::image::equivalent_filter::SampleWeight;
use crate::image::job::memory::method_request;
use crate::image::scene::Scene;
use crate::image::{sample_weights, ImageMethod, WaveletParams};
use crate::resources::{Advice, ImageRequest};

use super::adaptive::adaptive_request;
use super::experiment::{
    compare_methods, sample_scene, Comparison, ImageRunError, SamplingParams, TruthParams,
};

/// Colour channels of every lab scene.
const CHANNELS: usize = 3;

/// What the comparison runs: the sampling (its `noise` is each run's, [`ComparisonJob::run`]),
/// the methods, the wavelet fit, the truth; one pixel's equivalent filter of the first method
/// (`filter_at`, pixel `(x, y)`); the adaptive rows' parameters when they run beside it (for
/// the memory check; [`super::adaptive::compare_adaptive`] runs them).
#[derive(Debug, Clone)]
pub struct ComparisonRequest {
    /// Resolution, samples per pixel, sampler and seed.
    pub sampling: SamplingParams,
    /// The methods, run one after the other on the same samples.
    pub methods: Vec<ImageMethod>,
    /// The wavelet methods' parameters.
    pub wavelet: WaveletParams,
    /// The ground truth.
    pub truth: TruthParams,
    /// The pixel whose equivalent filter (each sample's weight) is computed.
    pub filter_at: Option<(usize, usize)>,
    /// The adaptive rows' parameters, when they run beside the methods.
    pub adaptive: Option<AdaptiveParams>,
}

/// A comparison checked against the memory limit ([`ComparisonJob::new`]), run on one scene
/// and noise level at a time ([`ComparisonJob::run`]).
#[derive(Debug, Clone)]
pub struct ComparisonJob {
    request: ComparisonRequest,
}

/// One run of a [`ComparisonJob`].
pub struct ComparisonRun {
    /// The methods measured on one sample set.
    pub comparison: Comparison,
    /// The equivalent filter at [`ComparisonRequest::filter_at`]: each sample's weight.
    pub weights: Option<Vec<SampleWeight>>,
}

impl ComparisonJob {
    /// Validates the request and refuses it above the memory limit, before any sample is
    /// drawn (module docs).
    pub fn new(request: ComparisonRequest) -> Result<Self, ImageRunError> {
        let plane = request.sampling.plane;
        let spp = request.sampling.spp;
        let samples = spp as f64 * plane.pixels() as f64;
        let images = request.methods.len() + 1;
        let wavelet = &request.wavelet;
        let mut memory = request
            .methods
            .iter()
            .map(|&m| method_request(plane, CHANNELS, samples, m, wavelet.p, wavelet.rho, images))
            .reduce(ImageRequest::larger)
            .ok_or(ImageRunError::Parameter {
                parameter: "methods",
                value: "none".into(),
                expected: "at least one method",
            })?;
        if request.filter_at.is_some() {
            memory.samples *= 2.0;
        }
        if let Some(params) = &request.adaptive {
            memory = memory.larger(adaptive_request(plane, spp * plane.pixels(), params));
        }
        let methods = &request.methods;
        memory.estimate().check_advised(
            || match methods.as_slice() {
                [method] => format!(
                    "{method} on {plane} at {spp} samples per pixel ({} samples)",
                    crate::norms::show(memory.samples)
                ),
                _ => format!(
                    "comparing {} methods on {plane} at {spp} samples per pixel",
                    methods.len()
                ),
            },
            || match methods.len() {
                1 => Advice::Fixes(
                    "a smaller {} or {}",
                    vec![Fix::Set(Param::Resolution), Fix::Set(Param::Spp)],
                ),
                _ => Advice::Fixes(
                    "a smaller {} or {}, or fewer {}",
                    vec![
                        Fix::Set(Param::Resolution),
                        Fix::Set(Param::Spp),
                        Fix::Set(Param::Methods),
                    ],
                ),
            },
        )?;
        Ok(Self { request })
    }

    /// The methods on one sample set of `scene` with noise of deviation `noise`, measured
    /// against the truth ([`compare_methods`]); the equivalent filter of the first method at
    /// [`ComparisonRequest::filter_at`] on the same samples ([`sample_weights`]).
    pub fn run(&self, scene: &Scene, noise: f64) -> Result<ComparisonRun, ImageRunError> {
        let r = &self.request;
        let sampling = SamplingParams {
            noise,
            ..r.sampling
        };
        let comparison = compare_methods(scene, &sampling, &r.methods, &r.wavelet, &r.truth)?;
        let weights = match r.filter_at {
            None => None,
            Some((x, y)) => {
                let samples = sample_scene(scene, &sampling)?;
                Some(sample_weights(r.methods[0], &samples, &r.wavelet, x, y)?)
            }
        };
        Ok(ComparisonRun {
            comparison,
            weights,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::ErrorKind;
    use crate::image::sampler::Sampler;
    use crate::image::ImagePlane;

    fn request(side: usize, spp: usize, methods: Vec<ImageMethod>) -> ComparisonRequest {
        ComparisonRequest {
            sampling: SamplingParams {
                plane: ImagePlane::new(side, side).unwrap(),
                spp,
                sampler: Sampler::Stratified,
                noise: 0.0,
                seed: 1,
            },
            methods,
            wavelet: WaveletParams::default(),
            truth: TruthParams::default(),
            filter_at: None,
            adaptive: None,
        }
    }

    /// No method is refused as a parameter; a request whose samples alone (`8 m (2 + c)`
    /// bytes at `m = 4096 * 16384²`, over 8 TB) exceed any machine's limit is refused as a
    /// resource limit before anything is allocated.
    #[test]
    fn refuses_before_sampling() {
        let none = ComparisonJob::new(request(8, 1, vec![])).unwrap_err();
        assert_eq!(none.kind(), ErrorKind::InvalidInput, "{none}");
        let huge =
            ComparisonJob::new(request(16384, 4096, vec![ImageMethod::Wavelet])).unwrap_err();
        assert_eq!(huge.kind(), ErrorKind::ResourceLimit, "{huge}");
        let text = huge.to_string();
        assert!(text.contains("SamplingParams::spp"), "{text}");
        assert!(!text.contains("--"), "{text}");
        let two = vec![ImageMethod::Wavelet, ImageMethod::Local];
        let text = ComparisonJob::new(request(16384, 4096, two))
            .unwrap_err()
            .to_string();
        assert!(text.contains("comparing 2 methods"), "{text}");
        assert!(text.contains("the methods compared"), "{text}");
    }
}
