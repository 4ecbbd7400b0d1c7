//! The built-in demo: what `cargo run --release` runs. It writes figures and a report to
//! `out/`.

use std::fmt::Write as _;
use std::time::Instant;

use rkwave::basis::{minimum_level, CdvBasis, FilterFamily, MAX_VANISHING_MOMENTS};
use rkwave::sampling::Domain;

use rkwave::report::basis::basis_report;
use rkwave::report::DemoSummary;

use super::{figures, CliError, DemoArgs};

/// Finest level of the demo's basis table.
const DEMO_FINE: u32 = 12;

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
        let started = Instant::now();
        let basis = CdvBasis::new(
            p,
            FilterFamily::cdv_default(p),
            minimum_level(p),
            DEMO_FINE,
            Domain::UNIT,
        )?;
        let r = basis_report(&basis, 20_000, 1, started);
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
    for extra in [
        vec![
            "--max-depth",
            "8",
            "--tolerance",
            "1e-3",
            "--plot",
            "adapt_jumps.png",
        ],
        vec![
            "--compare-uniform",
            "--counts",
            "512,1024,2048,4096",
            "--plot",
            "adapt_compare.png",
        ],
    ] {
        let mut argv: Vec<String> = ["rkwave", "adapt", "--signal", "jumps", "--force"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        for a in extra {
            argv.push(if a.ends_with(".png") {
                out.join(a).display().to_string()
            } else {
                a.to_string()
            });
        }
        let cli = <super::Cli as clap::Parser>::try_parse_from(&argv)
            .map_err(|e| CliError::Internal(format!("the demo's own arguments: {e}")))?;
        super::run(cli)?;
    }
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
