//! The lab: experiments that measure the library, their tables and their figures (feature
//! `plot`). Nothing in the library's production path calls into it; the command line's
//! measuring commands (`image`, `compare`, the demo) do.
//!
//! * [`comparison`]: the job of `image` and `compare`: methods on a sampled scene, checked
//!   against the memory limit before a sample is drawn;
//! * [`basis`]: the job of `basis`: a basis's measured facts, checked the same way;
//! * [`experiment`]: a scene sampled (with seeded noise), every image-plane [`ImageMethod`] run on
//!   the same samples through the library's [`reconstruct`], each measured against the
//!   box-filtered ground truth (PSNR, RMSE, relative MSE, SSIM), as typed `Serialize` reports;
//! * [`table`]: those comparisons as CSV and Markdown tables;
//! * [`figure`]: their figures (images side by side with zoomed crops, PSNR against time);
//! * [`adaptive`]: the adaptive wavelet image against film filters at equal total samples;
//! * [`refine`]: the 1D refiner against uniform sampling at equal sample counts (figure 4);
//! * [`refine_figures`]: the layout of the 1D adaptive refiner's figures.
//!
//! [`ImageMethod`]: crate::image::ImageMethod
//! [`reconstruct`]: crate::image::reconstruct

pub mod adaptive;
pub mod basis;
pub mod comparison;
pub mod experiment;
pub mod figure;
pub mod halo_study;
pub mod refine;
pub mod refine_figures;
pub mod table;
