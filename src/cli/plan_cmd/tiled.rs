//! `rkwave plan --tile`: the plan on tiles ([`rkwave::image::job::tiled_plan`]) through the
//! same round files as the untiled plan (positions out, every sample so far in); its state
//! is `tiled-state.json` in the plan's folder, committed with the positions as one step.

use std::path::{Path, PathBuf};

use rkwave::image::job::tiled_plan::{TiledPlanOptions, TiledPlanStart, TiledPlanState, TiledStep};
use rkwave::image::job::{PlanOptions, PlanRound};
use rkwave::image::NonFinitePolicy;
use rkwave::io::output::persist;
use rkwave::io::read_image_samples_with;

use super::super::image_args::parse_resolution;
use super::super::CliError;
use super::{positions_npy, PlanArgs};

use rkwave::image::job::tiled_plan::TILED_STATE_FILE;

/// The tiled state file in the folder `dir`.
pub fn path(dir: &Path) -> PathBuf {
    dir.join(TILED_STATE_FILE)
}

fn load(dir: &Path) -> Result<TiledPlanState, CliError> {
    let file = path(dir);
    let text = std::fs::read_to_string(&file).map_err(|e| {
        CliError::Invalid(format!(
            "cannot read the tiled plan state {}: {e}",
            file.display()
        ))
    })?;
    Ok(TiledPlanState::from_json(&text, &file)?)
}

/// `bytes` into a temporary file beside `target`.
fn temporary(target: &Path, bytes: &[u8]) -> Result<PathBuf, CliError> {
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".into());
    let tmp = target.with_file_name(format!(".{name}.rkwave-{}.tmp", std::process::id()));
    std::fs::write(&tmp, bytes).map_err(|source| {
        let _ = std::fs::remove_file(&tmp);
        CliError::Write {
            path: target.to_path_buf(),
            source,
        }
    })?;
    Ok(tmp)
}

/// The round committed as one step: the positions and the state, or neither (both written
/// to temporary files first; the positions put in place, then the state; a failure removes
/// what was written).
fn commit(
    state: &TiledPlanState,
    dir: &Path,
    positions: &Path,
    bytes: &[u8],
    overwrite: bool,
) -> Result<(), CliError> {
    let file = path(dir);
    for folder in [Some(dir), positions.parent()].into_iter().flatten() {
        if !folder.as_os_str().is_empty() {
            std::fs::create_dir_all(folder).map_err(|source| CliError::Write {
                path: folder.to_path_buf(),
                source,
            })?;
        }
    }
    let state_tmp = temporary(&file, state.to_json().as_bytes())?;
    let positions_tmp = match temporary(positions, bytes) {
        Ok(t) => t,
        Err(e) => {
            let _ = std::fs::remove_file(&state_tmp);
            return Err(e);
        }
    };
    if let Err(e) = persist(&positions_tmp, positions, overwrite) {
        let _ = std::fs::remove_file(&state_tmp);
        let _ = std::fs::remove_file(&positions_tmp);
        return Err(e.into());
    }
    if let Err(e) = persist(&state_tmp, &file, true) {
        let _ = std::fs::remove_file(positions);
        return Err(e.into());
    }
    Ok(())
}

/// Runs `rkwave plan --tile` (the checks of the output paths done by the caller).
pub fn run(args: &PlanArgs, options: &PlanOptions) -> Result<(), CliError> {
    PlanRound::check_tiled_samples(NonFinitePolicy::dropping(args.drop_nonfinite))?;
    let untiled = rkwave::image::plan::PlanState::path(&args.state);
    let (state, next, step, notes) = match &args.samples {
        None => {
            rkwave::image::plan::PlanState::check_new(
                &args.state,
                &[path(&args.state)],
                args.force,
            )?;
            let resolution = args
                .resolution
                .as_deref()
                .ok_or_else(|| CliError::Invalid("a new plan needs --resolution WxH".into()))?;
            let plane = parse_resolution(resolution)?;
            let tiles = TiledPlanOptions {
                tile: args.tile.unwrap_or(0),
                halo: args.halo,
                workers: None,
            };
            let start = TiledPlanStart::new(plane, options, &tiles)?;
            let mut notes = start.notes();
            notes.push(
                "memory checked for 3 channels (a renderer's RGB); later rounds check the \
                 channels the samples have"
                    .into(),
            );
            let (state, base) = start.run(3)?;
            if untiled.exists() {
                let _ = std::fs::remove_file(&untiled);
            }
            (state, base, None, notes)
        }
        Some(samples_path) => {
            let mut state = load(&args.state)?;
            if let Some(t) = args.tile.filter(|&t| t != state.tile) {
                return Err(CliError::Invalid(format!(
                    "--tile {t}: the plan in {} has tiles of {}; pass the same or none",
                    args.state.display(),
                    state.tile
                )));
            }
            if let Some(h) = args.halo.filter(|&h| h != state.halo) {
                return Err(CliError::Invalid(format!(
                    "--halo {h}: the plan in {} has a halo of {}; pass the same or none",
                    args.state.display(),
                    state.halo
                )));
            }
            let plane = args
                .resolution
                .as_deref()
                .map(parse_resolution)
                .transpose()?;
            state.check_options(plane, options)?;
            super::super::check_reading(samples_path)?;
            let (samples, _) =
                read_image_samples_with(samples_path, state.plane, NonFinitePolicy::Refuse)?;
            let step = state.advance(&samples)?;
            let mut notes = step_notes(&step);
            if let (Some(image), Some(_)) = (&args.final_image, step.stop) {
                let done = state.final_image(&samples, None)?;
                rkwave::io::image_file::write_image(image, &done.image, args.force)?;
                notes.push(format!("wrote the final image to {}", image.display()));
            }
            let next = step.next.clone();
            (state, next, Some(step), notes)
        }
    };
    commit(
        &state,
        &args.state,
        &args.out,
        &positions_npy(&next),
        args.force,
    )?;
    if args.json {
        #[derive(serde::Serialize)]
        struct Report<'a> {
            state: &'a Path,
            positions: &'a Path,
            tile: usize,
            halo: usize,
            tiles: usize,
            round: usize,
            handed_out: usize,
            budget: usize,
            next_positions: usize,
            stop: Option<rkwave::adaptive::StopReason>,
            step: Option<&'a TiledStep>,
            notes: &'a [String],
        }
        super::super::print_json(&Report {
            state: &args.state,
            positions: &args.out,
            tile: state.tile,
            halo: state.halo,
            tiles: state.tiles.len(),
            round: state.round(),
            handed_out: state.positions(),
            budget: state.params.stop.budget,
            next_positions: next.len(),
            stop: state.stop,
            step: step.as_ref(),
            notes: &notes,
        });
        return Ok(());
    }
    match (&step, state.stop) {
        (None, _) => println!(
            "new tiled plan for {} in {} tiles of {} (halo {}), budget {}: {} base positions \
             -> {}; render them, then call again with --samples",
            state.plane,
            state.tiles.len(),
            state.tile,
            state.halo,
            state.params.stop.budget,
            next.len(),
            args.out.display()
        ),
        (Some(s), None) => println!(
            "round {}: {} tiles stepped ({} stopped), growth {}; {} positions -> {} ({} of {} \
             handed out)",
            state.round() - 1,
            s.tiles_stepped,
            s.tiles_stopped,
            s.growth,
            next.len(),
            args.out.display(),
            state.positions(),
            state.params.stop.budget
        ),
        (Some(_), Some(stop)) => println!(
            "the tiled plan stopped ({stop:?}) at {} samples: no positions left ({} written \
             with 0 rows){}",
            state.positions(),
            args.out.display(),
            if args.final_image.is_some() {
                ""
            } else {
                "; pass --final-image IMAGE with the same samples to make the image"
            }
        ),
    }
    for note in &notes {
        super::super::print_note(note);
    }
    Ok(())
}

/// The round's decisions in words: the positions drawn in halos and discarded, those cut to
/// a tile's share.
fn step_notes(step: &TiledStep) -> Vec<String> {
    let mut notes = Vec::new();
    if step.halo_drawn > 0 {
        notes.push(format!(
            "{} of the positions were drawn by tiles in their halos (the neighbour that owns \
             those pixels counts them and tops up only where they lack samples)",
            step.halo_drawn
        ));
    }
    if step.cut > 0 {
        notes.push(format!(
            "{} positions beyond the tiles' shares of the round's growth were cut",
            step.cut
        ));
    }
    notes
}
