//! `rkwave eval`: every nonzero basis function at the given positions
//! ([`rkwave::report::basis::basis_values`]).

use rkwave::report::basis::basis_values;

use super::{CliError, EvalArgs};

/// Runs `rkwave eval`.
pub fn run(args: &EvalArgs) -> Result<(), CliError> {
    let basis = args.spec.build()?;
    let values = basis_values(&basis, &args.x)?;
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&values).expect("plain data serializes")
        );
    } else {
        for pt in &values.points {
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
