//! Sampling: the domain `[a, b]`, sample-position layouts and built-in test
//! signals.
//!
//! * [`Domain`] (from [`crate::domain`]) is a validated finite interval `[a, b]`, with an
//!   exact affine map to and from the unit interval.
//! * [`Layout`] generates `m` sorted sample positions in a domain from a `u64`
//!   seed, bit-for-bit reproducibly on every platform.
//! * [`Signal`] is a family of test functions on the unit interval (smooth,
//!   polynomial, discontinuous, singular and the Donoho–Johnstone signals).

mod layout;
mod signal;

pub use crate::domain::{Domain, DomainError};
pub use layout::{Layout, ParseLayoutError};
pub use signal::{ParseSignalError, Signal};

#[cfg(test)]
mod tests;
