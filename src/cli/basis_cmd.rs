//! `rkwave basis`: the measured facts of a CDV basis.

use std::time::Instant;

use rkwave::basis::facts::BasisFacts;
use rkwave::basis::{minimum_level, CdvBasis};
use serde::Serialize;

use super::{check_writable, figures, BasisArgs, CliError};

/// The report of `rkwave basis --json`.
#[derive(Debug, Serialize)]
pub struct BasisReport {
    /// Vanishing moments.
    pub p: usize,
    /// "db" or "sym".
    pub family: &'static str,
    /// Coarse level n.
    pub coarse: u32,
    /// Finest wavelet level N.
    pub fine: u32,
    /// `j_min(p)`.
    pub minimum_level: u32,
    /// `[a, b]`.
    pub domain: [f64; 2],
    /// `2^{N+1}`.
    pub dimension: usize,
    /// The measured identities.
    #[serde(flatten)]
    pub facts: BasisFacts,
    /// Seconds to build the filter bank and measure.
    pub time_s: f64,
}

/// Measures the facts of `basis`.
pub fn report(basis: &CdvBasis, points: usize, seed: u64, started: Instant) -> BasisReport {
    let facts = BasisFacts::measure(basis, points, seed);
    BasisReport {
        p: basis.p(),
        family: basis.bank().family().short_name(),
        coarse: basis.coarse(),
        fine: basis.fine(),
        minimum_level: minimum_level(basis.p()),
        domain: [basis.domain().a(), basis.domain().b()],
        dimension: basis.dimension(),
        facts,
        time_s: started.elapsed().as_secs_f64(),
    }
}

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
    // The facts multiply sparse synthesis matrices of all P = 2^{N+1} functions: about
    // 256 (N - n + 2) 2p bytes per function at their peak.
    let (n, fine) = (basis.coarse(), basis.fine());
    rkwave::resources::check(
        || format!("the basis facts of levels {n}..{fine} (P = 2^{})", fine + 1),
        256.0
            * rkwave::resources::dimension(fine)
            * (fine.saturating_sub(n) as f64 + 2.0)
            * (2 * basis.p()) as f64
            + rkwave::resources::grid_bytes(args.points, 1),
        || "lower --fine (evaluation alone, `rkwave eval`, works up to level 60)".into(),
    )
    .map_err(rkwave::reconstruct::ReconstructError::from)?;
    let rep = report(&basis, args.points, args.seed, started);
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&rep).expect("plain data serializes")
        );
    } else {
        print!("{}", table(&rep));
    }
    if let Some(path) = &args.plot {
        figures::basis_figure(&basis, path)?;
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
