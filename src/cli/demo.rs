//! The built-in demo: what `cargo run --release` runs. It writes figures and a report to
//! `out/`.

use std::fmt::Write as _;

use rkwave::basis::{CdvBasis, FilterFamily, MAX_VANISHING_MOMENTS};
use rkwave::sampling::Domain;

use rkwave::lab::basis::default_basis_facts;
use rkwave::report::DemoSummary;

use rkwave::lab::refine::{adaptive_vs_uniform, compare_uniform, comparison_budgets, Truth};
use rkwave::lab::refine_figures::{error_against_samples, figure4_layout};
use rkwave::refine::{RefineParams, SignalOracle, StopParams};
use rkwave::sampling::Signal;

use super::adapt_text::{adapt_table, comparison_table, refine_error};
use super::{check_writable, figures, CliError, DemoArgs};

/// Finest level of the demo's basis table.
const DEMO_FINE: u32 = 12;

/// The grid of the adaptive demo's errors (`rkwave adapt`'s default `--grid`).
const ADAPT_GRID: usize = 65_536;

/// Runs the demo.
pub fn run(args: &DemoArgs) -> Result<(), CliError> {
    let out = &args.out;
    std::fs::create_dir_all(out).map_err(|source| CliError::Write {
        path: out.clone(),
        source,
    })?;
    let mut summary = String::new();
    let _ = writeln!(summary, "# rkwave demo\n");
    let _ = writeln!(
        summary,
        "## CDV bases Psi(j_min(p), {DEMO_FINE}) on [0, 1]: measured identities\n"
    );
    let _ = writeln!(
        summary,
        "| p | family | n | dimension | orthonormality | polynomials | vanishing moments | FWT | time (s) |"
    );
    let _ = writeln!(summary, "|---|---|---|---|---|---|---|---|---|");
    let mut reports = Vec::new();
    for p in 1..=MAX_VANISHING_MOMENTS {
        let r = default_basis_facts(p, DEMO_FINE, 20_000, 1)?;
        let _ = writeln!(
            summary,
            "| {} | {}{} | {} | {} | {:.1e} | {:.1e} | {:.1e} | {:.1e} | {:.2} |",
            r.p,
            r.family,
            r.p,
            r.coarse,
            r.dimension,
            r.facts.orthonormality_error,
            r.facts.polynomial_error,
            r.facts.vanishing_moment_error,
            r.facts.fwt_error,
            r.time_s
        );
        eprintln!("basis p = {p}: done in {:.2} s", r.time_s);
        reports.push(r);
    }
    let basis = CdvBasis::new(3, FilterFamily::Extremal, 4, 8, Domain::UNIT)?;
    let fig = out.join("basis_p3.png");
    // The demo regenerates its own folder: its figures are replaced (atomically).
    figures::basis_figure(&basis, &fig, true)?;
    let basis8 = CdvBasis::new(8, FilterFamily::LeastAsymmetric, 5, 8, Domain::UNIT)?;
    figures::basis_figure(&basis8, &out.join("basis_p8.png"), true)?;
    let _ = writeln!(
        summary,
        "\nFigures: `basis_p3.png` (scaling functions and wavelets of V_4, W_4, p = 3), \
         `basis_p8.png` (p = 8, level 5)."
    );
    // Local inversion against the global pseudo-inverse at the paper's setting (nearest
    // orthonormal levels 4..8), and the dual kernels.
    let _ = writeln!(
        summary,
        "\n## Local vs global, p = 3, levels 4..8, 1024 uniform samples\n"
    );
    let mut reports_lg = Vec::new();
    for rings in [0usize, 1] {
        let setting = rkwave::report::ReportSetting {
            p: 3,
            family: FilterFamily::Extremal,
            coarse: 4,
            fine: 8,
            samples: 1024,
            layout: rkwave::sampling::Layout::Uniform,
            seed: 1,
            signal: rkwave::sampling::Signal::Smooth,
            local: rkwave::solve::LocalInversionParams {
                rings,
                ..Default::default()
            },
            grid: 8192,
        };
        let r = rkwave::report::local_vs_global(&setting)?;
        let _ = writeln!(summary, "```\n{}```", r.table());
        reports_lg.push(r);
    }
    let small = CdvBasis::new(3, FilterFamily::Extremal, 4, 5, Domain::UNIT)?;
    let xs = rkwave::sampling::Layout::Uniform.generate(128, Domain::UNIT, 0);
    figures::kernels_figure(&small, &xs, &out.join("kernels_p3.png"), true)?;
    let _ = writeln!(
        summary,
        "Figure: `kernels_p3.png` (dual and reproducing kernels)."
    );
    // The adaptive example of the supplement's figure 4 (depth 8 near the jumps, 6 elsewhere)
    // and adaptive against uniform sampling on the three-jump signal.
    let _ = writeln!(
        summary,
        "\n## Adaptive refinement (supplement figure 4): `adapt_jumps.png`, `adapt_compare.png`\n\n\
         Printed by `rkwave adapt --signal jumps --max-depth 8 --tolerance 1e-3` and \
         `rkwave adapt --signal jumps --compare-uniform --counts 512,1024,2048,4096`."
    );
    adaptive_jumps(out)?;
    super::demo_image::run(out, &mut summary)?;
    let md = out.join("summary.md");
    std::fs::write(&md, &summary).map_err(|source| CliError::Write {
        path: md.clone(),
        source,
    })?;
    let json = out.join("summary.json");
    std::fs::write(
        &json,
        serde_json::to_string_pretty(&DemoSummary {
            bases: reports,
            local_vs_global: reports_lg,
        })
        .expect("plain data serializes"),
    )
    .map_err(|source| CliError::Write {
        path: json.clone(),
        source,
    })?;
    print!("{summary}");
    println!(
        "wrote {}, {}, {}",
        fig.display(),
        md.display(),
        json.display()
    );
    Ok(())
}

/// The adaptive example of the supplement's figure 4 and adaptive against uniform sampling on
/// the three-jump signal: what `rkwave adapt --signal jumps --max-depth 8 --tolerance 1e-3
/// --plot adapt_jumps.png` and `rkwave adapt --signal jumps --compare-uniform --counts
/// 512,1024,2048,4096 --plot adapt_compare.png` print and draw, by the same library calls
/// with the command's defaults written out.
fn adaptive_jumps(out: &std::path::Path) -> Result<(), CliError> {
    let domain = Domain::UNIT;
    let signal = Signal::Jumps;
    let oracle = SignalOracle::new(signal, domain);
    let name = signal.to_string();
    let truth = Truth {
        oracle: &oracle,
        name: &name,
        singular_points: signal.singular_points(),
    };
    // `rkwave adapt`'s defaults: p 3 with CDV's family, base 256 jittered samples (seed 1),
    // rho 2, theta 0.5, the coefficient indicator, depth limit 32, tolerance 1e-6, budget
    // 100 000, every round's error on a grid of 4096.
    let defaults = RefineParams::default();
    let params = |max_depth: u32, tolerance: f64| {
        let mut p = RefineParams {
            domain,
            reference_grid: 4096,
            stop: StopParams {
                tolerance,
                ..defaults.stop
            },
            ..defaults
        };
        p.interval.family = Some(FilterFamily::cdv_default(p.tree.p));
        p.interval.max_depth = max_depth;
        p.validate().map_err(refine_error).map(|()| p)
    };
    let figure = out.join("adapt_jumps.png");
    check_writable(&figure, true)?;
    let (report, r) =
        adaptive_vs_uniform(truth, &params(8, 1e-3)?, ADAPT_GRID).map_err(refine_error)?;
    figures::save(&figure4_layout(&r, truth).map_err(refine_error)?, &figure)?;
    print!("{}", adapt_table(&report));
    println!("wrote {}", figure.display());
    let params = params(32, 1e-6)?;
    let figure = out.join("adapt_compare.png");
    check_writable(&figure, true)?;
    let budgets = comparison_budgets(&[512, 1024, 2048, 4096], &params);
    let compared = compare_uniform(truth, &params, &budgets, ADAPT_GRID).map_err(refine_error)?;
    figures::save(
        &error_against_samples(&compared.comparison, &compared.signal),
        &figure,
    )?;
    print!("{}", comparison_table(&compared, ADAPT_GRID));
    println!("wrote {}", figure.display());
    Ok(())
}
