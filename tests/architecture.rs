//! The shape of the source tree, checked: no import circle between the modules of `src/`
//! and no source file over 800 lines.
//!
//! A module is a file (`a/b.rs` or `a/b/mod.rs` is `a::b`; `lib.rs` and `main.rs` are the
//! root). Module `a` depends on module `b` when `a`'s text (its `#[cfg(test)] mod tests`
//! block excluded) names a path `crate::...`, `super::...` or `self::...` that resolves to
//! `b` — the longest prefix of the path that is a module. A dependency on an enclosing or an
//! enclosed module (`a::b` on `a` through `super::`, `a` on `a::b` through `self::b::`) counts
//! like any other: a parent that names its children's items and children that name the
//! parent's close a circle as surely as two siblings do. Circles are the strongly connected
//! components of more than one module (Tarjan).
//!
//! Not counted yet: a relative path into a child (`pub use child::Item;` in `a/mod.rs`), the
//! re-export pattern most parent modules use; counting those too finds the parent-child
//! circles of every module that both re-exports a child and defines items the child uses.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The longest a source file may be: one job a file.
const MAX_LINES: usize = 800;

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("src/ is readable") {
        let path = entry.expect("directory entry").path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

fn src_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

/// `src/a/b.rs` and `src/a/b/mod.rs` -> `a::b`; `src/lib.rs`, `src/main.rs` -> ``.
fn module_name(src: &Path, file: &Path) -> String {
    let rel = file
        .strip_prefix(src)
        .expect("file below src/")
        .with_extension("");
    let mut parts: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if matches!(
        parts.last().map(String::as_str),
        Some("mod" | "lib" | "main")
    ) {
        parts.pop();
    }
    parts.join("::")
}

/// The text of a file without its inline unit-test module (tests may reach anywhere): cut
/// at `#[cfg(test)] mod tests {`. A test module in its own file (`mod tests;`) is skipped as
/// a file (`tests.rs`), and the text after its declaration is read.
fn without_unit_tests(text: &str) -> &str {
    match text.find("#[cfg(test)]\nmod tests {") {
        Some(i) => &text[..i],
        None => text,
    }
}

/// Every `crate::`, `super::` or `self::` path in `text`, as its `::`-separated segments.
fn paths(text: &str) -> Vec<Vec<String>> {
    let bytes = text.as_bytes();
    let is_ident = |b: u8| b.is_ascii_alphanumeric() || b == b'_';
    let mut out = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let starts_word = i == 0 || !is_ident(bytes[i - 1]);
        let head = ["crate::", "super::", "self::"]
            .into_iter()
            .find(|h| starts_word && bytes[i..].starts_with(h.as_bytes()));
        let Some(_) = head else {
            i += 1;
            continue;
        };
        let mut segs = Vec::new();
        let mut j = i;
        loop {
            let s = j;
            while j < bytes.len() && is_ident(bytes[j]) {
                j += 1;
            }
            if s == j {
                break;
            }
            segs.push(text[s..j].to_string());
            if bytes[j..].starts_with(b"::") {
                j += 2;
            } else {
                break;
            }
        }
        i = j.max(i + 1);
        out.push(segs);
    }
    out
}

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

/// A module naming itself: not an edge. Every other path is one, between parent and child
/// modules too (`super::Item` in a child, `self::child::Item` in its parent): skipping those
/// is how a circle through a parent module (the error kinds' hub in `error/mod.rs`) went
/// unseen.
fn related(a: &str, b: &str) -> bool {
    a == b
}

fn dependency_graph() -> BTreeMap<String, BTreeSet<String>> {
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
    texts
        .iter()
        .map(|(m, text)| {
            let deps = paths(without_unit_tests(text))
                .iter()
                .filter_map(|segs| resolve(m, segs, &modules))
                .filter(|d| !related(m, d))
                .collect();
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
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    graph.insert("a".into(), ["c".to_string()].into());
    graph.insert("a::b".into(), BTreeSet::new());
    graph.insert("c".into(), ["a".to_string()].into());
    assert_eq!(
        circles(&graph),
        vec![vec!["a".to_string(), "c".to_string()]]
    );
}

#[test]
fn no_import_circle_between_modules() {
    let graph = dependency_graph();
    assert!(
        graph.len() > 50,
        "read only {} modules of src/",
        graph.len()
    );
    let found = circles(&graph);
    let described: Vec<String> = found
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
        .collect();
    assert!(
        found.is_empty(),
        "import circles:\n{}",
        described.join("\n")
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
