//! Where samples come from: a [`SampleOracle`] returns `f(x)` at a domain position `x`.
//!
//! Implemented for closures `Fn(f64) -> f64`, for the built-in test signals on a domain
//! ([`SignalOracle`]) and for user expressions in `x` ([`ExpressionOracle`]). The refiner
//! calls it once per sample, in a deterministic order, and never twice at the same sample.

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

/// A parsed expression: a tree evaluated recursively.
#[derive(Clone, Debug)]
enum Node {
    Num(f64),
    X,
    Neg(Box<Node>),
    Bin(BinaryOp, Box<Node>, Box<Node>),
    Call1(fn(f64) -> f64, Box<Node>),
    Call2(fn(f64, f64) -> f64, Box<Node>, Box<Node>),
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum BinaryOp {
    Add,
    Sub,
    Mul,
    Div,
    Pow,
    Lt,
    Le,
    Gt,
    Ge,
    Eq,
    Ne,
}

impl Node {
    fn eval(&self, x: f64) -> f64 {
        match self {
            Node::Num(v) => *v,
            Node::X => x,
            Node::Neg(a) => -a.eval(x),
            Node::Call1(f, a) => f(a.eval(x)),
            Node::Call2(f, a, b) => f(a.eval(x), b.eval(x)),
            Node::Bin(op, a, b) => {
                let (a, b) = (a.eval(x), b.eval(x));
                match op {
                    BinaryOp::Add => a + b,
                    BinaryOp::Sub => a - b,
                    BinaryOp::Mul => a * b,
                    BinaryOp::Div => a / b,
                    BinaryOp::Pow => a.powf(b),
                    BinaryOp::Lt => truth(a < b),
                    BinaryOp::Le => truth(a <= b),
                    BinaryOp::Gt => truth(a > b),
                    BinaryOp::Ge => truth(a >= b),
                    BinaryOp::Eq => truth(a == b),
                    BinaryOp::Ne => truth(a != b),
                }
            }
        }
    }
    fn uses_x(&self) -> bool {
        match self {
            Node::Num(_) => false,
            Node::X => true,
            Node::Neg(a) | Node::Call1(_, a) => a.uses_x(),
            Node::Bin(_, a, b) | Node::Call2(_, a, b) => a.uses_x() || b.uses_x(),
        }
    }
}

fn truth(b: bool) -> f64 {
    if b {
        1.0
    } else {
        0.0
    }
}

/// One-argument functions by name.
fn function1(name: &str) -> Option<fn(f64) -> f64> {
    Some(match name {
        "sin" => f64::sin,
        "cos" => f64::cos,
        "tan" => f64::tan,
        "asin" => f64::asin,
        "acos" => f64::acos,
        "atan" => f64::atan,
        "sinh" => f64::sinh,
        "cosh" => f64::cosh,
        "tanh" => f64::tanh,
        "exp" => f64::exp,
        "ln" | "log" => f64::ln,
        "log2" => f64::log2,
        "log10" => f64::log10,
        "sqrt" => f64::sqrt,
        "cbrt" => f64::cbrt,
        "abs" => f64::abs,
        "signum" => f64::signum,
        "floor" => f64::floor,
        "ceil" => f64::ceil,
        "round" => f64::round,
        "trunc" => f64::trunc,
        "fract" => f64::fract,
        _ => return None,
    })
}

/// Two-argument functions by name.
fn function2(name: &str) -> Option<fn(f64, f64) -> f64> {
    Some(match name {
        "min" => f64::min,
        "max" => f64::max,
        "atan2" => f64::atan2,
        _ => return None,
    })
}

const FUNCTIONS: &str = "sin cos tan asin acos atan sinh cosh tanh exp ln log log2 log10 sqrt \
                         cbrt abs signum floor ceil round trunc fract, min(a, b) max(a, b) \
                         atan2(y, x)";

/// Recursive descent over the characters of the text (precedence, loosest first:
/// comparisons, `+ -`, `* /`, unary `- +`, `^` right-associative with a signed exponent).
struct Parser<'a> {
    text: &'a str,
    pos: usize,
    depth: usize,
}

/// Longer expressions are refused (evaluation recurses over the tree).
const MAX_LENGTH: usize = 10_000;

/// Nesting deeper than this is refused (no stack overflow on hostile input).
const MAX_DEPTH: usize = 200;

impl<'a> Parser<'a> {
    fn skip(&mut self) {
        while self.text[self.pos..].starts_with(char::is_whitespace) {
            self.pos += self.text[self.pos..]
                .chars()
                .next()
                .map_or(1, char::len_utf8);
        }
    }
    fn peek(&mut self) -> Option<char> {
        self.skip();
        self.text[self.pos..].chars().next()
    }
    fn eat(&mut self, token: &str) -> bool {
        self.skip();
        if self.text[self.pos..].starts_with(token) {
            self.pos += token.len();
            true
        } else {
            false
        }
    }
    fn at(&self) -> String {
        let rest: String = self.text[self.pos..].chars().take(12).collect();
        if rest.is_empty() {
            "at the end".into()
        } else {
            format!(
                "at `{rest}` (character {})",
                self.text[..self.pos].chars().count() + 1
            )
        }
    }
    fn enter(&mut self) -> Result<(), String> {
        self.depth += 1;
        if self.depth > MAX_DEPTH {
            return Err(format!("it nests deeper than {MAX_DEPTH} levels"));
        }
        Ok(())
    }
    fn comparison(&mut self) -> Result<Node, String> {
        self.enter()?;
        let mut left = self.sum()?;
        loop {
            let op = if self.eat("<=") {
                BinaryOp::Le
            } else if self.eat(">=") {
                BinaryOp::Ge
            } else if self.eat("==") {
                BinaryOp::Eq
            } else if self.eat("!=") {
                BinaryOp::Ne
            } else if self.eat("<") {
                BinaryOp::Lt
            } else if self.eat(">") {
                BinaryOp::Gt
            } else {
                break;
            };
            let right = self.sum()?;
            left = Node::Bin(op, Box::new(left), Box::new(right));
        }
        self.depth -= 1;
        Ok(left)
    }
    fn sum(&mut self) -> Result<Node, String> {
        let mut left = self.product()?;
        loop {
            let op = if self.eat("+") {
                BinaryOp::Add
            } else if self.eat("-") {
                BinaryOp::Sub
            } else {
                break;
            };
            let right = self.product()?;
            left = Node::Bin(op, Box::new(left), Box::new(right));
        }
        Ok(left)
    }
    fn product(&mut self) -> Result<Node, String> {
        let mut left = self.unary()?;
        loop {
            let op = if self.eat("*") {
                BinaryOp::Mul
            } else if self.eat("/") {
                BinaryOp::Div
            } else {
                break;
            };
            let right = self.unary()?;
            left = Node::Bin(op, Box::new(left), Box::new(right));
        }
        Ok(left)
    }
    /// Unary minus binds more loosely than `^`: `-a^2 = -(a^2)`.
    fn unary(&mut self) -> Result<Node, String> {
        self.enter()?;
        let node = if self.eat("-") {
            Node::Neg(Box::new(self.unary()?))
        } else if self.eat("+") {
            self.unary()?
        } else {
            self.power()?
        };
        self.depth -= 1;
        Ok(node)
    }
    /// `a ^ b ^ c = a ^ (b ^ c)`; the exponent may carry a sign: `2^-x`.
    fn power(&mut self) -> Result<Node, String> {
        let base = self.primary()?;
        if self.eat("^") {
            let exponent = self.unary()?;
            return Ok(Node::Bin(BinaryOp::Pow, Box::new(base), Box::new(exponent)));
        }
        Ok(base)
    }
    fn primary(&mut self) -> Result<Node, String> {
        match self.peek() {
            None => Err("it ends where a number, x, a function or `(` is expected".into()),
            Some('(') => {
                self.pos += 1;
                let inner = self.comparison()?;
                if !self.eat(")") {
                    return Err(format!("a `)` is missing {}", self.at()));
                }
                Ok(inner)
            }
            Some(c) if c.is_ascii_digit() || c == '.' => self.number(),
            Some(c) if c.is_alphabetic() || c == '_' => self.name(),
            Some(_) => Err(format!(
                "a number, x, a function or `(` is expected {}",
                self.at()
            )),
        }
    }
    /// `12`, `1.5`, `.5`, `1e3`, `2.5E-4`.
    fn number(&mut self) -> Result<Node, String> {
        let rest = &self.text[self.pos..];
        let b = rest.as_bytes();
        let mut end = 0;
        while end < b.len() && (b[end].is_ascii_digit() || b[end] == b'.') {
            end += 1;
        }
        if end < b.len() && (b[end] == b'e' || b[end] == b'E') {
            let mut k = end + 1;
            if k < b.len() && (b[k] == b'+' || b[k] == b'-') {
                k += 1;
            }
            if k < b.len() && b[k].is_ascii_digit() {
                while k < b.len() && b[k].is_ascii_digit() {
                    k += 1;
                }
                end = k;
            }
        }
        let literal = &rest[..end];
        let value: f64 = literal
            .parse()
            .map_err(|_| format!("`{literal}` is not a number {}", self.at()))?;
        self.pos += end;
        Ok(Node::Num(value))
    }
    fn name(&mut self) -> Result<Node, String> {
        let rest = &self.text[self.pos..];
        let len = rest
            .char_indices()
            .find(|(_, c)| !(c.is_alphanumeric() || *c == '_'))
            .map_or(rest.len(), |(i, _)| i);
        let name = &rest[..len];
        self.pos += len;
        match name {
            "x" => return Ok(Node::X),
            "PI" | "pi" => return Ok(Node::Num(std::f64::consts::PI)),
            "E" => return Ok(Node::Num(std::f64::consts::E)),
            _ => {}
        }
        if let Some(f) = function1(name) {
            let args = self.arguments(name, 1)?;
            let [a]: [Node; 1] = args.try_into().map_err(|_| "internal".to_string())?;
            return Ok(Node::Call1(f, Box::new(a)));
        }
        if let Some(f) = function2(name) {
            let args = self.arguments(name, 2)?;
            let [a, b]: [Node; 2] = args.try_into().map_err(|_| "internal".to_string())?;
            return Ok(Node::Call2(f, Box::new(a), Box::new(b)));
        }
        Err(format!(
            "unknown name `{name}`: the only variable is x, the constants are PI and E, the \
             functions {FUNCTIONS} (or give a built-in signal name: smooth, polynomialN, \
             jumps, kink, cusp, blocks, bumps, heavisine, doppler)"
        ))
    }
    fn arguments(&mut self, name: &str, count: usize) -> Result<Vec<Node>, String> {
        if !self.eat("(") {
            return Err(format!(
                "`{name}` needs its argument in parentheses, e.g. `{name}(x)`"
            ));
        }
        let mut args = vec![self.comparison()?];
        while self.eat(",") {
            args.push(self.comparison()?);
        }
        if !self.eat(")") {
            return Err(format!(
                "a `)` is missing after the arguments of `{name}` {}",
                self.at()
            ));
        }
        if args.len() != count {
            return Err(format!(
                "`{name}` takes {count} argument{}, given {}",
                if count == 1 { "" } else { "s" },
                args.len()
            ));
        }
        Ok(args)
    }
}

/// A user expression in the domain variable `x`, e.g. `sin(8*x) + (x > 0.6)`.
///
/// `+ - * / ^` with the usual precedence: `^` binds tightest and is right-associative, unary
/// minus binds more loosely than `^` (`-x^2 = -(x^2)`, as in mathematics, Python and Julia)
/// and the exponent may be signed (`2^-x`); numbers in decimal or scientific notation
/// (`1e3`, `2.5E-4`); the functions `sin cos tan asin acos atan sinh cosh tanh exp ln log
/// log2 log10 sqrt cbrt abs signum floor ceil round trunc fract`, `min(a, b)`, `max(a, b)`,
/// `atan2(y, x)`; the constants `PI` and `E`; comparisons `< <= > >= == !=` that count as 1.0
/// (true) or 0.0 (false) and bind more loosely than `+` and `-`.
#[derive(Clone, Debug)]
pub struct ExpressionOracle {
    text: String,
    expr: Node,
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
        if text.len() > MAX_LENGTH {
            return Err(err(format!(
                "it is {} characters long, above the limit of {MAX_LENGTH}",
                text.len()
            )));
        }
        let mut parser = Parser {
            text,
            pos: 0,
            depth: 0,
        };
        let expr = parser.comparison().map_err(&err)?;
        if parser.peek().is_some() {
            return Err(err(format!(
                "unexpected text {}: write a formula in x such as `sin(8*x) + (x > 0.6)`",
                parser.at()
            )));
        }
        Ok(Self {
            text: text.to_string(),
            expr,
        })
    }

    /// The expression as given.
    pub fn text(&self) -> &str {
        &self.text
    }

    /// Whether the expression depends on `x`.
    pub fn uses_x(&self) -> bool {
        self.expr.uses_x()
    }
}

impl SampleOracle for ExpressionOracle {
    fn sample(&self, x: f64) -> f64 {
        self.expr.eval(x)
    }
}
