//! `rkwave plan`: the adaptive image refiner driven by a renderer through files
//! ([`rkwave::image::adaptive::protocol`]). The first call (no `--samples`) writes the base
//! positions; each later call takes every sample so far and writes the next round's positions
//! (none once the plan stops); `rkwave reconstruct --dim 2 --state DIR` fits on the tree built.

use std::path::PathBuf;

use clap::Args;
use rkwave::adaptive::marking::SpreadRule;
use rkwave::image::adaptive::protocol::{PlanState, ProtocolError};
use rkwave::image::adaptive::{
    AdaptiveParams, PixelEstimate, PositionPattern, SamplePositions, TreeSolver,
};
use rkwave::image::report::{PlanCallReport, PlanReconstructionReport};
use rkwave::image::{ImagePlane, NonFinitePolicy};
use rkwave::io::output::{same_file, OutputError};
use rkwave::io::{npy_bytes, read_image_samples_with, SampleSet};

use super::image_args::{check_p, parse_resolution, SolverChoice};
use super::{check_writable, CliError};
use rkwave::image::adaptive::{
    FitParams, GrowthParams, ImageSampling, NoiseParams, OutputParams, QuadTreeParams, StopParams,
    TreeParams,
};

/// `rkwave plan`.
#[derive(Args, Debug)]
pub struct PlanArgs {
    /// Every sample so far (`.npy` `m x (2 + channels)` or CSV `x,y,c1[,...]`, positions as
    /// the plan wrote them); without it, a new plan starts and writes the base positions.
    #[arg(long)]
    pub samples: Option<PathBuf>,
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
    /// estimated risks; `shrunk` where `auto` falls back, said). Default for a new plan:
    /// `blend`; later calls keep the state's.
    #[arg(long)]
    pub output_pixels: Option<PixelEstimate>,
    /// The solver of the rounds' fits (recorded in the state): `pcg` (default for a new plan:
    /// matrix-free conjugate gradients, the rounds to a relative residual of 1e-2 from the
    /// last round's coefficients carried in `pcg.bin`, the final image's fit to 1e-4) or
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
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// The parameters of this call: the flags given, the rest from `base` (the state's on later
/// calls, the defaults on the first).
fn params(
    args: &PlanArgs,
    plane: ImagePlane,
    base: &AdaptiveParams,
) -> Result<AdaptiveParams, CliError> {
    let budget = match (args.budget, args.spp) {
        (Some(b), _) => b,
        (None, Some(s)) => s.saturating_mul(plane.pixels()),
        (None, None) => base.stop.budget,
    };
    Ok(AdaptiveParams {
        tree: TreeParams {
            p: args.p.map_or(Ok(base.tree.p), check_p)?,
            rho: args.rho.unwrap_or(base.tree.rho),
        },
        quad: QuadTreeParams {
            below_pixel: args.below_pixel.unwrap_or(base.quad.below_pixel),
            ..base.quad
        },
        sampling: ImageSampling {
            seed: args.seed.unwrap_or(base.sampling.seed),
            pattern: args.pattern.unwrap_or(base.sampling.pattern),
            ..base.sampling
        },
        noise: NoiseParams {
            false_alarm: args.false_alarm.unwrap_or(base.noise.false_alarm),
            ..base.noise
        },
        stop: StopParams {
            budget,
            ..base.stop
        },
        growth: GrowthParams {
            min_growth: args.min_growth.unwrap_or(base.growth.min_growth),
            spread: args.spread.unwrap_or(base.growth.spread),
            ..base.growth
        },
        output: OutputParams {
            pixels: args.output_pixels.unwrap_or(base.output.pixels),
            ..base.output
        },
        fit: FitParams {
            solver: match args.solver {
                None => base.fit.solver,
                Some(SolverChoice::Pcg) => TreeSolver::plan_pcg(),
                Some(choice) => choice.solver(),
            },
            ..base.fit
        },
        ..*base
    })
}

fn protocol(e: ProtocolError) -> CliError {
    match e {
        ProtocolError::Write(e) => CliError::Output(e),
        e => CliError::Protocol(e),
    }
}

/// Loads the plan in `--state`, with a hint when there is none.
pub fn load_state(dir: &std::path::Path) -> Result<PlanState, CliError> {
    PlanState::load(dir).map_err(|e| match e {
        ProtocolError::Read { source, .. } if source.kind() == std::io::ErrorKind::NotFound => {
            CliError::Invalid(format!(
                "no plan in {}: start one with `rkwave plan --resolution WxH --budget B --out \
                 next.npy --state {}` (without --samples)",
                dir.display(),
                dir.display()
            ))
        }
        e => protocol(e),
    })
}

fn positions_npy(next: &SamplePositions) -> Vec<u8> {
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
    if let Some(samples) = args.samples.as_ref().filter(|s| same_file(&args.out, s)) {
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
        inputs.extend(args.samples.as_deref());
        rkwave::io::output::check_output(image, args.force, &inputs)?;
    }
    let state_file = PlanState::path(&args.state);
    let (state, next, step) = match &args.samples {
        None => {
            if state_file.exists() && !args.force {
                return Err(CliError::Invalid(format!(
                    "{} holds a plan already: pass --samples to continue it, --force to start \
                     a new one, or another --state",
                    args.state.display()
                )));
            }
            let resolution = args
                .resolution
                .as_deref()
                .ok_or_else(|| CliError::Invalid("a new plan needs --resolution WxH".into()))?;
            let plane = parse_resolution(resolution)?;
            if args.budget.is_none() && args.spp.is_none() {
                return Err(CliError::Invalid(
                    "a new plan needs --budget B (total samples) or --spp S".into(),
                ));
            }
            let params = params(args, plane, &AdaptiveParams::renderer_plan())?;
            let (state, base) = PlanState::start(plane, &params).map_err(protocol)?;
            (state, base, None)
        }
        Some(path) => {
            let mut state = load_state(&args.state)?;
            let plane = match &args.resolution {
                Some(r) => parse_resolution(r)?,
                None => state.plane,
            };
            let params = params(args, plane, &state.params)?;
            state.check_params(plane, &params).map_err(protocol)?;
            super::check_reading(path)?;
            let (samples, dropped) = read_image_samples_with(
                path,
                state.plane,
                NonFinitePolicy::dropping(args.drop_nonfinite),
            )?;
            let step = state.advance_dropped(&samples, dropped).map_err(protocol)?;
            let next = step.next.clone();
            (state, next, Some(step))
        }
    };
    // The round is committed as one step: the positions and the state, or neither.
    state
        .commit(&args.state, &args.out, &positions_npy(&next), args.force)
        .map_err(protocol)?;
    let final_image = match (
        &args.final_image,
        step.as_ref().and_then(|s| s.reconstruction.as_ref()),
    ) {
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
        println!(
            "wrote the final image to {} (the stopping round's fit)",
            path.display()
        );
        if matches!(state.params.fit.solver, TreeSolver::Pcg { .. }) {
            super::print_note(
                "the final image is the stopping round's conjugate-gradient fit continued to the \
                 solver's tolerance; `reconstruct --dim 2 --state` on the same samples solves \
                 again from the carried coefficients to that tolerance, so the two agree to it, \
                 not bit for bit (under --solver direct they are the same pixels)",
            );
        }
    }
    if let Some(s) = &step {
        if let Some(note) = &s.log.coverage {
            super::print_note(note);
        }
        if let Some(note) = s.dropped.note() {
            super::print_note(&note);
        }
        for note in [&s.solver_note, &s.gram_note, &s.pcg_note]
            .into_iter()
            .flatten()
        {
            super::print_note(note);
        }
        if s.log.fit.ridge > 0.0 {
            println!(
                "note: the normal matrix was numerically singular: a relative ridge {:.0e} was \
                 added",
                s.log.fit.ridge
            );
        }
    }
    Ok(())
}

/// `rkwave reconstruct --dim 2 --state DIR`: the samples fitted on the tree of the plan in
/// `dir`, the output pixels (by default the fit's box pixels plus the significant mean
/// residual, clamped to the local sample range; with `--no-residual` the box pixels alone)
/// written to `--output`.
pub fn reconstruct(
    args: &super::reconstruct_args::ReconstructArgs,
    dir: &std::path::Path,
    started: std::time::Instant,
) -> Result<(), CliError> {
    let state = load_state(dir)?;
    if let Some(r) = &args.resolution {
        let plane = parse_resolution(r)?;
        if plane != state.plane {
            return Err(CliError::Invalid(format!(
                "--resolution {plane}: the plan in {} is for {}; drop --resolution or give the \
                 plan's",
                dir.display(),
                state.plane
            )));
        }
    }
    super::check_reading(&args.input)?;
    let (samples, dropped) = read_image_samples_with(
        &args.input,
        state.plane,
        NonFinitePolicy::dropping(args.drop_nonfinite),
    )?;
    let estimate = if args.no_residual {
        PixelEstimate::FitOnly
    } else {
        state.params.output.pixels
    };
    let done = state
        .reconstruct_dropped(&samples, dropped, estimate)
        .map_err(protocol)?;
    rkwave::io::image_file::write_image(&args.output, &done.image, args.force)?;
    let mut overridden: Vec<String> = done.solver_note.iter().cloned().collect();
    // The plan fixes the basis and the solve: say so when the user asked for others.
    if let Some(p) = args.p.filter(|&p| p != state.params.tree.p) {
        overridden.push(format!(
            "p = {} from the plan's tree (--p, {p} here, is not used with --state)",
            state.params.tree.p
        ));
    }
    if args.family.is_some() {
        overridden
            .push("--family is not used: the plan's tree fixes the filter family".to_string());
    }
    if args.method != super::solve_args::MethodArg::Single {
        overridden.push(
            "--method is not used: the plan's tree is fitted by its own least squares".to_string(),
        );
    }
    let report = PlanReconstructionReport::new(
        &state,
        dir,
        &args.input,
        &args.output,
        &samples,
        &done,
        overridden,
        started.elapsed().as_secs_f64(),
    );
    if args.json {
        super::print_json(&report);
    } else {
        println!(
            "{} samples x {} channels (rounds 0..={}) -> {} pixels on the plan's tree ({} \
             functions, p = {}), {:.3} s; wrote {}",
            report.samples,
            report.channels,
            report.round,
            state.plane,
            report.fit.functions,
            report.p,
            report.time_s,
            args.output.display()
        );
        for note in &report.notes {
            super::print_note(note);
        }
    }
    Ok(())
}
