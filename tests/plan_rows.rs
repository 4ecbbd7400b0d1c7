//! The single-scale rows carried between a plan's calls (`rows.bin`, `CarriedRows`): read
//! back, they are the rows evaluated afresh field for field; a plan driven through files with
//! them is the in-process loop bit for bit; a damaged, cut, foreign or missing file is set
//! aside with a note and the round is the same as without it.

mod common;

use rkwave::basis::tensor::TensorBasis;
use rkwave::image::adaptive::pcg::SingleScaleRows;
use rkwave::image::adaptive::{refine_image, AdaptiveParams, ImagePlan, NoisyOracle, TreeSolver};
use rkwave::image::plan::{PlanState, ROWS_FILE};
use rkwave::image::ImagePlane;

use common::rendered::{small_plan, Rendered, NOISY_EDGE};

const ORACLE: NoisyOracle<'static> = NOISY_EDGE;

/// A 32² plan of 4 spp fitted by PCG (rounds to `1e-2`).
fn setup() -> (ImagePlane, AdaptiveParams) {
    let (plane, mut params) = small_plan();
    params.fit.solver = TreeSolver::default();
    (plane, params)
}

/// Jittered positions of the basis's image (one a pixel, seeded), some moved onto cell edges
/// and the border.
fn positions(b: &TensorBasis) -> (Vec<f64>, Vec<f64>) {
    let (mut xs, mut ys) = common::scenes::jittered(b.width(), b.height(), 1, 7);
    xs[0] = 0.0;
    ys[1] = 0.0;
    xs[2] = 0.5;
    ys[3] = (b.height() as f64 * 0.25).floor();
    (xs, ys)
}

fn basis() -> TensorBasis {
    let (plane, params) = setup();
    ImagePlan::new(plane, &params)
        .unwrap()
        .tree()
        .basis()
        .clone()
}

/// Rows written in pieces (one per "call") and read back are the rows evaluated afresh,
/// field for field; the pieces of a prefix continue a longer set of positions.
#[test]
fn pieces_read_back_are_the_rows_evaluated_afresh() {
    let b = basis();
    let (all_x, all_y) = positions(&b);
    assert!(all_x.len() > 900, "the test needs more than 900 positions");
    let (xs, ys) = (&all_x[..900], &all_y[..900]);
    let cuts = [0, 250, 600, 900];
    let mut file = Vec::new();
    let mut rows: Option<SingleScaleRows> = None;
    for pair in cuts.windows(2) {
        let (from, to) = (pair[0], pair[1]);
        let r = SingleScaleRows::continued(rows.take(), &b, &xs[..to], &ys[..to]);
        file.extend(r.piece_bytes(42, from, &xs[..to], &ys[..to]).unwrap());
        rows = Some(r);
    }
    let fresh = SingleScaleRows::new(&b, xs, ys);
    let (read, used, why) = SingleScaleRows::from_pieces(&file, 42, &b, xs, ys);
    assert!(why.is_none(), "{why:?}");
    assert_eq!(used as usize, file.len());
    assert_eq!(read.as_ref(), Some(&fresh));
    // more positions after them: the file's rows are a prefix, continued with the rest
    let (read, _, why) = SingleScaleRows::from_pieces(&file, 42, &b, &all_x, &all_y);
    assert!(why.is_none(), "{why:?}");
    let continued = SingleScaleRows::continued(read, &b, &all_x, &all_y);
    assert_eq!(continued, SingleScaleRows::new(&b, &all_x, &all_y));
    // another plan's tag, or other positions from the second piece on: the first piece only
    // (or none), and why
    let (none, used, why) = SingleScaleRows::from_pieces(&file, 43, &b, xs, ys);
    assert!(none.is_none() && used == 0, "{why:?}");
    assert!(why.unwrap().contains("another plan"));
    let mut moved = xs.to_vec();
    moved[300] = f64::from_bits(moved[300].to_bits() ^ 1);
    let (first, _, why) = SingleScaleRows::from_pieces(&file, 42, &b, &moved, ys);
    assert_eq!(first.map(|r| r.len()), Some(250));
    assert!(why.unwrap().contains("not those of the samples' positions"));
}

/// What a plan driven through files gave: the positions of every call, the final image,
/// the notes per call and whether `rows.bin` was there after each call.
struct Driven {
    positions: Vec<Vec<f64>>,
    image: Vec<Vec<f64>>,
    notes: Vec<Option<String>>,
    kept: Vec<bool>,
}

type Edit = fn(&std::path::Path);

/// Drives the plan of [`setup`] to its stop through `dir`, `edit` changing `rows.bin` before
/// the second fitting call.
fn drive(dir: &std::path::Path, edit: Option<Edit>) -> Driven {
    let (plane, params) = setup();
    let (state, base) = PlanState::start(plane, &params).unwrap();
    state.save(dir).unwrap();
    let mut rendered = Rendered::default();
    rendered.render(&ORACLE, &base);
    let mut positions = vec![base.xs.clone()];
    let (mut notes, mut kept) = (vec![], vec![]);
    for round in 1.. {
        if let (2, Some(e)) = (round, edit) {
            e(&dir.join(ROWS_FILE));
        }
        let mut state = PlanState::load(dir).unwrap();
        let step = state.advance(&rendered.samples(plane)).unwrap();
        notes.push(step.pcg_note.clone());
        state.save(dir).unwrap();
        kept.push(dir.join(ROWS_FILE).exists());
        if let Some(done) = step.reconstruction {
            return Driven {
                positions,
                image: done.image.channels,
                notes,
                kept,
            };
        }
        rendered.render(&ORACLE, &step.next);
        positions.push(step.next.xs.clone());
        assert!(round < 40, "the plan did not stop");
    }
    unreachable!()
}

/// Through files with `rows.bin` the plan is the in-process loop bit for bit, with no note;
/// the file is kept while the plan runs and removed when it stops.
#[test]
fn carried_rows_are_the_in_process_loop() {
    let dir = common::scratch("plan-rows", "loop");
    let driven = drive(&dir, None);
    let (plane, params) = setup();
    let run = refine_image(&ORACLE, plane, &params).unwrap();
    assert!(driven.positions.len() > 2, "the test needs several rounds");
    let xs: Vec<f64> = driven.positions.concat();
    assert_eq!(xs, run.xs);
    assert_eq!(driven.image, run.image.channels);
    assert!(
        driven.notes.iter().all(Option::is_none),
        "{:?}",
        driven.notes
    );
    let (last, running) = driven.kept.split_last().unwrap();
    assert!(running.iter().all(|&k| k) && !last, "{:?}", driven.kept);
}

/// A damaged, cut, foreign or missing `rows.bin` is set aside with a note (naming the file
/// when it is missing) and the plan is the same bit for bit.
#[test]
fn damaged_or_missing_rows_are_evaluated_afresh_with_a_note() {
    use common::damage::{cut, flip, remove};
    let whole = drive(&common::scratch("plan-rows", "whole"), None);
    fn junk(f: &std::path::Path) {
        std::fs::write(f, b"not rows at all, longer than a header").unwrap();
    }
    let cases: [(&str, Edit, &str); 4] = [
        ("flip", flip, "checksum"),
        ("cut", cut, "damaged"),
        ("junk", junk, "not all used"),
        ("remove", remove, "not found"),
    ];
    for (name, edit, says) in cases {
        let d = drive(&common::scratch("plan-rows", name), Some(edit));
        assert_eq!(d.positions, whole.positions, "{name}");
        assert_eq!(d.image, whole.image, "{name}");
        let note = d.notes[1]
            .as_deref()
            .unwrap_or_else(|| panic!("{name}: no note"));
        assert!(
            note.contains(says) && note.contains("afresh"),
            "{name}: {note}"
        );
        assert!(
            d.notes[2..].iter().all(Option::is_none),
            "{name}: {:?}",
            d.notes
        );
    }
}
