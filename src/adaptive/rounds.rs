//! The rounds driver: one round's decision for the 1D refiner (`refine`) and the
//! image plane (`image::adaptive`), over the interval tree and the quadtree, each
//! dimension with its own indicator, fit and sampler behind a [`RoundAdapter`].
//!
//! # The round both dimensions run
//!
//! ```text
//! fit on T  ->  eta_u of every markable unit u  ->  stop?  ->  mark  ->  deepen  ->  top up
//! ```
//!
//! 1. *Fit* the least-squares coefficients on the tree `T` with every sample so far (the
//!    normal matrix continued from the last round's where the dimension keeps it).
//! 2. *Indicate* the predicted detail `eta_u` of every unit `u` a round may deepen, and the
//!    estimated RMS error `e = sqrt(sum eta^2 / |Omega|)`.
//! 3. *Stop* ([`stop_test`]), the first that holds of, in this order: no indicator this round
//!    ([`StopReason::Budget`]: the 1D residual probes did not fit the budget);
//!    `e <= tolerance` ([`StopReason::Tolerance`]); nothing left to deepen or densify above
//!    the depth limit ([`StopReason::DepthLimit`]); nothing Dörfler wants that `f64` can
//!    resolve ([`StopReason::Resolution`]); the budget spent ([`StopReason::Budget`]); the
//!    round limit ([`StopReason::MaxRounds`]).
//! 4. *Mark* the fewest leading units holding `theta` of `sum eta^2`
//!    (`marking::dorfler`), cut to the longest prefix whose samples the rest of the
//!    budget pays for ([`cut`]); a round that would hand out nothing stops at the budget.
//!    With nothing significant left to deepen but budget and slots whose estimate is
//!    uncertain, the round *densifies* instead (no unit marked).
//! 5. *Deepen* the marked units (`2^D` children per cell) and *top up* every new leaf to
//!    `ceil(rho)` samples: the positions handed out.
//!
//! [`round`] runs steps 3-5 in that order through the dimension's adapter. A round is split
//! at the positions handed out: "decide and hand out" is [`round`]; "take the samples and
//! fit" is the dimension's, after the samples come back. The 1D refiner samples its oracle
//! in-process and fits at once; the image plane's round (`image::adaptive::ImagePlan::step`)
//! returns the positions, and the next call fits on them, so a renderer outside the process
//! (the file protocol, the plan's CLI rounds) drives the same rounds.
//!
//! # What differs by dimension (the adapters')
//!
//! | step | 1D refiner | image plane |
//! |------|-----------|-------------|
//! | fit | `NormalEquations` continued round by round, Cholesky or CGLS | `FitState` (the Gram matrix continued), Cholesky or PCG; the noise test's probe channels beside |
//! | indicator | coefficient decay and/or residual probes (the probes are samples, kept) | coefficient decay of the three details, less what is within the noise |
//! | markable unit | wavelets whose children are missing (with their ancestors) | a slot (leaf cell) below the depth limit whose detail is significant |
//! | resolution | a unit whose new leaves `f64` cannot stratify is dropped | none (cells stop at the depth limit) |
//! | Dörfler's set | as is | at least one slot, extended in indicator order to the round's least growth |
//! | cost of `k` marks | the samples the deepened tree's leaves lack (not additive: leaves overlap) | the prefix sum of the slots' children's shortfalls |
//! | budget spent | never a stop of its own (a marking whose leaves hold their samples costs nothing) | samples at the budget |
//! | rounds counted | the base fit counts: `max_rounds` fits | refinement rounds: `max_rounds + 1` fits |
//! | nothing to mark | stop ([`StopReason::Budget`]) | a densifying round, spare samples spread, the coverage rule's fill round before a stop |
//!
//! The difference in counting rounds is kept as it was (both dimensions' outputs unchanged
//! bit for bit when the driver came in); [`RoundFacts::rounds`] says which is counted.

use super::params::StopParams;
use super::stop::StopReason;

/// What the stop test ([`stop_test`]) reads of a round, filled in by the dimension.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RoundFacts {
    /// The estimated RMS error `sqrt(sum eta^2 / |Omega|)`; `None` when the round has no
    /// indicator (1D: the residual probes alone, over budget).
    pub estimate: Option<f64>,
    /// Whether anything is left to deepen or densify above the depth limit (1D: a markable
    /// unit whose part of the estimate is above the tolerance; 2D: a significant slot, an
    /// insignificant one to densify, or budget to densify under the uncertainty rule).
    pub markable: bool,
    /// Whether something markable can be deepened (else the round densifies: 2D only).
    pub deepenable: bool,
    /// Whether Dörfler's set holds a unit whose new leaves `f64` can resolve (1D; 2D: true).
    pub resolvable: bool,
    /// Whether the budget is spent (2D: samples at the budget; 1D: false, the cut decides).
    pub spent: bool,
    /// The rounds counted against [`StopParams::max_rounds`] (1D: the round to be made,
    /// counting the base fit; 2D: the rounds made).
    pub rounds: usize,
}

/// The stop test of a round: the first reason that holds, in the order of the module docs
/// (no indicator, tolerance, depth limit, resolution, budget, round limit); `None`: go on.
/// A non-finite estimate never meets the tolerance.
///
/// ```
/// use rkwave::adaptive::rounds::{stop_test, RoundFacts};
/// use rkwave::adaptive::{StopParams, StopReason};
/// let stop = StopParams { tolerance: 1e-3, budget: 100, max_rounds: 5 };
/// let facts = RoundFacts {
///     estimate: Some(2e-3), markable: true, deepenable: true,
///     resolvable: true, spent: false, rounds: 1,
/// };
/// assert_eq!(stop_test(&facts, &stop), None);
/// let done = RoundFacts { estimate: Some(1e-3), ..facts };
/// assert_eq!(stop_test(&done, &stop), Some(StopReason::Tolerance));
/// ```
pub fn stop_test(facts: &RoundFacts, stop: &StopParams) -> Option<StopReason> {
    let Some(e) = facts.estimate else {
        return Some(StopReason::Budget);
    };
    if e.is_finite() && e <= stop.tolerance {
        Some(StopReason::Tolerance)
    } else if !facts.markable {
        Some(StopReason::DepthLimit)
    } else if !facts.resolvable {
        Some(StopReason::Resolution)
    } else if facts.spent {
        Some(StopReason::Budget)
    } else if facts.rounds >= stop.max_rounds {
        Some(StopReason::MaxRounds)
    } else {
        None
    }
}

/// The budget cut: the largest `k <= wanted` whose cost fits, `cost(k) <= remaining`, for a
/// cost nondecreasing in `k` with `cost(0) <= remaining` (nothing marked costs nothing). Tries
/// `wanted` first, then bisects `(0, wanted)`: `O(log wanted)` evaluations of `cost`, each
/// dimension's own (1D: the leaves of a trial tree; 2D: a prefix sum).
///
/// ```
/// use rkwave::adaptive::rounds::cut;
/// let costs = [4, 3, 5, 1];
/// let prefix = |k: usize| costs[..k].iter().sum::<usize>();
/// assert_eq!(cut(4, 13, prefix), 4);
/// assert_eq!(cut(4, 12, prefix), 3);
/// assert_eq!(cut(4, 3, prefix), 0);
/// ```
pub fn cut(wanted: usize, remaining: usize, mut cost: impl FnMut(usize) -> usize) -> usize {
    if wanted == 0 || cost(wanted) <= remaining {
        return wanted;
    }
    let (mut lo, mut hi) = (0usize, wanted);
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if cost(mid) <= remaining {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// A dimension's side of a round (module docs): what the stop test reads, and the round's
/// steps after it. The adapter holds the round's fit and indicator; [`round`] calls the steps
/// in order and each returns what the dimension hands back (`Outcome`: the 1D refiner's step,
/// the image plane's positions or stop).
pub trait RoundAdapter {
    /// The accepted marking: the marked units, their cost, whatever deepening needs.
    type Marks;
    /// What a round ends with.
    type Outcome;
    /// Why a step failed.
    type Error;

    /// The facts of the stop test for this round's fit and indicator.
    fn facts(&mut self) -> RoundFacts;
    /// The round stops for `reason` (the coverage rule may top pixels up instead: 2D).
    fn stop(&mut self, reason: StopReason) -> Result<Self::Outcome, Self::Error>;
    /// Mark: Dörfler's set of the markable units, cut by [`cut`] to what the rest of the
    /// budget pays for; `None` when the round would hand out nothing (a stop at the budget).
    fn mark(&mut self) -> Result<Option<Self::Marks>, Self::Error>;
    /// Deepen the marked units and top their new leaves up (the positions handed out).
    fn deepen(&mut self, marks: Self::Marks) -> Result<Self::Outcome, Self::Error>;
    /// Densify (nothing significant left to deepen): more samples in the slots as they are;
    /// `None` when the budget is spent (a stop at the budget). The 1D refiner never densifies
    /// ([`RoundFacts::deepenable`] is its `markable`).
    fn densify(&mut self) -> Result<Option<Self::Outcome>, Self::Error>;
}

/// One round after the fit and the indicator: the stop test, then densify or mark and
/// deepen; a marking or a densifying round that hands out nothing stops at the budget.
pub fn round<A: RoundAdapter>(adapter: &mut A, stop: &StopParams) -> Result<A::Outcome, A::Error> {
    let facts = adapter.facts();
    if let Some(reason) = stop_test(&facts, stop) {
        return adapter.stop(reason);
    }
    if !facts.deepenable {
        return match adapter.densify()? {
            Some(outcome) => Ok(outcome),
            None => adapter.stop(StopReason::Budget),
        };
    }
    match adapter.mark()? {
        Some(marks) => adapter.deepen(marks),
        None => adapter.stop(StopReason::Budget),
    }
}
