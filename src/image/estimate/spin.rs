//! Cycle spinning's shifts run in parallel and summed in their fixed order.
//!
//! A cycle-spun estimate is the mean over the `S²` offsets `(o_x, o_y) in {0 .. S - 1}²` of
//! one estimate per offset of the Haar partition (`haar.rs`; used by `shrink.rs` and
//! `sureshrink.rs`, named without links: a link counts as an import, and they import this):
//! `x^ = (1 / S²) sum_{o_y} sum_{o_x} x^_o`. The offsets are independent, so they are computed
//! in parallel; their per-pixel sums are formed in the order `o_y` outer, `o_x` inner, as the
//! serial loop did, so every output is the serial loop's bit for bit (floating-point addition
//! is not associative: the order, not the threads, fixes the result). Offsets run in chunks of
//! the pool's threads, so at most that many per-offset results are held at once (a chunk's
//! results are folded before the next chunk starts).

use rayon::prelude::*;

/// Calls `shift(o_x, o_y)` for every offset (`shifts²` of them, at least one), in parallel,
/// and hands the results to `fold` in the order `o_y` outer, `o_x` inner (module docs).
pub fn for_each_shift_in_order<T: Send>(
    shifts: usize,
    shift: impl Fn(usize, usize) -> T + Sync,
    mut fold: impl FnMut(T),
) {
    let shifts = shifts.max(1);
    let offsets: Vec<(usize, usize)> = (0..shifts)
        .flat_map(|oy| (0..shifts).map(move |ox| (ox, oy)))
        .collect();
    let chunk = rayon::current_num_threads().max(1);
    for offsets in offsets.chunks(chunk) {
        let results: Vec<T> = offsets.par_iter().map(|&(ox, oy)| shift(ox, oy)).collect();
        results.into_iter().for_each(&mut fold);
    }
}

/// Adds `values` to `sum` element by element.
pub fn add_into(sum: &mut [f64], values: &[f64]) {
    for (s, v) in sum.iter_mut().zip(values) {
        *s += v;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The offsets arrive in the serial loop's order, each once, whatever the pool.
    #[test]
    fn offsets_arrive_in_the_serial_order() {
        let mut seen = vec![];
        for_each_shift_in_order(3, |ox, oy| (ox, oy), |o| seen.push(o));
        let serial: Vec<(usize, usize)> = (0..3)
            .flat_map(|oy| (0..3).map(move |ox| (ox, oy)))
            .collect();
        assert_eq!(seen, serial);
    }
}
