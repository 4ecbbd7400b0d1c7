//! The local-vs-global report over a grid of knobs, one knob at a time around a base setting
//! (docs/design.md §5): rings `r`, the local solver, vanishing moments `p`, the coarse level `n` (as a
//! depth `N - n` below the finest level) and the number of samples `m` (the oversampling
//! `m / P`).
//!
//! [`sweep_points`] is the plan (plain data: which settings, in which order); [`sweep`] runs
//! [`local_vs_global`] at each and returns a [`SweepReport`], whose rows flatten to
//! [`SweepCsvRow`]s and whose [`SweepReport::curves`] are the figure's data
//! (`max |K~ - K^+|` against local inversion time, one curve per knob).

use serde::Serialize;

use super::{local_vs_global, LocalGlobalReport, ReportSetting};
use crate::basis::{minimum_level, FilterFamily};
use crate::reconstruct::ReconstructError;
use crate::solve::Solver;

/// The knob a sweep row varies.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Knob {
    /// Neighbourhood rings of local inversion.
    #[serde(rename = "rings")]
    Rings,
    /// The dense solver of each local block.
    #[serde(rename = "solver")]
    Solver,
    /// Vanishing moments `p` (family CDV's choice; the coarse level raised to `j_min(p)` when
    /// it would be too small).
    #[serde(rename = "p")]
    P,
    /// Coarse level `n = max(N - depth, j_min(p))`.
    #[serde(rename = "coarse level")]
    CoarseLevel,
    /// Samples `m`.
    #[serde(rename = "samples")]
    Samples,
}

impl Knob {
    /// Every knob, in the order of the sweep.
    pub const ALL: [Knob; 5] = [
        Knob::Rings,
        Knob::Solver,
        Knob::P,
        Knob::CoarseLevel,
        Knob::Samples,
    ];

    /// The knob's name in tables and legends.
    pub fn name(self) -> &'static str {
        match self {
            Knob::Rings => "rings",
            Knob::Solver => "solver",
            Knob::P => "p",
            Knob::CoarseLevel => "coarse level",
            Knob::Samples => "samples",
        }
    }
}

/// The values each knob takes (the solver always takes SVD, QR and Cholesky).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SweepKnobs {
    /// Rings.
    pub rings: Vec<usize>,
    /// Vanishing moments.
    pub p: Vec<usize>,
    /// Depths `N - n` of the coarse level below the finest level.
    pub depth: Vec<u32>,
    /// Sample counts.
    pub samples: Vec<usize>,
}

impl Default for SweepKnobs {
    /// The sweep of the README: rings 0..2, p 2..5, depth 1..4, 640 to 4096 samples.
    fn default() -> Self {
        Self {
            rings: vec![0, 1, 2],
            p: vec![2, 3, 4, 5],
            depth: vec![1, 2, 3, 4],
            samples: vec![640, 1024, 2048, 4096],
        }
    }
}

/// One planned setting of a sweep.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct SweepPoint {
    /// The knob varied.
    pub knob: Knob,
    /// The full setting (every other knob at the base value).
    pub setting: ReportSetting,
}

impl SweepPoint {
    /// The knob's value as printed: rings, solver name, `p`, the resulting coarse level `n`,
    /// or the sample count.
    pub fn value(&self) -> String {
        let s = &self.setting;
        match self.knob {
            Knob::Rings => s.local.rings.to_string(),
            Knob::Solver => solver_name(s.local.solver).to_string(),
            Knob::P => s.p.to_string(),
            Knob::CoarseLevel => s.coarse.to_string(),
            Knob::Samples => s.samples.to_string(),
        }
    }
}

/// Lower-case name of a local solver.
pub fn solver_name(solver: Solver) -> &'static str {
    match solver {
        Solver::Svd => "svd",
        Solver::Qr => "qr",
        Solver::Cholesky => "cholesky",
    }
}

/// The plan: every setting of the sweep around `base`, knob by knob in [`Knob::ALL`] order.
///
/// Varying `p` also sets the family to CDV's choice for that `p` and clamps the coarse level
/// to `j_min(p) <= n <= N`; varying the depth `d` sets `n = max(N - d, j_min(p))`.
pub fn sweep_points(base: &ReportSetting, knobs: &SweepKnobs) -> Vec<SweepPoint> {
    let mut points = Vec::new();
    let mut push = |knob, setting| points.push(SweepPoint { knob, setting });
    for &r in &knobs.rings {
        let mut s = *base;
        s.local.rings = r;
        push(Knob::Rings, s);
    }
    for solver in [Solver::Svd, Solver::Qr, Solver::Cholesky] {
        let mut s = *base;
        s.local.solver = solver;
        push(Knob::Solver, s);
    }
    for &p in &knobs.p {
        let mut s = *base;
        s.p = p;
        s.family = FilterFamily::cdv_default(p);
        s.coarse = s.coarse.max(minimum_level(p)).min(s.fine);
        push(Knob::P, s);
    }
    for &d in &knobs.depth {
        let mut s = *base;
        s.coarse = s.fine.saturating_sub(d).max(minimum_level(s.p));
        push(Knob::CoarseLevel, s);
    }
    for &m in &knobs.samples {
        let mut s = *base;
        s.samples = m;
        push(Knob::Samples, s);
    }
    points
}

/// One row of a sweep: the knob, its value and the full report.
#[derive(Clone, Debug, Serialize)]
pub struct SweepRow {
    /// The knob varied.
    pub knob: Knob,
    /// Its value as printed (see [`SweepPoint::value`]).
    pub value: String,
    /// The report at this setting.
    pub report: LocalGlobalReport,
}

/// The sweep: its base setting and one row per planned setting.
#[derive(Clone, Debug, Serialize)]
pub struct SweepReport {
    /// The base setting.
    pub base: ReportSetting,
    /// The rows, in plan order.
    pub rows: Vec<SweepRow>,
}

/// Runs the sweep; `progress` is called before each report with its index, the total and
/// the point (e.g. for a progress bar).
pub fn sweep(
    base: &ReportSetting,
    knobs: &SweepKnobs,
    mut progress: impl FnMut(usize, usize, &SweepPoint),
) -> Result<SweepReport, ReconstructError> {
    let points = sweep_points(base, knobs);
    let total = points.len();
    let mut rows = Vec::with_capacity(total);
    for (i, point) in points.iter().enumerate() {
        progress(i, total, point);
        rows.push(SweepRow {
            knob: point.knob,
            value: point.value(),
            report: local_vs_global(&point.setting)?,
        });
    }
    Ok(SweepReport { base: *base, rows })
}

/// A sweep row flattened to the columns of `sweep.csv` (the element-wise errors are empty
/// where the dense reference was out of reach).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SweepCsvRow {
    /// Knob name.
    pub knob: &'static str,
    /// Knob value.
    pub value: String,
    /// Vanishing moments.
    pub p: usize,
    /// Coarse level `n`.
    pub coarse: u32,
    /// Finest level `N`.
    pub fine: u32,
    /// Samples `m`.
    pub samples: usize,
    /// Rings.
    pub rings: usize,
    /// Local solver.
    pub solver: &'static str,
    /// Median rows of a local block.
    pub rows_median: f64,
    /// Median columns of a local block.
    pub cols_median: f64,
    /// `max |K~ - K^+|`.
    pub max_abs: Option<f64>,
    /// RMS of `K~ - K^+`.
    pub rms: Option<f64>,
    /// `||K~ - K^+||_F / ||K^+||_F`.
    pub rel_frobenius: Option<f64>,
    /// RMS of `K~ f - K^+ f` on the grid.
    pub local_vs_global: f64,
    /// RMS of `K~ f` against the signal.
    pub local_vs_truth: f64,
    /// RMS of `K^+ f` against the signal.
    pub global_vs_truth: f64,
    /// Largest local condition number.
    pub condition_max: f64,
    /// Seconds building `K`.
    pub time_kernel: f64,
    /// Seconds of local inversion.
    pub time_local: f64,
    /// Seconds of the global reference.
    pub time_global: f64,
}

impl From<&SweepRow> for SweepCsvRow {
    fn from(row: &SweepRow) -> Self {
        let r = &row.report;
        let s = &r.setting;
        Self {
            knob: row.knob.name(),
            value: row.value.clone(),
            p: s.p,
            coarse: s.coarse,
            fine: s.fine,
            samples: s.samples,
            rings: s.local.rings,
            solver: solver_name(s.local.solver),
            rows_median: r.submatrix.rows.median,
            cols_median: r.submatrix.cols.median,
            max_abs: r.error.map(|e| e.max_abs),
            rms: r.error.map(|e| e.rms),
            rel_frobenius: r.error.map(|e| e.rel_frobenius),
            local_vs_global: r.reconstruction.local_vs_global,
            local_vs_truth: r.reconstruction.local_vs_truth,
            global_vs_truth: r.reconstruction.global_vs_truth,
            condition_max: r.condition.max,
            time_kernel: r.time_s.kernel,
            time_local: r.time_s.local,
            time_global: r.time_s.global,
        }
    }
}

/// One curve of the sweep figure: a knob's `(local inversion time, max |K~ - K^+|)` points.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SweepCurve {
    /// The knob.
    pub knob: Knob,
    /// `(seconds, max |K~ - K^+|)` per row of the knob with a dense reference, floored at
    /// `1e-17` so that exact agreement stays on a log axis.
    pub points: Vec<(f64, f64)>,
}

impl SweepReport {
    /// The rows as `sweep.csv` rows.
    pub fn csv_rows(&self) -> Vec<SweepCsvRow> {
        self.rows.iter().map(SweepCsvRow::from).collect()
    }

    /// The figure's data: one curve per knob, in [`Knob::ALL`] order.
    pub fn curves(&self) -> Vec<SweepCurve> {
        Knob::ALL
            .iter()
            .map(|&knob| SweepCurve {
                knob,
                points: self
                    .rows
                    .iter()
                    .filter(|r| r.knob == knob)
                    .filter_map(|r| {
                        let e = r.report.error.as_ref()?;
                        Some((r.report.time_s.local, e.max_abs.max(1e-17)))
                    })
                    .collect(),
            })
            .collect()
    }
}
