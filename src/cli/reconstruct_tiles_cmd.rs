//! `rkwave reconstruct --dim 2 --tile T [--halo H] [--workers N]`: the image fitted tile by
//! tile ([`rkwave::image::tiles::reconstruct_tiled`]), the input read in chunks, the output
//! written atomically once every tile is solved.

use std::io::IsTerminal;
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};
use rkwave::image::tiles::{
    reconstruct_tiled, TileGeometry, TiledInput, TiledParams, TiledReport, DEFAULT_HALO,
};
use rkwave::image::{ImageMethod, ImagePlane, UniformEstimate, WaveletParams};
use rkwave::io::image_file::write_image;
use serde::Serialize;

use super::reconstruct_args::ReconstructArgs;
use super::CliError;

/// The `--json` report of a tiled reconstruction.
#[derive(Serialize)]
struct TiledFileReport<'a> {
    input: String,
    output: String,
    resolution: String,
    p: usize,
    rho: f64,
    ridge: f64,
    /// What the tiled fit did, with every tile's report.
    tiled: &'a TiledReport,
    /// Seconds: reading (all passes), fitting, writing, total.
    time_s: Times,
    /// Tiles with functions left without samples (pinned to 0), in words.
    notes: Vec<String>,
}

#[derive(Serialize)]
struct Times {
    read: f64,
    fit: f64,
    write: f64,
    total: f64,
}

/// Runs the tiled 2D path (the flags already checked against `--state`).
pub fn run(
    args: &ReconstructArgs,
    plane: ImagePlane,
    method: ImageMethod,
    tile: usize,
    wavelet: &WaveletParams,
    started: Instant,
) -> Result<(), CliError> {
    if method != ImageMethod::Wavelet {
        return Err(CliError::Invalid(
            "--tile fits each tile by the global solve of its window: use --method single or \
             global (the default), or drop --tile"
                .into(),
        ));
    }
    if args.pixels.is_some_and(|p| p != UniformEstimate::Fit) {
        return Err(CliError::Invalid(
            "--tile computes the fit's box pixels: drop --pixels (or give --pixels fit), or \
             drop --tile"
                .into(),
        ));
    }
    if args.drop_nonfinite {
        return Err(CliError::Invalid(
            "--tile reads the samples in chunks and refuses non-finite values: drop \
             --drop-nonfinite (and remove them from the file), or drop --tile"
                .into(),
        ));
    }
    // The default halo, clipped to the tile (said in the notes).
    let halo = args.halo.unwrap_or(DEFAULT_HALO.min(tile));
    let geometry = TileGeometry::new(plane, tile, halo).map_err(|e| {
        let flag = match e {
            rkwave::image::tiles::TileGeometryError::HaloLargerThanTile { .. } => "--halo",
            _ => "--tile",
        };
        CliError::flag(
            flag,
            rkwave::image::tiles::TiledError::from(rkwave::image::tiles::TileError::from(e)),
        )
    })?;
    let workers = match args.workers {
        Some(0) => {
            return Err(CliError::Invalid(
                "--workers 0: give at least 1 (tiles fitted at once)".into(),
            ))
        }
        Some(n) => n,
        None => TiledParams::default().workers,
    };
    let scratch = match &args.scratch {
        Some(dir) => dir.clone(),
        None => match args.output.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => std::path::PathBuf::from("."),
        },
    };
    if !scratch.is_dir() {
        return Err(CliError::Invalid(format!(
            "--scratch `{}` is not a folder: give an existing folder with room for about the \
             input's size",
            scratch.display()
        )));
    }
    let tiled = TiledParams {
        workers,
        scratch: Some(scratch),
        ..TiledParams::default()
    };
    let bar = if std::io::stderr().is_terminal() {
        ProgressBar::new(geometry.count() as u64)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} tiles {msg} [{elapsed}]")
            .expect("a valid template"),
    );
    let progress = |r: &rkwave::image::tiles::TileReport| {
        bar.set_message(format!("tile {} {:.2} s", r.tile, r.seconds));
        bar.inc(1);
    };
    let out = reconstruct_tiled(
        TiledInput::File(&args.input),
        &geometry,
        wavelet,
        &tiled,
        &progress,
    );
    bar.finish_and_clear();
    let out = out?;
    let t_write = Instant::now();
    write_image(&args.output, &out.image, args.force)?;
    let write_s = t_write.elapsed().as_secs_f64();
    let r = &out.report;
    let mut notes: Vec<String> = Vec::new();
    if args.halo.is_none() && tile < DEFAULT_HALO {
        notes.push(format!(
            "halo {tile}: the default halo {DEFAULT_HALO} clipped to the tile size (a halo is at \
             most one tile)"
        ));
    }
    notes.extend(pinned_note(&r.tiles));
    if let Some(spill) = &r.spill {
        notes.push(format!(
            "spilled {} sample rows ({}) into {} band files in {} ({:.3} s), removed after the fit",
            spill.rows,
            rkwave::resources::format_bytes(spill.bytes as f64),
            spill.bands,
            spill.folder.display(),
            spill.seconds
        ));
    }
    let report = TiledFileReport {
        input: args.input.display().to_string(),
        output: args.output.display().to_string(),
        resolution: plane.to_string(),
        p: wavelet.p,
        rho: wavelet.rho,
        ridge: wavelet.ridge,
        tiled: r,
        time_s: Times {
            read: r.read_s,
            fit: r.fit_s,
            write: write_s,
            total: started.elapsed().as_secs_f64(),
        },
        notes,
    };
    if args.json {
        super::print_json(&report);
    } else {
        println!(
            "{} samples x {} channels -> {plane} pixels by tiles of {} (halo {}, {} x {} tiles, \
             {} workers, {} passes over the input), {:.3} s; wrote {}",
            r.samples,
            r.channels,
            r.tile,
            r.halo,
            r.grid.0,
            r.grid.1,
            r.workers,
            r.passes,
            report.time_s.total,
            args.output.display()
        );
        for note in &report.notes {
            super::print_note(note);
        }
    }
    Ok(())
}

/// One line for the tiles with functions pinned to 0 or pivots replaced: how many, the totals
/// and the three tiles with the most (a 4096² image has a thousand tiles).
fn pinned_note(tiles: &[rkwave::image::tiles::TileReport]) -> Option<String> {
    let mut hit: Vec<_> = tiles
        .iter()
        .filter(|t| t.unsampled > 0 || t.replaced_pivots > 0)
        .collect();
    if hit.is_empty() {
        return None;
    }
    let unsampled: usize = hit.iter().map(|t| t.unsampled).sum();
    let replaced: usize = hit.iter().map(|t| t.replaced_pivots).sum();
    hit.sort_by_key(|t| std::cmp::Reverse(t.unsampled + t.replaced_pivots));
    let most: Vec<String> = hit
        .iter()
        .take(3)
        .map(|t| {
            format!(
                "tile {} (pixels {}): {} + {}",
                t.tile, t.interior, t.unsampled, t.replaced_pivots
            )
        })
        .collect();
    Some(format!(
        "{} of {} tiles have functions without samples pinned to 0 ({unsampled} in all) or \
         Cholesky pivots replaced ({replaced} in all); the most (pinned + replaced): {}",
        hit.len(),
        tiles.len(),
        most.join(", ")
    ))
}
