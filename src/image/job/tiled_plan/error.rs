//! Why a tiled plan was refused: one enum, classified beside its definition.

use thiserror::Error;

use crate::error::{ErrorKind, Fix, Param};
use crate::image::job::JobError;
use crate::image::plan::ProtocolError;
use crate::image::tiles::TileGeometryError;
use crate::resources::format_bytes;

/// Why a tiled plan was refused.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum TiledPlanError {
    /// The plan's options (budget, ranges).
    #[error(transparent)]
    Job(#[from] JobError),
    /// The plan's protocol: samples that are not the positions handed out, a state of
    /// another plan, a refiner's refusal.
    #[error(transparent)]
    Protocol(#[from] ProtocolError),
    /// The tile grid (`param` at fault).
    #[error("{}: {source}", Fix::Set(*param))]
    Grid {
        /// The parameter at fault.
        param: Param,
        /// The grid's refusal.
        source: TileGeometryError,
    },
    /// Workers 0.
    #[error(
        "workers 0: give at least 1 ({} 1 or more: tiles stepped at once)",
        Fix::Set(Param::Workers)
    )]
    Workers,
    /// A tile's fit beside the samples and the image exceeds the memory limit.
    #[error(
        "{what} would need about {} of memory ({} per tile fit x {workers} workers, {} of \
         samples and images), above the limit of {}: {fix}",
        format_bytes(*needed),
        format_bytes(*per_tile),
        format_bytes(*held),
        format_bytes(*limit as f64)
    )]
    TooLarge {
        /// What was checked.
        what: String,
        /// Bytes of one tile's fit.
        per_tile: f64,
        /// Tiles at once.
        workers: usize,
        /// Bytes of the samples and images held beside.
        held: f64,
        /// Bytes in all.
        needed: f64,
        /// The memory limit.
        limit: u64,
        /// The way out (the tile size that would fit, or fewer workers, or a smaller budget).
        fix: String,
    },
    /// The thread pool could not be built.
    #[error(
        "the pool of {workers} workers could not start ({reason}): give fewer {}",
        Fix::Set(Param::Workers)
    )]
    Pool {
        /// Workers asked for.
        workers: usize,
        /// The system's reason.
        reason: String,
    },
}

impl TiledPlanError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> ErrorKind {
        match self {
            TiledPlanError::Job(e) => e.kind(),
            TiledPlanError::Protocol(e) => e.kind(),
            TiledPlanError::Grid { .. } | TiledPlanError::Workers => ErrorKind::InvalidInput,
            TiledPlanError::TooLarge { .. } | TiledPlanError::Pool { .. } => {
                ErrorKind::ResourceLimit
            }
        }
    }

    /// The parameter at fault, where one is (the front ends spell it).
    pub fn param(&self) -> Option<Param> {
        match self {
            TiledPlanError::Grid { param, .. } => Some(*param),
            TiledPlanError::Workers | TiledPlanError::Pool { .. } => Some(Param::Workers),
            TiledPlanError::TooLarge { .. } => Some(Param::Tile),
            _ => None,
        }
    }
}

crate::error::classified!(TiledPlanError);
