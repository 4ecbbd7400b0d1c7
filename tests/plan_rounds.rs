//! The plan's final image at no second solve: the round that stops a plan carries its fit
//! (`final.bin`), and every final image of those samples (`plan --final-image`,
//! `reconstruct --dim 2 --state`, Python's `Plan.image()`: [`PlanFinal::run`]) is made from
//! it. Checked against independent references: the in-process loop's image (which never
//! leaves memory), the stopping round's own report (the same solve, not another), and, when
//! the carried fit is missing or is not of the samples given, a fit again whose pixels agree
//! to the solver's tolerance, with a note.

mod common;

use rkwave::image::adaptive::{refine_image, AdaptiveParams, TreeSolver};
use rkwave::image::job::PlanFinal;
use rkwave::image::plan::{PlanReconstruction, PlanState};
use rkwave::image::{DroppedSamples, ImagePlane, ImageSamples};
use rkwave::io::plan_files::FINAL_FILE;

use common::rendered::{small_plan, Rendered, NOISY_EDGE};

/// The renderer plan's PCG tolerance ([`TreeSolver::plan_pcg`]), the final fit's.
const TOL: f64 = 3e-4;

/// The small plan of the file-protocol tests under the renderer plan's PCG (`3e-4`, rounds
/// to `1e-2`).
fn setup() -> (ImagePlane, AdaptiveParams) {
    let (plane, mut params) = small_plan();
    params.fit.solver = TreeSolver::plan_pcg();
    assert_eq!(
        params.fit.solver.with_tolerance(TOL),
        Some(params.fit.solver)
    );
    (plane, params)
}

/// Drives the plan of [`setup`] to its stop through the folder `dir` (each call loads the
/// state and its files, then saves them); returns the last samples and the stopping round's
/// image.
fn to_stop(dir: &std::path::Path) -> (ImageSamples, PlanReconstruction) {
    let (plane, params) = setup();
    let (state, base) = PlanState::start(plane, &params).unwrap();
    state.save(dir).unwrap();
    let mut rendered = Rendered::default();
    rendered.render(&NOISY_EDGE, &base);
    for _ in 0..40 {
        let mut state = PlanState::load(dir).unwrap();
        let samples = rendered.samples(plane);
        let step = state.advance(&samples).unwrap();
        state.save(dir).unwrap();
        if let Some(done) = step.reconstruction {
            assert!(dir.join(FINAL_FILE).exists());
            return (samples, *done);
        }
        assert!(
            !dir.join(FINAL_FILE).exists(),
            "a final fit before the stop"
        );
        rendered.render(&NOISY_EDGE, &step.next);
    }
    panic!("the plan did not stop")
}

/// The final image of the plan in `dir` from its files, as `reconstruct --dim 2 --state`
/// makes it (no stopping round handed over).
fn final_image(dir: &std::path::Path, samples: &ImageSamples) -> PlanReconstruction {
    let state = PlanState::load(dir).unwrap();
    PlanFinal::of(&state, false)
        .run(samples, DroppedSamples::default(), None)
        .unwrap()
}

/// From the files, the final image is the stopping round's, bit for bit, and its fit is the
/// stopping round's solve itself (the same iterations and the same timings to the bit: no
/// second solve); and it is the in-process loop's image.
#[test]
fn the_final_image_is_the_stopping_rounds_fit() {
    let dir = common::scratch("plan-rounds", "carried");
    let (samples, stopping) = to_stop(&dir);
    let done = final_image(&dir, &samples);
    assert!(done.fit_note.is_none(), "{:?}", done.fit_note);
    assert!(done.complete);
    assert_eq!(done.image.channels, stopping.image.channels);
    assert_eq!(done.fit.coefficients, stopping.fit.coefficients);
    let (a, b) = (&done.fit.report, &stopping.fit.report);
    assert_eq!(
        (a.iterations, a.solve_s.to_bits(), a.kernel_s.to_bits()),
        (b.iterations, b.solve_s.to_bits(), b.kernel_s.to_bits())
    );
    assert!(a.converged && a.relative_residual <= TOL, "{a:?}");
    let (plane, params) = setup();
    let run = refine_image(&NOISY_EDGE, plane, &params).unwrap();
    assert_eq!(done.image.channels, run.image.channels);
}

/// Without `final.bin` (removed, or damaged), or given the same positions with other values,
/// the samples are fitted again, with a note naming why; that fit solves the same equations to
/// the same relative residual `tol = 3e-4` of the normal equations from the carried start,
/// so its fit's box pixels differ from the carried ones by at most about `kappa tol`
/// relative (`kappa` the Lanczos estimate of the preconditioned `G` both report; the
/// box pixels are an orthonormal synthesis and box integrals of the coefficients). Allowed:
/// `4 kappa tol`.
#[test]
fn without_the_carried_fit_the_samples_are_fitted_again_with_a_note() {
    let dir = common::scratch("plan-rounds", "again");
    let (samples, stopping) = to_stop(&dir);
    let close = |done: &PlanReconstruction| {
        let (a, b) = (&stopping.fit_image.channels[0], &done.fit_image.channels[0]);
        let norm = a.iter().map(|v| v * v).sum::<f64>().sqrt();
        let diff = a
            .iter()
            .zip(b)
            .map(|(x, y)| (x - y) * (x - y))
            .sum::<f64>()
            .sqrt();
        let kappa = stopping.fit.report.condition.max(done.fit.report.condition);
        assert!(
            diff <= 4.0 * kappa * TOL * norm,
            "relative difference {:.3e}, kappa {kappa:.1}",
            diff / norm
        );
    };
    let bytes = std::fs::read(dir.join(FINAL_FILE)).unwrap();
    std::fs::remove_file(dir.join(FINAL_FILE)).unwrap();
    let missing = final_image(&dir, &samples);
    let note = missing
        .fit_note
        .as_deref()
        .expect("no note without final.bin");
    assert!(
        note.contains(FINAL_FILE) && note.contains("not found") && note.contains("fitted again"),
        "{note}"
    );
    close(&missing);
    let mut flipped = bytes.clone();
    let at = flipped.len() / 2;
    flipped[at] ^= 0x04;
    std::fs::write(dir.join(FINAL_FILE), &flipped).unwrap();
    let damaged = final_image(&dir, &samples);
    let note = damaged
        .fit_note
        .as_deref()
        .expect("no note for a damaged final.bin");
    assert!(
        note.contains(FINAL_FILE) && note.contains("checksum") && note.contains("fitted again"),
        "{note}"
    );
    assert_eq!(damaged.image.channels, missing.image.channels);
    // the same positions, other values: not the carried fit's samples
    std::fs::write(dir.join(FINAL_FILE), &bytes).unwrap();
    let (plane, _) = setup();
    let shifted: Vec<f64> = samples.values()[0].iter().map(|v| v + 1e-3).collect();
    let other = ImageSamples::new(
        plane,
        samples.xs().to_vec(),
        samples.ys().to_vec(),
        vec![shifted],
    )
    .unwrap();
    let refit = final_image(&dir, &other);
    let note = refit.fit_note.as_deref().expect("no note for other values");
    assert!(note.contains("not the ones it fitted"), "{note}");
    assert_ne!(refit.fit.coefficients, stopping.fit.coefficients);
    // and the carried fit is still there for the samples it fitted
    let again = final_image(&dir, &samples);
    assert!(again.fit_note.is_none());
    assert_eq!(again.image.channels, stopping.image.channels);
}
