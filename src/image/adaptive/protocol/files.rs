//! The plan's files: the state as JSON in its folder (`state.json`, replaced atomically) and
//! the carried solver state beside it (`gram.bin`, `pcg.bin`: caches, tagged with the plan),
//! and the commit of a round (the state and the positions, both or neither).

use std::path::{Path, PathBuf};

use super::super::mix64;
use super::super::refiner::ImagePlan;
use super::super::{AdaptiveError, TreeSolver};
use super::{
    CarriedGram, CarriedPcg, PlanState, ProtocolError, GRAM_FILE, PCG_FILE, STATE_FILE,
    STATE_VERSION,
};
use crate::io::output::{persist, temporary, write_new, OutputError};

impl PlanState {
    /// The state as JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("a plan state serialises")
    }

    /// Parses a state written by [`PlanState::to_json`] (`file` names it in errors), checking
    /// its format, version and history against its own parameters.
    pub fn from_json(text: &str, file: &Path) -> Result<Self, ProtocolError> {
        let state: Self = serde_json::from_str(text).map_err(|e| ProtocolError::State {
            file: file.to_path_buf(),
            problem: e.to_string(),
        })?;
        state.check_layout(file)?;
        ImagePlan::resume(state.plane, &state.params, state.progress.clone()).map_err(|e| {
            match e {
                // A memory limit below the plan's budget is no fault of the state.
                AdaptiveError::Resource(e) => ProtocolError::Adaptive(e.into()),
                e => ProtocolError::State {
                    file: file.to_path_buf(),
                    problem: e.to_string(),
                },
            }
        })?;
        Ok(state)
    }

    /// The state file in the directory `dir`.
    pub fn path(dir: &Path) -> PathBuf {
        dir.join(STATE_FILE)
    }

    /// Reads the state in `dir`, with the normal matrix carried in [`GRAM_FILE`] and the PCG
    /// start and diagonal in [`PCG_FILE`] when they are there and whole (module docs;
    /// otherwise a note says why they are not used: a damaged file, or a missing
    /// [`PCG_FILE`] of a plan that has fitted rounds by PCG).
    pub fn load(dir: &Path) -> Result<Self, ProtocolError> {
        let file = Self::path(dir);
        let text = std::fs::read_to_string(&file).map_err(|source| ProtocolError::Read {
            file: file.clone(),
            source,
        })?;
        let mut state = Self::from_json(&text, &file)?;
        state.carried = CarriedGram::read(&dir.join(GRAM_FILE), state.tag());
        let n = ImagePlan::new(state.plane, &state.params)?
            .tree()
            .basis()
            .len();
        let pcg_file = dir.join(PCG_FILE);
        state.pcg = CarriedPcg::read(&pcg_file, state.tag(), n);
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

    /// The tag of this plan's carried normal matrix: a hash of the state's version, plane
    /// and parameters (a matrix of another plan is not continued).
    pub fn tag(&self) -> u64 {
        let params = serde_json::to_string(&self.params).expect("parameters serialise");
        format!("{}/{}/{params}", STATE_VERSION, self.plane)
            .bytes()
            .fold(0u64, |h, b| mix64(h ^ u64::from(b)))
    }

    /// Writes the state into `dir` (created if missing), replacing the previous state
    /// atomically, and the carried normal matrix and PCG start beside it.
    pub fn save(&self, dir: &Path) -> Result<(), ProtocolError> {
        let file = Self::path(dir);
        create_folder(dir, &file)?;
        write_new(&file, self.to_json().as_bytes(), true)?;
        self.carried.write(&dir.join(GRAM_FILE), self.tag());
        self.pcg.write(&dir.join(PCG_FILE), self.tag());
        Ok(())
    }

    /// Commits a round as one step: the state into `dir` and the positions `bytes` to
    /// `positions` (replacing an existing file only with `overwrite`), both or neither; then
    /// the carried normal matrix (a cache, [`PlanState::save`]).
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
    ) -> Result<(), ProtocolError> {
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
        self.carried.write(&dir.join(GRAM_FILE), self.tag());
        self.pcg.write(&dir.join(PCG_FILE), self.tag());
        Ok(())
    }
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
