//! Random quadtrees for the tree-fit tests, and samples that keep every slot of a tree
//! sampled.

use rand::Rng;
use rkwave::image::adaptive::{Cell, QuadTree};

/// Activates `cells` random slots above the depth limit, one at a time (so the tree stays
/// closed under "parent present", as every refined tree is); stops early if none is left.
pub fn deepen_randomly(tree: &mut QuadTree, cells: usize, rng: &mut impl Rng) {
    for _ in 0..cells {
        let slots: Vec<Cell> = tree
            .leaves()
            .into_iter()
            .filter(|c| c.step < tree.steps())
            .collect();
        if slots.is_empty() {
            break;
        }
        let c = slots[rng.random_range(0..slots.len())];
        assert!(tree.deepen(c));
    }
}

/// Appends `per_slot` uniform positions in every slot's cell to `xs`, `ys` (so every
/// function of the tree has samples in its support).
pub fn sample_slots(
    tree: &QuadTree,
    per_slot: usize,
    rng: &mut impl Rng,
    xs: &mut Vec<f64>,
    ys: &mut Vec<f64>,
) {
    for slot in tree.leaves() {
        let r = tree.rect(slot);
        for _ in 0..per_slot {
            xs.push(r[0] + (r[1] - r[0]) * rng.random::<f64>());
            ys.push(r[2] + (r[3] - r[2]) * rng.random::<f64>());
        }
    }
}
