//! Where samples come from: a [`SampleOracle`] returns `f(x)` at a domain position `x`.
//!
//! Implemented for closures `Fn(f64) -> f64`, for the built-in test signals on a domain
//! ([`SignalOracle`]) and for user expressions in `x` ([`ExpressionOracle`]). The refiner
//! calls it once per sample, in a deterministic order, and never twice at the same sample.

use exmex::prelude::*;
use exmex::{BinOp, FloatOpsFactory, MakeOperators, Operator};
use thiserror::Error;

use crate::sampling::{Domain, Signal};

/// A function that can be sampled at any position of its domain.
pub trait SampleOracle {
    /// `f(x)`; a NaN or infinity is reported by the refiner as an error.
    fn sample(&self, x: f64) -> f64;
}

impl<F: Fn(f64) -> f64> SampleOracle for F {
    fn sample(&self, x: f64) -> f64 {
        self(x)
    }
}

/// A built-in [`Signal`] on a domain: `x -> signal.value((x - a) / (b - a))`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SignalOracle {
    /// The signal (defined on the unit interval).
    pub signal: Signal,
    /// The domain it is stretched over.
    pub domain: Domain,
}

impl SignalOracle {
    /// `signal` stretched over `domain`.
    pub fn new(signal: Signal, domain: Domain) -> Self {
        Self { signal, domain }
    }
}

impl SampleOracle for SignalOracle {
    fn sample(&self, x: f64) -> f64 {
        self.signal.value_in(self.domain, x)
    }
}

/// Why an expression was rejected.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("cannot use the expression `{expression}`: {reason}")]
pub struct ExpressionError {
    /// The expression as given.
    pub expression: String,
    /// What is wrong and how to fix it.
    pub reason: String,
}

/// exmex's float operators plus comparisons `<`, `<=`, `>`, `>=`, `==`, `!=` that give 1.0 or
/// 0.0 and bind more loosely than `+` and `-`.
#[derive(Clone, Debug)]
struct ComparisonOps;

fn truth(b: bool) -> f64 {
    if b {
        1.0
    } else {
        0.0
    }
}

impl MakeOperators<f64> for ComparisonOps {
    fn make<'a>() -> Vec<Operator<'a, f64>> {
        let mut ops = FloatOpsFactory::<f64>::make();
        let cmp = |repr: &'a str, apply: fn(f64, f64) -> f64| {
            Operator::make_bin(
                repr,
                BinOp {
                    apply,
                    prio: -1,
                    is_commutative: false,
                },
            )
        };
        ops.push(cmp(">=", |a, b| truth(a >= b)));
        ops.push(cmp("<=", |a, b| truth(a <= b)));
        ops.push(cmp("==", |a, b| truth(a == b)));
        ops.push(cmp("!=", |a, b| truth(a != b)));
        ops.push(cmp(">", |a, b| truth(a > b)));
        ops.push(cmp("<", |a, b| truth(a < b)));
        ops
    }
}

/// A user expression in the domain variable `x`, e.g. `sin(8*x) + (x > 0.6)`.
///
/// Parsed by [exmex](https://docs.rs/exmex): `+ - * / ^`, `sin cos tan asin acos atan sinh cosh
/// tanh exp ln log log2 log10 sqrt cbrt abs signum floor ceil round trunc fract`, `min`, `max`,
/// `atan2` as binary operators, the constants `PI` and `E`, and comparisons that count as 1.0
/// (true) or 0.0 (false). Note exmex's rule that unary operators bind tightest: `-x^2` is
/// `(-x)^2`; write `-(x^2)`.
#[derive(Clone, Debug)]
pub struct ExpressionOracle {
    text: String,
    // Boxed: exmex keeps its operators inline (~20 KB).
    expr: Box<FlatEx<f64, ComparisonOps>>,
    uses_x: bool,
}

impl ExpressionOracle {
    /// Parses `text`; the only variable allowed is `x`.
    pub fn parse(text: &str) -> Result<Self, ExpressionError> {
        let err = |reason: String| ExpressionError {
            expression: text.to_string(),
            reason,
        };
        if text.trim().is_empty() {
            return Err(err(
                "it is empty: give a formula in x, e.g. `sin(8*x)`".into()
            ));
        }
        let expr = FlatEx::<f64, ComparisonOps>::parse(text).map_err(|e| {
            err(format!(
                "{e}; write a formula in x such as `sin(8*x) + (x > 0.6)`"
            ))
        })?;
        let vars: Vec<&str> = expr.var_names().iter().map(|s| s.as_str()).collect();
        if let Some(bad) = vars.iter().find(|v| **v != "x") {
            return Err(err(format!(
                "unknown name `{bad}`: the only variable is x (or give a built-in signal name: \
                 smooth, polynomialN, jumps, kink, cusp, blocks, bumps, heavisine, doppler)"
            )));
        }
        Ok(Self {
            text: text.to_string(),
            uses_x: !vars.is_empty(),
            expr: Box::new(expr),
        })
    }

    /// The expression as given.
    pub fn text(&self) -> &str {
        &self.text
    }
}

impl SampleOracle for ExpressionOracle {
    fn sample(&self, x: f64) -> f64 {
        let args: &[f64] = if self.uses_x { &[x] } else { &[] };
        self.expr.eval(args).unwrap_or(f64::NAN)
    }
}
