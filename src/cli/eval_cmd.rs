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

/// Runs `rkwave eval`: each position is evaluated and printed before the next (JSON
/// streamed too), so memory stays that of one position whatever the number of positions.
pub fn run(args: &EvalArgs) -> Result<(), CliError> {
    use std::io::Write;
    let basis = args.spec.build()?;
    // Validate every position before printing anything.
    for &x in &args.x {
        basis.to_unit(x)?;
    }
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    let mut write = |text: &str| -> Result<(), CliError> {
        match out.write_all(text.as_bytes()) {
            Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => std::process::exit(141),
            r => r.map_err(|source| CliError::Write {
                path: "<stdout>".into(),
                source,
            }),
        }
    };
    if args.json {
        let header = serde_json::json!({
            "p": basis.p(),
            "family": basis.bank().family().short_name(),
            "coarse": basis.coarse(),
            "fine": basis.fine(),
            "domain": [basis.domain().a(), basis.domain().b()],
        })
        .to_string();
        // `{...header..., "points": [` then one object per position.
        write(&format!(
            "{},\n\"points\": [\n",
            &header[..header.len() - 1]
        ))?;
    }
    let mut ev = basis.evaluator();
    for (k, &x) in args.x.iter().enumerate() {
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
        let pt = EvalPoint { x, functions };
        if args.json {
            let sep = if k + 1 < args.x.len() { ",\n" } else { "\n" };
            let obj = serde_json::to_string(&pt).expect("plain data serializes");
            write(&format!("{obj}{sep}"))?;
        } else {
            let mut text = format!("x = {} ({} nonzero functions)\n", pt.x, pt.functions.len());
            for f in &pt.functions {
                text.push_str(&format!(
                    "  {:<8} {:<8} level {:>2} index {:>6}  {:+.17e}\n",
                    format!("{:?}", f.kind).to_lowercase(),
                    format!("{:?}", f.side).to_lowercase(),
                    f.level,
                    f.index,
                    f.value
                ));
            }
            write(&text)?;
        }
    }
    if args.json {
        write("]}\n")?;
    }
    match out.flush() {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => std::process::exit(141),
        r => r.map_err(|source| CliError::Write {
            path: "<stdout>".into(),
            source,
        }),
    }
}
