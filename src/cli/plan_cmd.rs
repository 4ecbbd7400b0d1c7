//! `rkwave plan`: the adaptive image refiner driven by a renderer through files. The first
//! call (no `--samples`) writes the base positions ([`rkwave::image::job::PlanStart`]); each
//! later call takes every sample so far (`--samples`), or only the samples of the round just
//! handed out (`--new-samples`, joined to the samples the plan keeps in its folder,
//! [`rkwave::image::plan::new_round::ReadSamples`]), and writes the next round's positions, none once the
//! plan stops ([`rkwave::image::job::PlanRound`]; the stopping call writes `--final-image` by
//! [`rkwave::image::job::PlanFinal`]); the plan's files are [`rkwave::io::plan_files`]'s.
//! This file parses the flags and prints: the decisions are the library's.

mod tiled;

use std::path::PathBuf;

use clap::Args;
use rkwave::adaptive::marking::SpreadRule;
use rkwave::image::adaptive::{PixelEstimate, PositionPattern, SamplePositions};
use rkwave::image::job::{
    PlanBudget, PlanFinal, PlanOptions, PlanRound, PlanSolver, PlanStart, RoundSamples,
};
use rkwave::image::plan::new_round::ReadSamples;
use rkwave::image::plan::PlanState;
use rkwave::image::report::PlanCallReport;
use rkwave::image::NonFinitePolicy;
use rkwave::io::output::{same_file, OutputError};
use rkwave::io::{npy_bytes, read_image_samples_with, SampleSet};

use super::image_args::{load_plan, parse_resolution, plan_file, SolverChoice};
use super::{check_writable, CliError};

/// `rkwave plan`.
#[derive(Args, Debug)]
pub struct PlanArgs {
    /// Every sample so far (`.npy` `m x (2 + channels)` or CSV `x,y,c1[,...]`, positions as
    /// the plan wrote them); without it, a new plan starts and writes the base positions.
    #[arg(long)]
    pub samples: Option<PathBuf>,
    /// Only the samples of the round just handed out (the positions of the last `--out`, in
    /// any order; the same formats as `--samples`): the plan joins them to the samples of the
    /// earlier rounds it keeps in its folder (`samples.bin`, written by every call), so the
    /// round is the one `--samples` with every sample so far would give. Samples of another
    /// round (repeated, or every sample so far), another count, or positions not those
    /// handed out are refused, naming the round expected. Not available with --tile.
    #[arg(long, conflicts_with = "samples")]
    pub new_samples: Option<PathBuf>,
    /// Folder of the plan's state (`state.json`), kept between calls.
    #[arg(long, default_value = "rkwave-plan")]
    pub state: PathBuf,
    /// Positions to render next: `.npy` `n x 2` (x, y in pixel units); 0 rows once the plan
    /// has stopped.
    #[arg(long)]
    pub out: PathBuf,
    /// Image resolution `WxH` (needed to start; later calls check it).
    #[arg(long)]
    pub resolution: Option<String>,
    /// Total sample budget (or `--spp`), plain or in `1e6` notation.
    #[arg(long, conflicts_with = "spp", value_parser = super::limits::count)]
    pub budget: Option<usize>,
    /// Average samples per pixel: the budget is spp x pixels; plain or in `1e3` notation.
    #[arg(long, value_parser = super::limits::count)]
    pub spp: Option<usize>,
    /// Vanishing moments p (default 2).
    #[arg(long)]
    pub p: Option<usize>,
    /// Samples per slot of the tree (default 2).
    #[arg(long)]
    pub rho: Option<f64>,
    /// Depth limit in levels below the pixel (default 1).
    #[arg(long)]
    pub below_pixel: Option<u32>,
    /// Seed of the positions (default 1).
    #[arg(long)]
    pub seed: Option<u64>,
    /// False-alarm rate of the noise test, the chance per round that noise alone deepens a
    /// slot (default 0.01; 0: no noise test, every detail is deepened).
    #[arg(long)]
    pub false_alarm: Option<f64>,
    /// Where to write the final image (`.npy`, `.exr`, `.png` as in `reconstruct --dim 2`)
    /// when this call stops the plan: the stopping round's fit, so no `reconstruct --dim 2
    /// --state` call (which would fit the same samples again) is needed. Nothing is written
    /// while the plan continues.
    #[arg(long)]
    pub final_image: Option<PathBuf>,
    /// Least growth per round, as a share of the samples so far (default 0.25): larger
    /// values mean fewer rounds, so fewer fits while the renderer waits, and coarser steps
    /// of the refinement.
    #[arg(long)]
    pub min_growth: Option<f64>,
    /// Share of each round's new samples given to the pixels by the spread of their own
    /// samples (pooled over 3 x 3 pixels), beside the tree's marking (0 to 1; default 0: the
    /// tree alone). Applies only at budgets of at most 4 samples a pixel (above it the plan is
    /// the tree's alone: the share lost on glossy and caustic scenes there). Each round says
    /// how many it gave (none where the base slots are not the pixels or the budget is above
    /// the cut). Not available with --tile.
    #[arg(long)]
    pub pixel_share: Option<f64>,
    /// Where a slot's positions go (recorded in the state, continued by later calls):
    /// `sobol` (default: per slot an Owen-scrambled Sobol (0, 2)-sequence, each round taking
    /// its next points) or `stratified` (jittered strata per round).
    #[arg(long)]
    pub pattern: Option<PositionPattern>,
    /// Where a round's spare samples go: `indicator` (default: by the predicted detail),
    /// `uncertainty` (where detail does not decay, by the uncertainty of each slot's mean,
    /// sqrt(area) x spread of its residuals; a tree deep wherever its detail is significant
    /// keeps densifying until the budget is spent) or `uniform`.
    #[arg(long)]
    pub spread: Option<SpreadRule>,
    /// The final image's pixels (recorded in the state; the rounds do not depend on it):
    /// `residual_clamped` (the fit plus the significant mean residual, clamped to the local
    /// sample range), `residual_corrected`, `fit_only`, `shrunk` (residual_clamped, then
    /// wavelet-shrunk at the noise level of the samples' own spread), `box_shrunk` (the
    /// box pixels, shrunk likewise), `auto` (per pixel the film filter of least SURE, then
    /// shrunk, as `reconstruct --dim 2 --pixels auto`; `shrunk` where a pixel has no sample,
    /// said) or `blend` (per pixel `shrunk` and `auto` weighted by the inverse of their
    /// estimated risks; `shrunk` where `auto` falls back, said) or `blend_gated` (`blend`,
    /// then per pixel the least estimated risk of the box pixels, `auto` and the blend over a
    /// window, so that no pixel takes a step its estimate says raises the risk over the mean
    /// of its own samples; what it chose is in the report) or `blend_sure` (`blend` with
    /// `shrunk`'s weight capped by the weight of least SURE of the combination, which sees
    /// the two errors' correlation; what it did is in the report). Default for a new plan:
    /// `blend`; later calls keep the state's.
    #[arg(long)]
    pub output_pixels: Option<PixelEstimate>,
    /// The solver of the rounds' fits (recorded in the state): `pcg` (default for a new plan:
    /// matrix-free conjugate gradients, the rounds to a relative residual of 1e-2 from the
    /// last round's coefficients carried in `pcg.bin`, the final image's fit to 3e-4) or
    /// `direct` (the sparse Cholesky of the normal matrix carried in `gram.bin`). A fit whose
    /// direct solve would exceed the memory limit uses PCG, with a note.
    #[arg(long, value_enum)]
    pub solver: Option<SolverChoice>,
    /// Overwrite the positions file; without `--samples`, also replace an existing plan.
    #[arg(long)]
    pub force: bool,
    /// Drop the samples whose value is NaN or infinite (counted in the report) instead of
    /// refusing the round; the round is recognised by all its positions either way.
    #[arg(long)]
    pub drop_nonfinite: bool,
    /// Tile side in pixels: the plan on tiles (a quadtree and its fits per tile over the
    /// tile plus its halo grown to a power of two, one global budget shared by the tiles' indicators, memory bounded
    /// by the tile; the final image stitched as `reconstruct --dim 2 --tile` does). Recorded
    /// in the state (`tiled-state.json`); later calls continue it without the flag. Refuses
    /// --pixel-share and --drop-nonfinite.
    #[arg(long)]
    pub tile: Option<usize>,
    /// Halo of each tile in pixels, at most the tile (default 0: a power-of-two tile is its
    /// own window); with --tile.
    #[arg(long)]
    pub halo: Option<usize>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// The plan's options from the flags (each flag not given stays `None`: the plan's value, or
/// for a new plan the library's default).
pub(super) fn options(args: &PlanArgs) -> PlanOptions {
    PlanOptions {
        budget: args
            .budget
            .map(PlanBudget::Samples)
            .or(args.spp.map(PlanBudget::PerPixel)),
        p: args.p,
        rho: args.rho,
        below_pixel: args.below_pixel,
        seed: args.seed,
        false_alarm: args.false_alarm,
        min_growth: args.min_growth,
        pixel_share: args.pixel_share,
        pattern: args.pattern,
        spread: args.spread,
        output_pixels: args.output_pixels,
        solver: args.solver.map(|choice| match choice {
            SolverChoice::Pcg => PlanSolver::Pcg,
            SolverChoice::Direct => PlanSolver::Direct,
            SolverChoice::Schwarz => PlanSolver::Schwarz,
        }),
    }
}

pub(super) fn positions_npy(next: &SamplePositions) -> Vec<u8> {
    let set = SampleSet::new(next.xs.clone(), vec![next.ys.clone()])
        .and_then(|s| s.with_names(vec!["y".into()]))
        .expect("positions and ys have equal lengths");
    npy_bytes(&set).expect("positions are finite")
}

/// Runs `rkwave plan`.
pub fn run(args: &PlanArgs) -> Result<(), CliError> {
    if args.out.extension().and_then(|e| e.to_str()) != Some("npy") {
        return Err(CliError::Invalid(format!(
            "--out {}: the positions are written as .npy (n x 2); give a path ending in .npy",
            args.out.display()
        )));
    }
    let given = args.samples.as_ref().or(args.new_samples.as_ref());
    if let Some(samples) = given.filter(|s| same_file(&args.out, s)) {
        return Err(OutputError::SameFile {
            output: args.out.clone(),
            input: samples.clone(),
        }
        .into());
    }
    check_writable(&args.out, args.force)?;
    if let Some(image) = &args.final_image {
        rkwave::io::image_file::ImageFormat::from_path(image)
            .map_err(|e| CliError::flag("--final-image", e))?;
        let mut inputs = vec![args.out.as_path()];
        inputs.extend(given.map(PathBuf::as_path));
        rkwave::io::output::check_output(image, args.force, &inputs)?;
    }
    let options = options(args);
    let tiled = tiled::path(&args.state).exists();
    PlanStart::check_halo(args.tile, args.halo, tiled)?;
    if args.tile.is_some() || tiled {
        if args.new_samples.is_some() {
            return Err(CliError::Invalid(
                "--new-samples is not available with the tiled plan (--tile) yet: give every \
                 sample so far with --samples"
                    .into(),
            ));
        }
        return tiled::run(args, &options);
    }
    let (state, next, step, final_image) = match given {
        None => {
            PlanState::check_new(&args.state, &[], args.force)?;
            let resolution = args
                .resolution
                .as_deref()
                .ok_or_else(|| CliError::Invalid("a new plan needs --resolution WxH".into()))?;
            let plane = parse_resolution(resolution)?;
            let (state, base) = PlanStart::new(plane, &options)?.run()?;
            (state, base, None, None)
        }
        Some(path) => {
            let mut state = load_plan(&args.state)?;
            // the last round handed out: the one this call's samples complete
            let through = state.round();
            let plane = args
                .resolution
                .as_deref()
                .map(parse_resolution)
                .transpose()?;
            // a round given only its new samples: the earlier rounds' from the plan's folder
            // (refused when they are not kept there); with every sample so far, the samples
            // kept, to append the new rows to when they are the first of these
            let earlier = match &args.new_samples {
                Some(_) => Some(state.read_samples(&args.state).map_err(plan_file)?),
                None => state.read_samples(&args.state).ok(),
            };
            let round = PlanRound::new(&mut state, plane, &options)?;
            super::check_reading(path)?;
            let (given, given_dropped) = read_image_samples_with(
                path,
                round.plane(),
                NonFinitePolicy::dropping(args.drop_nonfinite),
            )?;
            let RoundSamples {
                samples,
                dropped,
                continued,
            } = round.gather(earlier, args.new_samples.is_some(), given, given_dropped)?;
            let step = round.run(&samples, dropped.clone())?;
            // The stopping round's call makes the final image, as `reconstruct --dim 2
            // --state` would from these samples (the same library call).
            let final_image = match (&args.final_image, step.stop) {
                (Some(_), Some(_)) => Some(PlanFinal::of(&state, false).run(
                    &samples,
                    dropped.clone(),
                    Some(&step),
                )?),
                _ => None,
            };
            let next = step.next.clone();
            let read = ReadSamples {
                through: Some(through),
                samples: Some(samples),
                dropped,
            };
            // The round is committed as one step: the positions and the state, or neither;
            // then the samples read (appended when they continue those kept).
            state
                .commit(&args.state, &args.out, &positions_npy(&next), args.force)
                .map_err(plan_file)?;
            let mut step = step;
            step.samples_note = state.keep_samples(&args.state, &read, continued);
            (state, next, Some(step), final_image)
        }
    };
    if step.is_none() {
        // The round is committed as one step: the positions and the state, or neither.
        state
            .commit(&args.state, &args.out, &positions_npy(&next), args.force)
            .map_err(plan_file)?;
    }
    let final_image = match (&args.final_image, final_image) {
        (Some(path), Some(done)) => {
            rkwave::io::image_file::write_image(path, &done.image, args.force)?;
            Some(path)
        }
        _ => None,
    };
    if args.json {
        let report = PlanCallReport::new(&state, &args.state, &args.out, &next, step);
        super::print_json(&report);
        return Ok(());
    }
    match (&step, state.stop) {
        (None, _) => println!(
            "new plan for {} (budget {}): {} base positions -> {}; render them, then call \
             again with --samples",
            state.plane,
            state.params.stop.budget,
            next.len(),
            args.out.display()
        ),
        (Some(s), None) => println!(
            "round {}: fit on {} samples ({} functions, estimated RMS error {:.3e}), {} slots \
             marked; {} positions of round {} -> {} ({} of {} handed out)",
            s.log.round,
            s.log.samples,
            s.log.functions,
            s.log.estimate_rms,
            s.log.marked,
            next.len(),
            state.round(),
            args.out.display(),
            state.positions(),
            state.params.stop.budget
        ),
        (Some(s), Some(stop)) => println!(
            "round {}: fit on {} samples ({} functions, estimated RMS error {:.3e}); the plan \
             stopped ({stop:?}): no positions left ({} written with 0 rows){}",
            s.log.round,
            s.log.samples,
            s.log.functions,
            s.log.estimate_rms,
            args.out.display(),
            // With --final-image the image is written below: no second call to send the
            // user to.
            match final_image {
                Some(_) => String::new(),
                None => format!(
                    "; reconstruct with `rkwave reconstruct --dim 2 --state {} --input SAMPLES \
                     --output IMAGE` (or pass --final-image IMAGE to this call)",
                    args.state.display()
                ),
            }
        ),
    }
    if let Some(path) = final_image {
        println!("wrote the final image to {}", path.display());
    }
    if let Some(s) = &step {
        for note in PlanRound::notes(&state.params, s) {
            super::print_note(&note);
        }
    }

    Ok(())
}
