//! The image plane's front door: one library call per job a user meets, which validates the
//! parameters, decides the defaults, estimates the memory and refuses before it allocates,
//! then does the work. The command line (`rkwave reconstruct --dim 2`) and the Python module
//! (`rkwave.reconstruct_image`) call these and only parse and print, so both give the same
//! refusals and the same decisions for the same request.
//!
//! * [`UniformJob`]: scattered samples `(x_i, y_i, f_i)` to the pixels of a `W x H` image on
//!   the uniform path ([`crate::image::reconstruct_estimated`]: a pixel estimate, by default
//!   a film per pixel chosen by SURE; the least-squares fit; or a film filter). Built once
//!   from [`ImageParams`] ([`UniformJob::new`], no allocation beyond the parameters), checked
//!   against the memory limit from the sizes alone ([`UniformJob::check_memory`], before the
//!   samples are read or converted), then run ([`UniformJob::run`]).
//! * [`TiledJob`]: the same fit tile by tile, the samples read in chunks from a file
//!   ([`crate::image::tiles`]), for images whose fit does not fit in memory at once.
//! * The plan's jobs ([`PlanStart`], [`PlanRound`], [`PlanFinal`]): a renderer's adaptive
//!   loop, one call per step, on the plan's state machine ([`crate::image::plan`]).
//! * [`memory`]: the memory requests of every image-plane path; [`text`]: notes wrapped at
//!   a readable width for the front ends to print.
//!
//! Messages name the parameter at fault as data ([`crate::error::Param`] through
//! [`crate::error::Fix::Set`]): the command line spells it as its flag (`--rho`), Python as
//! its keyword (`rho=`).
//!
//! Why `image::job`: the jobs sit on top of the image plane's stages (estimates, fits,
//! films) and beside them, below the front ends; they are image-plane code, so they live in
//! `image/`, but in a room of their own so that the stages never call back into them.

mod error;
pub mod memory;
mod params;
mod plan;
pub mod text;
mod tiled;
pub mod tiled_plan;
mod uniform;

pub use plan::{
    PlanBudget, PlanFinal, PlanOptions, PlanRound, PlanSolver, PlanStart, RoundSamples,
};
pub use tiled::{TileOptions, TiledJob, TiledRun};
pub use uniform::{PixelChoice, UniformJob, UniformOutput};

use error::in_range;
pub use error::{check_p, By, JobError};
pub use params::{FitOptions, ImageParams};

#[cfg(test)]
mod tests;
