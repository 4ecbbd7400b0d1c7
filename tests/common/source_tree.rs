//! Reading `src/` as text for the architecture tests (`tests/architecture*.rs`): the source
//! files and their module names, the `use` declarations and their paths, the text without
//! inline unit tests. Included by each architecture test with `#[path]`.
#![allow(dead_code)]

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

pub fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("src/ is readable") {
        let path = entry.expect("directory entry").path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

pub fn src_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

/// `src/a/b.rs` and `src/a/b/mod.rs` -> `a::b`; `src/lib.rs`, `src/main.rs` -> ``.
pub fn module_name(src: &Path, file: &Path) -> String {
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

/// The text of a file without its inline test modules (tests may reach anywhere): every
/// `#[cfg(test)]` module written inline (`mod tests { ... }`, `pub(crate) mod test_support {
/// ... }`) is blanked from its attribute to its closing brace (braces counted; the text after
/// it is read). A test module in its own file (`mod tests;`) is skipped as a file
/// (`tests.rs`).
pub fn without_unit_tests(text: &str) -> String {
    let mut bytes = text.as_bytes().to_vec();
    let mut from = 0;
    while let Some(found) = text[from..].find("#[cfg(test)]") {
        let start = from + found;
        let after = &text[start + "#[cfg(test)]".len()..];
        let item = after.trim_start();
        let item = item.strip_prefix("pub(crate) ").unwrap_or(item);
        let item = item.strip_prefix("pub ").unwrap_or(item);
        let inline_module = item.strip_prefix("mod ").is_some_and(|rest| {
            let head = rest.split(['{', ';']).next().unwrap_or("");
            head.trim()
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_')
                && rest[head.len()..].starts_with('{')
        });
        from = start + 1;
        if !inline_module {
            continue;
        }
        let Some(open) = text[start..].find('{').map(|k| start + k) else {
            break;
        };
        let mut depth = 0usize;
        let mut end = text.len();
        for (k, b) in text.as_bytes()[open..].iter().enumerate() {
            match b {
                b'{' => depth += 1,
                b'}' => {
                    depth -= 1;
                    if depth == 0 {
                        end = open + k + 1;
                        break;
                    }
                }
                _ => {}
            }
        }
        for byte in &mut bytes[start..end] {
            if *byte != b'\n' {
                *byte = b' ';
            }
        }
        from = end;
    }
    String::from_utf8(bytes).expect("only ASCII spaces were written")
}

/// Every `crate::`, `super::` or `self::` path in `text`, as its `::`-separated segments.
pub fn paths(text: &str) -> Vec<Vec<String>> {
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

/// The byte ranges of the `use` declarations of `text` (`use ...;`, `pub use ...;`,
/// `pub(crate) use ...;`, at the start of a line).
pub fn use_declarations(text: &str) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut line_start = 0;
    for line in text.split_inclusive('\n') {
        let trimmed = line.trim_start();
        let offset = line_start + (line.len() - trimmed.len());
        let rest = match trimmed.strip_prefix("pub") {
            Some(r) if r.starts_with('(') => r.find(')').map(|k| r[k + 1..].trim_start()),
            Some(r) => Some(r.trim_start()),
            None => Some(trimmed),
        };
        if let Some(r) = rest {
            if let Some(tree) = r.strip_prefix("use ") {
                let start = offset + (trimmed.len() - tree.len());
                if let Some(end) = text[start..].find(';') {
                    out.push((start, start + end));
                }
            }
        }
        line_start += line.len();
    }
    out
}

/// Every path of a use tree (`a::{b, c::{d, e}}` -> `a::b`, `a::c::d`, `a::c::e`; `self`
/// inside braces names the prefix; `as` renames and `*` are dropped).
pub fn expand_use_tree(tree: &str) -> Vec<Vec<String>> {
    fn expand(prefix: &[String], tree: &str, out: &mut Vec<Vec<String>>) {
        let tree = tree.trim();
        if tree.is_empty() {
            return;
        }
        let (head, group) = match tree.find('{') {
            Some(open) => {
                let close = tree.rfind('}').unwrap_or(tree.len());
                (&tree[..open], Some(&tree[open + 1..close]))
            }
            None => (tree, None),
        };
        let head = head.split(" as ").next().unwrap_or("");
        let mut path = prefix.to_vec();
        path.extend(
            head.split("::")
                .map(str::trim)
                .filter(|s| !s.is_empty() && *s != "*" && (*s != "self" || prefix.is_empty()))
                .map(str::to_string),
        );
        match group {
            None => out.push(path),
            Some(group) => {
                let mut depth = 0;
                let mut start = 0;
                for (k, c) in group.char_indices() {
                    match c {
                        '{' => depth += 1,
                        '}' => depth -= 1,
                        ',' if depth == 0 => {
                            expand(&path, &group[start..k], out);
                            start = k + 1;
                        }
                        _ => {}
                    }
                }
                expand(&path, &group[start..], out);
            }
        }
    }
    let mut out = Vec::new();
    expand(&[], tree, &mut out);
    out.retain(|p| !p.is_empty());
    out
}

/// The paths of `module`'s `use` declarations as [`resolve`] reads them: a path starting
/// with a child module's name becomes `self::child::...`; one starting with anything else
/// (an external crate, `std`) is not a module of `src/` and is dropped.
pub fn use_paths(module: &str, text: &str, modules: &BTreeSet<String>) -> Vec<Vec<String>> {
    use_declarations(text)
        .into_iter()
        .flat_map(|(a, b)| expand_use_tree(&text[a..b]))
        .filter_map(|mut path| match path[0].as_str() {
            "crate" | "super" | "self" => Some(path),
            first => {
                let child = if module.is_empty() {
                    first.to_string()
                } else {
                    format!("{module}::{first}")
                };
                modules.contains(&child).then(|| {
                    path.insert(0, "self".to_string());
                    path
                })
            }
        })
        .collect()
}

/// `text` with its `use` declarations blanked (they are read by [`use_paths`]).
pub fn without_use_declarations(text: &str) -> String {
    let mut bytes = text.as_bytes().to_vec();
    for (a, b) in use_declarations(text) {
        for byte in &mut bytes[a..b] {
            *byte = b' ';
        }
    }
    String::from_utf8(bytes).expect("only ASCII spaces were written")
}

/// The command files of the command line: `src/cli/*_cmd.rs` and `src/cli/demo.rs`, each the
/// `run` of one command (`cli::run` dispatches to them).
pub fn is_command_file(module: &str) -> bool {
    module
        .strip_prefix("cli::")
        .is_some_and(|name| !name.contains("::") && (name.ends_with("_cmd") || name == "demo"))
}
