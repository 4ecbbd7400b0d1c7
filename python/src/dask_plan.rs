//! The tiled plan's rounds as tasks, one per band of tile rows (`rkwave.dask.TiledPlan`; the
//! library's seam `rkwave::image::job::tiled_plan::{HeldBandTask, BandedRound}`).
//!
//! The client holds a `_rkwave.TiledPlanRounds`: every sample so far, the plan's state with
//! each tile's record (its state without the refinement history and PCG's start) and the
//! digest of every band's states held elsewhere. A round is `begin(xy, values)` (the samples
//! checked as `Plan(tile=).add` checks them, the shares computed, nothing changed: a refused
//! round leaves the plan as it was), which gives a pending round and its band tasks
//! `(task, samples, rows)`: the task as JSON bytes (the band's stepped tiles' records, their
//! shares and the digest of the band's held states it steps), the band's samples as a planar
//! `(2 + C, m)` float64 array and its tile rows (the band's name from round to round: its
//! samples grow only at their end, so a worker may keep them and be sent only the new
//! columns). Any process runs a task with `tiled_plan_band(task, held, samples)`, `held` the
//! band's `HeldBand` (its tiles' whole states: the previous round's output for the band, or
//! `held_band(rows)` from the client for a band never stepped, or `initial_band(rows)`
//! replayed through the band's earlier tasks), which gives the band's outcome as JSON bytes
//! and the band's new `HeldBand`; then `commit(pending, outcomes)` takes the round as one
//! step, or refuses it whole. The final image is `final_tasks()`,
//! `tiled_plan_final_band(task, held, samples)` per band and `stitch(strips)`;
//! `state_json(held)` writes the whole state from the held bands.

use numpy::{IntoPyArray, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyTuple};

use rkwave::image::adaptive::{PixelEstimate, SamplePositions};
use rkwave::image::job::tiled_plan::{
    BandStrip, BandedRound, HeldBand, HeldBandOutcome, HeldBandTask, HeldBands, HeldFinalBandTask,
    RoundPlan, TiledPlanOptions, TiledPlanStart, TiledPlanState, TiledStep,
};
use rkwave::image::{ImagePlane, ImageSamples, NonFinitePolicy};
use serde::Serialize;

use crate::arrays::{image_out, positions_out};
use crate::errors::{invalid, to_py, warn_all};
use crate::image::{plane_of, samples_of};
use crate::params::{plan_options, PlanArgs};
use crate::plan::appended;
use crate::report::to_dict;

/// Samples as a planar `(2 + C, m)` array: x, y, then each channel.
fn planar<'py>(py: Python<'py>, s: &ImageSamples) -> Bound<'py, PyAny> {
    let m = s.len();
    let mut flat = Vec::with_capacity((2 + s.channels()) * m);
    flat.extend_from_slice(s.xs());
    flat.extend_from_slice(s.ys());
    for v in s.values() {
        flat.extend_from_slice(v);
    }
    numpy::ndarray::Array2::from_shape_vec((2 + s.channels(), m), flat)
        .expect("rows of m")
        .into_pyarray(py)
        .into_any()
}

/// A planar `(2 + C, m)` array back to samples on `plane` (checked).
fn from_planar(plane: ImagePlane, a: &PyReadonlyArray2<'_, f64>) -> PyResult<ImageSamples> {
    let a = a.as_array();
    if a.nrows() < 3 {
        return Err(invalid(format!(
            "band samples must have shape (2 + channels, m), got ({}, {})",
            a.nrows(),
            a.ncols()
        )));
    }
    let mut rows = a.rows().into_iter().map(|r| r.to_vec());
    let (xs, ys) = (rows.next().expect("x"), rows.next().expect("y"));
    ImageSamples::new(plane, xs, ys, rows.collect()).map_err(to_py)
}

/// JSON bytes of `value` (plain data: it serialises).
fn json_bytes<'py, T: Serialize>(py: Python<'py>, value: &T) -> Bound<'py, PyBytes> {
    PyBytes::new(py, &serde_json::to_vec(value).expect("plain data"))
}

/// A task or outcome read back from JSON bytes, named in the error.
fn from_json<T: serde::de::DeserializeOwned>(bytes: &[u8], what: &str) -> PyResult<T> {
    serde_json::from_slice(bytes).map_err(|e| {
        invalid(format!(
            "{what} could not be read ({e}): give the bytes the plan's client made"
        ))
    })
}

/// A band's tiles' whole states, held by the worker that steps the band (module docs;
/// `rkwave::image::job::tiled_plan::HeldBand`). Pickles as its JSON bytes.
#[pyclass(name = "HeldBand", module = "rkwave", frozen)]
pub struct PyHeldBand {
    band: HeldBand,
}

#[pymethods]
impl PyHeldBand {
    /// The band's tile rows `(r0, r1)`.
    #[getter]
    fn rows(&self) -> (usize, usize) {
        (self.band.rows().start, self.band.rows().end)
    }

    /// The states' digest (16 hex digits).
    #[getter]
    fn digest(&self) -> String {
        format!("{:016x}", self.band.digest())
    }

    /// Pickling: the JSON bytes, rebuilt by `rkwave._rkwave._held_band_from_bytes`.
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        let rebuild = py
            .import("rkwave._rkwave")?
            .getattr("_held_band_from_bytes")?;
        let state = (json_bytes(py, &self.band),);
        PyTuple::new(py, [rebuild, state.into_pyobject(py)?.into_any()])
    }

    fn __repr__(&self) -> String {
        format!(
            "rkwave.HeldBand(rows={:?}, tiles={}, digest={:016x})",
            self.band.rows(),
            self.band.tiles().len(),
            self.band.digest()
        )
    }
}

/// Rebuilds a pickled `HeldBand` (`HeldBand.__reduce__`).
#[pyfunction]
pub fn _held_band_from_bytes(bytes: &[u8]) -> PyResult<PyHeldBand> {
    Ok(PyHeldBand {
        band: from_json(bytes, "a band's held states")?,
    })
}

/// Runs one band's step of a round (module docs): `task` as `begin` made it, `held` the
/// band's `HeldBand` of the digest the task names, `samples` its planar `(2 + C, m)`
/// samples; returns the band's outcome as JSON bytes and its new `HeldBand`. A pure function
/// of its inputs: run again, it gives the same bytes and states.
#[pyfunction]
pub fn tiled_plan_band<'py>(
    py: Python<'py>,
    task: &[u8],
    held: &PyHeldBand,
    samples: PyReadonlyArray2<'py, f64>,
) -> PyResult<(Bound<'py, PyBytes>, PyHeldBand)> {
    let task: HeldBandTask = from_json(task, "the band task")?;
    let samples = from_planar(task.band.plane, &samples)?;
    let (outcome, band) = py
        .detach(|| task.run(&held.band, &samples))
        .map_err(to_py)?;
    Ok((json_bytes(py, &outcome), PyHeldBand { band }))
}

/// Runs one band's part of the final image from its `HeldBand`: `(r0, r1, y0, y1, pixels)`,
/// the band's tile rows, its image rows and their pixels `(y1 - y0, W, C)`.
#[pyfunction]
pub fn tiled_plan_final_band<'py>(
    py: Python<'py>,
    task: &[u8],
    held: &PyHeldBand,
    samples: PyReadonlyArray2<'py, f64>,
) -> PyResult<(usize, usize, usize, usize, Bound<'py, PyAny>)> {
    let task: HeldFinalBandTask = from_json(task, "the final band task")?;
    let samples = from_planar(task.task.band.plane, &samples)?;
    let strip = py
        .detach(|| task.run(&held.band, &samples))
        .map_err(to_py)?;
    let width = task.task.band.plane.width();
    let pixels = image_out(py, &strip.channels, width, strip.y.len());
    Ok((
        strip.rows.start,
        strip.rows.end,
        strip.y.start,
        strip.y.end,
        pixels,
    ))
}

/// A band's task as Python sees it: the task's JSON bytes, the band's samples as a planar
/// `(2 + C, m)` array (every sample in one of its tiles' windows, in the order handed out, so
/// a later round's are this round's followed by the new ones), and its tile rows `(r0, r1)`.
type BandTaskOut<'py> = (Bound<'py, PyBytes>, Bound<'py, PyAny>, (usize, usize));

/// A round begun and not yet committed: its plan and the samples it is on.
#[pyclass(name = "PendingRound", module = "rkwave")]
pub struct PyPendingRound {
    plan: RoundPlan,
    samples: ImageSamples,
}

/// The client's side of a tiled plan run as band tasks (module docs).
#[pyclass(name = "TiledPlanRounds", module = "rkwave")]
pub struct PyTiledPlanRounds {
    state: TiledPlanState,
    next: SamplePositions,
    samples: Option<ImageSamples>,
    steps: Vec<TiledStep>,
    rows_per_task: usize,
    threads: usize,
    held: HeldBands,
}

#[derive(Serialize)]
struct RoundsReport<'a> {
    resolution: String,
    budget: usize,
    tiles: (usize, usize),
    rows_per_task: usize,
    threads: usize,
    tasks_per_round: usize,
    round: usize,
    handed_out: usize,
    samples: usize,
    done: bool,
    stop: Option<rkwave::refine::StopReason>,
    bands_held: usize,
    steps: &'a [TiledStep],
}

#[pymethods]
impl PyTiledPlanRounds {
    /// A new tiled plan (the keywords of `rkwave.Plan(tile=...)`), its rounds in bands of
    /// `rows_per_task` tile rows, `threads` tiles at once inside a band's task (its memory
    /// check counts that many tile fits at once).
    #[new]
    #[pyo3(signature = (resolution, spp=None, budget=None, *, tile, halo=None, p=None,
        rho=None, below_pixel=None, seed=None, false_alarm=None, min_growth=None,
        pixel_share=None, pattern=None, spread=None, solver=None, output_pixels=None,
        rows_per_task=1, threads=1))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        resolution: (usize, usize),
        spp: Option<usize>,
        budget: Option<usize>,
        tile: usize,
        halo: Option<usize>,
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
        rows_per_task: usize,
        threads: usize,
    ) -> PyResult<Self> {
        if rows_per_task == 0 || threads == 0 {
            return Err(invalid(format!(
                "rows_per_task={rows_per_task}, threads={threads}: give both at least 1 (tile \
                 rows per task, tiles stepped at once in a task)"
            )));
        }
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
        let tiles = TiledPlanOptions {
            tile,
            halo,
            workers: Some(threads),
        };
        let start = TiledPlanStart::new(plane, &options, &tiles).map_err(to_py)?;
        let (state, next) = py.detach(|| start.run(3)).map_err(to_py)?;
        warn_all(py, &start.notes())?;
        Ok(Self {
            state,
            next,
            samples: None,
            steps: Vec::new(),
            rows_per_task,
            threads,
            held: HeldBands::default(),
        })
    }

    /// The positions to render next, `(n, 2)`; `(0, 2)` once the plan is done.
    fn positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        positions_out(py, &self.next.xs, &self.next.ys)
    }

    /// Begins a round on the rendered samples of the positions handed out (`xy` `(n, 2)`,
    /// `values` `(n,)` or `(n, C)`): checked, the shares computed, nothing changed. Returns
    /// `(pending, tasks)`, `tasks` a list of `(task bytes, planar samples, tile rows)`; `pending` is
    /// `None` when the plan stopped here (then committed already, `tasks` empty).
    #[allow(clippy::type_complexity)]
    fn begin<'py>(
        &mut self,
        py: Python<'py>,
        xy: &Bound<'py, PyAny>,
        values: &Bound<'py, PyAny>,
    ) -> PyResult<(Option<PyPendingRound>, Vec<BandTaskOut<'py>>)> {
        if self.state.stop.is_some() {
            return Err(invalid(
                "the plan has stopped: no positions are pending; take the result with image()",
            ));
        }
        let (new, _) = samples_of(
            self.state.plane,
            xy,
            values,
            NonFinitePolicy::dropping(false),
        )?;
        let all = appended(self.samples.as_ref(), new)?;
        let mut state = self.state.clone();
        let (rows, threads) = (self.rows_per_task, self.threads);
        let begun = py
            .detach(|| state.begin_round(&all, rows, threads))
            .map_err(to_py)?;
        match begun {
            BandedRound::Stopped(step) => {
                self.state = state;
                self.next = step.next.clone();
                self.samples = Some(all);
                self.steps.push(step);
                Ok((None, Vec::new()))
            }
            BandedRound::Steps(mut plan) => {
                let tasks = self
                    .state
                    .held_tasks(&mut plan, &self.held)
                    .into_iter()
                    .map(|(t, s)| {
                        let rows = (t.band.rows.start, t.band.rows.end);
                        (json_bytes(py, &t), planar(py, &s), rows)
                    })
                    .collect();
                let pending = PyPendingRound { plan, samples: all };
                Ok((Some(pending), tasks))
            }
        }
    }

    /// Commits a pending round from its bands' outcomes (JSON bytes of `tiled_plan_band`),
    /// as one step: refused whole, the plan unchanged, when an outcome is missing, repeated,
    /// of another round or stepped from other held states than the band's, or the plan moved
    /// on since `begin`. The bands' new states' digests are recorded (their states stay
    /// where the tasks ran).
    fn commit(&mut self, pending: &PyPendingRound, outcomes: Vec<Vec<u8>>) -> PyResult<()> {
        let outcomes = outcomes
            .iter()
            .map(|b| from_json::<HeldBandOutcome>(b, "a band's outcome"))
            .collect::<PyResult<Vec<_>>>()?;
        let step = self
            .state
            .commit_held_round(&pending.plan, &mut self.held, outcomes)
            .map_err(to_py)?;
        self.next = step.next.clone();
        self.samples = Some(pending.samples.clone());
        self.steps.push(step);
        Ok(())
    }

    /// The final image's band tasks, `(task bytes, planar samples, tile rows)` per band: the plan's
    /// output pixels, or the fit's alone (`residual=False`).
    #[pyo3(signature = (residual=true))]
    fn final_tasks<'py>(&self, py: Python<'py>, residual: bool) -> PyResult<Vec<BandTaskOut<'py>>> {
        let Some(samples) = &self.samples else {
            return Err(invalid(
                "the plan has no samples yet: render positions() and add() them first",
            ));
        };
        let estimate = (!residual).then_some(PixelEstimate::FitOnly);
        let (rows, threads) = (self.rows_per_task, self.threads);
        let tasks = py
            .detach(|| self.state.final_bands(samples, estimate, rows, threads))
            .map_err(to_py)?;
        Ok(tasks
            .into_iter()
            .map(|(t, s)| {
                let rows = (t.band.rows.start, t.band.rows.end);
                let d = self.state.band_digest(&self.held, &t.band.rows);
                let t = HeldFinalBandTask::new(t, d);
                (json_bytes(py, &t), planar(py, &s), rows)
            })
            .collect())
    }

    /// The band `(r0, r1)`'s whole states from the client, for a band whose states are not
    /// held elsewhere (never stepped); refused for a held band (use its held states, or
    /// `initial_band` and a replay).
    fn held_band(&self, rows: (usize, usize)) -> PyResult<PyHeldBand> {
        let rows = self.band_rows(rows)?;
        if let Some(d) = self.held.get(&rows) {
            return Err(invalid(format!(
                "tile rows {rows:?}' states are held by a worker (digest {d:016x}), not the                  client: use the band's held states, or replay it from initial_band"
            )));
        }
        Ok(PyHeldBand {
            band: self.state.held_band(rows),
        })
    }

    /// The band `(r0, r1)`'s states at the plan's start (a replay's first input).
    fn initial_band(&self, rows: (usize, usize)) -> PyResult<PyHeldBand> {
        let rows = self.band_rows(rows)?;
        Ok(PyHeldBand {
            band: self.state.initial_band(rows),
        })
    }

    /// The tile rows `(r0, r1)` of the bands whose states are held elsewhere.
    #[getter]
    fn held_bands(&self) -> Vec<(usize, usize)> {
        self.held.iter().map(|(r, _)| (r.start, r.end)).collect()
    }

    /// The image `(H, W, C)` from every band's strip `(r0, r1, y0, y1, pixels)` (as
    /// `tiled_plan_final_band` gives them, in any order), each band once.
    #[allow(clippy::type_complexity)]
    fn stitch<'py>(
        &self,
        py: Python<'py>,
        strips: Vec<(usize, usize, usize, usize, PyReadonlyArray3<'py, f64>)>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let channels = self.channels().ok_or_else(|| {
            invalid("the plan has no samples yet: render positions() and add() them first")
        })?;
        let strips = strips
            .into_iter()
            .map(|(r0, r1, y0, y1, px)| {
                let px = px.as_array();
                let (h, w, c) = px.dim();
                let channels = (0..c)
                    .map(|k| {
                        let mut v = Vec::with_capacity(h * w);
                        for y in 0..h {
                            v.extend((0..w).map(|x| px[(y, x, k)]));
                        }
                        v
                    })
                    .collect();
                BandStrip {
                    rows: r0..r1,
                    y: y0..y1,
                    channels,
                }
            })
            .collect();
        let done = self.state.stitch_bands(strips, channels).map_err(to_py)?;
        let plane = self.state.plane;
        Ok(image_out(
            py,
            &done.image.channels,
            plane.width(),
            plane.height(),
        ))
    }

    /// Whether the plan has stopped.
    #[getter]
    fn done(&self) -> bool {
        self.state.stop.is_some()
    }

    /// The last round whose positions were handed out.
    #[getter]
    fn round(&self) -> usize {
        self.state.round()
    }

    /// The channels of the samples so far (`None` before the first round).
    #[getter]
    fn channels(&self) -> Option<usize> {
        self.samples.as_ref().map(ImageSamples::channels)
    }

    /// Where the plan stands, as a plain dict (as `Plan.report`, and the bands' layout).
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let rows = self.state.geometry().grid().1;
        let report = RoundsReport {
            resolution: self.state.plane.to_string(),
            budget: self.state.params.stop.budget,
            tiles: (self.state.tile, self.state.halo),
            rows_per_task: self.rows_per_task,
            threads: self.threads,
            tasks_per_round: rows.div_ceil(self.rows_per_task),
            round: self.state.round(),
            handed_out: self.state.positions(),
            samples: self.samples.as_ref().map_or(0, ImageSamples::len),
            done: self.done(),
            stop: self.state.stop,
            bands_held: self.held.len(),
            steps: &self.steps,
        };
        to_dict(py, &serde_json::to_string(&report).expect("plain data"))
    }

    /// The plan's state as the JSON of `rkwave plan --tile --state` (`tiled-state.json`),
    /// the held bands' whole states spliced in (`held`: every band of `held_bands` with its
    /// recorded digest, else refused).
    #[pyo3(signature = (held=Vec::new()))]
    fn state_json(&self, held: Vec<PyRef<'_, PyHeldBand>>) -> PyResult<String> {
        let bands: Vec<HeldBand> = held.iter().map(|b| b.band.clone()).collect();
        let whole = self.state.with_held(&self.held, &bands).map_err(to_py)?;
        Ok(whole.to_json())
    }
}

impl PyTiledPlanRounds {
    /// `(r0, r1)` checked to be one of the plan's bands.
    fn band_rows(&self, rows: (usize, usize)) -> PyResult<std::ops::Range<usize>> {
        let grid_rows = self.state.geometry().grid().1;
        let bands = rkwave::image::job::tiled_plan::tile_row_bands(grid_rows, self.rows_per_task);
        let rows = rows.0..rows.1;
        if !bands.contains(&rows) {
            return Err(invalid(format!(
                "tile rows {rows:?} are not a band of this plan ({} tile rows, {} a band): give                  the rows of a task",
                grid_rows, self.rows_per_task
            )));
        }
        Ok(rows)
    }
}
