//! Scaffolding shared by the integration tests that run the `rkwave` binary: run it, read
//! its output, expect a user error, scratch folders and files.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the binary with `args`.
pub fn rkwave(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rkwave"))
        .args(args)
        .output()
        .expect("binary runs")
}

/// Standard output and standard error together.
pub fn text(out: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// A user error: exit code 2 and no panic; returns everything printed.
#[track_caller]
pub fn user_error(args: &[&str]) -> String {
    let out = rkwave(args);
    let all = text(&out);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {all}");
    assert!(!all.contains("panicked"), "{args:?}: {all}");
    all
}

/// A fresh, empty folder `rkwave-<prefix>-<pid>-<name>` in the temporary directory.
pub fn scratch(prefix: &str, name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("rkwave-{prefix}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Writes `text` to `path` and returns the path as a string argument.
pub fn write(path: &Path, text: &str) -> String {
    std::fs::write(path, text).unwrap();
    path.to_str().unwrap().to_string()
}
