//! `rkwave basis`: the measured facts of a CDV basis ([`rkwave::report::basis`]).

use std::time::Instant;

use rkwave::lab::basis::basis_facts;
use rkwave::report::basis::BasisReport;

use super::{check_writable, figures, BasisArgs, CliError};

/// Runs `rkwave basis`.
pub fn run(args: &BasisArgs) -> Result<(), CliError> {
    if args.points < 2 {
        return Err(CliError::Invalid(format!(
            "--points {} is too few: give at least 2 (10000 or more recommended)",
            args.points
        )));
    }
    if let Some(path) = &args.plot {
        check_writable(path, args.force)?;
    }
    let started = Instant::now();
    let basis = args.spec.build()?;
    // The job refuses facts above the memory limit before measuring them.
    let rep = basis_facts(&basis, args.points, args.seed, started)?;
    if args.json {
        super::print_json(&rep);
    } else {
        print!("{}", table(&rep));
    }
    if let Some(path) = &args.plot {
        figures::basis_figure(&basis, path, args.force)?;
        if !args.json {
            println!("figure: {}", path.display());
        }
    }
    Ok(())
}

/// The report as a table for people.
pub fn table(r: &BasisReport) -> String {
    format!(
        "CDV basis Psi(n = {}, N = {}), p = {} ({}{}), domain [{}, {}], dimension {}\n\
         (coarsest orthonormal level j_min(p) = {})\n\
         \x20 orthonormality error   max |G - I|              {:.2e}\n\
         \x20 polynomial error       max |P_n t^d - t^d|, d<p {:.2e}  ({} points, edges included)\n\
         \x20 vanishing moments      max |<t^d, psi>|         {:.2e}\n\
         \x20 FWT reconstruction     max |S A f - f|          {:.2e}\n\
         \x20 time                                            {:.3} s\n",
        r.coarse,
        r.fine,
        r.p,
        r.family,
        r.p,
        r.domain[0],
        r.domain[1],
        r.dimension,
        r.minimum_level,
        r.facts.orthonormality_error,
        r.facts.polynomial_error,
        r.facts.polynomial_points,
        r.facts.vanishing_moment_error,
        r.facts.fwt_error,
        r.time_s
    )
}
