//! The `rkwave` binary from the outside: run it with arguments, read its standard output and
//! error and its exit code (0 success, 1 a failure of the machine, 2 a user error, never a
//! panic), and scratch folders for its input and output files that are removed when the
//! test is done with them.

use std::ffi::OsStr;
use std::ops::Deref;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// The binary this test run built, as a command to add arguments, a folder or its standard
/// streams to: every test starts `rkwave` through this.
pub fn command() -> Command {
    Command::new(env!("CARGO_BIN_EXE_rkwave"))
}

/// Runs the binary with `args` and waits for it.
pub fn rkwave<S: AsRef<OsStr>>(args: &[S]) -> Output {
    command().args(args).output().expect("binary runs")
}

/// Standard output and standard error together.
pub fn text(out: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// A successful run (exit code 0); returns everything printed.
#[track_caller]
pub fn succeeds<S: AsRef<OsStr> + std::fmt::Debug>(args: &[S]) -> String {
    let out = rkwave(args);
    let all = text(&out);
    assert!(out.status.success(), "{args:?}: {all}");
    all
}

/// A user error: exit code 2 and no panic; returns everything printed.
#[track_caller]
pub fn user_error<S: AsRef<OsStr> + std::fmt::Debug>(args: &[S]) -> String {
    let out = rkwave(args);
    let all = text(&out);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {all}");
    assert!(!all.contains("panicked"), "{args:?}: {all}");
    all
}

/// Runs the binary with `args` in the temporary directory, standard output discarded, and
/// kills it after `limit`: the exit code (-1 for a signal) and standard error, or `None` if
/// it had to be killed.
pub fn rkwave_bounded<S: AsRef<OsStr>>(args: &[S], limit: Duration) -> Option<(i32, String)> {
    let mut child = command()
        .args(args)
        .current_dir(std::env::temp_dir())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("binary starts");
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().expect("wait") {
            let mut err = String::new();
            use std::io::Read;
            if let Some(mut e) = child.stderr.take() {
                let _ = e.read_to_string(&mut err);
            }
            return Some((status.code().unwrap_or(-1), err));
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            return None;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// A fresh, empty folder in the temporary directory, removed with everything in it when the
/// value is dropped (at the end of the test, or when it panics). Derefs to its [`Path`].
#[derive(Debug)]
pub struct Scratch(PathBuf);

impl Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A fresh, empty folder `rkwave-<prefix>-<pid>-<name>` in the temporary directory (the pid
/// keeps concurrent test binaries apart, `prefix` and `name` the tests of one binary).
pub fn scratch(prefix: &str, name: &str) -> Scratch {
    let d = std::env::temp_dir().join(format!("rkwave-{prefix}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    Scratch(d)
}

/// Writes `text` to `path` and returns the path as a string argument.
pub fn write(path: &Path, text: &str) -> String {
    std::fs::write(path, text).unwrap();
    path.to_str().unwrap().to_string()
}
