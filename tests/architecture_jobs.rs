//! The front door, checked on the source: each command file of the command line
//! (`src/cli/*_cmd.rs`, `src/cli/demo.rs`) parses, calls one library job per job it runs, and
//! prints. Read as text (as `tests/architecture.rs` reads the imports): the library functions
//! a command file calls by their paths, each classed as a job, a service (files, figures,
//! tables), a value (a parameter, an input, a report constructed) or a piece a job is built
//! from (the solver layer, the basis, the fits, the estimators, the memory check).
//!
//! What reading cannot see: a method's receiver type (`job.run()`), so a job is recognised by
//! the call that makes it (`UniformJob::new`), and a call through a local alias.

use std::collections::{BTreeMap, BTreeSet};

#[path = "common/source_tree.rs"]
mod source_tree;
use source_tree::*;

/// The library functions `text` (a command file) calls by a module path: `rkwave::m::f(`,
/// or `f(` / `m::f(` where `f` / `m` is a name its `use rkwave::...` declarations bring in;
/// and associated functions of a type it brings in (`PlanStart::new(`), each as its full path
/// from the crate's root (`image::job::memory::check`, `image::job::PlanStart::new`). Line
/// comments are skipped; methods (`.run()`) are not seen (their receiver's type is not
/// written), so a job is recognised by the call that makes it.
fn library_calls(text: &str) -> Vec<String> {
    let text = without_unit_tests(text);
    let mut imported: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for (a, b) in use_declarations(&text) {
        for path in expand_use_tree(&text[a..b]) {
            if path.first().map(String::as_str) == Some("rkwave") && path.len() > 1 {
                imported.insert(path.last().cloned().unwrap_or_default(), path[1..].to_vec());
            }
        }
    }
    let code: String = without_use_declarations(&text)
        .lines()
        .map(|l| l.split("//").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n");
    let bytes = code.as_bytes();
    let is_ident = |b: u8| b.is_ascii_alphanumeric() || b == b'_';
    let lower = |s: &str| s.starts_with(|c: char| c.is_ascii_lowercase());
    let mut out = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        if !is_ident(bytes[i]) || (i > 0 && (is_ident(bytes[i - 1]) || bytes[i - 1] == b'.')) {
            i += 1;
            continue;
        }
        let mut segs = Vec::new();
        let mut j = i;
        loop {
            let s = j;
            while j < bytes.len() && is_ident(bytes[j]) {
                j += 1;
            }
            segs.push(code[s..j].to_string());
            if bytes[j..].starts_with(b"::") && bytes.get(j + 2).is_some_and(|&b| is_ident(b)) {
                j += 2;
            } else {
                break;
            }
        }
        i = j;
        // Module functions (`m::f(`) and a type's associated functions (`m::T::f(`, `T::f(`):
        // every segment a module's name but the one before the function's, which may be a
        // type's.
        let n = segs.len();
        let named = n >= 2 || lower(&segs[0]);
        let modules_then_item = segs[..n.saturating_sub(2)].iter().all(|s| lower(s));
        if bytes.get(j) != Some(&b'(') || !named || !modules_then_item || !lower(&segs[n - 1]) {
            continue;
        }
        let full = if segs[0] == "rkwave" {
            segs[1..].to_vec()
        } else if let Some(prefix) = imported.get(&segs[0]) {
            prefix.iter().chain(&segs[1..]).cloned().collect()
        } else {
            continue;
        };
        out.push(full.join("::"));
    }
    out
}

/// Where a library call of a command file goes ([`library_calls`]): a job (the library's
/// entry that validates, checks and computes one request), a service (files, figures,
/// tables, the reports' text, the plan's state folder), a value (constructing a parameter, an input or a report:
/// `T::new`, `T::default`, `T::parse`, `T::from_*`, ...) or a piece a job is built from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Layer {
    Job,
    Service,
    Value,
    Piece,
}

fn layer(call: &str) -> Layer {
    let under = |prefixes: &[&str]| prefixes.iter().any(|p| call.starts_with(p));
    let segs: Vec<&str> = call.split("::").collect();
    let last = segs[segs.len() - 1];
    let of_type =
        segs.len() >= 2 && segs[segs.len() - 2].starts_with(|c: char| c.is_ascii_uppercase());
    if under(&["io::", "plot::", "norms::", "lab::figure::", "lab::table::"])
        || under(&[
            "lab::refine_figures::",
            "image::adaptive::figure::",
            "image::report::",
        ])
        || under(&["report::reconstruction::", "image::plan::"])
        || last.ends_with("_markdown")
        || last.ends_with("_csv")
    {
        return Layer::Service;
    }
    let pieces = [
        "basis::",
        "solve::",
        "adaptive::",
        "resources::",
        "reconstruct::",
        "refine::",
        "image::fit::",
        "image::adaptive::",
        "image::estimate::",
        "image::tiles::",
        "image::job::memory::",
        "image::sample_weights",
    ];
    if under(&pieces) && call != "reconstruct::fit" {
        let constructs = matches!(last, "new" | "default" | "parse" | "all" | "dropping")
            || last.starts_with("from_")
            || last.starts_with("cdv_");
        return if of_type && constructs {
            Layer::Value
        } else {
            Layer::Piece
        };
    }
    if under(&["image::job::", "lab::", "report::"]) || call == "reconstruct::fit" {
        return if of_type && !matches!(last, "new" | "of") {
            Layer::Value
        } else {
            Layer::Job
        };
    }
    Layer::Value
}

/// Each command file's jobs: the library entries it calls, one per job the command runs (a
/// job made of several library calls shows up here as calls that are not jobs).
const COMMAND_JOBS: &[(&str, &[&str])] = &[
    (
        "cli::adapt_cmd",
        &[
            "lab::refine::adaptive_vs_uniform",
            "lab::refine::compare_uniform",
            "lab::refine::comparison_budgets",
        ],
    ),
    ("cli::basis_cmd", &["lab::basis::basis_facts"]),
    (
        "cli::compare_cmd",
        &[
            "lab::adaptive::compare_adaptive",
            "lab::comparison::ComparisonJob::new",
        ],
    ),
    (
        "cli::demo",
        &[
            "lab::basis::default_basis_facts",
            "lab::refine::adaptive_vs_uniform",
            "lab::refine::compare_uniform",
            "lab::refine::comparison_budgets",
            "report::local_vs_global",
        ],
    ),
    ("cli::eval_cmd", &[]),
    (
        "cli::image_adaptive_cmd",
        &["lab::adaptive::compare_adaptive"],
    ),
    ("cli::image_cmd", &["lab::comparison::ComparisonJob::new"]),
    (
        "cli::plan_cmd",
        &[
            "image::job::PlanFinal::of",
            "image::job::PlanRound::new",
            "image::job::PlanStart::new",
        ],
    ),
    (
        "cli::reconstruct2d_cmd",
        &[
            "image::job::PlanFinal::new",
            "image::job::TiledJob::new",
            "image::job::UniformJob::new",
        ],
    ),
    ("cli::reconstruct_cmd", &["reconstruct::fit"]),
    ("cli::report_cmd", &["report::local_vs_global"]),
    ("cli::scaling_cmd", &["report::scaling::scaling_run"]),
    ("cli::sweep_cmd", &["report::sweep::sweep"]),
];

/// The calls of one command file's text: its jobs (sorted, deduplicated) and the pieces it
/// calls (sorted, deduplicated).
fn jobs_and_pieces(text: &str) -> (Vec<String>, Vec<String>) {
    let calls: BTreeSet<String> = library_calls(text).into_iter().collect();
    let of = |l: Layer| calls.iter().filter(|c| layer(c) == l).cloned().collect();
    (of(Layer::Job), of(Layer::Piece))
}

#[test]
fn the_job_checker_finds_a_job_assembled_from_pieces() {
    // A uniform reconstruction written out of its pieces: the memory check, the fit, the
    // pixels; no job entry.
    let assembled = "use rkwave::image::fit::fit_image;\nuse rkwave::image::job::memory;\n\
        use rkwave::image::adaptive::correction::output_pixels;\n\
        pub fn run() {\n    memory::check(memory::method_request(1))?;\n    \
        let fit = fit_image(&samples, &params)?; // not rkwave::image::job::UniformJob::new(\n    \
        let pixels = output_pixels(&fit)?;\n    rkwave::io::image_file::write_image(&pixels)?;\n}\n";
    let (jobs, pieces) = jobs_and_pieces(assembled);
    assert!(jobs.is_empty(), "{jobs:?}");
    assert_eq!(
        pieces,
        [
            "image::adaptive::correction::output_pixels",
            "image::fit::fit_image",
            "image::job::memory::check",
            "image::job::memory::method_request",
        ],
    );
    // The same request through its job: one entry, no piece.
    let job = "use rkwave::image::job::UniformJob;\npub fn run() {\n    \
        let out = UniformJob::new(&params)?.run(&samples)?;\n    \
        rkwave::io::image_file::write_image(&out.pixels)?;\n}\n";
    assert_eq!(
        jobs_and_pieces(job),
        (vec!["image::job::UniformJob::new".to_string()], vec![])
    );
}

/// What is wrong with the command file `module` whose source is `text`: a module missing
/// from [`COMMAND_JOBS`], jobs other than its declared ones, any piece a job is built from
/// (the solver layer, the basis, the fits, the estimators, the memory check), a command run
/// through the dispatcher.
fn violations(module: &str, text: &str) -> Vec<String> {
    let mut wrong = Vec::new();
    let (jobs, pieces) = jobs_and_pieces(text);
    match COMMAND_JOBS.iter().find(|(m, _)| *m == module) {
        None => wrong.push(format!("{module}: not in COMMAND_JOBS (calls {jobs:?})")),
        Some((_, expected)) if jobs != *expected => {
            wrong.push(format!(
                "{module}: calls the jobs {jobs:?}, declared {expected:?}"
            ));
        }
        Some(_) => {}
    }
    if !pieces.is_empty() {
        wrong.push(format!(
            "{module}: calls pieces a job is built from: {pieces:?} (give the job a library \
             entry that validates, checks memory and decides defaults)"
        ));
    }
    let code = without_unit_tests(text);
    if code.contains("super::run(") || code.contains("try_parse_from") {
        wrong.push(format!("{module}: runs a command through the dispatcher"));
    }
    wrong
}

#[test]
fn a_planted_assembled_command_fails_the_check() {
    // `image`'s command file as it was before its job: the memory check and the equivalent
    // filter's weights called as pieces beside the comparison.
    let planted = "use rkwave::image::sample_weights;\n\
        use rkwave::lab::experiment::compare_methods;\n\
        pub fn run() {\n    rkwave::image::job::memory::check(&request, what, fix)?;\n    \
        let cmp = compare_methods(&scene, &sampling, &[method], &wavelet, &truth)?;\n    \
        let w = sample_weights(method, &samples, &wavelet, x, y)?;\n}\n";
    let wrong = violations("cli::image_cmd", planted);
    assert_eq!(wrong.len(), 2, "{wrong:#?}");
    assert!(
        wrong[0].contains("lab::experiment::compare_methods"),
        "{wrong:#?}"
    );
    assert!(
        wrong[1].contains("image::job::memory::check")
            && wrong[1].contains("image::sample_weights"),
        "{wrong:#?}"
    );
    // A command that runs another through the dispatcher fails too.
    let nested = "use rkwave::lab::comparison::ComparisonJob;\npub fn run() {\n    \
        let job = ComparisonJob::new(request)?;\n    super::run(&other)?;\n}\n";
    assert_eq!(violations("cli::image_cmd", nested).len(), 1);
}

/// Each command file calls the library's job entries, one per job it runs (the table
/// [`COMMAND_JOBS`]), and no piece a job is built from (the solver layer, the basis, the
/// fits, the estimators, the memory check): a command that assembles a job from pieces
/// fails here ([`a_planted_assembled_command_fails_the_check`]).
#[test]
fn each_command_file_calls_one_library_job_per_job() {
    let src = src_dir();
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut seen = BTreeSet::new();
    let mut wrong = Vec::new();
    for f in &files {
        let module = module_name(&src, f);
        if !is_command_file(&module) {
            continue;
        }
        let text = std::fs::read_to_string(f).expect("source is UTF-8");
        wrong.extend(violations(&module, &text));
        seen.insert(module);
    }
    assert!(seen.len() >= 10, "found only {} command files", seen.len());
    assert!(wrong.is_empty(), "{wrong:#?}");
}
