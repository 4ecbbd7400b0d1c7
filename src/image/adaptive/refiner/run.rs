//! The in-process loop ([`refine_image`]): the plan's rounds with a scene as the oracle.

use std::time::Instant;

use super::super::correction::output_pixels;
use super::super::{AdaptiveError, ImageOracle};
use super::{AdaptiveImage, AdaptiveParams, AdaptiveTimes, Decision, ImagePlan, SamplePositions};
use crate::image::ImagePlane;

/// Growing sample store of the in-process loop: the oracle's values at the plan's positions.
struct Store<'a> {
    oracle: &'a dyn ImageOracle,
    xs: Vec<f64>,
    ys: Vec<f64>,
    values: Vec<Vec<f64>>,
    round_of: Vec<u32>,
}

impl Store<'_> {
    fn sample(&mut self, positions: &SamplePositions, round: u32) {
        let mut buf = vec![0.0; self.values.len()];
        for (&x, &y) in positions.xs.iter().zip(&positions.ys) {
            self.oracle.sample(x, y, &mut buf);
            self.xs.push(x);
            self.ys.push(y);
            for (c, v) in self.values.iter_mut().zip(&buf) {
                c.push(*v);
            }
            self.round_of.push(round);
        }
    }
}

/// Refines the image of `oracle` on `plane`: adaptive tree and samples, until the tolerance,
/// the depth limit, the budget or the round limit. A loop over [`ImagePlan::step`], the oracle
/// sampling each round's positions.
pub fn refine_image(
    oracle: &dyn ImageOracle,
    plane: ImagePlane,
    params: &AdaptiveParams,
) -> Result<AdaptiveImage, AdaptiveError> {
    let mut plan = ImagePlan::new(plane, params)?;
    let mut times = AdaptiveTimes::default();
    let mut store = Store {
        oracle,
        xs: Vec::new(),
        ys: Vec::new(),
        values: vec![Vec::new(); oracle.channels()],
        round_of: Vec::new(),
    };
    let t = Instant::now();
    store.sample(&plan.base_positions(), 0);
    times.sample_s += t.elapsed().as_secs_f64();
    let base_samples = store.xs.len();
    let mut rounds = Vec::new();
    let (fit, stop) = loop {
        let values: Vec<&[f64]> = store.values.iter().map(|v| v.as_slice()).collect();
        let round = plan.step(&store.xs, &store.ys, &values)?;
        times.fit_s += round.fit_s;
        times.refine_s += round.refine_s;
        times.sample_s += round.position_s;
        times.rebuild_s += round.log.rebuild.as_ref().map_or(0.0, |r| r.rebuild_s);
        rounds.push(round.log);
        match round.decision {
            Decision::Stop(stop) => break (round.fit, stop),
            Decision::Sample(next) => {
                let t = Instant::now();
                store.sample(&next, rounds.len() as u32);
                times.sample_s += t.elapsed().as_secs_f64();
            }
        }
    };
    // the output pixels, with the final round's noise estimate (as the protocol's)
    let sigma = rounds
        .last()
        .and_then(|r| r.noise.as_ref())
        .map_or(0.0, |n| n.sigma);
    let (_, image, correction) = output_pixels(
        &plan.tree,
        &fit,
        &store.xs,
        &store.ys,
        &store.values,
        params.output.pixels,
        sigma,
        params.output.residual_z,
    )?;
    let mut report = plan.report(base_samples, store.xs.len(), &fit, stop, rounds, times);
    report.notes.push(correction.note());
    report.pixels = correction;
    Ok(AdaptiveImage {
        tree: plan.tree,
        xs: store.xs,
        ys: store.ys,
        values: store.values,
        round_of: store.round_of,
        fit,
        image,
        report,
    })
}
