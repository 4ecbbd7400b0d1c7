//! The plan's files in its folder: the state as JSON (`state.json`, replaced atomically), the
//! carried solver state beside it (`gram.bin`, `pcg.bin`, and once the plan stopped the
//! stopping round's fit `final.bin`; while the plan runs the single-scale rows `rows.bin`, a
//! piece appended per call: caches, tagged with the plan and checksummed), and the commit of
//! a round (the state and the positions, both or neither).
//!
//! Beside them, `samples.bin` holds every sample the plan has read, in the order read
//! ([`ReadSamples`], a piece appended per call; not a cache): a call given only the new
//! round's samples joins them to it ([`PlanState::read_samples`]); without it, or with one
//! that is damaged or of another state, that call is refused, naming the fix (give every
//! sample so far, which writes it again: [`PlanState::keep_samples`]).
//!
//! The plan's state machine ([`crate::image::plan`]) knows no paths: it gives and takes the
//! state as JSON text and the carried solver state as bytes; this module puts them in files
//! and reads them back ([`PlanState::load`], [`PlanState::save`], [`PlanState::commit`]).
//!
//! A carried file is a cache: a missing one is silently absent (the next fit assembles or
//! starts afresh); a damaged one, or one of another plan, is set aside with a note naming the
//! file and the fault ([`CarriedGram::note`], [`CarriedPcg::note`]); one that cannot be
//! written is removed, so the next call starts afresh rather than from a stale file.

use std::path::{Path, PathBuf};

use thiserror::Error;

use super::output::{persist, temporary, write_new, OutputError};
use crate::image::adaptive::gram::GramBytesError;
use crate::image::adaptive::TreeSolver;
use crate::image::plan::new_round::ReadSamples;
use crate::image::plan::{
    CarriedFinal, CarriedGram, CarriedPcg, FinalFit, PlanState, ProtocolError, TreeGram,
};

/// The state's file name inside the plan's folder.
pub const STATE_FILE: &str = "state.json";
/// The carried normal matrix's file name inside the plan's folder.
pub const GRAM_FILE: &str = "gram.bin";
/// The carried PCG start's file name inside the plan's folder.
pub const PCG_FILE: &str = "pcg.bin";
/// The stopping round's carried fit's file name inside the plan's folder.
pub const FINAL_FILE: &str = "final.bin";
/// The file of every sample the plan has read, inside the plan's folder.
pub const SAMPLES_FILE: &str = "samples.bin";
/// The single-scale rows of the samples fitted so far, inside the plan's folder (a cache,
/// [`crate::image::plan::CarriedRows`]).
pub use crate::image::plan::ROWS_FILE;

/// Why a plan's files could not be read or written.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum PlanFileError {
    /// The folder holds no plan.
    #[error(
        "no plan in {}: {} does not exist; start a plan there first (its first call writes it)",
        .dir.display(),
        .file.display()
    )]
    NoPlan {
        /// The folder.
        dir: PathBuf,
        /// The state file looked for.
        file: PathBuf,
    },
    /// The state file could not be read.
    #[error("cannot read the plan state {}: {source}", .file.display())]
    Read {
        /// The file.
        file: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The state or the positions could not be written.
    #[error(transparent)]
    Write(#[from] OutputError),
    /// A call given only the new round's samples, but the plan's file of the samples it has
    /// read is missing, damaged or of another state of the plan.
    #[error(
        "{}: {problem}; a round given only its new samples is joined to the samples the plan \
         has read, kept there: give every sample so far instead ({}), which writes it again",
        .file.display(),
        crate::error::Fix::Set(crate::error::Param::Samples)
    )]
    SamplesNotKept {
        /// The file.
        file: PathBuf,
        /// What is wrong.
        problem: String,
    },
    /// The state read is not a plan state this build reads, or its plan refuses.
    #[error(transparent)]
    Plan(#[from] ProtocolError),
}

impl PlanFileError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            PlanFileError::NoPlan { .. } | PlanFileError::SamplesNotKept { .. } => {
                crate::error::ErrorKind::InvalidInput
            }
            PlanFileError::Read { .. } => crate::error::ErrorKind::Unreadable,
            PlanFileError::Write(e) => e.kind(),
            PlanFileError::Plan(e) => e.kind(),
        }
    }
}

crate::error::classified!(PlanFileError);

impl PlanState {
    /// The state file in the folder `dir`.
    pub fn path(dir: &Path) -> PathBuf {
        dir.join(STATE_FILE)
    }

    /// Reads the state in `dir`, with the normal matrix carried in [`GRAM_FILE`], the PCG
    /// start and diagonal in [`PCG_FILE`] and the stopping round's fit in [`FINAL_FILE`] when
    /// they are there and whole (module docs; otherwise a note says why they are not used: a
    /// damaged file, a missing [`PCG_FILE`] of a plan that has fitted rounds by PCG, a missing
    /// [`FINAL_FILE`] of a plan that has stopped).
    pub fn load(dir: &Path) -> Result<Self, PlanFileError> {
        let file = Self::path(dir);
        let text = std::fs::read_to_string(&file).map_err(|source| {
            if source.kind() == std::io::ErrorKind::NotFound {
                PlanFileError::NoPlan {
                    dir: dir.to_path_buf(),
                    file: file.clone(),
                }
            } else {
                PlanFileError::Read {
                    file: file.clone(),
                    source,
                }
            }
        })?;
        let mut state = Self::from_json(&text, &file)?;
        let tag = state.tag();
        let (gram, note) = read_carried(
            &dir.join(GRAM_FILE),
            "the normal matrix is assembled afresh (the same result, more time)",
            |bytes| TreeGram::from_bytes(bytes, tag),
        );
        state.carried = CarriedGram { gram, note };
        let n = state.basis_len()?;
        let pcg_file = dir.join(PCG_FILE);
        let (pcg, note) = read_carried(
            &pcg_file,
            "PCG starts from zero with the diagonal summed afresh (the same tolerance, more \
             iterations)",
            |bytes| CarriedPcg::from_bytes(bytes, tag, n),
        );
        state.pcg = CarriedPcg {
            note,
            ..pcg.unwrap_or_default()
        };
        let final_file = dir.join(FINAL_FILE);
        let again = "the final image is fitted again (the same tolerance, other bits than the \
                     plan's own final image)";
        let (fit, mut note) = read_carried(&final_file, again, |bytes| {
            FinalFit::from_bytes(bytes, tag, n)
        });
        if state.stop.is_some() && fit.is_none() && note.is_none() {
            note = Some(format!(
                "{}: not found, although the plan has stopped (removed, or the stopping call \
                 could not write it); {again}",
                final_file.display()
            ));
        }
        state.final_fit = CarriedFinal { fit, note };
        // a cache read whole; its pieces are checked against the samples when a round fits
        state.rows.bytes = std::fs::read(dir.join(ROWS_FILE)).ok();
        let fitted = state.progress.marked.len();
        if fitted > 0
            && matches!(state.params.fit.solver, TreeSolver::Pcg { .. })
            && state.pcg.note.is_none()
            && !pcg_file.exists()
        {
            // A plan fitted by PCG leaves its start here after every round: its absence
            // costs iterations, so it is said, as a damaged file is.
            state.pcg.note = Some(format!(
                "{}: not found, although the plan has fitted {fitted} round(s) by PCG (removed, \
                 or the last call could not write it); PCG starts from zero with the diagonal \
                 summed afresh (the same tolerance, more iterations)",
                pcg_file.display()
            ));
        }
        Ok(state)
    }

    /// Writes the state into `dir` (created if missing), replacing the previous state
    /// atomically, and the carried normal matrix and PCG start beside it.
    pub fn save(&self, dir: &Path) -> Result<(), PlanFileError> {
        let file = Self::path(dir);
        create_folder(dir, &file)?;
        write_new(&file, self.to_json().as_bytes(), true)?;
        self.write_carried(dir);
        Ok(())
    }

    /// Commits a round as one step: the state into `dir` and the positions `bytes` to
    /// `positions` (replacing an existing file only with `overwrite`), both or neither; then
    /// the carried normal matrix and PCG start (caches, [`PlanState::save`]).
    ///
    /// Both are written to temporary files beside their targets first; then the positions
    /// are moved into place (refused if the file appeared meanwhile), then the state (a
    /// rename over the previous state). When the state cannot be moved, the positions just
    /// placed are removed again: a failed commit leaves the previous state and no positions
    /// file, and the same call can be retried.
    pub fn commit(
        &self,
        dir: &Path,
        positions: &Path,
        bytes: &[u8],
        overwrite: bool,
    ) -> Result<(), PlanFileError> {
        let file = Self::path(dir);
        create_folder(dir, &file)?;
        if let Some(folder) = positions.parent().filter(|d| !d.as_os_str().is_empty()) {
            create_folder(folder, positions)?;
        }
        let state_tmp = write_temporary(&file, self.to_json().as_bytes())?;
        let positions_tmp = match write_temporary(positions, bytes) {
            Ok(t) => t,
            Err(e) => {
                let _ = std::fs::remove_file(&state_tmp);
                return Err(e.into());
            }
        };
        if let Err(e) = persist(&positions_tmp, positions, overwrite) {
            let _ = std::fs::remove_file(&state_tmp);
            return Err(e.into());
        }
        if let Err(e) = persist(&state_tmp, &file, true) {
            let _ = std::fs::remove_file(positions);
            return Err(e.into());
        }
        self.write_carried(dir);
        Ok(())
    }

    /// The samples the plan has read, from [`SAMPLES_FILE`] in `dir` (module docs): those of
    /// every round before the last handed out (of every round, once the plan has stopped),
    /// and the length of the file's bytes they fill; refused when the file is missing,
    /// damaged or not those rounds' samples. Nothing is read at round 0 (no earlier round).
    pub fn read_samples(&self, dir: &Path) -> Result<(ReadSamples, u64), PlanFileError> {
        let read = match self.stop {
            Some(_) => Some(self.round()),
            None => self.round().checked_sub(1),
        };
        let Some(through) = read else {
            return Ok((ReadSamples::default(), 0));
        };
        let file = dir.join(SAMPLES_FILE);
        let refused = |problem: String| PlanFileError::SamplesNotKept {
            file: file.clone(),
            problem,
        };
        let bytes = std::fs::read(&file).map_err(|e| {
            refused(match e.kind() {
                std::io::ErrorKind::NotFound => "not found".into(),
                _ => format!("cannot be read ({e})"),
            })
        })?;
        let (read, used) = ReadSamples::from_bytes(&bytes, self.tag(), self.plane, self, through)
            .map_err(refused)?;
        Ok((read, used as u64))
    }

    /// Keeps `all` (every sample of the round just read, `through`) in [`SAMPLES_FILE`] in
    /// `dir`: with `continued` (`(kept, dropped, used)`: `all` starts with the samples kept in
    /// the file's first `used` bytes, `kept` finite and `dropped` dropped ones), their new
    /// rows are appended as one piece; otherwise the file is written afresh (through a
    /// temporary file). A note when it could not be written (the file is then removed: a
    /// later call given only its new samples is refused, naming the fix); the round itself
    /// is committed already.
    pub fn keep_samples(
        &self,
        dir: &Path,
        all: &ReadSamples,
        continued: Option<(usize, usize, u64)>,
    ) -> Option<String> {
        let file = dir.join(SAMPLES_FILE);
        let through = all.through?;
        let tag = self.tag();
        let written = match continued {
            Some((kept, dropped, used)) => {
                append(&file, used, &all.piece_bytes(tag, through, (kept, dropped)))
            }
            None => write_new(&file, &all.piece_bytes(tag, through, (0, 0)), true)
                .map_err(|e| e.to_string()),
        };
        written.err().map(|why| {
            let _ = std::fs::remove_file(&file);
            format!(
                "{}: the samples read could not be kept ({why}); removed: a call given only \
                 its new samples will be refused until one gives every sample so far",
                file.display()
            )
        })
    }

    /// The carried normal matrix and PCG start into `dir` (module docs: caches).
    fn write_carried(&self, dir: &Path) {
        let tag = self.tag();
        write_cache(
            &dir.join(GRAM_FILE),
            self.carried.gram.as_ref().map(|g| g.to_bytes(tag)),
        );
        write_cache(&dir.join(PCG_FILE), self.pcg.to_bytes(tag));
        write_cache(
            &dir.join(FINAL_FILE),
            self.final_fit.fit.as_ref().map(|f| f.to_bytes(tag)),
        );
        // the rows: the new ones appended (or all written afresh); none kept, none left
        let rows = dir.join(ROWS_FILE);
        let written = match self.rows.piece() {
            Some((bytes, Some(at))) => append(&rows, at, bytes).is_ok(),
            Some((bytes, None)) => write_new(&rows, bytes, true).is_ok(),
            None => !self.rows.is_empty(),
        };
        if !written {
            let _ = std::fs::remove_file(&rows);
        }
    }
}

/// A carried state read from `file` by `parse`: none, silently, when there is no file; none,
/// with a note naming the file, the fault and `consequence`, when it cannot be read or parsed.
fn read_carried<T>(
    file: &Path,
    consequence: &str,
    parse: impl FnOnce(&[u8]) -> Result<T, GramBytesError>,
) -> (Option<T>, Option<String>) {
    let set_aside = |why: String| {
        (
            None,
            Some(format!("{}: {why}; {consequence}", file.display())),
        )
    };
    match std::fs::read(file) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => (None, None),
        Err(e) => set_aside(format!("cannot be read ({e})")),
        Ok(bytes) => match parse(&bytes) {
            Ok(value) => (Some(value), None),
            Err(e) => set_aside(e.to_string()),
        },
    }
}

/// Writes `bytes` to `file` (through a temporary file), or removes a stale file when there
/// are none. A cache: when it cannot be written, the file is removed and the next call
/// starts afresh.
fn write_cache(file: &Path, bytes: Option<Vec<u8>>) {
    let written = bytes.is_some_and(|b| write_new(file, &b, true).is_ok());
    if !written {
        let _ = std::fs::remove_file(file);
    }
}

/// Appends `bytes` to `file` after its first `used` bytes (a longer file's rest, a later
/// call's piece of a state since replaced, is cut first).
fn append(file: &Path, used: u64, bytes: &[u8]) -> Result<(), String> {
    use std::io::Write;
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .open(file)
        .map_err(|e| e.to_string())?;
    f.set_len(used).map_err(|e| e.to_string())?;
    std::io::Seek::seek(&mut f, std::io::SeekFrom::Start(used)).map_err(|e| e.to_string())?;
    f.write_all(bytes).map_err(|e| e.to_string())
}

/// Creates `folder` (and its parents) for the file `file`.
fn create_folder(folder: &Path, file: &Path) -> Result<(), OutputError> {
    std::fs::create_dir_all(folder).map_err(|source| OutputError::NotWritable {
        file: file.to_path_buf(),
        source,
    })
}

/// `bytes` in a fresh temporary file beside `target` (removed again if the write fails).
fn write_temporary(target: &Path, bytes: &[u8]) -> Result<PathBuf, OutputError> {
    let tmp = temporary(target);
    std::fs::write(&tmp, bytes).map_err(|source| {
        let _ = std::fs::remove_file(&tmp);
        OutputError::NotWritable {
            file: target.to_path_buf(),
            source,
        }
    })?;
    Ok(tmp)
}
