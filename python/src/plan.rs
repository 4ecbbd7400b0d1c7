//! Adaptive sampling of the image plane in process: `rkwave.Plan`, the renderer's loop of
//! `rkwave plan` without files. The plan is the library's [`PlanState`] (the state machine of
//! `rkwave::image::plan`), driven by the library's plan jobs as the command line drives it
//! (`rkwave::image::job`: [`PlanStart`], [`PlanRound`], [`PlanFinal`]); this class parses the
//! keywords, keeps every sample so far in memory and the positions it handed out for the
//! next round.
//!
//! The state in memory carries the last round's solver state to the next round (under PCG,
//! the plan's default, its start and diagonal, [`PlanState::pcg`]; under the direct solve,
//! the normal matrix, [`PlanState::carried`]), as `rkwave plan` does through `pcg.bin` and
//! `gram.bin`.
//!
//! `save(dir)` writes the state in the format of `rkwave plan --state DIR` (`state.json`,
//! and `pcg.bin` or `gram.bin`),
//! every sample so far as `samples.npy` (`m x (2 + channels)`, what `--samples` and
//! `reconstruct --dim 2 --state` read) and the pending positions as `next.npy` (`n x 2`, what
//! `--out` writes), so a loop can move between the command line and Python either way.

use std::path::{Path, PathBuf};
use std::time::Instant;

use pyo3::prelude::*;
use rkwave::image::adaptive::SamplePositions;
use rkwave::image::job::tiled_plan::TILED_STATE_FILE;
use rkwave::image::job::{PlanFinal, PlanOptions, PlanRound, PlanStart};
use rkwave::image::plan::new_round::ReadSamples;
use rkwave::image::plan::{PlanReconstruction, PlanState, PlanStep};
use rkwave::image::report::plan_fit_notes;
use rkwave::image::{DroppedSamples, ImagePlane, ImageSamples, NonFinitePolicy};
use rkwave::io::output::write_new;
use rkwave::io::plan_files::SAMPLES_FILE;
use rkwave::io::{npy_bytes, read_image_samples, read_samples, SampleSet};
use serde::Serialize;

use crate::arrays::{image_out, positions_out};
use crate::errors::{invalid, to_py, warn_all};
use crate::image::{plane_of, samples_of};
use crate::params::{plan_options, PlanArgs};
use crate::report::to_dict;
use crate::tiled_plan::PlanCore;

/// Seconds a plan spent inside the library (fits, positions, reconstructions) and in this
/// module's own work around it (checks, conversion, copies of the samples).
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct PlanSeconds {
    /// Inside the library's calls.
    pub library: f64,
    /// Everything else this class did.
    pub glue: f64,
}

/// What the plan reports: where it stands, every round's log, the last image's notes.
#[derive(Serialize)]
struct PlanReport<'a> {
    resolution: String,
    budget: usize,
    /// `(tile, halo)` of a tiled plan.
    tiles: Option<(usize, usize)>,
    round: usize,
    handed_out: usize,
    samples: usize,
    done: bool,
    stop: Option<rkwave::refine::StopReason>,
    steps: Steps<'a>,
    time_s: PlanSeconds,
}

/// The rounds' reports: the untiled plan's or the tiled plan's.
#[derive(Serialize)]
#[serde(untagged)]
enum Steps<'a> {
    Untiled(&'a [PlanStep]),
    Tiled(&'a [rkwave::image::job::tiled_plan::TiledStep]),
}

/// Adaptive sampling of the image plane (module docs).
#[pyclass(name = "Plan", module = "rkwave")]
pub struct PyPlan {
    /// The plan: untiled, or on tiles (`tile=`).
    state: PlanCore,
    /// Positions handed out for the round in progress (empty once the plan stopped).
    next: SamplePositions,
    /// Every sample so far, in the order added (those with a finite value).
    samples: Option<ImageSamples>,
    /// The samples dropped for a non-finite value so far (`add(drop_nonfinite=True)`).
    dropped: DroppedSamples,
    steps: Vec<PlanStep>,
    time_s: PlanSeconds,
    /// The folder this plan was loaded from or last saved to (canonical): `save` replaces
    /// its own folder, and another plan's only when asked (`overwrite=True`).
    home: Option<PathBuf>,
    /// The final image made since the last `add`, and whether it is the fit alone
    /// (`image(residual=False)`): asked again, it is not fitted again.
    made: Option<(bool, PlanReconstruction)>,
}

/// `dir` with links and spellings resolved (as given where it does not exist yet).
fn canonical(dir: &Path) -> PathBuf {
    std::fs::canonicalize(dir).unwrap_or_else(|_| dir.to_path_buf())
}

/// A path from a Python `str` or `os.PathLike`, `None` for anything else.
fn path_of(obj: &Bound<'_, PyAny>) -> Option<PathBuf> {
    obj.extract::<PathBuf>().ok()
}

/// Samples `(m, 2 + channels)` as an array or a file (`.npy` or CSV), on `plane`.
fn samples_from(plane: ImagePlane, obj: &Bound<'_, PyAny>) -> PyResult<ImageSamples> {
    if let Some(path) = path_of(obj) {
        return read_image_samples(&path, plane).map_err(to_py);
    }
    let data = crate::arrays::floats(obj, "samples")?;
    let view = data.view();
    if view.ndim() != 2 || !(3..=6).contains(&view.shape()[1]) {
        return Err(invalid(format!(
            "samples must have shape (m, 2 + channels) with 1 to 4 channels, got {}",
            crate::arrays::shape(view.shape())
        )));
    }
    let cols = crate::arrays::columns(&view, "samples")?;
    let mut cols = cols.into_iter().map(|c| c.into_owned());
    let (xs, ys) = (cols.next().expect("x"), cols.next().expect("y"));
    ImageSamples::new(plane, xs, ys, cols.collect()).map_err(to_py)
}

/// Positions `n x 2` from a `.npy` file.
fn positions_file(path: &Path) -> PyResult<SamplePositions> {
    let set = read_samples(path).map_err(to_py)?;
    if set.channels() != 1 {
        return Err(invalid(format!(
            "{}: positions are n x 2 (x, y), this file has {} columns",
            path.display(),
            1 + set.channels()
        )));
    }
    let mut values = set.values;
    Ok(SamplePositions {
        xs: set.positions,
        ys: values.swap_remove(0),
    })
}

/// Positions `(n, 2)` as an array or a `.npy` file.
fn positions_from(obj: &Bound<'_, PyAny>) -> PyResult<SamplePositions> {
    if let Some(path) = path_of(obj) {
        return positions_file(&path);
    }
    let data = crate::arrays::floats(obj, "positions")?;
    let view = data.view();
    if view.ndim() != 2 || view.shape()[1] != 2 {
        return Err(invalid(format!(
            "positions must have shape (n, 2), got {}",
            crate::arrays::shape(view.shape())
        )));
    }
    let cols = crate::arrays::columns(&view, "positions")?;
    Ok(SamplePositions {
        xs: cols[0].to_vec(),
        ys: cols[1].to_vec(),
    })
}

/// `samples` with the samples of `new` appended (the library's join: the same plane and
/// channels, else refused).
pub(crate) fn appended(old: Option<&ImageSamples>, new: ImageSamples) -> PyResult<ImageSamples> {
    rkwave::image::plan::new_round::appended(old, new).map_err(to_py)
}

/// `.npy` bytes of the columns `first`, then `rest`.
fn npy_of(first: &[f64], rest: Vec<Vec<f64>>) -> PyResult<Vec<u8>> {
    let set = SampleSet::new(first.to_vec(), rest).map_err(to_py)?;
    npy_bytes(&set).map_err(to_py)
}

#[pymethods]
impl PyPlan {
    /// A new plan on a `W x H` image with a sample budget (`spp` per pixel on average, or
    /// `budget` in all); the other parameters default as in `rkwave plan`: `solver="pcg"`
    /// (the rounds' fits by warm-started conjugate gradients; `"direct"`: the sparse Cholesky
    /// of the normal matrix carried between rounds, `rkwave plan --solver`) and
    /// `output_pixels="blend"` (the final image's pixels, `rkwave plan --output-pixels`:
    /// also `"shrunk"`, `"auto"`, `"residual_clamped"`, `"residual_corrected"`,
    /// `"fit_only"`, `"box_shrunk"`). Each other keyword is the flag of `rkwave plan` of the
    /// same name (`_` for `-`), with its default: `p`, `rho`, `below_pixel`, `seed`,
    /// `false_alarm`, `min_growth`, `pixel_share` (the share of each round's new samples given
    /// to the pixels by the spread of their own samples, at budgets of at most 4 a pixel; default
    /// 0, off; each round's count is
    /// `report["steps"][k]["log"]["pixel_spread"]`), `pattern` (`"sobol"` or `"stratified"`)
    /// and `spread` (`"indicator"`, `"uncertainty"` or `"uniform"`).
    ///
    /// >>> import rkwave
    /// >>> plan = rkwave.Plan(resolution=(32, 32), spp=4)
    /// >>> plan.positions().shape[1], plan.done
    /// (2, False)
    ///
    /// `tile=T` plans on tiles (the job of `rkwave plan --tile`): a quadtree and its fits per
    /// tile of `T` pixels over a window that holds the tile and its `halo=` (default 0)
    /// grown to a power of two, one global budget shared by the tiles' indicators, memory
    /// bounded by the tile; the final image stitched from the tiles' interiors. A tiled
    /// plan refuses non-finite samples (no `drop_nonfinite`) and a `pixel_share` (its tiles
    /// would place a share the rounds do not report), and gives its image once done.
    ///
    /// >>> plan = rkwave.Plan(resolution=(64, 64), spp=4, tile=32)
    /// >>> plan.report["tiles"]
    /// [32, 0]
    #[new]
    #[pyo3(signature = (resolution, spp=None, budget=None, *, p=None, rho=None,
        below_pixel=None, seed=None, false_alarm=None, min_growth=None, pixel_share=None,
        pattern=None, spread=None, solver=None, output_pixels=None, tile=None, halo=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        resolution: (usize, usize),
        spp: Option<usize>,
        budget: Option<usize>,
        p: Option<usize>,
        rho: Option<f64>,
        below_pixel: Option<u32>,
        seed: Option<u64>,
        false_alarm: Option<f64>,
        min_growth: Option<f64>,
        pixel_share: Option<f64>,
        pattern: Option<&str>,
        spread: Option<&str>,
        solver: Option<&str>,
        output_pixels: Option<&str>,
        tile: Option<usize>,
        halo: Option<usize>,
    ) -> PyResult<Self> {
        let plane = plane_of(resolution)?;
        let options = plan_options(&PlanArgs {
            budget,
            spp,
            p,
            rho,
            below_pixel,
            seed,
            false_alarm,
            min_growth,
            pixel_share,
            pattern,
            spread,
            solver,
            output_pixels,
        })?;
        let t = Instant::now();
        let (state, next) = match tile {
            Some(tile) => {
                let (core, next, notes) = py
                    .detach(|| PlanCore::tiled(plane, &options, tile, halo))
                    .map_err(to_py)?;
                warn_all(py, &notes)?;
                (core, next)
            }
            None => {
                PlanStart::check_halo(tile, halo, false).map_err(to_py)?;
                let start = PlanStart::new(plane, &options).map_err(to_py)?;
                let (state, next) = py.detach(|| start.run()).map_err(to_py)?;
                (PlanCore::Untiled(state), next)
            }
        };
        Ok(Self {
            state,
            next,
            samples: None,
            dropped: DroppedSamples::default(),
            steps: Vec::new(),
            time_s: PlanSeconds {
                library: t.elapsed().as_secs_f64(),
                glue: 0.0,
            },
            home: None,
            made: None,
        })
    }

    /// The positions to render next, `(n, 2)` float64 (x, y in pixel units); `(0, 2)` once
    /// the plan is done. Pass them to `add` as given (the plan recognises its positions).
    ///
    /// >>> import rkwave
    /// >>> xy = rkwave.Plan(resolution=(16, 8), budget=512).positions()
    /// >>> bool((xy[:, 0] <= 16).all() and (xy[:, 1] <= 8).all())
    /// True
    fn positions<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyAny> {
        let t = Instant::now();
        let out = positions_out(py, &self.next.xs, &self.next.ys);
        self.time_s.glue += t.elapsed().as_secs_f64();
        out
    }

    /// Adds the rendered samples of the positions handed out (`xy` `(n, 2)` as returned by
    /// `positions()`, in any order, `values` `(n,)` or `(n, channels)`) and plans the next
    /// round: the fit on every sample so far (the earlier ones kept in memory, as `rkwave plan
    /// --new-samples` keeps them in its folder), then new positions or the stop (`done`).
    /// Samples of another round, another count or positions not those handed out are
    /// refused, naming the round expected. A value that is NaN
    /// or infinite is refused (the error names the count and the first sample; the plan is
    /// unchanged and the round can be added again); `drop_nonfinite=True` drops those
    /// samples, counts them in the round's report and fits the rest.
    ///
    /// >>> import rkwave
    /// >>> plan = rkwave.Plan(resolution=(16, 16), spp=4)
    /// >>> xy = plan.positions(); plan.add(xy, xy[:, 0] / 16)
    /// >>> plan.round
    /// 1
    #[pyo3(signature = (xy, values, *, drop_nonfinite=false))]
    fn add(
        &mut self,
        py: Python<'_>,
        xy: &Bound<'_, PyAny>,
        values: &Bound<'_, PyAny>,
        drop_nonfinite: bool,
    ) -> PyResult<()> {
        if self.state.stop().is_some() {
            return Err(invalid(
                "the plan has stopped: no positions are pending; take the result with image()",
            ));
        }
        if self.state.tiles().is_some() {
            PlanRound::check_tiled_samples(NonFinitePolicy::dropping(drop_nonfinite))
                .map_err(to_py)?;
        }
        let t = Instant::now();
        let (new, dropped) = samples_of(
            self.state.plane(),
            xy,
            values,
            NonFinitePolicy::dropping(drop_nonfinite),
        )?;
        let rows = self.samples.as_ref().map_or(0, ImageSamples::len) + self.dropped.count;
        if let PlanCore::Untiled(state) = &self.state {
            // the new samples must be the round handed out, alone (the command line's
            // `--new-samples` refusals, with the same words)
            state.check_new_round(rows, &new, &dropped).map_err(to_py)?;
        }
        let all = appended(self.samples.as_ref(), new)?;
        let mut all_dropped = self.dropped.clone();
        all_dropped.extend(dropped, rows);
        let t_lib = Instant::now();
        let state = match &mut self.state {
            PlanCore::Untiled(state) => state,
            PlanCore::Tiled(core) => {
                let step = py.detach(|| core.state.advance(&all)).map_err(to_py)?;
                self.made = None;
                let library = t_lib.elapsed().as_secs_f64();
                self.next = step.next.clone();
                self.samples = Some(all);
                core.steps.push(step);
                self.time_s.library += library;
                self.time_s.glue += t.elapsed().as_secs_f64() - library;
                return Ok(());
            }
        };
        let so_far = all_dropped.clone();
        let step = py
            .detach(|| PlanRound::new(state, None, &PlanOptions::default())?.run(&all, so_far))
            .map_err(to_py)?;
        self.made = None;
        self.dropped = all_dropped;
        warn_all(py, &PlanRound::notes(&state.params, &step))?;
        let library = t_lib.elapsed().as_secs_f64();
        self.next = step.next.clone();
        self.samples = Some(all);
        self.steps.push(step);
        self.time_s.library += library;
        self.time_s.glue += t.elapsed().as_secs_f64() - library;
        Ok(())
    }

    /// Whether the plan has stopped (budget spent, tolerance reached, depth limit): then
    /// `positions()` is empty and `image()` is the final image.
    #[getter]
    fn done(&self) -> bool {
        self.state.stop().is_some()
    }

    /// The last round whose positions were handed out (0: the base positions).
    #[getter]
    fn round(&self) -> usize {
        self.state.round()
    }

    /// The image `(H, W, C)` from every sample so far on the tree they were planned for: the
    /// plan's output pixels (`output_pixels=`, by default `blend`), made by the library's
    /// final-image job, the one `rkwave plan --final-image` and `rkwave reconstruct --dim 2
    /// --state` call, so the three give the same pixels; `residual=False` gives the fit's box
    /// pixels alone (as `--no-residual`). Before the plan is done this is an intermediate
    /// image (a warning says so).
    ///
    /// >>> import rkwave, warnings
    /// >>> plan = rkwave.Plan(resolution=(16, 16), spp=4)
    /// >>> xy = plan.positions(); plan.add(xy, xy[:, 0] / 16)
    /// >>> with warnings.catch_warnings():
    /// ...     warnings.simplefilter("ignore")
    /// ...     plan.image().shape
    /// (16, 16, 1)
    #[pyo3(signature = (residual=true))]
    fn image<'py>(&mut self, py: Python<'py>, residual: bool) -> PyResult<Bound<'py, PyAny>> {
        let Some(samples) = &self.samples else {
            return Err(invalid(
                "the plan has no samples yet: render positions() and add() them first",
            ));
        };
        let t = Instant::now();
        let fit_only = !residual;
        if let PlanCore::Tiled(core) = &self.state {
            // the tiled plan's final image: every tile's fit, its interior stitched
            let estimate = fit_only.then_some(rkwave::image::adaptive::PixelEstimate::FitOnly);
            let done = py
                .detach(|| core.state.final_image(samples, estimate))
                .map_err(to_py)?;
            self.time_s.library += t.elapsed().as_secs_f64();
            let plane = core.state.plane;
            return Ok(image_out(
                py,
                &done.image.channels,
                plane.width(),
                plane.height(),
            ));
        }
        let done = match self.made.take() {
            Some((made, done)) if made == fit_only => done,
            _ => {
                // the plan's final image job, as `rkwave plan --final-image` and `rkwave
                // reconstruct --dim 2 --state` make it
                let PlanCore::Untiled(state) = &self.state else {
                    unreachable!("the tiled plan returned above")
                };
                let dropped = self.dropped.clone();
                let stopping = self.steps.last().filter(|s| s.stop.is_some());
                py.detach(|| PlanFinal::of(state, fit_only).run(samples, dropped, stopping))
                    .map_err(to_py)?
            }
        };
        self.time_s.library += t.elapsed().as_secs_f64();
        let t = Instant::now();
        let mut notes = plan_fit_notes(&done);
        notes.extend(done.solver_note.clone());
        notes.extend(done.dropped.note());
        warn_all(py, &notes)?;
        let plane = self.state.plane();
        let out = image_out(py, &done.image.channels, plane.width(), plane.height());
        self.made = Some((fit_only, done));
        self.time_s.glue += t.elapsed().as_secs_f64();
        Ok(out)
    }

    /// Every sample so far, `(m, 2 + channels)`: x, y, values (the file `rkwave plan
    /// --samples` reads); `None` before the first `add`.
    #[getter]
    fn samples<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyAny>> {
        self.samples.as_ref().map(|s| {
            let mut cols = vec![s.xs().to_vec(), s.ys().to_vec()];
            cols.extend(s.values().iter().cloned());
            crate::arrays::channels_out(py, cols, false)
        })
    }

    /// Where the plan stands, as a plain dict: resolution, budget, round, positions handed
    /// out, samples, `done` and the stop reason, every round's log (`steps`, as in `rkwave
    /// plan --json`) and the seconds spent inside the library and around it (`time_s`).
    ///
    /// >>> import rkwave
    /// >>> rkwave.Plan(resolution=(16, 16), spp=4).report["budget"]
    /// 1024
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let report = PlanReport {
            resolution: self.state.plane().to_string(),
            budget: self.state.budget(),
            tiles: self.state.tiles(),
            round: self.state.round(),
            handed_out: self.state.positions(),
            samples: self.samples.as_ref().map_or(0, ImageSamples::len),
            done: self.done(),
            stop: self.state.stop(),
            steps: match &self.state {
                PlanCore::Untiled(_) => Steps::Untiled(&self.steps),
                PlanCore::Tiled(core) => Steps::Tiled(&core.steps),
            },
            time_s: self.time_s,
        };
        to_dict(py, &serde_json::to_string(&report).expect("plain data"))
    }

    /// Writes the plan into `dir` (module docs): `state.json` as `rkwave plan --state DIR`,
    /// `samples.npy` (every sample so far), `samples.bin` (the same samples as `rkwave plan`
    /// keeps them, so the command line can go on with `--new-samples`) and `next.npy` (the
    /// pending positions). A folder
    /// that holds another plan (one this object was neither loaded from nor saved to) is
    /// refused unless `overwrite=True`, as `rkwave plan` refuses one without `--force`.
    ///
    /// >>> import rkwave, tempfile
    /// >>> d = tempfile.mkdtemp(); plan = rkwave.Plan(resolution=(16, 16), spp=4)
    /// >>> plan.save(d); rkwave.Plan.load(d).positions().shape == plan.positions().shape
    /// True
    #[pyo3(signature = (dir, overwrite=false))]
    fn save(&mut self, py: Python<'_>, dir: PathBuf, overwrite: bool) -> PyResult<()> {
        // The command line's one "holds a plan already" refusal; the plan's own folder is
        // its to write.
        if self.home.as_ref() != Some(&canonical(&dir)) {
            PlanState::check_new(&dir, &[dir.join(TILED_STATE_FILE)], overwrite).map_err(to_py)?;
        }
        let state = &self.state;
        let samples = self.samples.as_ref();
        let next = &self.next;
        let dropped = &self.dropped;
        let note = py.detach(|| -> PyResult<Option<String>> {
            state.save(&dir).map_err(to_py)?;
            // the samples read, as `rkwave plan` keeps them for `--new-samples`
            let kept = match (state, samples) {
                (PlanCore::Untiled(s), Some(read)) => s.keep_samples(
                    &dir,
                    &ReadSamples {
                        through: Some(s.round() - usize::from(s.stop.is_none())),
                        samples: Some(read.clone()),
                        dropped: dropped.clone(),
                    },
                    None,
                ),
                _ => None,
            };
            let file = dir.join("samples.npy");
            match samples {
                Some(s) => {
                    let mut rest = vec![s.ys().to_vec()];
                    rest.extend(s.values().iter().cloned());
                    write_new(&file, &npy_of(s.xs(), rest)?, true).map_err(to_py)?;
                }
                None if file.exists() => std::fs::remove_file(&file).map_err(|e| {
                    pyo3::exceptions::PyOSError::new_err(format!(
                        "cannot remove the stale {}: {e}",
                        file.display()
                    ))
                })?,
                None => {}
            }
            let bytes = npy_of(&next.xs, vec![next.ys.clone()])?;
            write_new(&dir.join("next.npy"), &bytes, true).map_err(to_py)?;
            Ok(kept)
        })?;
        warn_all(py, note.as_slice())?;
        self.home = Some(canonical(&dir));
        Ok(())
    }

    /// A plan from `dir`: a state written by `save` or by `rkwave plan --state DIR` (with
    /// `--tile`: `tiled-state.json`, a tiled plan). The
    /// samples so far come from `samples` (an `(m, 2 + channels)` array or a sample file) or
    /// else `DIR/samples.npy`, or else the samples `rkwave plan` kept (`DIR/samples.bin`); the pending positions from `positions` (an `(n, 2)` array or
    /// the `.npy` that `rkwave plan --out` wrote) or else `DIR/next.npy` (a plan at its base
    /// round regenerates them).
    ///
    /// >>> import rkwave, tempfile
    /// >>> d = tempfile.mkdtemp(); rkwave.Plan(resolution=(8, 8), budget=256).save(d)
    /// >>> rkwave.Plan.load(d).report["budget"]
    /// 256
    #[staticmethod]
    #[pyo3(signature = (dir, samples=None, positions=None))]
    fn load(
        dir: PathBuf,
        samples: Option<&Bound<'_, PyAny>>,
        positions: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let state = PlanCore::load(&dir).map_err(|e| e.into_py())?;
        let plane = state.plane();
        let mut dropped = DroppedSamples::default();
        let samples = match samples {
            Some(obj) => Some(samples_from(plane, obj)?),
            None => {
                let file = dir.join("samples.npy");
                match &state {
                    _ if file.exists() => Some(read_image_samples(&file, plane).map_err(to_py)?),
                    // a plan the command line drove with `--new-samples`: the samples it kept
                    PlanCore::Untiled(s) if dir.join(SAMPLES_FILE).exists() => {
                        let (read, _) = s.read_samples(&dir).map_err(to_py)?;
                        dropped = read.dropped;
                        read.samples
                    }
                    _ => None,
                }
            }
        };
        let next = match positions {
            Some(obj) => positions_from(obj)?,
            None if state.stop().is_some() => SamplePositions::default(),
            None => {
                let file = dir.join("next.npy");
                if file.exists() {
                    positions_file(&file)?
                } else if let (PlanCore::Untiled(s), 0, None) = (&state, state.round(), &samples) {
                    PlanState::start(plane, &s.params).map_err(to_py)?.1
                } else {
                    return Err(invalid(format!(
                        "the positions of round {} are not in {}: pass positions= (the .npy \
                         `rkwave plan --out` wrote for that round)",
                        state.round(),
                        dir.display()
                    )));
                }
            }
        };
        Ok(Self {
            state,
            next,
            samples,
            dropped,
            steps: Vec::new(),
            time_s: PlanSeconds::default(),
            home: Some(canonical(&dir)),
            made: None,
        })
    }

    fn __repr__(&self) -> String {
        format!(
            "rkwave.Plan(resolution={}, budget={}, round={}, samples={}, done={}{})",
            self.state.plane(),
            self.state.budget(),
            self.state.round(),
            self.samples.as_ref().map_or(0, ImageSamples::len),
            if self.done() { "True" } else { "False" },
            self.state
                .tiles()
                .map_or(String::new(), |(t, h)| format!(", tile={t}, halo={h}"))
        )
    }
}
