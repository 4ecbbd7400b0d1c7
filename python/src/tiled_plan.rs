//! The plan behind `rkwave.Plan`: untiled (the library's [`PlanState`]) or on tiles
//! (`Plan(tile=..., halo=...)`: the library's [`TiledPlanState`], the job `rkwave plan --tile`
//! drives, with the same refusals: a bad grid names `tile=` or `halo=`, samples that are not
//! the positions handed out are refused with what was expected).

use std::path::Path;

use rkwave::image::adaptive::SamplePositions;
use rkwave::image::job::tiled_plan::{
    TiledPlanError, TiledPlanOptions, TiledPlanStart, TiledPlanState, TiledStep, TILED_STATE_FILE,
};
use rkwave::image::job::PlanOptions;
use rkwave::image::plan::PlanState;
use rkwave::image::ImagePlane;
use rkwave::io::output::write_new;
use rkwave::io::plan_files::PlanFileError;

/// Why a plan could not be read back.
pub enum LoadError {
    /// The untiled state, or a file that could not be read.
    Untiled(PlanFileError),
    /// The tiled state.
    Tiled(TiledPlanError),
}

impl LoadError {
    /// The Python exception of its kind.
    pub fn into_py(self) -> pyo3::PyErr {
        match self {
            LoadError::Untiled(e) => crate::errors::to_py(e),
            LoadError::Tiled(e) => crate::errors::to_py(e),
        }
    }
}

/// A tiled plan in memory: its state and every round's report.
pub struct TiledCore {
    /// The library's tiled plan.
    pub state: TiledPlanState,
    /// Every round's report, in order.
    pub steps: Vec<TiledStep>,
}

/// The plan of a `rkwave.Plan`: untiled or on tiles. One per Python object, never in a
/// collection, so the untiled variant's size is not boxed away.
#[allow(clippy::large_enum_variant)]
pub enum PlanCore {
    /// The untiled plan.
    Untiled(PlanState),
    /// The plan on tiles.
    Tiled(Box<TiledCore>),
}

impl PlanCore {
    /// A new tiled plan on `plane` (memory checked for three channels, a renderer's RGB, as
    /// `rkwave plan --tile` does; later rounds check the samples' channels) and its base
    /// positions, with the decisions made for the caller.
    pub fn tiled(
        plane: ImagePlane,
        options: &PlanOptions,
        tile: usize,
        halo: Option<usize>,
    ) -> Result<(Self, SamplePositions, Vec<String>), TiledPlanError> {
        let start = TiledPlanStart::new(
            plane,
            options,
            &TiledPlanOptions {
                tile,
                halo,
                workers: None,
            },
        )?;
        let (state, base) = start.run(3)?;
        let core = TiledCore {
            state,
            steps: Vec::new(),
        };
        Ok((PlanCore::Tiled(Box::new(core)), base, start.notes()))
    }

    /// The image plane.
    pub fn plane(&self) -> ImagePlane {
        match self {
            PlanCore::Untiled(s) => s.plane,
            PlanCore::Tiled(t) => t.state.plane,
        }
    }

    /// Why the plan stopped (`None` while it runs).
    pub fn stop(&self) -> Option<rkwave::refine::StopReason> {
        match self {
            PlanCore::Untiled(s) => s.stop,
            PlanCore::Tiled(t) => t.state.stop,
        }
    }

    /// The last round handed out.
    pub fn round(&self) -> usize {
        match self {
            PlanCore::Untiled(s) => s.round(),
            PlanCore::Tiled(t) => t.state.round(),
        }
    }

    /// Positions handed out so far.
    pub fn positions(&self) -> usize {
        match self {
            PlanCore::Untiled(s) => s.positions(),
            PlanCore::Tiled(t) => t.state.positions(),
        }
    }

    /// The sample budget.
    pub fn budget(&self) -> usize {
        match self {
            PlanCore::Untiled(s) => s.params.stop.budget,
            PlanCore::Tiled(t) => t.state.params.stop.budget,
        }
    }

    /// `(tile, halo)` of a tiled plan.
    pub fn tiles(&self) -> Option<(usize, usize)> {
        match self {
            PlanCore::Untiled(_) => None,
            PlanCore::Tiled(t) => Some((t.state.tile, t.state.halo)),
        }
    }

    /// The plan in `dir`: a tiled plan where `tiled-state.json` is, else the untiled
    /// `state.json`.
    pub fn load(dir: &Path) -> Result<Self, LoadError> {
        let file = dir.join(TILED_STATE_FILE);
        if !file.exists() {
            return Ok(PlanCore::Untiled(
                PlanState::load(dir).map_err(LoadError::Untiled)?,
            ));
        }
        let text = std::fs::read_to_string(&file).map_err(|source| {
            LoadError::Untiled(PlanFileError::Read {
                file: file.clone(),
                source,
            })
        })?;
        let state = TiledPlanState::from_json(&text, &file).map_err(LoadError::Tiled)?;
        Ok(PlanCore::Tiled(Box::new(TiledCore {
            state,
            steps: Vec::new(),
        })))
    }

    /// Writes the state into `dir`: `state.json` as `rkwave plan --state DIR` writes it, or
    /// for a tiled plan `tiled-state.json` as `rkwave plan --tile --state DIR` does.
    pub fn save(&self, dir: &Path) -> Result<(), PlanFileError> {
        match self {
            PlanCore::Untiled(s) => s.save(dir),
            PlanCore::Tiled(t) => {
                // a folder that cannot be made is named by the write that follows
                let _ = std::fs::create_dir_all(dir);
                let file = dir.join(TILED_STATE_FILE);
                write_new(&file, t.state.to_json().as_bytes(), true)?;
                Ok(())
            }
        }
    }
}
