//! Samples grown round by round as a renderer answering a plan would: the positions handed
//! out, in order, and an oracle's values at them (one channel: [`Rendered`]; every channel of
//! the oracle: [`RenderedChannels`]).

use rkwave::image::adaptive::{
    AdaptiveImage, AdaptiveParams, ImageOracle, NoisyOracle, SamplePositions,
};
use rkwave::image::{ImagePlane, ImageSamples};

use super::scenes::straight_edge;

/// The renderer of the file-protocol tests: [`straight_edge`] with noise `sigma = 0.05`.
pub const NOISY_EDGE: NoisyOracle<'static> = NoisyOracle {
    inner: &straight_edge,
    sigma: 0.05,
    seed: 3,
};

/// Their plan: 32², 4 spp, positions seeded by 11, the engine's default parameters otherwise.
pub fn small_plan() -> (ImagePlane, AdaptiveParams) {
    let plane = ImagePlane::new(32, 32).unwrap();
    let mut params = AdaptiveParams::default();
    params.stop.budget = 4 * plane.pixels();
    params.sampling.seed = 11;
    (plane, params)
}

/// The samples so far.
#[derive(Default)]
pub struct Rendered {
    /// Positions, in the order handed out.
    pub xs: Vec<f64>,
    /// Positions, in the order handed out.
    pub ys: Vec<f64>,
    /// The oracle's value at each position.
    pub values: Vec<f64>,
}

impl Rendered {
    /// Appends `oracle`'s values at the positions `next`.
    pub fn render(&mut self, oracle: &dyn ImageOracle, next: &SamplePositions) {
        let mut buf = [0.0];
        for (&x, &y) in next.xs.iter().zip(&next.ys) {
            oracle.sample(x, y, &mut buf);
            self.xs.push(x);
            self.ys.push(y);
            self.values.push(buf[0]);
        }
    }

    /// The samples so far on `plane`.
    pub fn samples(&self, plane: ImagePlane) -> ImageSamples {
        ImageSamples::new(
            plane,
            self.xs.clone(),
            self.ys.clone(),
            vec![self.values.clone()],
        )
        .unwrap()
    }
}

/// The samples so far in every channel of the oracle, grown round by round.
pub struct RenderedChannels {
    /// Positions, in the order handed out.
    pub xs: Vec<f64>,
    /// Positions, in the order handed out.
    pub ys: Vec<f64>,
    /// Per channel, the oracle's value at each position.
    pub values: Vec<Vec<f64>>,
}

impl RenderedChannels {
    /// No samples yet, in `channels` channels.
    pub fn new(channels: usize) -> Self {
        Self {
            xs: vec![],
            ys: vec![],
            values: vec![vec![]; channels],
        }
    }

    /// Appends `oracle`'s values at the positions `next`.
    pub fn render(&mut self, oracle: &dyn ImageOracle, next: &SamplePositions) {
        let mut buf = vec![0.0; oracle.channels()];
        for (&x, &y) in next.xs.iter().zip(&next.ys) {
            oracle.sample(x, y, &mut buf);
            self.xs.push(x);
            self.ys.push(y);
            for (c, v) in self.values.iter_mut().zip(&buf) {
                c.push(*v);
            }
        }
    }

    /// The samples so far on `plane`.
    pub fn samples(&self, plane: ImagePlane) -> ImageSamples {
        ImageSamples::new(plane, self.xs.clone(), self.ys.clone(), self.values.clone()).unwrap()
    }
}

/// A run on a scene whose only detail is noise did not chase it: no leaf more than one step
/// below the base, and at most one round marked cells (the noise test's false-alarm rate).
pub fn assert_noise_not_chased(run: &AdaptiveImage) {
    let base_step = run.report.base_levels.0 - run.report.coarse_levels.0;
    let deeper = run
        .tree
        .leaves()
        .iter()
        .filter(|c| c.step > base_step + 1)
        .count();
    assert_eq!(deeper, 0, "{:?}", run.report.cells_per_step);
    let marking = run.report.rounds.iter().filter(|r| r.marked > 0).count();
    assert!(marking <= 1, "{marking} rounds deepened the tree");
}
