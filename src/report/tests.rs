//! Tests of the experiments: each report agrees with the direct computation it summarises.

use super::reconstruction::{onto_grid, uniform_grid, PerChannel};
use super::scaling::{scaling_run, ScalingMethod, ScalingSetting, SCALING_SIGNALS};
use super::sweep::{sweep, sweep_points, Knob, SweepCsvRow, SweepKnobs};
use super::{local_vs_global, rms, ReportSetting};
use crate::basis::{minimum_level, CdvBasis, FilterFamily};
use crate::io::SampleSet;
use crate::reconstruct::{fit, FitParams};
use crate::sampling::{Domain, Layout, Signal};
use crate::solve::{LocalInversionParams, Solver};

/// A small setting (P = 128 functions, 256 samples) so that every report is fast.
fn small_setting() -> ReportSetting {
    ReportSetting {
        p: 3,
        family: FilterFamily::Extremal,
        coarse: 4,
        fine: 6,
        samples: 256,
        layout: Layout::Uniform,
        seed: 1,
        signal: Signal::Smooth,
        local: LocalInversionParams::default(),
        grid: 512,
    }
}

/// The plan varies one knob at a time and keeps every other at the base value; `p` brings
/// CDV's family and a coarse level inside `[j_min(p), N]`; depth `d` gives `n = N - d`.
#[test]
fn sweep_plan_varies_one_knob_at_a_time() {
    let base = small_setting();
    let knobs = SweepKnobs {
        rings: vec![0, 2],
        p: vec![2, 5],
        depth: vec![1, 2],
        samples: vec![300],
    };
    let points = sweep_points(&base, &knobs);
    assert_eq!(points.len(), 2 + 3 + 2 + 2 + 1);
    for pt in &points {
        let s = &pt.setting;
        let same = |k: Knob| pt.knob == k;
        assert!(same(Knob::Rings) || s.local.rings == base.local.rings);
        assert!(same(Knob::Solver) || s.local.solver == base.local.solver);
        assert!(same(Knob::P) || s.p == base.p);
        assert!(same(Knob::CoarseLevel) || same(Knob::P) || s.coarse == base.coarse);
        assert!(same(Knob::Samples) || s.samples == base.samples);
        assert!(s.coarse >= minimum_level(s.p) && s.coarse <= s.fine);
        assert_eq!(s.family, FilterFamily::cdv_default(s.p));
    }
    let p5 = points
        .iter()
        .find(|pt| pt.knob == Knob::P && pt.setting.p == 5)
        .unwrap();
    assert_eq!(p5.setting.coarse, minimum_level(5).min(base.fine));
    let depth2 = points
        .iter()
        .find(|pt| pt.knob == Knob::CoarseLevel && pt.value() == "4")
        .unwrap();
    assert_eq!(depth2.setting.coarse, 4);
    let solvers: Vec<String> = points
        .iter()
        .filter(|pt| pt.knob == Knob::Solver)
        .map(|pt| pt.value())
        .collect();
    assert_eq!(solvers, ["svd", "qr", "cholesky"]);
}

/// Every sweep row is the report of its setting run alone (the same deterministic
/// computation, so equal to the last bit), its CSV row carries the same numbers, and the
/// figure's curves hold exactly the rows with a dense reference.
#[test]
fn sweep_rows_match_individual_reports() {
    let base = small_setting();
    let knobs = SweepKnobs {
        rings: vec![0, 1],
        p: vec![2],
        depth: vec![1],
        samples: vec![384],
    };
    let mut calls = 0;
    let report = sweep(&base, &knobs, |i, total, _| {
        assert_eq!(i, calls);
        assert_eq!(total, 2 + 3 + 1 + 1 + 1);
        calls += 1;
    })
    .unwrap();
    assert_eq!(calls, report.rows.len());
    for (row, pt) in report.rows.iter().zip(sweep_points(&base, &knobs)) {
        let alone = local_vs_global(&pt.setting).unwrap();
        let (a, b) = (&row.report, &alone);
        assert_eq!(a.functions, b.functions);
        assert_eq!(a.error.map(|e| e.max_abs), b.error.map(|e| e.max_abs));
        assert_eq!(
            a.error.map(|e| e.rel_frobenius),
            b.error.map(|e| e.rel_frobenius)
        );
        assert_eq!(
            a.reconstruction.local_vs_global,
            b.reconstruction.local_vs_global
        );
        assert_eq!(
            a.reconstruction.global_vs_truth,
            b.reconstruction.global_vs_truth
        );
        assert_eq!(a.condition.max, b.condition.max);
        assert_eq!(a.cut, b.cut);
        let csv = SweepCsvRow::from(row);
        assert_eq!(csv.knob, row.knob.name());
        assert_eq!(csv.max_abs, a.error.map(|e| e.max_abs));
        assert_eq!(csv.local_vs_truth, a.reconstruction.local_vs_truth);
        assert_eq!(
            (csv.p, csv.coarse, csv.fine),
            (pt.setting.p, pt.setting.coarse, pt.setting.fine)
        );
        assert_eq!(csv.time_local, a.time_s.local);
    }
    // With one ring around each group, local inversion is the pseudo-inverse to rounding
    // (README: 3.9e-16 at levels 4..8); a few hundred rounding errors of 1e-16 bound it.
    let rings1 = &report.rows[1].report;
    assert_eq!(rings1.setting.local.rings, 1);
    assert!(rings1.error.unwrap().max_abs < 1e-12, "{:?}", rings1.error);
    let curves = report.curves();
    assert_eq!(curves.len(), Knob::ALL.len());
    for c in &curves {
        let rows: Vec<_> = report.rows.iter().filter(|r| r.knob == c.knob).collect();
        assert_eq!(c.points.len(), rows.len());
        for (pt, r) in c.points.iter().zip(rows) {
            assert_eq!(pt.0, r.report.time_s.local);
            assert_eq!(pt.1, r.report.error.unwrap().max_abs.max(1e-17));
        }
    }
}

/// The scaling harness' RMS error is the RMS of a direct fit's evaluation against the true
/// signals on the same grid (the same computation: equal to rounding), and its basis is the
/// direct fit's.
#[test]
fn scaling_rms_matches_a_direct_fit() {
    let setting = ScalingSetting {
        samples: 5000,
        channels: 2,
        method: ScalingMethod::Single,
        grid: 1001,
    };
    let row = scaling_run(&setting).unwrap();
    let domain = Domain::UNIT;
    let xs = Layout::Random.generate(5000, domain, super::scaling::SCALING_SEED);
    let ys: Vec<Vec<f64>> = SCALING_SIGNALS[..2]
        .iter()
        .map(|s| s.sample(domain, &xs))
        .collect();
    let refs: Vec<&[f64]> = ys.iter().map(Vec::as_slice).collect();
    let direct = fit(&xs, &refs, domain, &FitParams::default()).unwrap();
    let grid: Vec<f64> = (0..=1000).map(|i| i as f64 / 1000.0).collect();
    let out = direct.evaluate(&grid).unwrap();
    let expected = (0..2)
        .map(|c| {
            let truth = SCALING_SIGNALS[c].sample(domain, &grid);
            let sq: f64 = out[c]
                .iter()
                .zip(&truth)
                .map(|(a, b)| (a - b).powi(2))
                .sum();
            (sq / 1001.0).sqrt()
        })
        .fold(0.0, f64::max);
    assert!(
        (row.rms_error - expected).abs() <= 1e-12 * expected,
        "{} vs {expected}",
        row.rms_error
    );
    assert_eq!(row.functions, direct.active.len());
    assert_eq!(row.levels, (direct.levels.coarse, direct.levels.fine));
    assert_eq!(row.method, ScalingMethod::Single);
    let uni = uniform_grid(domain, 1001);
    assert_eq!(uni.len(), grid.len());
    assert!(uni.iter().zip(&grid).all(|(a, b)| (a - b).abs() <= 1e-15));
}

/// Method names round-trip and stand for the documented solves.
#[test]
fn scaling_methods() {
    for m in [
        ScalingMethod::Single,
        ScalingMethod::Global,
        ScalingMethod::Local0,
        ScalingMethod::Local1,
    ] {
        assert_eq!(m.name().parse::<ScalingMethod>().unwrap(), m);
    }
    assert!("local2".parse::<ScalingMethod>().is_err());
    let rings = |m: ScalingMethod| match m.method() {
        crate::reconstruct::Method::Local(p) => Some((p.rings, p.solver)),
        _ => None,
    };
    assert_eq!(rings(ScalingMethod::Local0), Some((0, Solver::Svd)));
    assert_eq!(rings(ScalingMethod::Local1), Some((1, Solver::Svd)));
    assert_eq!(rings(ScalingMethod::Single), None);
    assert!(matches!(
        scaling_run(&ScalingSetting {
            samples: 100,
            channels: 1,
            method: ScalingMethod::Single,
            grid: 1,
        }),
        Err(super::scaling::ScalingError::GridTooSmall { grid: 1 })
    ));
}

/// Degree < p polynomials are reproduced: the residual at the samples and the error on the
/// grid are at rounding level (1e-10 leaves room for the condition of the normal equations).
#[test]
fn reconstruction_onto_grid_reproduces_polynomials() {
    let domain = Domain::new(-1.0, 2.0).unwrap();
    let xs = Layout::Jittered.generate(2000, domain, 3);
    let quad: Vec<f64> = xs.iter().map(|x| 1.0 - x + 0.5 * x * x).collect();
    let line: Vec<f64> = xs.iter().map(|x| 3.0 * x).collect();
    let set = SampleSet::new(xs.clone(), vec![quad, line]).unwrap();
    let refs: Vec<&[f64]> = set.values.iter().map(Vec::as_slice).collect();
    let f = fit(&xs, &refs, domain, &FitParams::default()).unwrap();
    // The sink sees every grid point once, in order, with one value vector per channel.
    let (mut xs_seen, mut quad_seen) = (Vec::new(), Vec::new());
    let rec = onto_grid(f, &set, domain, 31, |xs, values| {
        assert_eq!(values.len(), 2);
        xs_seen.extend_from_slice(xs);
        quad_seen.extend_from_slice(&values[0]);
        Ok::<(), crate::reconstruct::ReconstructError>(())
    })
    .unwrap();
    assert_eq!(rec.points, 31);
    assert_eq!(xs_seen, uniform_grid(domain, 31));
    assert_eq!(xs_seen.first(), Some(&-1.0));
    assert_eq!(xs_seen.last(), Some(&2.0));
    for r in &rec.residual_rms {
        assert!(*r < 1e-10, "{r}");
    }
    let truth: Vec<f64> = xs_seen.iter().map(|x| 1.0 - x + 0.5 * x * x).collect();
    assert!(rms(&quad_seen, &truth) < 1e-10);
    assert_eq!(PerChannel::from(vec![0.5]), PerChannel::One(0.5));
    assert_eq!(
        serde_json::to_string(&PerChannel::from(vec![0.5, 1.0])).unwrap(),
        "[0.5,1.0]"
    );
}

/// The basis figure's interior scaling function is `L2`-normalised and orthogonal to the
/// interior wavelet of its level: the trapezoid rule on the figure's 2401 points
/// (h = 1/2400, ~750 points across a support of 5/16) reproduces both to 1e-3.
#[test]
fn basis_figure_curves_are_orthonormal() {
    let basis = CdvBasis::new(3, FilterFamily::Extremal, 4, 8, Domain::UNIT).unwrap();
    let data = super::figures::basis_functions(&basis).unwrap();
    assert_eq!(data.scaling.len(), data.wavelets.len());
    let inner = |a: &[(f64, f64)], b: &[(f64, f64)]| -> f64 {
        let f: Vec<f64> = a.iter().zip(b).map(|(x, y)| x.1 * y.1).collect();
        let h = a[1].0 - a[0].0;
        h * (f.iter().sum::<f64>() - 0.5 * (f[0] + f[f.len() - 1]))
    };
    let mid = data
        .scaling
        .iter()
        .position(|c| c.label.contains("interior"))
        .unwrap();
    let phi = &data.scaling[mid].points;
    let psi = &data.wavelets[mid].points;
    assert!((inner(phi, phi) - 1.0).abs() < 1e-3, "{}", inner(phi, phi));
    assert!((inner(psi, psi) - 1.0).abs() < 1e-3, "{}", inner(psi, psi));
    assert!(inner(phi, psi).abs() < 1e-3, "{}", inner(phi, psi));
}

/// The kernels figure picks samples at both edges and the middle; the reproducing kernel
/// `k_i(x) = sum_a psi_a(lambda_i) psi_a(x)` at the grid point nearest `lambda_i` is positive
/// (it approximates `sum_a psi_a(lambda_i)^2 > 0`).
#[test]
fn kernels_figure_data() {
    let basis = CdvBasis::new(3, FilterFamily::Extremal, 4, 5, Domain::UNIT).unwrap();
    let xs = Layout::Uniform.generate(128, Domain::UNIT, 0);
    let data = super::figures::kernels(&basis, &xs).unwrap();
    assert_eq!(data.picks, vec![0, 3, 64, 124, 127]);
    assert_eq!(data.dual.len(), 5);
    for (c, &i) in data.reproducing.iter().zip(&data.picks) {
        let nearest = c
            .points
            .iter()
            .min_by(|a, b| (a.0 - xs[i]).abs().total_cmp(&(b.0 - xs[i]).abs()))
            .unwrap();
        assert!(nearest.1 > 0.0, "k_{i}({}) = {}", nearest.0, nearest.1);
    }
}
