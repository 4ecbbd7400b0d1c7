//! The uniform image fit's solvers on one sample file: the Gaussian film splat, the sparse
//! Cholesky and Jacobi PCG at several tolerances, each with its stage times (wall) and the
//! largest pixel difference from the Cholesky's box pixels.
//!
//! `cargo run --release --example uniform_fit_probe -- SAMPLES.npy SIZE` (a `SIZE x SIZE`
//! image; `benches/uniform_speed.py` writes such a file); `ONLY=TEXT` runs the solvers whose
//! name contains `TEXT`.

use std::path::Path;
use std::time::Instant;

use rkwave::image::filters::GaussianFilter;
use rkwave::image::fit::{NormalSolver, StencilPreconditioner};
use rkwave::image::pixels::{fit_pixels, PixelFilter};
use rkwave::image::splat::splat;
use rkwave::image::{fit_image, ImageFitParams, ImagePlane, NonFinitePolicy};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        return Err("usage: uniform_fit_probe SAMPLES.npy SIZE".into());
    }
    let size: usize = args[1].parse()?;
    let plane = ImagePlane::new(size, size)?;
    let (s, _) =
        rkwave::io::read_image_samples_with(Path::new(&args[0]), plane, NonFinitePolicy::Refuse)?;
    let refs: Vec<&[f64]> = s.values().iter().map(|v| v.as_slice()).collect();
    let t0 = Instant::now();
    let _ = splat(&s, &GaussianFilter::default());
    println!("splat: wall {:.3} s", t0.elapsed().as_secs_f64());
    let mut solvers = vec![("cholesky".to_string(), NormalSolver::Cholesky)];
    for tolerance in [1e-4, 1e-6, 1e-8, 1e-10] {
        let cg = NormalSolver::Cg {
            preconditioner: StencilPreconditioner::Jacobi,
            tolerance,
            forward_error: None,
            max_iterations: 1000,
        };
        solvers.push((format!("jacobi {tolerance:e}"), cg));
    }
    // the residual tolerance 1e-6 with the forward-error stop at several tolerances
    for forward_error in [1e-3, 1e-4, 1e-5, 1e-6] {
        let cg = NormalSolver::Cg {
            preconditioner: StencilPreconditioner::Jacobi,
            tolerance: 1e-6,
            forward_error: Some(forward_error),
            max_iterations: 1000,
        };
        solvers.push((format!("jacobi 1e-6 forward {forward_error:e}"), cg));
    }
    solvers.push(("default".to_string(), NormalSolver::default_cg()));
    let only = std::env::var("ONLY").ok();
    let mut reference: Option<Vec<Vec<f64>>> = None;
    for (name, solver) in solvers {
        if only.as_deref().is_some_and(|o| !name.contains(o)) {
            continue;
        }
        let params = ImageFitParams {
            solver,
            ..ImageFitParams::default()
        };
        let t0 = Instant::now();
        let fit = fit_image(size, size, s.xs(), s.ys(), &refs, &params)?;
        let pixels = fit_pixels(&fit, PixelFilter::Box)?;
        let wall = t0.elapsed().as_secs_f64();
        let t = fit.report.timings;
        let cg = fit.report.cg.as_ref().map_or(String::new(), |r| {
            let list = |v: &[f64]| v.iter().map(|x| format!("{x:.1e}")).collect::<Vec<_>>();
            format!(
                "iterations {:?} residuals {:?} forward-error bounds {:?}{}",
                r.iterations,
                list(&r.residual),
                r.forward_error.as_deref().map(list),
                r.fallback
                    .as_ref()
                    .map_or("", |_| " (fell back to the Cholesky)")
            )
        });
        let gap = reference.as_ref().map_or("-".to_string(), |r| {
            let g = r
                .iter()
                .flatten()
                .zip(pixels.iter().flatten())
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            format!("{g:.1e}")
        });
        println!(
            "{name}: wall {wall:.3} s (accumulate {:.3}, factor {:.3}, solve {:.3}) {cg}; \
             largest pixel difference from the Cholesky {gap}",
            t.accumulate_s, t.factor_s, t.solve_s
        );
        reference.get_or_insert(pixels);
    }
    Ok(())
}
