//! Output files that never clobber: checked before any computation, written to a temporary
//! file beside the target and moved into place at the end.
//!
//! - [`check_output`]: before computing, refuses an output that exists (unless overwriting
//!   is allowed), that is one of the inputs (compared after resolving symbolic links and
//!   path spellings), or whose directory cannot take a new file;
//! - [`write_new`]: writes the bytes to `.NAME.rkwave-PID-N.tmp` in the target's directory,
//!   then moves it into place: without overwrite by a hard link, which the operating system
//!   refuses atomically if the target appeared in the meantime; with overwrite by a rename
//!   (atomic on one file system). A failed write never leaves a partial target behind.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use thiserror::Error;

/// Why an output cannot be written.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum OutputError {
    /// The output exists and overwriting was not allowed.
    #[error(
        "`{}` exists: allow overwriting ({}) or choose another path",
        .file.display(),
        crate::error::Fix::Set(crate::error::Param::Overwrite)
    )]
    Exists {
        /// The output.
        file: PathBuf,
    },
    /// The output appeared while the result was computed.
    #[error(
        "`{}` appeared while the result was computed and was left alone: allow overwriting \
         ({}) or choose another path",
        .file.display(),
        crate::error::Fix::Set(crate::error::Param::Overwrite)
    )]
    Appeared {
        /// The output.
        file: PathBuf,
    },
    /// The output is one of the inputs.
    #[error(
        "the output `{}` is the input `{}` (the same file): writing would destroy the input; \
         choose another output path",
        .output.display(),
        .input.display()
    )]
    SameFile {
        /// The output as given.
        output: PathBuf,
        /// The input as given.
        input: PathBuf,
    },
    /// The directory does not exist or refuses a new file.
    #[error(
        "cannot write `{}`: {source}; check that the directory exists and is writable",
        .file.display()
    )]
    NotWritable {
        /// The output.
        file: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
}

static COUNTER: AtomicUsize = AtomicUsize::new(0);

/// The directory a path's file lives in (`.` for a bare name).
fn directory(path: &Path) -> PathBuf {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// A fresh temporary name beside `path`.
pub(crate) fn temporary(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".into());
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    directory(path).join(format!(".{name}.rkwave-{}-{n}.tmp", std::process::id()))
}

/// The canonical form of a path that may not exist yet: its directory resolved, its name
/// kept (a symbolic link at the name itself is resolved too).
fn canonical(path: &Path) -> Option<PathBuf> {
    if let Ok(c) = std::fs::canonicalize(path) {
        return Some(c);
    }
    let dir = std::fs::canonicalize(directory(path)).ok()?;
    Some(dir.join(path.file_name()?))
}

/// Whether two paths name the same file (after symbolic links and spellings; on Unix also
/// hard links, by device and inode).
pub fn same_file(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if let (Ok(ma), Ok(mb)) = (std::fs::metadata(a), std::fs::metadata(b)) {
            return ma.dev() == mb.dev() && ma.ino() == mb.ino();
        }
    }
    matches!((canonical(a), canonical(b)), (Some(x), Some(y)) if x == y)
}

/// Checks an output before anything is computed: not one of `inputs`, not existing unless
/// `overwrite`, and its directory takes a new file (probed by creating and removing a
/// temporary file there).
pub fn check_output(path: &Path, overwrite: bool, inputs: &[&Path]) -> Result<(), OutputError> {
    if let Some(input) = inputs.iter().find(|i| same_file(path, i)) {
        return Err(OutputError::SameFile {
            output: path.to_path_buf(),
            input: input.to_path_buf(),
        });
    }
    if path.is_dir() {
        return Err(OutputError::NotWritable {
            file: path.to_path_buf(),
            source: std::io::Error::new(std::io::ErrorKind::IsADirectory, "it is a directory"),
        });
    }
    if !overwrite && std::fs::symlink_metadata(path).is_ok() {
        return Err(OutputError::Exists {
            file: path.to_path_buf(),
        });
    }
    let probe = temporary(path);
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
        .map_err(|source| OutputError::NotWritable {
            file: path.to_path_buf(),
            source,
        })?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// Writes `bytes` to `path` through a temporary file beside it; without `overwrite`, refuses
/// (and leaves alone) a target that exists by the time the file is moved into place.
pub fn write_new(path: &Path, bytes: &[u8], overwrite: bool) -> Result<(), OutputError> {
    let tmp = temporary(path);
    let not_writable = |source| OutputError::NotWritable {
        file: path.to_path_buf(),
        source,
    };
    std::fs::write(&tmp, bytes).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        not_writable(e)
    })?;
    persist(&tmp, path, overwrite)
}

/// Moves a finished temporary file `tmp` (in the target's directory) to `path`, with the
/// rule of [`write_new`]; `tmp` is removed in every case.
pub fn persist(tmp: &Path, path: &Path, overwrite: bool) -> Result<(), OutputError> {
    let result = if overwrite {
        std::fs::rename(tmp, path).map_err(|source| OutputError::NotWritable {
            file: path.to_path_buf(),
            source,
        })
    } else {
        match std::fs::hard_link(tmp, path) {
            Ok(()) => Ok(()),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Err(OutputError::Appeared {
                file: path.to_path_buf(),
            }),
            // File systems without hard links: the check and the rename are separate steps.
            Err(_) if std::fs::symlink_metadata(path).is_ok() => Err(OutputError::Appeared {
                file: path.to_path_buf(),
            }),
            Err(_) => std::fs::rename(tmp, path).map_err(|source| OutputError::NotWritable {
                file: path.to_path_buf(),
                source,
            }),
        }
    };
    let _ = std::fs::remove_file(tmp);
    result
}

impl OutputError {
    /// The kind of this error ([`crate::error`]): always `ErrorKind::OutputRefused`.
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            OutputError::Exists { .. }
            | OutputError::Appeared { .. }
            | OutputError::SameFile { .. }
            | OutputError::NotWritable { .. } => crate::error::ErrorKind::OutputRefused,
        }
    }
}

crate::error::classified!(OutputError);

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("rkwave-output-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn a_target_that_appears_is_left_alone() {
        let d = scratch("appear");
        let out = d.join("out.csv");
        check_output(&out, false, &[]).unwrap();
        std::fs::write(&out, b"precious").unwrap();
        assert!(matches!(
            write_new(&out, b"new", false),
            Err(OutputError::Appeared { .. })
        ));
        assert_eq!(std::fs::read(&out).unwrap(), b"precious");
        write_new(&out, b"new", true).unwrap();
        assert_eq!(std::fs::read(&out).unwrap(), b"new");
        // no temporary file is left behind
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 1);
    }

    #[test]
    fn the_input_is_recognised_through_spellings_and_links() {
        let d = scratch("same");
        let input = d.join("in.csv");
        std::fs::write(&input, b"x,y\n").unwrap();
        let spelled = d.join(".").join("in.csv");
        assert!(matches!(
            check_output(&spelled, true, &[&input]),
            Err(OutputError::SameFile { .. })
        ));
        #[cfg(unix)]
        {
            let link = d.join("link.csv");
            std::os::unix::fs::symlink(&input, &link).unwrap();
            assert!(matches!(
                check_output(&link, true, &[&input]),
                Err(OutputError::SameFile { .. })
            ));
        }
        assert!(matches!(
            check_output(&d.join("missing").join("o.csv"), true, &[]),
            Err(OutputError::NotWritable { .. })
        ));
        check_output(&d.join("other.csv"), false, &[&input]).unwrap();
    }
}
