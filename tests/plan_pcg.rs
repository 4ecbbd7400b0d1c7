//! The plan under matrix-free PCG through files: the last round's start and diagonal carried
//! in `pcg.bin` make the calls the in-process loop's rounds bit for bit; a damaged or foreign
//! `pcg.bin` is set aside with a note and the round starts from zero, as without the file
//! (whose absence after fitted rounds is noted too);
//! a start from zero reaches the same final fit to the solver's tolerance; and a plan whose
//! direct fit would exceed the memory limit fits by PCG instead, saying so, and completes.

mod common;

use rkwave::image::adaptive::{
    refine_image, AdaptiveParams, ImagePlan, NoisyOracle, SamplePositions, TreeSolver,
};
use rkwave::image::plan::{CarriedPcg, PlanState};
use rkwave::image::ImagePlane;
use rkwave::io::plan_files::PCG_FILE;

use common::image_cli::{arg, plan_round, plan_start, render};
use common::rendered::{small_plan, Rendered, NOISY_EDGE};
use common::succeeds;

const ORACLE: NoisyOracle<'static> = NOISY_EDGE;

/// A 32² plan of 4 spp fitted by PCG (to `1e-6`, rounds to `1e-2`).
fn setup() -> (ImagePlane, AdaptiveParams) {
    let (plane, mut params) = small_plan();
    params.fit.solver = TreeSolver::default();
    (plane, params)
}

/// An edit of `pcg.bin` before a call.
type Edit<'a> = &'a dyn Fn(&std::path::Path);

/// What a plan driven through files gave: the positions of every call, the final output
/// image and the fit's box pixels, the PCG notes per call, and the last call's final fit's
/// condition estimate.
struct Driven {
    positions: Vec<SamplePositions>,
    image: Vec<Vec<f64>>,
    fit_image: Vec<Vec<f64>>,
    notes: Vec<Option<String>>,
    condition: f64,
}

/// Drives the plan of [`setup`] to its stop through the folder `dir` (every call loads the
/// state and `pcg.bin`, then saves them), `edit` changing `pcg.bin` before the calls it
/// names.
fn drive(dir: &std::path::Path, edit: &dyn Fn(usize) -> Option<Edit<'static>>) -> Driven {
    let (plane, params) = setup();
    let (state, base) = PlanState::start(plane, &params).unwrap();
    state.save(dir).unwrap();
    let mut rendered = Rendered::default();
    rendered.render(&ORACLE, &base);
    let mut positions = vec![base];
    let mut notes = vec![];
    for round in 1.. {
        if let Some(e) = edit(round) {
            e(&dir.join(PCG_FILE));
        }
        let mut state = PlanState::load(dir).unwrap();
        let step = state.advance(&rendered.samples(plane)).unwrap();
        assert_eq!(step.log.fit.solver, "pcg");
        assert!(step.solver_note.is_none());
        notes.push(step.pcg_note.clone());
        state.save(dir).unwrap();
        if let Some(done) = step.reconstruction {
            let last = step.log.final_fit.expect("the final fit continued");
            assert!(last.converged);
            return Driven {
                positions,
                image: done.image.channels,
                fit_image: done.fit_image.channels,
                notes,
                condition: last.condition,
            };
        }
        rendered.render(&ORACLE, &step.next);
        positions.push(step.next);
        assert!(round < 40, "the plan did not stop");
    }
    unreachable!()
}

fn no_edit(_: usize) -> Option<Edit<'static>> {
    None
}

/// Through files with `pcg.bin` the plan is the in-process loop (which keeps the start and
/// the diagonal in memory) bit for bit: the same positions, the same output image.
#[test]
fn carried_start_is_the_in_process_loop() {
    let dir = common::scratch("plan-pcg", "loop");
    let driven = drive(&dir, &no_edit);
    let (plane, params) = setup();
    let run = refine_image(&ORACLE, plane, &params).unwrap();
    assert!(driven.positions.len() > 2, "the test needs several rounds");
    let xs: Vec<f64> = driven.positions.iter().flat_map(|p| p.xs.clone()).collect();
    let ys: Vec<f64> = driven.positions.iter().flat_map(|p| p.ys.clone()).collect();
    assert_eq!(xs, run.xs);
    assert_eq!(ys, run.ys);
    assert_eq!(driven.image, run.image.channels);
    assert!(
        driven.notes.iter().all(Option::is_none),
        "{:?}",
        driven.notes
    );
    assert!(dir.join(PCG_FILE).exists());
}

/// A damaged `pcg.bin` (a flipped bit, cut short, not one at all) or one of another plan is
/// set aside with a note naming the file and the fault; the call then starts from zero,
/// exactly as a call without the file does (the same positions and image, bit for bit), and
/// a missing file is noted as such.
#[test]
fn damaged_or_foreign_start_is_set_aside_with_a_note() {
    use common::damage::{cut, flip, remove};
    fn junk(f: &std::path::Path) {
        std::fs::write(f, b"not a start").unwrap();
    }
    fn foreign(f: &std::path::Path) {
        let (plane, params) = setup();
        let (state, _) = PlanState::start(plane, &params).unwrap();
        let n = ImagePlan::new(plane, &params).unwrap().tree().basis().len();
        let carried = CarriedPcg::from_bytes(&std::fs::read(f).unwrap(), state.tag(), n);
        let bytes = carried.unwrap().to_bytes(state.tag() ^ 1).unwrap();
        std::fs::write(f, bytes).unwrap();
    }
    let missing = drive(&common::scratch("plan-pcg", "missing"), &|r| {
        (r == 2).then_some(&remove as Edit<'static>)
    });
    // A missing file after fitted rounds is said too (the first call has none to find).
    assert!(missing.notes[0].is_none(), "{:?}", missing.notes);
    let note = missing.notes[1]
        .as_deref()
        .expect("no note for a missing pcg.bin");
    assert!(
        note.contains(PCG_FILE) && note.contains("not found") && note.contains("from zero"),
        "{note}"
    );
    assert!(
        missing.notes[2..].iter().all(Option::is_none),
        "{:?}",
        missing.notes
    );
    let cases: [(&str, Edit<'static>, &str); 4] = [
        ("flip", &flip, "checksum"),
        ("cut", &cut, "damaged"),
        ("junk", &junk, "layout"),
        ("foreign", &foreign, "another plan"),
    ];
    for (name, edit, says) in cases {
        let d = drive(&common::scratch("plan-pcg", name), &|r| {
            (r == 2).then_some(edit)
        });
        assert_eq!(d.positions, missing.positions, "{name}");
        assert_eq!(d.image, missing.image, "{name}");
        let note = d.notes[1]
            .as_deref()
            .unwrap_or_else(|| panic!("{name}: no note"));
        assert!(
            note.contains(PCG_FILE) && note.contains(says) && note.contains("from zero"),
            "{name}: {note}"
        );
        assert!(
            d.notes[2..].iter().all(Option::is_none),
            "{name}: {:?}",
            d.notes
        );
    }
}

/// The stopping call from zero (no `pcg.bin`) and from the carried start end with the same
/// final fit to the solver's tolerance: both continue the last round to a relative residual
/// `tol = 1e-6` of the normal equations, so their coefficients differ by at most about
/// `kappa tol` relative, `kappa` the condition of the Jacobi-preconditioned `G` (the
/// Lanczos estimate the fit reports); the box pixels are an orthonormal synthesis and box
/// integrals of them, so their relative difference is bounded alike. Allowed: `4 kappa tol`.
#[test]
fn fresh_start_reaches_the_same_final_fit() {
    let carried = drive(&common::scratch("plan-pcg", "carried"), &no_edit);
    let last = carried.positions.len();
    use common::damage::remove;
    let fresh = drive(&common::scratch("plan-pcg", "fresh"), &|r| {
        (r == last).then_some(&remove as Edit<'static>)
    });
    assert_eq!(fresh.positions, carried.positions, "the calls before agree");
    let (a, b) = (&carried.fit_image[0], &fresh.fit_image[0]);
    let norm = a.iter().map(|v| v * v).sum::<f64>().sqrt();
    let diff = a
        .iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt();
    let allowed = 4.0 * carried.condition.max(fresh.condition) * 1e-6;
    assert!(
        diff <= allowed * norm,
        "relative difference {:.3e} > {allowed:.3e}",
        diff / norm
    );
    assert!(diff > 0.0, "two starts, two iterations: not the same bits");
}

/// Runs a whole 64² CLI plan (`--solver direct`) with `limit` as the memory limit on every
/// call; returns the text of every call after the first and whether a final image came.
fn cli_loop(name: &str, limit: &str, json: bool) -> (Vec<String>, bool) {
    let d = common::scratch("plan-pcg", name);
    let n0 = d.join("n0.npy");
    let mut start = plan_start("64x64", "8", &d, &n0);
    start.extend(["--solver", "direct", "--memory-limit", limit].map(String::from));
    succeeds(&start);
    let fin = d.join("final.npy");
    let (mut samples, mut next, mut texts) = (None, n0, vec![]);
    for k in 0..40 {
        let s = d.join(format!("s{k}.npy"));
        render(samples.as_deref(), &next, &s);
        let n = d.join(format!("n{}.npy", k + 1));
        let mut args = plan_round(&d, &s, &n);
        args.extend(["--final-image", arg(&fin), "--memory-limit", limit].map(String::from));
        if json {
            args.push("--json".into());
        }
        texts.push(succeeds(&args));
        samples = Some(s);
        next = n;
        if fin.exists() {
            break;
        }
    }
    (texts, fin.exists())
}

/// With a memory limit below the direct fit's estimate, the plan's calls fit by PCG instead
/// of refusing, say so in the text and in `--json`, and the loop ends with its final image;
/// with room enough the direct solve is used and nothing is said.
#[test]
fn direct_fit_over_the_memory_limit_falls_back_to_pcg() {
    let (texts, done) = cli_loop("roomy", "8G", false);
    assert!(done, "the loop completes");
    assert!(texts.iter().all(|t| !t.contains("PCG")), "{texts:?}");
    let (texts, done) = cli_loop("tight", "200M", false);
    assert!(done, "the loop completes under the fallback");
    assert!(
        texts
            .iter()
            .any(|t| t.contains("does not fit in memory") && t.contains("matrix-free PCG")),
        "{texts:?}"
    );
    let (texts, done) = cli_loop("tight-json", "200M", true);
    assert!(done);
    let notes: Vec<String> = texts
        .iter()
        .filter_map(|t| {
            let v: serde_json::Value = serde_json::from_str(t).unwrap();
            assert!(
                v["step"]["solver_note"].is_null() || v["step"]["log"]["fit"]["solver"] == "pcg"
            );
            v["step"]["solver_note"].as_str().map(String::from)
        })
        .collect();
    assert!(
        !notes.is_empty() && notes.iter().all(|n| n.contains("PCG")),
        "{texts:?}"
    );
}
