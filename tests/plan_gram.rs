//! The normal matrix carried between calls of the file protocol (`gram.bin`): the carried
//! matrix is the freshly assembled one bit for bit, a plan driven through files with it
//! gives the plan driven without it bit for bit, and a damaged or foreign `gram.bin` is set
//! aside with a note, the round assembling afresh to the same result.

mod common;

use rkwave::image::adaptive::{
    fit_tree_updating, FitState, NoisyOracle, SamplePositions, TreeGram, TreeSolver,
};
use rkwave::image::plan::PlanState;
use rkwave::image::ImagePlane;
use rkwave::io::plan_files::GRAM_FILE;

use common::rendered::{small_plan, Rendered, NOISY_EDGE};

const ORACLE: NoisyOracle<'static> = NOISY_EDGE;

/// A plan of [`small_plan`] started and saved in `dir`, its base positions rendered.
fn started(dir: &std::path::Path) -> (ImagePlane, Rendered) {
    let (plane, params) = small_plan();
    let (state, base) = PlanState::start(plane, &params).unwrap();
    state.save(dir).unwrap();
    let mut rendered = Rendered {
        xs: vec![],
        ys: vec![],
        values: vec![],
    };
    rendered.render(&ORACLE, &base);
    (plane, rendered)
}

/// An edit of `gram.bin` between two calls.
type Damage<'a> = &'a dyn Fn(&std::path::Path);

/// Drives a plan to its stop. With `dir`, every call loads the state (and `gram.bin`) from
/// `dir` and saves it back, `damage` editing `gram.bin` before round `round` when given;
/// without, the state goes through its JSON only (no carried matrix). Returns the
/// positions of every call, the final image and the notes about the carried matrix.
#[allow(clippy::type_complexity)]
fn drive(
    dir: Option<&std::path::Path>,
    damage: Option<(usize, Damage<'_>)>,
) -> (Vec<SamplePositions>, Vec<Vec<f64>>, Vec<Option<String>>) {
    let (plane, params) = small_plan();
    let (state, base) = PlanState::start(plane, &params).unwrap();
    let mut json = state.to_json();
    if let Some(d) = dir {
        state.save(d).unwrap();
    }
    let mut rendered = Rendered {
        xs: vec![],
        ys: vec![],
        values: vec![],
    };
    rendered.render(&ORACLE, &base);
    let mut positions = vec![base];
    let mut notes = vec![];
    for round in 1.. {
        let mut state = match dir {
            Some(d) => {
                if let Some((r, edit)) = damage.filter(|(r, _)| *r == round) {
                    assert_eq!(r, round);
                    edit(&d.join(GRAM_FILE));
                }
                PlanState::load(d).unwrap()
            }
            None => PlanState::from_json(&json, "state.json".as_ref()).unwrap(),
        };
        let step = state.advance(&rendered.samples(plane)).unwrap();
        notes.push(step.gram_note.clone());
        if dir.is_some() && round > 1 {
            let kept = step.log.fit.normal_kept_samples;
            assert_eq!(
                kept > 0,
                step.gram_note.is_none(),
                "round {round}: kept {kept}"
            );
        }
        match dir {
            Some(d) => state.save(d).unwrap(),
            None => json = state.to_json(),
        }
        if let Some(done) = step.reconstruction {
            return (positions, done.image.channels, notes);
        }
        rendered.render(&ORACLE, &step.next);
        positions.push(step.next);
        assert!(round < 40, "the plan did not stop");
    }
    unreachable!()
}

/// The matrix carried through `gram.bin` after a round equals the one assembled from scratch
/// for the same samples on the same tree, bit for bit (the continued sums are the full
/// sums, term for term: `image::adaptive::gram`).
#[test]
fn carried_matrix_equals_a_fresh_assembly() {
    let dir = common::scratch("gram", "fresh");
    let (plane, mut rendered) = started(&dir);
    let mut continued = 0;
    for round in 1..=4 {
        let mut state = PlanState::load(&dir).unwrap();
        let samples = rendered.samples(plane);
        let step = state.advance(&samples).unwrap();
        state.save(&dir).unwrap();
        continued += usize::from(step.log.fit.normal_kept_samples > 0);
        let carried = PlanState::load(&dir)
            .unwrap()
            .carried
            .gram
            .expect("gram.bin");
        assert_eq!(Some(&carried), state.carried.gram.as_ref(), "round {round}");
        // the fresh assembly on the round's tree (the reconstruction's, of the same samples)
        let done = state.reconstruct(&samples).unwrap();
        let mut fresh = FitState::default();
        let values = [samples.values()[0].as_slice()];
        fit_tree_updating(
            &done.tree,
            samples.xs(),
            samples.ys(),
            &values,
            TreeSolver::Direct,
            None,
            &mut fresh,
        )
        .unwrap();
        assert_eq!(
            fresh.gram.as_ref(),
            Some(&carried),
            "round {round}: carried != fresh"
        );
        if step.stop.is_some() {
            break;
        }
        rendered.render(&ORACLE, &step.next);
    }
    assert!(
        continued >= 2,
        "the test needs rounds that continue the matrix"
    );
}

/// Through files with `gram.bin`, the plan hands out the same positions and ends with the same
/// image as without any carried matrix, bit for bit.
#[test]
fn plan_outputs_unchanged_by_the_carried_matrix() {
    let dir = common::scratch("gram", "same");
    let (pos_files, image_files, notes) = drive(Some(&dir), None);
    let (pos_json, image_json, _) = drive(None, None);
    assert!(pos_files.len() > 2, "the test needs several rounds");
    assert_eq!(pos_files, pos_json);
    assert_eq!(image_files, image_json);
    assert!(notes.iter().all(Option::is_none), "{notes:?}");
}

/// A damaged `gram.bin` (a flipped bit, cut short, not one at all) or one written for another
/// plan is set aside with a note naming the file and the fault; the round assembles afresh
/// and the plan's outputs stay those of the undamaged run.
#[test]
fn damaged_or_foreign_matrix_is_rebuilt_with_a_note() {
    let clean_dir = common::scratch("gram", "clean");
    let (positions, image, _) = drive(Some(&clean_dir), None);
    let flip = |f: &std::path::Path| {
        let mut b = std::fs::read(f).unwrap();
        let at = b.len() / 2;
        b[at] ^= 0x10;
        std::fs::write(f, b).unwrap();
    };
    let cut = |f: &std::path::Path| {
        let b = std::fs::read(f).unwrap();
        std::fs::write(f, &b[..b.len() - 24]).unwrap();
    };
    let junk = |f: &std::path::Path| std::fs::write(f, b"not a matrix").unwrap();
    let foreign = |f: &std::path::Path| {
        // a well-formed matrix of the same plan's samples under another plan's tag
        let (plane, params) = small_plan();
        let (state, _) = PlanState::start(plane, &params).unwrap();
        let gram = TreeGram::from_bytes(&std::fs::read(f).unwrap(), state.tag()).unwrap();
        std::fs::write(f, gram.to_bytes(state.tag() ^ 1)).unwrap();
    };
    let cases: [(&str, Damage<'_>, &str); 4] = [
        ("flip", &flip, "checksum"),
        ("cut", &cut, "damaged"),
        ("junk", &junk, "layout"),
        ("foreign", &foreign, "another plan"),
    ];
    for (name, edit, says) in cases {
        let dir = common::scratch("gram", name);
        let (p, img, notes) = drive(Some(&dir), Some((2, edit)));
        assert_eq!(p, positions, "{name}");
        assert_eq!(img, image, "{name}");
        let note = notes[1]
            .as_deref()
            .unwrap_or_else(|| panic!("{name}: no note"));
        assert!(
            note.contains(GRAM_FILE) && note.contains(says) && note.contains("afresh"),
            "{name}: {note}"
        );
        assert!(notes[2..].iter().all(Option::is_none), "{name}: {notes:?}");
    }
}

/// Samples that do not start with the carried matrix's (a renderer that reorders them) are
/// fitted afresh, with a note; `rkwave plan` prints it.
#[test]
fn reordered_samples_are_fitted_afresh_with_a_note() {
    let dir = common::scratch("gram", "order");
    let (plane, mut rendered) = started(&dir);
    let mut state = PlanState::load(&dir).unwrap();
    let step = state.advance(&rendered.samples(plane)).unwrap();
    state.save(&dir).unwrap();
    rendered.render(&ORACLE, &step.next);
    rendered.xs.reverse();
    rendered.ys.reverse();
    rendered.values.reverse();
    let mut state = PlanState::load(&dir).unwrap();
    let step = state.advance(&rendered.samples(plane)).unwrap();
    assert_eq!(step.log.fit.normal_kept_samples, 0);
    let note = step.gram_note.expect("a note");
    assert!(note.contains("not continued"), "{note}");
}
