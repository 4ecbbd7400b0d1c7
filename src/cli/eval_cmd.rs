//! `rkwave eval`: every nonzero basis function at the given positions.

use rkwave::report::basis::{BasisValue as EvalEntry, BasisValuesAt as EvalPoint};

use super::{CliError, EvalArgs};

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
