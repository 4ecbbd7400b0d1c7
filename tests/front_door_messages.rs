//! Library messages name parameters, never command-line flags: a string literal in the
//! library's source (everything under `src/` but the command line, `src/cli/` and
//! `src/main.rs`; comments and unit tests aside) that contains `--word` is a message a library
//! or Python user would read with a flag they cannot type. The library names the parameter as
//! a typed fix (`rkwave::error::Fix`), which each front end spells (`--rho`, `rho=`).

use std::path::Path;

/// Literals that may name a flag, each with why: `(file below src/, flag)`.
const ALLOWED: [(&str, &str, &str); 1] = [(
    "image/scene/parse.rs",
    "--features",
    "a cargo flag: how to rebuild the crate, not a parameter of a call",
)];

#[path = "common/source_tree.rs"]
mod source_tree;
use source_tree::rust_files;

/// `text` without its comments (`//` to the end of the line, outside string literals) and its
/// inline unit tests (from `#[cfg(test)] mod tests {`).
fn code(text: &str) -> String {
    let text = match text.find("#[cfg(test)]\nmod tests {") {
        Some(i) => &text[..i],
        None => text,
    };
    let mut out = String::with_capacity(text.len());
    let mut chars = text.chars().peekable();
    let mut in_string = false;
    while let Some(c) = chars.next() {
        if in_string {
            out.push(c);
            if c == '\\' {
                out.extend(chars.next());
            } else if c == '"' {
                in_string = false;
            }
        } else if c == '/' && chars.peek() == Some(&'/') {
            for c in chars.by_ref() {
                if c == '\n' {
                    out.push('\n');
                    break;
                }
            }
        } else if c == '\'' {
            // A char literal holding a quote (`'"'` or `'\"'`) must not open a string: it is
            // written as `'_'`. A lifetime or another char literal is copied as it is.
            out.push(c);
            let rest: String = chars.clone().take(3).collect();
            let skip = if rest.starts_with("\"'") {
                1
            } else if rest.starts_with("\\\"'") {
                2
            } else {
                0
            };
            if skip > 0 {
                chars.by_ref().take(skip).for_each(drop);
                out.push('_');
            }
        } else {
            if c == '"' {
                in_string = true;
            }
            out.push(c);
        }
    }
    out
}

/// The string literals of `code` (text between unescaped double quotes).
fn literals(code: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut chars = code.chars();
    while let Some(c) = chars.next() {
        if c != '"' {
            continue;
        }
        let mut lit = String::new();
        while let Some(c) = chars.next() {
            match c {
                '\\' => {
                    lit.push(c);
                    lit.extend(chars.next());
                }
                '"' => break,
                c => lit.push(c),
            }
        }
        out.push(lit);
    }
    out
}

/// The flags `--word` (a letter after the dashes, not inside a longer word) in `text`.
fn flags(text: &str) -> Vec<String> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    for i in 0..b.len().saturating_sub(2) {
        let before_ok = i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'-');
        if before_ok && b[i] == b'-' && b[i + 1] == b'-' && b[i + 2].is_ascii_lowercase() {
            let end = (i + 2..b.len())
                .find(|&j| !(b[j].is_ascii_lowercase() || b[j] == b'-'))
                .unwrap_or(b.len());
            out.push(text[i..end].to_string());
        }
    }
    out
}

#[test]
fn the_scanner_finds_flags_in_literals_only() {
    let text = "// --comment\nlet a = \"use --rho 2\"; let b = '\"'; let c = \"x--y, -- z\";\n\
                #[cfg(test)]\nmod tests {\n\"--tested\"\n}";
    let lits = literals(&code(text));
    assert_eq!(lits, ["use --rho 2", "x--y, -- z"]);
    assert_eq!(flags(&lits[0]), ["--rho"]);
    assert!(flags(&lits[1]).is_empty());
}

#[test]
fn no_library_message_names_a_flag() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut found = Vec::new();
    for file in &files {
        let rel = file.strip_prefix(&src).expect("below src/");
        let rel = rel.to_string_lossy().replace('\\', "/");
        if rel.starts_with("cli/") || rel == "main.rs" || rel.ends_with("tests.rs") {
            continue;
        }
        let text = std::fs::read_to_string(file).expect("source is UTF-8");
        for lit in literals(&code(&text)) {
            for flag in flags(&lit) {
                let allowed = ALLOWED.iter().any(|(f, g, _)| *f == rel && *g == flag);
                if !allowed {
                    found.push(format!("{rel}: {flag} in \"{lit}\""));
                }
            }
        }
    }
    assert!(files.len() > 100, "read only {} files of src/", files.len());
    assert!(
        found.is_empty(),
        "library messages naming a flag (name the parameter as a rkwave::error::Fix):\n{}",
        found.join("\n")
    );
}
