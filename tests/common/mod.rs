//! Scaffolding shared by the integration tests, written once:
//!
//! - [`runner`]: run the `rkwave` binary (every test starts it through [`runner::command`])
//!   and read what it printed and its exit code; scratch
//!   folders that remove themselves;
//! - [`scenes`]: the image-plane scenes several tests fit (a straight edge, stripes past
//!   Nyquist beside a disc, a polynomial the
//!   basis reproduces);
//! - [`trees`]: random quadtrees (closed under "parent present") and samples in every slot,
//!   for the tree fits;
//! - [`oracle`]: the dense least-squares oracle `c = K^+ f` by an SVD (nalgebra), with the
//!   one tolerance rule every solver is held to;
//! - [`image_cli`]: image-plane sample files, `reconstruct --dim 2` / `plan` arguments and a
//!   renderer answering a plan, for the image plane's hardening tests;
//! - [`rendered`]: one-channel samples grown round by round, for the plan's library tests;
//! - [`metrics`]: the PSNR of clipped images (the harness's definition);
//! - [`damage`]: a bit flipped, a file cut short or removed (the plan's kept files);
//! - [`nets`]: whether positions are a `(0, m, 2)`-net of a rectangle (the plan's placement);
//! - [`sub_pixel_checker`]: texture past the pixel scale plus noise, sampled as a plan samples,
//!   and the final image's error against the pixel integrals (the final-image tests).
//!
//! Each test file that needs them declares `mod common;`; what a file does not use is dead
//! code there, hence the `allow`.
#![allow(dead_code, unused_imports)]

pub mod damage;
pub mod image_cli;
pub mod metrics;
pub mod nets;
pub mod oracle;
pub mod rendered;
pub mod runner;
pub mod scenes;
pub mod stored;
pub mod sub_pixel_checker;
pub mod trees;

pub use metrics::psnr;
pub use runner::{
    command, rkwave, rkwave_bounded, scratch, succeeds, text, user_error, write, Scratch,
};
