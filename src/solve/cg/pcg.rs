//! The lockstep preconditioned conjugate gradient of [`super`]: one run per channel, the
//! products of the channels still iterating batched into one call of the operator and one
//! of the preconditioner per iteration.

use rayon::prelude::*;

use super::{
    lanczos_condition, lanczos_extremes, CgParams, CgReport, ConditionEstimate, Preconditioner,
    ResidualReport, SymmetricOperator,
};
use crate::solve::vectors::dot;

/// One channel's conjugate-gradient state.
struct Channel {
    x: Vec<f64>,
    r: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    /// `A p` of the current iteration.
    q: Vec<f64>,
    /// `r . z`.
    rz: f64,
    /// `||b||`.
    bnorm: f64,
    /// `b . M^{-1} b` (`||b'||^2` of the forward-error stop; 0 when not asked).
    bmb: f64,
    /// The forward-error bound at the last check (infinite before any).
    error_bound: f64,
    /// The recurred `||r|| / ||b||`.
    residual: f64,
    /// `||b - A x_0|| / ||b||` of the start.
    start_residual: f64,
    /// The channel's stop: `||r|| <= tolerance ||b||`.
    tolerance: f64,
    /// The step length of the current iteration.
    alpha: f64,
    /// Whether the current iteration stepped (no breakdown).
    stepped: bool,
    iterations: usize,
    alphas: Vec<f64>,
    betas: Vec<f64>,
    active: bool,
}

impl Channel {
    /// The first half of an iteration, given `q = A p`: `alpha = r.z / p.q`, `x += alpha p`,
    /// `r -= alpha q`; a breakdown (`p.q` not positive and finite) stops the channel with
    /// its iterate. Whether it stepped.
    fn advance(&mut self) -> bool {
        let pq = dot(&self.p, &self.q);
        if !(pq > 0.0 && pq.is_finite()) {
            self.active = false;
            return false;
        }
        let alpha = self.rz / pq;
        for ((x, r), (p, q)) in self
            .x
            .iter_mut()
            .zip(self.r.iter_mut())
            .zip(self.p.iter().zip(&self.q))
        {
            *x += alpha * p;
            *r -= alpha * q;
        }
        self.alpha = alpha;
        true
    }

    /// The second half, given `z = M^{-1} r`: `beta = r.z / (r.z)_old`, `p = z + beta p`,
    /// and the stopping rule (with the forward-error stop when `forward_error` is given).
    fn conjugate(&mut self, keep: bool, forward_error: Option<f64>) {
        let rz_new = dot(&self.r, &self.z);
        let beta = rz_new / self.rz;
        for (p, z) in self.p.iter_mut().zip(&self.z) {
            *p = z + beta * *p;
        }
        self.rz = rz_new;
        if keep {
            self.alphas.push(self.alpha);
            self.betas.push(beta);
        }
        self.iterations += 1;
        let rnorm = dot(&self.r, &self.r).sqrt();
        self.residual = rnorm / self.bnorm;
        let mut done = rnorm <= self.tolerance * self.bnorm;
        if let (true, Some(eps)) = (done, forward_error) {
            self.error_bound = self.forward_bound();
            done = self.error_bound <= eps;
        }
        self.active = rz_new > 0.0 && !done;
    }

    /// `cond(T_j) sqrt(r.z / b.M^{-1}b)`: the bound on `||x - x*||_M / ||x*||_M` with the
    /// Lanczos estimate of `cond(M^{-1} A)` from the iterations so far ([`super`]).
    fn forward_bound(&self) -> f64 {
        let ratio = (self.rz.max(0.0) / self.bmb).sqrt();
        match lanczos_extremes(&self.alphas, &self.betas) {
            Some((lo, hi)) if lo > 0.0 => hi / lo * ratio,
            _ => f64::INFINITY,
        }
    }
}

/// `q_c = A p_c` for the channels `on`, in one call.
fn apply_operator(op: &dyn SymmetricOperator, ch: &mut [Channel], on: &[usize]) {
    let mut qs: Vec<Vec<f64>> = on.iter().map(|&c| std::mem::take(&mut ch[c].q)).collect();
    let ps: Vec<&[f64]> = on.iter().map(|&c| ch[c].p.as_slice()).collect();
    op.apply(&ps, &mut qs);
    for (&c, q) in on.iter().zip(qs) {
        ch[c].q = q;
    }
}

/// `z_c = M^{-1} r_c` for the channels `on`, in one call.
fn apply_preconditioner(pre: &dyn Preconditioner, ch: &mut [Channel], on: &[usize]) {
    let mut zs: Vec<Vec<f64>> = on.iter().map(|&c| std::mem::take(&mut ch[c].z)).collect();
    let rs: Vec<&[f64]> = on.iter().map(|&c| ch[c].r.as_slice()).collect();
    pre.apply(&rs, &mut zs);
    for (&c, z) in on.iter().zip(zs) {
        ch[c].z = z;
    }
}

/// Solves `A x_c = b_c` for every channel `c` by preconditioned conjugate gradients in
/// lockstep, from `start` (per channel; `None`: 0), as stated in [`super`]. Returns the
/// iterates and the report; never fails (see [`CgReport::converged`]).
pub fn pcg(
    op: &dyn SymmetricOperator,
    pre: &dyn Preconditioner,
    b: &[&[f64]],
    start: Option<Vec<Vec<f64>>>,
    params: &CgParams,
) -> (Vec<Vec<f64>>, CgReport) {
    pcg_to(
        op,
        pre,
        b,
        start,
        params,
        &vec![params.tolerance; b.len()],
        false,
    )
}

/// [`pcg`] with channel `c` stopping at its own relative residual `tolerances[c]`
/// ([`CgParams::tolerance`] unused): the channels still share each iteration's products.
///
/// With `scale_start`, a channel's nonzero start `x_0` is replaced by `s x_0`,
/// `s = (x_0 . b) / (x_0 . A x_0)` when finite (`A x_0 != 0`): the multiple of the start
/// nearest the solution in the energy norm (the Galerkin step on `span{x_0}`), so
/// `||s x_0 - x*||_A^2 = ||x*||_A^2 - (x_0 . b)^2 / (x_0 . A x_0)`, never farther than the
/// zero start nor than `x_0` itself. It costs no product (`A x_0` is the start's residual's)
/// and matters where the start is a poor guess of a new right-hand side (a probe channel
/// whose new samples carry new values).
pub fn pcg_to(
    op: &dyn SymmetricOperator,
    pre: &dyn Preconditioner,
    b: &[&[f64]],
    start: Option<Vec<Vec<f64>>>,
    params: &CgParams,
    tolerances: &[f64],
    scale_start: bool,
) -> (Vec<Vec<f64>>, CgReport) {
    let k = b.len();
    let n = op.dim();
    assert_eq!(tolerances.len(), k, "one tolerance per channel");
    let forward_error = params.forward_error;
    let keep = params.condition == ConditionEstimate::Lanczos || forward_error.is_some();
    let mut xs = start.unwrap_or_else(|| vec![vec![0.0; n]; k]);
    debug_assert_eq!(xs.len(), k);
    // r_0 = b - A x_0 (A x_0 only computed when some start is not 0)
    let warm = xs.iter().any(|x| x.iter().any(|&v| v != 0.0));
    let rs: Vec<Vec<f64>> = if warm {
        let refs: Vec<&[f64]> = xs.iter().map(|x| x.as_slice()).collect();
        let mut ax = vec![vec![0.0; n]; k];
        op.apply(&refs, &mut ax);
        if scale_start {
            for ((x, ax), b) in xs.iter_mut().zip(ax.iter_mut()).zip(b) {
                let s = dot(x, b) / dot(x, ax);
                if s.is_finite() {
                    x.iter_mut().for_each(|v| *v *= s);
                    ax.iter_mut().for_each(|v| *v *= s);
                }
            }
        }
        b.iter()
            .zip(&ax)
            .map(|(b, ax)| b.iter().zip(ax).map(|(b, a)| b - a).collect())
            .collect()
    } else {
        b.iter().map(|b| b.to_vec()).collect()
    };
    let mut zs = vec![vec![0.0; n]; k];
    {
        let refs: Vec<&[f64]> = rs.iter().map(|r| r.as_slice()).collect();
        pre.apply(&refs, &mut zs);
    }
    // b . M^{-1} b for the forward-error stop (r_0 . z_0 from a zero start)
    let bmbs: Vec<f64> = match (forward_error, warm) {
        (None, _) => vec![0.0; k],
        (Some(_), false) => rs.iter().zip(&zs).map(|(r, z)| dot(r, z)).collect(),
        (Some(_), true) => {
            let mut mb = vec![vec![0.0; n]; k];
            pre.apply(b, &mut mb);
            b.iter().zip(&mb).map(|(b, mb)| dot(b, mb)).collect()
        }
    };
    let mut ch: Vec<Channel> = xs
        .into_iter()
        .zip(rs.into_iter().zip(zs))
        .zip(b.iter().zip(bmbs))
        .zip(tolerances)
        .map(|(((x, (r, z)), (b, bmb)), &tolerance)| {
            let rz = dot(&r, &z);
            let bnorm = dot(b, b).sqrt();
            let rnorm = dot(&r, &r).sqrt();
            // before any iteration the forward bound is taken with cond 1 (its least value)
            let error_far = forward_error.is_some_and(|eps| rz.max(0.0) > eps * eps * bmb);
            Channel {
                p: z.clone(),
                q: vec![0.0; n],
                active: bnorm > 0.0 && rz > 0.0 && (rnorm > tolerance * bnorm || error_far),
                residual: if bnorm > 0.0 { rnorm / bnorm } else { 0.0 },
                start_residual: if bnorm > 0.0 { rnorm / bnorm } else { 0.0 },
                tolerance,
                x,
                r,
                z,
                rz,
                bnorm,
                bmb,
                error_bound: if forward_error.is_some() && rz > 0.0 {
                    (rz / bmb).sqrt()
                } else {
                    0.0
                },
                alpha: 0.0,
                stepped: false,
                iterations: 0,
                alphas: Vec::new(),
                betas: Vec::new(),
            }
        })
        .collect();
    for _ in 0..params.max_iterations {
        let live: Vec<usize> = (0..k).filter(|&c| ch[c].active).collect();
        if live.is_empty() {
            break;
        }
        apply_operator(op, &mut ch, &live);
        ch.par_iter_mut()
            .filter(|s| s.active)
            .for_each(|s| s.stepped = s.advance());
        let stepped: Vec<usize> = live.into_iter().filter(|&c| ch[c].stepped).collect();
        apply_preconditioner(pre, &mut ch, &stepped);
        ch.par_iter_mut().filter(|s| s.stepped).for_each(|s| {
            s.conjugate(keep, forward_error);
            s.stepped = false;
        });
    }
    let residuals: Vec<f64> = match params.residual {
        ResidualReport::Recurred => ch.iter().map(|s| s.residual).collect(),
        ResidualReport::Recomputed => {
            let refs: Vec<&[f64]> = ch.iter().map(|s| s.x.as_slice()).collect();
            let mut ax = vec![vec![0.0; n]; k];
            op.apply(&refs, &mut ax);
            ch.iter()
                .zip(ax.iter().zip(b))
                .map(|(s, (ax, b))| {
                    let res: f64 = b
                        .iter()
                        .zip(ax)
                        .map(|(b, g)| (b - g) * (b - g))
                        .sum::<f64>()
                        .sqrt();
                    res / s.bnorm
                })
                .collect()
        }
    };
    let mut report = CgReport {
        condition: (params.condition == ConditionEstimate::Lanczos).then(Vec::new),
        forward_error: forward_error.map(|_| Vec::new()),
        ..CgReport::default()
    };
    let mut solutions = Vec::with_capacity(k);
    for (s, residual) in ch.into_iter().zip(residuals) {
        if s.bnorm == 0.0 {
            // b = 0: the solution is 0, whatever the start
            report.iterations.push(0);
            report.relative_residual.push(0.0);
            report.start_residual.push(0.0);
            report.converged.push(true);
            if let Some(cond) = report.condition.as_mut() {
                cond.push(1.0);
            }
            if let Some(bound) = report.forward_error.as_mut() {
                bound.push(0.0);
            }
            solutions.push(vec![0.0; n]);
            continue;
        }
        report.iterations.push(s.iterations);
        report.relative_residual.push(residual);
        report.start_residual.push(s.start_residual);
        let bound_ok = forward_error.is_none_or(|eps| s.error_bound <= eps);
        report.converged.push(residual <= s.tolerance && bound_ok);
        if let Some(cond) = report.condition.as_mut() {
            cond.push(lanczos_condition(&s.alphas, &s.betas));
        }
        if let Some(bound) = report.forward_error.as_mut() {
            bound.push(s.error_bound);
        }
        solutions.push(s.x);
    }
    (solutions, report)
}
