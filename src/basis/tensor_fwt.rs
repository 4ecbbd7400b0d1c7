//! The 2D non-standard FWT of [`TensorBasis`], level by level, skipping the work whose result
//! is known: the products with entries that are exactly zero, and the outputs a caller
//! discards.
//!
//! One level applies the 1D step ([`super::fwt::StepMatrix`]) to every row of the `ly x lx`
//! block (the *row pass*), then combines whole rows by the column step,
//! `y_o = sum_i w_oi x_i` (the *column pass*). Every entry is a sum taken from 0 in the
//! order of the 1D step, so:
//!
//! - *Synthesis* from a vector that is zero off a tree (the tree fit's products `S P_T v`):
//!   a row that is all zero stays zero (its row pass is skipped), an output of the row pass
//!   leaves out its wavelet (`d`) terms, summed after its scaling terms, where they read only
//!   zeros ([`super::fwt::StepMatrix::apply_range_sparse_high`]), and the column pass adds
//!   row `i` only over the runs of its nonzero entries (runs under [`GAP`] apart joined).
//!   The terms left out are `w 0 = ±0`; a sum from `+0` is never `-0` and is unchanged by
//!   adding `±0` (round to nearest: `a + ±0 = a` for `a != 0`, `+0 + ±0 = +0`), so every
//!   entry has the bits of the full transform.
//! - *Analysis kept to a set* `K` (the tree, `P_T^T S^T u`): the result is wanted on `K` only,
//!   and every level needs the whole low-low block (the next level's input) but of the three
//!   detail blocks only the entries in `K`. The column pass computes, per output row `o`,
//!   the scaling columns when `o < ly / 2` (the low-low block) and the runs of kept columns;
//!   the row pass of row `i` the union of the runs of the output rows whose column step
//!   reads row `i`. The entries computed are the full transform's sums in the same order
//!   (equal bits); the others are set to 0 off `K`.
//!
//! What is saved is the detail blocks' share outside the tree's runs: up to about half of
//! a level's synthesis and three quarters of its column pass in analysis, where a level holds
//! few tree functions in a few runs a row (docs/measurements.md, "The renderer loop's FWT
//! restricted to the tree").

use rayon::prelude::*;

use super::tensor::TensorBasis;

/// A half-open column range `[a, b)`, empty when `a >= b`.
type Span = (usize, usize);

/// Runs closer than this many columns are taken as one (fewer, longer loops; the columns
/// between them are computed in vain, with the same bits).
const GAP: usize = 8;

/// The runs of `true` in `flags` (offset by `at`), ascending, gaps under [`GAP`] closed.
fn runs(flags: impl Iterator<Item = bool>, at: usize) -> Vec<Span> {
    let mut out: Vec<Span> = Vec::new();
    for (c, on) in flags.enumerate() {
        if !on {
            continue;
        }
        let c = at + c;
        match out.last_mut() {
            Some(last) if c <= last.1 + GAP => last.1 = c + 1,
            _ => out.push((c, c + 1)),
        }
    }
    out
}

/// Sorts `spans` and merges those that overlap or lie under [`GAP`] apart.
fn merged(mut spans: Vec<Span>) -> Vec<Span> {
    spans.sort_unstable();
    let mut out: Vec<Span> = Vec::with_capacity(spans.len());
    for s in spans.into_iter().filter(|s| s.0 < s.1) {
        match out.last_mut() {
            Some(last) if s.0 <= last.1 + GAP => last.1 = last.1.max(s.1),
            _ => out.push(s),
        }
    }
    out
}

/// The runs of row `k`, or `full` when no row has its own (nothing restricted).
fn pick<'a>(rows: &'a [Vec<Span>], k: usize, full: &'a [Span]) -> &'a [Span] {
    rows.get(k).map_or(full, |c| c.as_slice())
}

fn intersect(a: Span, b: Span) -> Span {
    (a.0.max(b.0), a.1.min(b.1))
}

/// The 2D FWT of `basis` on `data` (`ny x nx`, row-major): analysis (single scale to the
/// Mallat layout) or synthesis (the transpose). `keep` (analysis only): the entries wanted;
/// the result is zero off them. Both passes run in parallel over rows, each entry summed in
/// the order of the 1D step, so the bits are those of [`super::fwt::analysis_step`] /
/// [`super::fwt::synthesis_step`] applied line by line whatever the thread count.
pub(super) fn transform(
    basis: &TensorBasis,
    data: &[f64],
    analysis: bool,
    keep: Option<&[bool]>,
) -> Vec<f64> {
    let (nx, ny) = basis.dims();
    assert_eq!(data.len(), nx * ny, "2D FWT input length");
    if let Some(keep) = keep {
        assert!(analysis, "only the analysis is kept to a set");
        assert_eq!(keep.len(), nx * ny, "2D FWT kept set length");
    }
    let (cx, cy) = basis.coarse_levels();
    let mut x = data.to_vec();
    // the column pass's output: a buffer kept per thread (a fresh one per call cost its
    // page faults every PCG iteration); every entry read is written first
    let mut y = FWT_SCRATCH.with(|b| b.take());
    y.resize(nx * ny, 0.0);
    let order: Vec<u32> = if analysis {
        (0..basis.steps()).rev().collect()
    } else {
        (0..basis.steps()).collect()
    };
    for s in order {
        let (jx, jy) = (cx + s, cy + s);
        let (lx, ly) = (2usize << jx, 2usize << jy);
        let (hx, hy) = (lx / 2, ly / 2);
        let which = usize::from(!analysis);
        let step_x = &basis.steps_x[s as usize][which];
        let step_y = &basis.steps_y[s as usize][which];
        // the column runs each output row of the column pass computes, and each row of the
        // row pass
        let (col_out, row_out): (Vec<Vec<Span>>, Vec<Vec<Span>>) = match keep {
            Some(keep) => {
                let col: Vec<Vec<Span>> = (0..ly)
                    .map(|o| {
                        let row = &keep[o * nx..o * nx + lx];
                        if o < hy {
                            let mut r = vec![(0, hx)];
                            r.extend(runs(row[hx..].iter().copied(), hx));
                            merged(r)
                        } else {
                            runs(row.iter().copied(), 0)
                        }
                    })
                    .collect();
                let mut row: Vec<Vec<Span>> = vec![Vec::new(); ly];
                for (o, c) in col.iter().enumerate() {
                    for &i in step_y.entries(o).0 {
                        row[i].extend_from_slice(c);
                    }
                }
                (col, row.into_iter().map(merged).collect())
            }
            None => (Vec::new(), Vec::new()),
        };
        let full = [(0, lx)];
        // row pass; the runs of each row the column pass reads (synthesis; the analysis
        // reads what the row pass computed)
        let spans: Vec<Vec<Span>> = x[..ly * nx]
            .par_chunks_mut(nx)
            .enumerate()
            .map_init(
                || vec![0.0; lx],
                |out, (i, row)| {
                    let row = &mut row[..lx];
                    if !analysis && row.iter().all(|&v| v == 0.0) {
                        return Vec::new();
                    }
                    if analysis {
                        for r in pick(&row_out, i, &full) {
                            step_x.apply_range(row, out, r.0..r.1);
                        }
                    } else {
                        // the wavelet half's nonzero runs: an output reads its `d` terms
                        // only where they meet one
                        let high = runs(row[hx..].iter().map(|&v| v != 0.0), hx);
                        let nonzero = |lo: usize, hi: usize| {
                            let k = high.partition_point(|r| r.1 <= lo);
                            k < high.len() && high[k].0 < hi
                        };
                        step_x.apply_range_sparse_high(row, out, 0..lx, nonzero);
                    }
                    for r in pick(&row_out, i, &full) {
                        row[r.0..r.1].copy_from_slice(&out[r.0..r.1]);
                    }
                    if analysis {
                        Vec::new()
                    } else {
                        runs(row.iter().map(|&v| v != 0.0), 0)
                    }
                },
            )
            .collect();
        // column pass
        y[..ly * nx]
            .par_chunks_mut(nx)
            .enumerate()
            .for_each(|(o, out)| {
                let (input, weight) = step_y.entries(o);
                for &r in pick(&col_out, o, &full) {
                    out[r.0..r.1].iter_mut().for_each(|v| *v = 0.0);
                    for (&i, &w) in input.iter().zip(weight) {
                        let read: &[Span] = if analysis { &full } else { &spans[i] };
                        for &q in read {
                            let (a, b) = intersect(r, q);
                            if a >= b {
                                continue;
                            }
                            let xr = &x[i * nx + a..i * nx + b];
                            for (v, &xv) in out[a..b].iter_mut().zip(xr) {
                                *v += w * xv;
                            }
                        }
                    }
                }
            });
        if lx == nx && ly == ny {
            // the level covers the whole layout: the output is all of `y` (entries outside
            // `col_out` are set to 0 below: they lie off `keep`)
            std::mem::swap(&mut x, &mut y);
        } else {
            x[..ly * nx]
                .par_chunks_mut(nx)
                .zip(y[..ly * nx].par_chunks(nx))
                .enumerate()
                .for_each(|(o, (xr, yr))| {
                    for r in pick(&col_out, o, &full) {
                        xr[r.0..r.1].copy_from_slice(&yr[r.0..r.1]);
                    }
                });
        }
    }
    FWT_SCRATCH.with(|b| b.replace(y));
    if let Some(keep) = keep {
        x.par_iter_mut().zip(keep).for_each(|(v, &k)| {
            if !k {
                *v = 0.0;
            }
        });
    }
    x
}

thread_local! {
    /// Scratch of [`TensorBasis`]'s 2D FWT, one per thread.
    static FWT_SCRATCH: std::cell::RefCell<Vec<f64>> = const { std::cell::RefCell::new(Vec::new()) };
}
