//! The adaptive core shared by the 1D refiner (`refine`) and the image plane's
//! (`image::adaptive`): dyadic trees, marking, stop reasons, the rounds driver. It depends on the bases
//! only; both refiners build on it.
//!
//! Both dimensions grow the same object. A tree `T` of wavelets closed under "parent
//! present" over a coarse level; its *local depth* `d(x)` is the finest active level at `x`,
//! and the points of depth `d` form whole dyadic cells one level deeper, the tree's *leaves*
//! (both dimensions): each is one slot of the local space, holding one function per
//! `2^D` cell of `[0, 1]^D`. The sampling invariant is
//!
//! ```text
//! samples(C) >= ceil(rho)      for every leaf C,
//! ```
//!
//! and a round fits on `T`, indicates the predicted detail `eta_C` of every markable unit,
//! stops ([`StopReason`]) when the estimated RMS error `sqrt(sum eta^2 / |Omega|)` is at most
//! the tolerance, when nothing markable is left above the depth limit, at the budget or the
//! round limit, and otherwise marks the fewest leading units holding `theta` of
//! `sum eta^2` ([`marking::dorfler`]), as many as the budget pays for
//! ([`marking::within_budget`]), deepens them (each deepened cell has `2^D` children) and
//! tops the new leaves up to `ceil(rho)` samples. That round is one function for both,
//! [`rounds::round`], over each dimension's [`rounds::RoundAdapter`] (the stop test
//! [`rounds::stop_test`], the budget cut [`rounds::cut`]).
//!
//! What differs by dimension, and where:
//!
//! | idea | 1D ([`tree::interval`]) | 2D ([`tree::quad`]) |
//! |------|-------------------------|---------------------|
//! | tree | [`WaveletTree`] of wavelet indices | [`QuadTree`] of [`Cell`]s (three details each) |
//! | cell depth | level `j` (absolute) | step `s` (levels `cx + s`, `cy + s`: two coarse levels) |
//! | leaf | [`Leaf`] (`leaves()`) | leaf [`Cell`] (`leaves()`, `leaf_at`) |
//! | deepen | `extend`, `deepen` (wavelets and their ancestors) | `deepen` (one cell) |
//! | children | 2 | 4 |
//! | budget cut ([`rounds::cut`]) | the new leaves' shortfall of a trial tree | prefix sums of additive costs |
//!
//! ([`density`]: the 1D tree from sample counts, for samples nobody chose.)

pub mod density;
pub mod marking;
pub mod params;
pub mod rounds;
mod stop;
pub mod tree;

pub use params::{MarkingParams, StopParams, TreeParams};
pub use stop::StopReason;
pub use tree::interval::{Leaf, WaveletTree};
pub use tree::quad::{Cell, QuadTree};
