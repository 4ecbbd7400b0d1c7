//! The renderer in the loop (issue 13, item 3): the adaptive refiner driven through its file
//! protocol gives the in-process loop's image, and bad input is refused with typed errors.

mod common;

use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_pcg::Pcg64;
use rkwave::image::adaptive::{
    refine_image, AdaptiveImage, AdaptiveParams, ImageOracle, NoisyOracle, PixelEstimate,
    SceneOracle,
};
use rkwave::image::plan::{PlanReconstruction, PlanState, ProtocolError, STATE_VERSION};
use rkwave::image::scene::Scene;
use rkwave::image::{ImagePlane, ImageSamples};
use rkwave::io::{read_npy, write_npy, SampleSet};

use common::rendered::RenderedChannels;
use common::scenes::{straight_edge, DiscsAndLine};
use rkwave::image::adaptive::{ImageSampling, StopParams, TreeSolver};

/// The default parameters with `budget` samples and positions seeded by `seed`.
fn budget_and_seed(budget: usize, seed: u64) -> AdaptiveParams {
    let mut params = AdaptiveParams::default();
    params.stop.budget = budget;
    params.sampling.seed = seed;
    params
}

/// The protocol's reconstruction and the in-process run agree bit for bit: the fit's box
/// pixels, the output pixels (the fit plus the significant mean residual, with the same noise
/// estimate and `z`) and the count of pixels corrected; and the correction did something.
fn same_pixels(done: &PlanReconstruction, run: &AdaptiveImage) {
    let fit_only = run.fit_pixels().unwrap();
    assert_eq!(done.fit.box_pixels(&done.tree).unwrap(), fit_only.channels);
    assert_eq!(done.fit_image, fit_only);
    assert_eq!(done.image, run.image);
    assert_eq!(done.correction, run.report.pixels);
    assert_eq!(done.correction.estimate, PixelEstimate::ResidualClamped);
    assert!(done.correction.corrected > 0, "{:?}", done.correction);
    assert_ne!(done.image, done.fit_image);
}

/// Drives a plan to its stop, passing the state through its JSON between calls as the
/// command line does; returns the final state and the samples.
fn drive(
    oracle: &dyn ImageOracle,
    plane: ImagePlane,
    params: &AdaptiveParams,
) -> (PlanState, RenderedChannels) {
    let (state, base) = PlanState::start(plane, params).unwrap();
    let mut json = state.to_json();
    let mut rendered = RenderedChannels::new(oracle.channels());
    rendered.render(oracle, &base);
    loop {
        let mut state = PlanState::from_json(&json, "state.json".as_ref()).unwrap();
        let step = state.advance(&rendered.samples(plane)).unwrap();
        json = state.to_json();
        if step.stop.is_some() {
            assert!(step.next.is_empty());
            return (state, rendered);
        }
        assert!(!step.next.is_empty());
        rendered.render(oracle, &step.next);
    }
}

/// Driving the protocol with the positions as handed out (in order, float64) repeats the
/// in-process loop exactly: the same positions, the same tree, bit-identical pixels (the same
/// arithmetic on the same numbers in the same order).
#[test]
fn protocol_gives_the_in_process_image() {
    let scene = Scene::from_file(Scene::builtin_dir().join("shapes.json")).unwrap();
    let plane = ImagePlane::new(40, 32).unwrap();
    let oracle = SceneOracle {
        scene: &scene,
        plane,
    };
    let params = budget_and_seed(4 * plane.pixels(), 11);
    let run = refine_image(&oracle, plane, &params).unwrap();
    assert!(run.report.rounds.len() > 2, "the test needs several rounds");
    let (state, rendered) = drive(&oracle, plane, &params);
    assert_eq!(rendered.xs, run.xs);
    assert_eq!(rendered.ys, run.ys);
    assert_eq!(state.stop, Some(run.report.stop));
    assert_eq!(state.issued.len(), run.report.rounds.len());
    let done = state.reconstruct(&rendered.samples(plane)).unwrap();
    assert!(done.complete);
    assert_eq!(done.tree.depth_map(), run.tree.depth_map());
    same_pixels(&done, &run);
}

/// With noise (a renderer's Monte Carlo estimates): the noise is a function of the seed and
/// the position, the noise test's probes too, so the file protocol still repeats the
/// in-process loop bit for bit, rounds that add samples to slots that stay slots (densifying
/// rounds, spare samples spread by the least growth) included.
#[test]
fn protocol_with_noise_gives_the_in_process_image() {
    let plane = ImagePlane::new(32, 32).unwrap();
    let oracle = NoisyOracle {
        inner: &straight_edge,
        sigma: 0.05,
        seed: 3,
    };
    let params = budget_and_seed(4 * plane.pixels(), 11);
    let run = refine_image(&oracle, plane, &params).unwrap();
    assert!(
        run.report
            .rounds
            .iter()
            .any(|r| r.densified_to.is_some() || r.spread > 0),
        "the test needs a round that densifies or spreads samples"
    );
    let (state, rendered) = drive(&oracle, plane, &params);
    assert_eq!(rendered.xs, run.xs);
    assert_eq!(rendered.ys, run.ys);
    assert_eq!(rendered.values, run.values);
    assert_eq!(state.stop, Some(run.report.stop));
    let done = state.reconstruct(&rendered.samples(plane)).unwrap();
    assert!(done.complete);
    assert_eq!(done.tree.depth_map(), run.tree.depth_map());
    same_pixels(&done, &run);
}

/// A renderer may return the samples in any order: the fingerprint is order-free, and the fit
/// differs only by rounding (sums in another order): pixels within `1e-12` of the in-process
/// image (values in [0, 1], `cond(G)` of the tree fit below `1e3`, so reordering changes the
/// solution by at most a few hundred ulps).
#[test]
fn samples_in_any_order() {
    let plane = ImagePlane::new(32, 32).unwrap();
    let params = budget_and_seed(3 * plane.pixels(), AdaptiveParams::default().sampling.seed);
    let run = refine_image(&straight_edge, plane, &params).unwrap();
    let (state, rendered) = drive(&straight_edge, plane, &params);
    let mut order: Vec<usize> = (0..rendered.xs.len()).collect();
    order.shuffle(&mut Pcg64::seed_from_u64(3));
    let shuffled = ImageSamples::new(
        plane,
        order.iter().map(|&i| rendered.xs[i]).collect(),
        order.iter().map(|&i| rendered.ys[i]).collect(),
        vec![order.iter().map(|&i| rendered.values[0][i]).collect()],
    )
    .unwrap();
    let done = state.reconstruct(&shuffled).unwrap();
    let pixels = done.fit.box_pixels(&done.tree).unwrap();
    let reference = run.fit_pixels().unwrap().channels;
    let largest = |a: &[f64], b: &[f64]| {
        a.iter()
            .zip(b)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
    };
    let err = largest(&pixels[0], &reference[0]);
    assert!(err <= 1e-12, "max pixel difference {err:e}");
    // the mean residuals too (sums of the same residuals in another order; no pixel at the
    // significance threshold for this seed: the same pixels are corrected)
    assert_eq!(done.correction.corrected, run.report.pixels.corrected);
    let err = largest(&done.image.channels[0], &run.image.channels[0]);
    assert!(err <= 1e-12, "max corrected pixel difference {err:e}");
}

/// The samples of an earlier round reconstruct on that round's tree (what the in-process loop
/// fitted in that round), and are refused by `advance` with the round they complete.
#[test]
fn earlier_rounds_are_recognised() {
    let plane = ImagePlane::new(32, 32).unwrap();
    let params = budget_and_seed(4 * plane.pixels(), AdaptiveParams::default().sampling.seed);
    let (state, base) = PlanState::start(plane, &params).unwrap();
    let mut rendered = RenderedChannels::new(1);
    rendered.render(&straight_edge, &base);
    let base_samples = rendered.samples(plane);
    let mut advanced = state.clone();
    let step = advanced.advance(&base_samples).unwrap();
    assert_eq!(step.next_round, Some(1));
    let err = advanced.clone().advance(&base_samples).unwrap_err();
    assert!(
        matches!(
            err,
            ProtocolError::AlreadyPlanned {
                matched: 0,
                round: 1,
                ..
            }
        ),
        "{err}"
    );
    // round 0's samples on the base tree: the first fit of the loop
    let done = advanced.reconstruct(&base_samples).unwrap();
    assert_eq!(done.round, 0);
    assert!(!done.complete);
    assert_eq!(done.fit.report.functions, step.log.functions);
    let base_depth = done.tree.leaves()[0].step;
    assert!(done.tree.leaves().iter().all(|c| c.step == base_depth));
}

/// A state written before the output pixels were a parameter (no `pixels`, no `residual_z`)
/// still parses, with the defaults: the residual correction, clamped, at `z = 3`; its
/// reconstruction is the current in-process image.
#[test]
fn a_state_without_the_output_parameters_parses_with_the_defaults() {
    let plane = ImagePlane::new(32, 32).unwrap();
    let params = budget_and_seed(4 * plane.pixels(), AdaptiveParams::default().sampling.seed);
    let (state, rendered) = drive(&straight_edge, plane, &params);
    let mut value: serde_json::Value = serde_json::from_str(&state.to_json()).unwrap();
    let fields = value["params"].as_object_mut().unwrap();
    assert!(fields.remove("pixels").is_some() && fields.remove("residual_z").is_some());
    let old = PlanState::from_json(&value.to_string(), "state.json".as_ref()).unwrap();
    assert_eq!(old.params.output.pixels, PixelEstimate::ResidualClamped);
    assert_eq!(old.params.output.residual_z, 3.0);
    assert_eq!(old, state);
    let run = refine_image(&straight_edge, plane, &params).unwrap();
    let done = old.reconstruct(&rendered.samples(plane)).unwrap();
    assert_eq!(done.image, run.image);
}

#[test]
fn bad_input_is_refused() {
    let plane = ImagePlane::new(32, 32).unwrap();
    let params = budget_and_seed(4 * plane.pixels(), 5);
    let (state, base) = PlanState::start(plane, &params).unwrap();
    // samples of another seed
    let (_, other) = PlanState::start(
        plane,
        &AdaptiveParams {
            sampling: ImageSampling {
                seed: 6,
                ..params.sampling
            },
            ..params
        },
    )
    .unwrap();
    let mut foreign = RenderedChannels::new(1);
    foreign.render(&straight_edge, &other);
    let err = state.clone().advance(&foreign.samples(plane)).unwrap_err();
    assert!(
        matches!(err, ProtocolError::Mismatch { round: 0, .. }),
        "{err}"
    );
    // positions rounded to float32 on the way
    let mut rounded = RenderedChannels::new(1);
    rounded.render(&straight_edge, &base);
    for x in &mut rounded.xs {
        *x = *x as f32 as f64;
    }
    let err = state.clone().advance(&rounded.samples(plane)).unwrap_err();
    assert!(matches!(err, ProtocolError::Mismatch { .. }), "{err}");
    // a subset (a lost sample)
    let mut rendered = RenderedChannels::new(1);
    rendered.render(&straight_edge, &base);
    let mut lost = rendered.samples(plane);
    lost = ImageSamples::new(
        plane,
        lost.xs()[1..].to_vec(),
        lost.ys()[1..].to_vec(),
        vec![lost.values()[0][1..].to_vec()],
    )
    .unwrap();
    assert!(matches!(
        state.clone().advance(&lost).unwrap_err(),
        ProtocolError::Mismatch { .. }
    ));
    // another plane
    let wider = ImageSamples::new(
        ImagePlane::new(33, 32).unwrap(),
        rendered.xs.clone(),
        rendered.ys.clone(),
        rendered.values.clone(),
    )
    .unwrap();
    assert!(matches!(
        state.clone().advance(&wider).unwrap_err(),
        ProtocolError::Plane { .. }
    ));
    // channels change between rounds
    let mut s = state.clone();
    let step = s.advance(&rendered.samples(plane)).unwrap();
    let mut two = RenderedChannels::new(2);
    let both = |x: f64, y: f64| straight_edge(x, y);
    two.xs = rendered.xs.clone();
    two.ys = rendered.ys.clone();
    two.values = vec![rendered.values[0].clone(), rendered.values[0].clone()];
    two.render(&TwoChannels(both), &step.next);
    assert!(matches!(
        s.advance(&two.samples(plane)).unwrap_err(),
        ProtocolError::Channels { state: 1, given: 2 }
    ));
    // other parameters than the state's
    let err = state
        .check_params(
            plane,
            &AdaptiveParams {
                stop: StopParams {
                    budget: 5000,
                    ..params.stop
                },
                ..params
            },
        )
        .unwrap_err();
    assert!(
        matches!(&err, ProtocolError::OtherParameters { parameter, .. } if parameter == "budget"),
        "{err}"
    );
    state.check_params(plane, &params).unwrap();
    // a state of another version, of another format, or with a history that does not fit
    let json = state.to_json();
    let file = std::path::Path::new("state.json");
    let newer = json.replace(
        &format!("\"version\":{STATE_VERSION}"),
        &format!("\"version\":{}", STATE_VERSION + 1),
    );
    assert!(matches!(
        PlanState::from_json(&newer, file).unwrap_err(),
        ProtocolError::State { .. }
    ));
    assert!(matches!(
        PlanState::from_json("{\"format\": \"something else\"}", file).unwrap_err(),
        ProtocolError::State { .. }
    ));
    let mut s = state.clone();
    s.advance(&rendered.samples(plane)).unwrap();
    let mut broken = s.clone();
    broken.progress.marked[0][0].step = 0;
    let err = PlanState::from_json(&broken.to_json(), file).unwrap_err();
    assert!(matches!(err, ProtocolError::State { .. }), "{err}");
}

struct TwoChannels<F>(F);
impl<F: Fn(f64, f64) -> f64 + Sync> ImageOracle for TwoChannels<F> {
    fn channels(&self) -> usize {
        2
    }
    fn sample(&self, x: f64, y: f64, out: &mut [f64]) {
        out[0] = (self.0)(x, y);
        out[1] = out[0];
    }
}

/// The pixels of an `.npy` image written by `rkwave` (`<f8`, shape `(H, W, C)`).
fn npy_image(path: &std::path::Path) -> Vec<f64> {
    let bytes = std::fs::read(path).unwrap();
    let header = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    bytes[10 + header..]
        .chunks_exact(8)
        .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
        .collect()
}

/// The same from the command line: `rkwave plan` in a loop with a "renderer" (the edge
/// function) writing `.npy` samples, then `rkwave reconstruct --dim 2 --state`: the image is
/// the in-process loop's, bit for bit (float64 files keep every position and value). The
/// plan is started with the engine's output pixels (`--output-pixels residual_clamped`; a new
/// plan's own default shrinks them, which on this noise-free edge moves pixels by round-off)
/// and solver (`--solver direct`; a new plan's own is PCG, `tests/plan_pcg.rs`).
#[test]
fn command_line_protocol_gives_the_in_process_image() {
    let dir = common::scratch("plan", "loop");
    let state = dir.join("state");
    let (w, h) = (32usize, 24usize);
    let budget = 3 * w * h;
    let s = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let mut set = SampleSet::default();
    let mut call = 0;
    let final_samples = loop {
        let next = dir.join(format!("next{call}.npy"));
        let samples = dir.join(format!("samples{call}.npy"));
        let mut args = vec![
            "plan".to_string(),
            "--state".into(),
            s(&state),
            "--budget".into(),
            budget.to_string(),
            "--out".into(),
            s(&next),
        ];
        if call == 0 {
            args.extend([
                "--resolution".into(),
                format!("{w}x{h}"),
                "--output-pixels".into(),
                "residual_clamped".into(),
                "--solver".into(),
                "direct".into(),
            ]);
        } else {
            args.extend([
                "--samples".into(),
                s(&dir.join(format!("samples{}.npy", call - 1))),
            ]);
        }
        let argv: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = common::rkwave(&argv);
        assert!(out.status.success(), "{}", common::text(&out));
        if common::text(&out).contains("the plan stopped") {
            // the last call writes 0 rows (which the sample reader refuses as samples)
            let e = read_npy(&next).unwrap_err();
            assert_eq!(e.kind(), rkwave::error::ErrorKind::InvalidInput, "{e}");
            break dir.join(format!("samples{}.npy", call - 1));
        }
        common::image_cli::append_rendered(&mut set, &next, straight_edge);
        write_npy(&samples, &set).unwrap();
        call += 1;
        assert!(call < 60, "the plan did not stop");
    };
    // `reconstruct --dim 2` from the plan's state and the final samples into `output`
    let reconstruct_args = |output: &std::path::Path, extra: &[&str]| -> Vec<String> {
        let mut args: Vec<String> = ["reconstruct", "--dim", "2", "--state"]
            .map(String::from)
            .to_vec();
        args.extend([
            s(&state),
            "--input".into(),
            s(&final_samples),
            "--output".into(),
        ]);
        args.push(s(output));
        args.extend(extra.iter().map(|e| e.to_string()));
        args
    };
    fn strs(v: &[String]) -> Vec<&str> {
        v.iter().map(String::as_str).collect()
    }
    let image = dir.join("image.npy");
    let out = common::rkwave(&strs(&reconstruct_args(&image, &[])));
    assert!(out.status.success(), "{}", common::text(&out));
    let plane = ImagePlane::new(w, h).unwrap();
    let run = refine_image(
        &straight_edge,
        plane,
        &AdaptiveParams {
            stop: StopParams {
                budget,
                ..AdaptiveParams::default().stop
            },
            // the command line's plan fits the renderer plan's probe channels
            noise: AdaptiveParams::renderer_plan().noise,
            ..AdaptiveParams::default()
        },
    )
    .unwrap();
    assert_eq!(set.positions, run.xs);
    assert_eq!(npy_image(&image), run.image.channels[0]);
    assert!(run.report.pixels.corrected > 0);
    assert_ne!(run.image, run.fit_pixels().unwrap());
    // --no-residual: the fit's box pixels, bit for bit; the JSON counts the pixels corrected
    let fit_only = dir.join("fit_only.npy");
    let out = common::rkwave(&strs(&reconstruct_args(
        &fit_only,
        &["--no-residual", "--json"],
    )));
    assert!(out.status.success(), "{}", common::text(&out));
    assert_eq!(npy_image(&fit_only), run.fit_pixels().unwrap().channels[0]);
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["pixels"]["estimate"], "fit_only");
    assert_eq!(report["pixels"]["corrected"], 0);
    let corrected = common::rkwave(&strs(&reconstruct_args(
        &dir.join("again.npy"),
        &["--json"],
    )));
    let report: serde_json::Value = serde_json::from_slice(&corrected.stdout).unwrap();
    assert_eq!(report["pixels"]["estimate"], "residual_clamped");
    assert_eq!(
        report["pixels"]["corrected"].as_u64(),
        Some(run.report.pixels.corrected as u64)
    );
    let without_state = common::user_error(&[
        "reconstruct",
        "--dim",
        "2",
        "--resolution",
        "32x24",
        "--input",
        &s(&final_samples),
        "--output",
        &s(&dir.join("x.npy")),
        "--no-residual",
    ]);
    assert!(without_state.contains("--state"), "{without_state}");
    // outputs are never replaced without --force; a plan is not restarted over another
    let again = common::user_error(&strs(&reconstruct_args(&image, &[])));
    assert!(again.contains("--force"), "{again}");
    let restart = common::user_error(&[
        "plan",
        "--state",
        &s(&state),
        "--resolution",
        "32x24",
        "--budget",
        "2000",
        "--out",
        &s(&dir.join("fresh.npy")),
    ]);
    assert!(restart.contains("holds a plan"), "{restart}");
    // The library's one check (`PlanState::check_new`), its fixes spelled as flags.
    assert!(
        restart.contains(
            "holds a plan already: continue it (--samples), start a new one (--force) or plan \
             in another folder (--state)"
        ),
        "{restart}"
    );
    // samples of another run, another budget, no state
    let other = common::user_error(&[
        "plan",
        "--state",
        &s(&state),
        "--samples",
        &s(&dir.join("samples0.npy")),
        "--out",
        &s(&dir.join("other.npy")),
    ]);
    assert!(other.contains("advanced past"), "{other}");
    let budget_changed = common::user_error(&[
        "plan",
        "--state",
        &s(&state),
        "--budget",
        "999",
        "--samples",
        &s(&final_samples),
        "--out",
        &s(&dir.join("other.npy")),
    ]);
    assert!(budget_changed.contains("budget"), "{budget_changed}");
    let none = common::user_error(&[
        "reconstruct",
        "--dim",
        "2",
        "--state",
        &s(&dir.join("nothing")),
        "--input",
        &s(&final_samples),
        "--output",
        &s(&dir.join("x.npy")),
    ]);
    assert!(none.contains("no plan in"), "{none}");
    // wrong columns, positions outside the image
    let two_columns = dir.join("two.npy");
    write_npy(
        &two_columns,
        &SampleSet::new(vec![1.0, 2.0], vec![vec![1.0, 2.0]]).unwrap(),
    )
    .unwrap();
    let cols = common::user_error(&[
        "plan",
        "--state",
        &s(&state),
        "--samples",
        &s(&two_columns),
        "--out",
        &s(&dir.join("other.npy")),
    ]);
    assert!(cols.contains("columns"), "{cols}");
    let outside = dir.join("outside.npy");
    write_npy(
        &outside,
        &SampleSet::new(vec![1.0, 40.0], vec![vec![1.0, 2.0], vec![0.5, 0.5]]).unwrap(),
    )
    .unwrap();
    let out_msg = common::user_error(&[
        "plan",
        "--state",
        &s(&state),
        "--samples",
        &s(&outside),
        "--out",
        &s(&dir.join("other.npy")),
    ]);
    assert!(out_msg.contains("40"), "{out_msg}");
}

/// A plan whose budget runs out while detail is still significant stops at the round whose
/// samples spend it: no call hands out zero positions without stopping (the renderer would
/// have nothing to render and no final image; `drive` asserts every other call hands out
/// positions). Noise-free and noisy, 8 spp. The third plan (three noisy channels at 32², a
/// renderer plan's parameters with the direct solve) is one where the round that reaches the
/// budget has marked slots whose children already hold their samples: without the budget stop
/// it deepened the tree and handed out zero positions (checked by removing the stop). The
/// fourth is the same plan with a renderer plan's own solver (PCG).
#[test]
fn a_spent_budget_stops_the_plan() {
    let scene = Scene::from_file(Scene::builtin_dir().join("shapes.json")).unwrap();
    let plane = ImagePlane::new(64, 64).unwrap();
    let clean = SceneOracle {
        scene: &scene,
        plane,
    };
    let noisy = NoisyOracle {
        inner: &straight_edge,
        sigma: 0.05,
        seed: 3,
    };
    let small = ImagePlane::new(32, 32).unwrap();
    let discs = DiscsAndLine { w: 32.0, h: 32.0 };
    let noisy_discs = NoisyOracle {
        inner: &discs,
        sigma: 0.05,
        seed: 7,
    };
    let mut renderer = AdaptiveParams::renderer_plan();
    renderer.stop.budget = 8 * small.pixels();
    renderer.sampling.seed = 1;
    let mut renderer_direct = renderer;
    renderer_direct.fit.solver = TreeSolver::Direct;
    let plans: [(&dyn ImageOracle, ImagePlane, AdaptiveParams); 4] = [
        (&clean, plane, budget_and_seed(8 * plane.pixels(), 3)),
        (&noisy, plane, budget_and_seed(8 * plane.pixels(), 3)),
        (&noisy_discs, small, renderer_direct),
        (&noisy_discs, small, renderer),
    ];
    let mut spent = 0;
    for (k, (oracle, plane, params)) in plans.into_iter().enumerate() {
        let (state, rendered) = drive(oracle, plane, &params);
        if state.stop == Some(rkwave::adaptive::StopReason::Budget) {
            assert_eq!(rendered.xs.len(), params.stop.budget, "oracle {k}");
            spent += 1;
        }
        assert!(rendered.xs.len() <= params.stop.budget, "oracle {k}");
    }
    assert!(spent > 0, "the test needs a plan that spends its budget");
}
