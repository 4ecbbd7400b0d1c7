//! Random quadtrees for the tree-fit tests, and samples that keep every slot of a tree
//! sampled.

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rkwave::basis::tensor::TensorBasis;
use rkwave::image::adaptive::{Cell, QuadTree};

/// A random tree: `basis`'s tree uniform to `base`, then `cells` random slots activated by
/// [`deepen_randomly`] with `rng` (closed under "parent present").
pub fn random_tree_with(
    basis: TensorBasis,
    base: u32,
    cells: usize,
    rng: &mut impl Rng,
) -> QuadTree {
    let mut tree = QuadTree::uniform(basis, base);
    deepen_randomly(&mut tree, cells, rng);
    tree
}

/// [`random_tree_with`] from a seed (`Pcg64`).
pub fn random_tree(basis: TensorBasis, base: u32, cells: usize, seed: u64) -> QuadTree {
    random_tree_with(basis, base, cells, &mut Pcg64::seed_from_u64(seed))
}

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
