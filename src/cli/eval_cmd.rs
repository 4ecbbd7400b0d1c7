//! `rkwave eval`: every nonzero basis function at the given positions.

use rkwave::basis::{FunctionKind, Side};
use serde::Serialize;

use super::{CliError, EvalArgs};

/// One basis function's value at a position.
#[derive(Debug, Serialize)]
pub struct EvalEntry {
    /// "scaling" or "wavelet".
    pub kind: FunctionKind,
    /// "left", "interior" or "right".
    pub side: Side,
    /// Level j.
    pub level: u32,
    /// Index within the level (`0..2^j`).
    pub index: usize,
    /// Global index in `Psi(n, N)`.
    pub global: usize,
    /// The value.
    pub value: f64,
}

/// All functions at one position.
#[derive(Debug, Serialize)]
pub struct EvalPoint {
    /// The position.
    pub x: f64,
    /// The nonzero functions, ascending global index.
    pub functions: Vec<EvalEntry>,
}

/// Runs `rkwave eval`.
pub fn run(args: &EvalArgs) -> Result<(), CliError> {
    let basis = args.spec.build()?;
    // Validate every position before printing anything.
    for &x in &args.x {
        basis.to_unit(x)?;
    }
    let mut ev = basis.evaluator();
    let mut points = Vec::with_capacity(args.x.len());
    for &x in &args.x {
        let values = ev.eval(x)?;
        let functions = values
            .iter()
            .map(|v| {
                let id = basis.function(v.index);
                EvalEntry {
                    kind: id.kind,
                    side: id.side,
                    level: id.level,
                    index: id.index,
                    global: v.index,
                    value: v.value,
                }
            })
            .collect();
        points.push(EvalPoint { x, functions });
    }
    if args.json {
        let out = serde_json::json!({
            "p": basis.p(),
            "family": basis.bank().family().short_name(),
            "coarse": basis.coarse(),
            "fine": basis.fine(),
            "domain": [basis.domain().a(), basis.domain().b()],
            "points": points,
        });
        println!(
            "{}",
            serde_json::to_string_pretty(&out).expect("plain data serializes")
        );
    } else {
        for pt in &points {
            println!("x = {} ({} nonzero functions)", pt.x, pt.functions.len());
            for f in &pt.functions {
                println!(
                    "  {:<8} {:<8} level {:>2} index {:>6}  {:+.17e}",
                    format!("{:?}", f.kind).to_lowercase(),
                    format!("{:?}", f.side).to_lowercase(),
                    f.level,
                    f.index,
                    f.value
                );
            }
        }
    }
    Ok(())
}
