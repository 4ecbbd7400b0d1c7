//! The plan's final image by `blend_gated` (`src/image/adaptive/correction.rs`, module docs, *No
//! harm*) against the per-pixel mean of its own samples, on texture past the pixel scale:
//! a random sub-pixel checker (cells of a third of a pixel, so every pixel integral is a
//! deterministic mix the fit cannot resolve) plus Gaussian noise, sampled as a plan samples
//! (the adaptive run's positions, deep where the tree deepens, plus a second set of 2 to 12
//! jittered samples a pixel, uneven by pixel). Properties:
//!
//! 1. the final gate ran and its estimated risk (the chosen candidates' SURE, per pixel
//!    averaged over the image) is not above the box pixels' (`v_P` summed over channels):
//!    each pixel took the candidate of least window risk, the box among them;
//! 2. the final image's squared error against the pixel integrals (by a 24 x 24 midpoint
//!    rule, exact for the checker's cells up to their boundaries) is at most 1.05 times that
//!    of the mean of the same samples, for three seeds and two noise levels (the tolerance:
//!    the gate decides on an estimate of the risk, so it may take a step that raises the
//!    true risk by a small amount).

mod common;

use common::sub_pixel_checker::run;
use rkwave::image::adaptive::correction::PixelEstimate;

#[test]
fn the_final_image_is_not_worse_than_the_mean_of_its_own_samples_on_sub_pixel_texture() {
    for sigma in [0.02, 0.2] {
        for seed in 1..=3 {
            let (err_final, err_box, report) = run(seed, sigma, PixelEstimate::BlendGated);
            let note = report.note();
            let gate = report
                .final_gate
                .as_ref()
                .unwrap_or_else(|| panic!("{note}"));
            assert_eq!(gate.counts.len(), 3, "{note}");
            let (risk, box_risk) = (gate.risk, gate.box_risk);
            assert!(
                risk <= box_risk,
                "seed {seed} sigma {sigma}: {risk} > {box_risk}; {note}"
            );
            assert!(
                err_final <= 1.05 * err_box,
                "seed {seed} sigma {sigma}: final {err_final:.4e} against the box's {err_box:.4e}; {note}"
            );
        }
    }
}
