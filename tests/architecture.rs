//! The shape of the source tree, checked: no import circle between the modules of `src/`
//! and no source file over 800 lines.
//!
//! A module is a file (`a/b.rs` or `a/b/mod.rs` is `a::b`; `lib.rs` and `main.rs` are the
//! root). Module `a` depends on module `b` when `a`'s text (its inline `#[cfg(test)]`
//! modules excluded) names a path `crate::...`, `super::...` or `self::...` that resolves to
//! `b` — the longest prefix of the path that is a module. A dependency on an enclosing or an
//! enclosed module (`a::b` on `a` through `super::`, `a` on `a::b` through `self::b::`) counts
//! like any other: a parent that names its children's items and children that name the
//! parent's close a circle as surely as two siblings do. Circles are the strongly connected
//! components of more than one module (Tarjan).
//!
//! Every `use` declaration counts, `pub use` re-exports included, each path of its tree
//! (`use super::{a::X, b}` names `super::a` and `super::b`, not `super`): a path starting
//! with a child module's name (`pub use child::Item;` in `a/mod.rs`, the re-export pattern of
//! most parent modules) is an edge `a -> a::child`. A parent that re-exports a child and
//! defines items the child names closes a circle; so does a child naming a sibling's item
//! through the parent's re-export (`super::Item` resolves to the parent): the child names
//! `super::sibling::Item`, and an item the children share lives in a child of its own.
//! Not counted: a relative path in code (`child::f()` outside a `use`).

use std::collections::{BTreeMap, BTreeSet};

#[path = "common/source_tree.rs"]
mod source_tree;
use source_tree::*;

/// The longest a source file may be: one job a file.
const MAX_LINES: usize = 800;

/// The module a path from module `current` names: the longest prefix that is a module.
fn resolve(current: &str, segs: &[String], modules: &BTreeSet<String>) -> Option<String> {
    let mut base: Vec<String> = if current.is_empty() {
        Vec::new()
    } else {
        current.split("::").map(str::to_string).collect()
    };
    let mut rest = segs;
    match rest.first().map(String::as_str) {
        Some("crate") => {
            base.clear();
            rest = &rest[1..];
        }
        Some("super" | "self") => {
            while let Some(first) = rest.first() {
                match first.as_str() {
                    "super" => {
                        base.pop();
                    }
                    "self" => {}
                    _ => break,
                }
                rest = &rest[1..];
            }
        }
        _ => return None,
    }
    (0..=rest.len()).rev().find_map(|k| {
        let mut name = base.clone();
        name.extend(rest[..k].iter().cloned());
        let name = name.join("::");
        modules.contains(&name).then_some(name)
    })
}

/// The names each module brings in with `use` (`pub use` re-exports and private imports
/// alike, which its children can name as `super::Name`), each with the path it stands for:
/// `aliases["solve"]["SolveError"] = self::error::SolveError`. A path through a re-export
/// names the module that defines the item, as the compiler resolves it: `super::SolveError`
/// in `solve::compare` depends on `solve::error`, not on `solve`. Renames (`as`) and globs
/// (`*`) are not followed: such a path names the module that imports.
type Aliases = BTreeMap<String, BTreeMap<String, Vec<String>>>;

/// [`resolve`], then through the aliases of the module found (at most 8 re-exports deep).
fn resolve_through(
    current: &str,
    segs: &[String],
    modules: &BTreeSet<String>,
    aliases: &Aliases,
    depth: usize,
) -> Option<String> {
    let found = resolve(current, segs, modules)?;
    let consumed = found.split("::").filter(|s| !s.is_empty()).count();
    let absolute: Vec<String> = absolute_path(current, segs)?;
    // A path that ends at a module: not counted when written so (as before), but one
    // reached through a re-export of a module (`pub use crate::a::b;` in `c`, then
    // `c::b::Item` or `c::b`) names the module re-exported, not the one re-exporting it.
    let Some(next) = absolute.get(consumed) else {
        return (depth > 0).then_some(found);
    };
    match aliases.get(&found).and_then(|a| a.get(next)) {
        Some(target) if depth < 8 => {
            let mut path = target.clone();
            path.extend(absolute[consumed + 1..].iter().cloned());
            resolve_through(&found, &path, modules, aliases, depth + 1).or(Some(found))
        }
        _ => Some(found),
    }
}

/// `segs` from module `current` as a path from the crate's root (without `crate`).
fn absolute_path(current: &str, segs: &[String]) -> Option<Vec<String>> {
    let mut base: Vec<String> = current
        .split("::")
        .filter(|s| !s.is_empty())
        .map(str::to_string)
        .collect();
    let mut rest = segs;
    match rest.first().map(String::as_str) {
        Some("crate") => {
            base.clear();
            rest = &rest[1..];
        }
        Some("super" | "self") => {
            while let Some(first) = rest.first() {
                match first.as_str() {
                    "super" => {
                        base.pop();
                    }
                    "self" => {}
                    _ => break,
                }
                rest = &rest[1..];
            }
        }
        _ => return None,
    }
    base.extend(rest.iter().cloned());
    Some(base)
}

/// A module naming itself: not an edge. Every other path is one, between parent and child
/// modules too (`super::Item` in a child, `self::child::Item` in its parent): skipping those
/// is how a circle through a parent module (the error kinds' hub in `error/mod.rs`) went
/// unseen.
fn related(a: &str, b: &str) -> bool {
    a == b
}

/// The graph of module dependencies: with `use_declarations` false, every `crate::`,
/// `super::` and `self::` path of the text, resolved to the longest module prefix (a
/// re-export in a parent, `pub use child::X`, is not seen); with it true, also every path of
/// every `use` declaration, relative ones included, each resolved through re-exports to the
/// module that defines the item ([`resolve_through`]).
fn dependency_graph(use_declarations: bool) -> BTreeMap<String, BTreeSet<String>> {
    let src = src_dir();
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let texts: BTreeMap<String, String> = files
        .iter()
        .filter(|f| f.file_stem().is_some_and(|s| s != "tests"))
        .map(|f| {
            let text = std::fs::read_to_string(f).expect("source is UTF-8");
            (module_name(&src, f), text)
        })
        .collect();
    let modules: BTreeSet<String> = texts.keys().cloned().collect();
    let aliases: Aliases = texts
        .iter()
        .map(|(m, text)| {
            let names = use_paths(m, &without_unit_tests(text), &modules)
                .into_iter()
                .filter_map(|path| {
                    let name = path.last()?.clone();
                    (!matches!(name.as_str(), "crate" | "super" | "self")).then_some((name, path))
                })
                .collect();
            (m.clone(), names)
        })
        .collect();
    texts
        .iter()
        .map(|(m, text)| {
            let text = &without_unit_tests(text);
            let deps: BTreeSet<String> = if use_declarations {
                paths(&without_use_declarations(text))
                    .into_iter()
                    .chain(use_paths(m, text, &modules))
                    .filter_map(|segs| resolve_through(m, &segs, &modules, &aliases, 0))
                    .filter(|d| !related(m, d))
                    .collect()
            } else {
                paths(text)
                    .iter()
                    .filter_map(|segs| resolve(m, segs, &modules))
                    .filter(|d| !related(m, d))
                    .collect()
            };
            (m.clone(), deps)
        })
        .collect()
}

/// Strongly connected components with more than one module (Tarjan's algorithm).
fn circles(graph: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct State<'g> {
        graph: &'g BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<&'g str, usize>,
        low: BTreeMap<&'g str, usize>,
        stack: Vec<&'g str>,
        on_stack: BTreeSet<&'g str>,
        out: Vec<Vec<String>>,
    }
    fn visit<'g>(s: &mut State<'g>, v: &'g str) {
        let n = s.index.len();
        s.index.insert(v, n);
        s.low.insert(v, n);
        s.stack.push(v);
        s.on_stack.insert(v);
        for w in &s.graph[v] {
            let w = w.as_str();
            if !s.index.contains_key(w) {
                visit(s, w);
                let lw = s.low[w];
                let lv = s.low.get_mut(v).expect("visited");
                *lv = (*lv).min(lw);
            } else if s.on_stack.contains(w) {
                let iw = s.index[w];
                let lv = s.low.get_mut(v).expect("visited");
                *lv = (*lv).min(iw);
            }
        }
        if s.low[v] == s.index[v] {
            let mut component = Vec::new();
            while let Some(w) = s.stack.pop() {
                s.on_stack.remove(w);
                component.push(w.to_string());
                if w == v {
                    break;
                }
            }
            if component.len() > 1 {
                component.sort();
                s.out.push(component);
            }
        }
    }
    let mut s = State {
        graph,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on_stack: BTreeSet::new(),
        out: Vec::new(),
    };
    for v in graph.keys() {
        if !s.index.contains_key(v.as_str()) {
            visit(&mut s, v);
        }
    }
    s.out
}

#[test]
fn the_checker_finds_a_planted_circle_and_resolves_paths() {
    let modules: BTreeSet<String> = ["a", "a::b", "c"].iter().map(|s| s.to_string()).collect();
    let segs = |p: &str| paths(p).remove(0);
    assert_eq!(
        resolve("c", &segs("crate::a::b::Thing"), &modules).as_deref(),
        Some("a::b")
    );
    assert_eq!(
        resolve("a::b", &segs("super::super::c::f"), &modules).as_deref(),
        Some("c")
    );
    assert_eq!(
        resolve("a", &segs("self::b::X"), &modules).as_deref(),
        Some("a::b")
    );
    assert_eq!(
        expand_use_tree("super::{a::X, b::{self, c as d}, *}"),
        vec![
            vec!["super", "a", "X"],
            vec!["super", "b"],
            vec!["super", "b", "c"],
            vec!["super"],
        ]
    );
    let text = "pub use b::{X, Y};\nuse std::fmt;\npub(crate) use c::Z;\nfn f() { b::g() }\n";
    let relative: Vec<Option<String>> = use_paths("a", text, &modules)
        .iter()
        .map(|segs| resolve("a", segs, &modules))
        .collect();
    assert_eq!(relative, vec![Some("a::b".to_string()); 2]);
    let aliases: Aliases = [(
        "a".to_string(),
        [("X".to_string(), segs("self::b::X"))].into(),
    )]
    .into();
    assert_eq!(
        resolve_through("a::b", &segs("super::X"), &modules, &aliases, 0).as_deref(),
        Some("a::b"),
        "a name re-exported by the parent resolves to its defining module"
    );
    assert_eq!(
        resolve_through("c", &segs("crate::a::Y"), &modules, &aliases, 0).as_deref(),
        Some("a")
    );
    let with_tests = "use super::X;\n#[cfg(test)]\npub(crate) mod support {\n    use super::Y;\n    fn f() { g({ 1 }) }\n}\nuse super::Z;\n#[cfg(test)]\nmod tests {\n    use crate::c;\n}\n";
    let kept = without_unit_tests(with_tests);
    assert_eq!(kept.len(), with_tests.len(), "blanked, not cut");
    assert!(kept.contains("super::X") && kept.contains("super::Z"));
    assert!(!kept.contains("super::Y") && !kept.contains("crate::c"));
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    graph.insert("a".into(), ["c".to_string()].into());
    graph.insert("a::b".into(), BTreeSet::new());
    graph.insert("c".into(), ["a".to_string()].into());
    assert_eq!(
        circles(&graph),
        vec![vec!["a".to_string(), "c".to_string()]]
    );
}

/// The circles of `graph`, each with its edges, one a line.
fn describe(graph: &BTreeMap<String, BTreeSet<String>>, found: &[Vec<String>]) -> String {
    found
        .iter()
        .map(|c| {
            let edges: Vec<String> = c
                .iter()
                .flat_map(|a| {
                    graph[a]
                        .iter()
                        .filter(|b| c.contains(b))
                        .map(move |b| format!("{a} -> {b}"))
                })
                .collect();
            format!("{{{}}}: {}", c.join(", "), edges.join("; "))
        })
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn no_import_circle_between_modules() {
    let graph = dependency_graph(false);
    assert!(
        graph.len() > 50,
        "read only {} modules of src/",
        graph.len()
    );
    let found = circles(&graph);
    assert!(
        found.is_empty(),
        "import circles:\n{}",
        describe(&graph, &found)
    );
}

/// With every `use` declaration counted, `pub use` re-exports included: no circle. A parent
/// module that defines items its children use and re-exports those children would close one:
/// such items live in a child of their own (`basis/error.rs`, `image/types.rs`, ...), the
/// parent re-exporting them. The circles are printed.
#[test]
fn use_declarations_close_no_circle() {
    let graph = dependency_graph(true);
    let found = circles(&graph);
    assert!(
        found.is_empty(),
        "import circles with re-exports counted:\n{}",
        describe(&graph, &found)
    );
}

#[test]
fn no_source_file_over_800_lines() {
    let mut files = Vec::new();
    rust_files(&src_dir(), &mut files);
    let long: Vec<String> = files
        .iter()
        .filter_map(|f| {
            let n = std::fs::read_to_string(f)
                .expect("source is UTF-8")
                .lines()
                .count();
            (n > MAX_LINES).then(|| format!("{} ({n} lines)", f.display()))
        })
        .collect();
    assert!(long.is_empty(), "files over {MAX_LINES} lines: {long:?}");
}

/// A command file parses, calls the library and prints; it never calls or imports another
/// command file (shared arguments live in `cli/*_args.rs`, shared printing in the library or
/// a `cli` helper): every path of its text, `use` declarations included, is counted.
#[test]
fn no_command_file_imports_another() {
    let graph = dependency_graph(true);
    let commands: Vec<&String> = graph.keys().filter(|m| is_command_file(m)).collect();
    assert!(
        commands.len() >= 10,
        "found only {} command files: {commands:?}",
        commands.len()
    );
    let calls: Vec<String> = commands
        .iter()
        .flat_map(|m| {
            graph[*m]
                .iter()
                .filter(|d| is_command_file(d))
                .map(move |d| format!("{m} -> {d}"))
        })
        .collect();
    assert!(
        calls.is_empty(),
        "command files using command files: {calls:?}"
    );
}

/// One rounds driver (`adaptive::rounds`) for both dimensions: the 1D refiner's round
/// (`refine::refiner`) and the image plane's (`image::adaptive::refiner::step`) both use it,
/// and no file of either refiner decides a stop for the tolerance, the depth limit or the
/// resolution of `f64` on its own (those reasons come from the driver's stop test only).
#[test]
fn both_dimensions_round_through_one_driver() {
    let graph = dependency_graph(true);
    for round in ["refine::refiner", "image::adaptive::refiner::step"] {
        let deps = graph
            .get(round)
            .unwrap_or_else(|| panic!("module {round} not found"));
        assert!(
            deps.contains("adaptive::rounds"),
            "{round} does not use the rounds driver adaptive::rounds: {deps:?}"
        );
    }
    let mut files = Vec::new();
    rust_files(&src_dir().join("refine"), &mut files);
    rust_files(&src_dir().join("image").join("adaptive"), &mut files);
    assert!(files.len() > 20, "read only {} files", files.len());
    let own: Vec<String> = files
        .iter()
        .flat_map(|f| {
            let text = without_unit_tests(&std::fs::read_to_string(f).expect("UTF-8"));
            ["Tolerance", "DepthLimit", "Resolution"]
                .into_iter()
                .filter(move |r| text.contains(&format!("StopReason::{r}")))
                .map(move |r| format!("{} decides StopReason::{r}", f.display()))
        })
        .collect();
    assert!(own.is_empty(), "stops decided outside the driver: {own:?}");
}
