//! Bayesian regularisation: Levenberg–Marquardt on `β·E_D + α·E_W` with α and β re-estimated
//! every epoch (MATLAB `trainbr`; MacKay 1992, in the Gauss–Newton approximation of Foresee &
//! Hagan 1997).
//!
//! `E_D = ‖r(p)‖²` is the sum of squared errors and `E_W = ‖p‖²` the sum of squared weights.
//! With `λ = α/β` each epoch takes the LM step of `E_D + λ·E_W`:
//! `(JᵀJ + (λ + μ) I) δ = −(Jᵀr + λp)`, through the dual system
//! `δ = −(g − Jᵀ (JJᵀ + cI)⁻¹ J g) / c` (`g = Jᵀr + λp`, `c = λ + μ`) when there are fewer
//! residuals than parameters. After an accepted step the evidence framework re-estimates
//! `γ = Σ λᵢ/(λᵢ + λ)` over the eigenvalues `λᵢ` of `JᵀJ` — the effective number of parameters,
//! computed as `k − λ·tr((G + λI)⁻¹)` on the smaller Gram matrix `G` of size `k` — then
//! `α = γ / (2 E_W)` and `β = (N − γ) / (2 E_D)` for `N` residuals. No validation split is
//! needed: the weight penalty is what keeps the network from fitting the noise.
//!
//! The start follows MATLAB: `γ = n`, `α = γ / (2 E_W)`, `β = (N − γ) / (2 E_D)` (1 when that is
//! not positive). Damping is μ·I whatever [`LmConfig::damping`] says.

use faer::Mat;

use crate::damped::DampedSolver;
use crate::lm::{
    gradient_stop, start_stop, sum_sq, system_at, Control, Jacobian, LmConfig, LmOutcome, Problem,
    Start, Step, StopReason,
};

/// The regularisation state after an epoch.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Evidence {
    /// Weight on the sum of squared weights.
    pub alpha: f64,
    /// Weight on the sum of squared errors.
    pub beta: f64,
    /// Effective number of parameters γ (at most the parameter count).
    pub gamma: f64,
    /// Sum of squared errors `E_D`.
    pub sse: f64,
    /// Sum of squared weights `E_W`.
    pub ssw: f64,
}

impl Evidence {
    /// MATLAB's start: every one of `n` parameters counted as effective, with `m` residuals.
    fn start((n, m): (usize, usize), (sse, ssw): (f64, f64)) -> Self {
        let gamma = n as f64;
        let beta = (m as f64 - gamma) / (2.0 * sse);
        Self {
            alpha: if ssw > 0.0 { gamma / (2.0 * ssw) } else { 1.0 },
            beta: if beta.is_finite() && beta > 0.0 {
                beta
            } else {
                1.0
            },
            gamma,
            sse,
            ssw,
        }
    }

    /// MacKay's re-estimate from `gamma_raw` = k − λ·tr((H + λI)⁻¹) (clamped to the parameters
    /// and the residuals, keeping β finite: some residual degrees of freedom always remain),
    /// when the sums of squares allow it.
    fn update(&mut self, gamma_raw: f64, (n, m): (usize, usize)) {
        let (sse, ssw) = (self.sse, self.ssw);
        let g_new = gamma_raw.clamp(0.0, n.min(m) as f64).min(m as f64 - 1e-3);
        if ssw > 0.0 && sse > 0.0 && g_new > 0.0 {
            self.gamma = g_new;
            self.alpha = g_new / (2.0 * ssw);
            self.beta = (m as f64 - g_new) / (2.0 * sse);
        }
    }
}

/// What the callback sees after each epoch.
#[derive(Clone, Copy, Debug)]
pub struct BrProgress<'a> {
    /// Epochs done.
    pub iteration: usize,
    /// α, β, γ and the two sums.
    pub evidence: Evidence,
    /// Current μ.
    pub mu: f64,
    /// ‖Jᵀr + λp‖ at the start of the epoch.
    pub gradient_norm: f64,
    /// Current parameters.
    pub params: &'a [f64],
}

/// The result of a run: the solver's outcome (`cost` is `E_D`) and the final evidence.
#[derive(Clone, Debug, PartialEq)]
pub struct BrOutcome {
    /// Parameters, E_D, iterations, μ and why it stopped.
    pub lm: LmOutcome,
    /// α, β, γ at the end.
    pub evidence: Evidence,
}

/// `MATLAB trainbr`'s μ schedule: μ = 0.005, ×0.1 / ×10, μ_max 1e10, 1000 epochs.
pub const TRAINBR: LmConfig = LmConfig {
    mu: 0.005,
    ..LmConfig::TRAINLM
};

/// The gradient of `½(E_D + λE_W)`: `Jᵀr + λp` from `Jᵀr`.
fn regularised_gradient(jtr: Vec<f64>, p: &[f64], lambda: f64) -> Vec<f64> {
    let mut g = jtr;
    for (gi, pi) in g.iter_mut().zip(p) {
        *gi += lambda * pi;
    }
    g
}

/// The regularised step at damping `c` = λ + μ from the kept Gram matrix: dual (`jac` and
/// `jg` = J·g given) `δ = −(g − Jᵀ(JJᵀ + cI)⁻¹ J g) / c`, primal `δ = −(JᵀJ + cI)⁻¹ g`.
fn regularised_step(
    solver: &mut DampedSolver,
    ones: &[f64],
    jac: Option<(&Jacobian<'_>, &[f64])>,
    g: &[f64],
    c: f64,
) -> Option<Vec<f64>> {
    let Some((jac, jg)) = jac else {
        return solver
            .solve(c, ones, g)
            .map(|y| y.iter().map(|v| -v).collect());
    };
    solver.solve(c, ones, jg).map(|y| {
        let jty = jac.transpose_times(&y);
        g.iter().zip(&jty).map(|(gi, ti)| -(gi - ti) / c).collect()
    })
}

/// Minimises `β‖r(p)‖² + α‖p‖²` from `p0` with α and β re-estimated each epoch, calling
/// `callback` after every epoch.
pub fn minimize_br<P: Problem>(
    problem: &mut P,
    p0: &[f64],
    cfg: &LmConfig,
    mut callback: impl FnMut(&BrProgress<'_>) -> Control,
) -> BrOutcome {
    let mut st = Start::at(problem, p0);
    let (n, m, dual) = (st.n, st.m, st.dual);
    let mut dense: Option<Mat<f64>> = None;
    let mut evaluations = 1;
    let mut mu = cfg.mu;
    let mut ev = Evidence::start((n, m), (sum_sq(&st.r), sum_sq(&st.p)));
    let mut fallbacks = 0;
    // Every exit gives why and after how many epochs; the outcome is built once below.
    let (reason, iterations) = 'run: {
        if let Some(stop) = start_stop(cfg, ev.sse.is_finite() && ev.ssw.is_finite()) {
            break 'run (stop, 0);
        }
        let k = if dual { m } else { n };
        let mut solver = DampedSolver::new(k);
        let ones = vec![1.0; k];
        for iteration in 0..cfg.max_iterations {
            let lambda = ev.alpha / ev.beta;
            let mut cost = ev.sse + lambda * ev.ssw;
            if cost == 0.0 {
                break 'run (StopReason::ZeroResidual, iteration);
            }
            let structured = dual.then(|| problem.dual_jacobian(&st.p)).flatten();
            let with = (&structured, &mut dense);
            let (jac, jtr) = system_at(problem, (&st.p, &st.r, dual), with, &mut solver);
            let g = regularised_gradient(jtr, &st.p, lambda);
            let gnorm = g.iter().map(|v| v * v).sum::<f64>().sqrt();
            if let Some(stop) = gradient_stop(gnorm, cfg) {
                break 'run (stop, iteration);
            }
            let jg = jac.as_ref().map(|jac| jac.times(&g, m));
            let solve = |mu: f64| {
                let with_jac = jac.as_ref().zip(jg.as_deref());
                let step = regularised_step(&mut solver, &ones, with_jac, &g, lambda + mu);
                fallbacks = solver.fallbacks;
                step
            };
            let objective = |p: &[f64], r: &[f64]| sum_sq(r) + lambda * sum_sq(p);
            let costs = (&mut mu, &mut cost);
            let (step, evals) = st.damped_step(problem, costs, cfg, None, solve, objective);
            evaluations += evals;
            if step == Step::MuMax {
                break 'run (StopReason::MuMax, iteration + 1);
            }
            (ev.sse, ev.ssw) = (sum_sq(&st.r), sum_sq(&st.p));
            // The evidence with this epoch's Gauss–Newton Hessian (as trainbr does).
            if let Some(tr) = solver.trace_inverse(lambda) {
                ev.update(k as f64 - lambda * tr, (n, m));
            }
            let progress = BrProgress {
                iteration: iteration + 1,
                evidence: ev,
                mu,
                gradient_norm: gnorm,
                params: &st.p,
            };
            if callback(&progress) == Control::Stop {
                break 'run (StopReason::Callback, iteration + 1);
            }
        }
        (StopReason::MaxIterations, cfg.max_iterations)
    };
    BrOutcome {
        lm: LmOutcome {
            params: st.p,
            cost: ev.sse,
            iterations,
            evaluations,
            mu,
            reason,
            lu_fallbacks: fallbacks,
        },
        evidence: ev,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lm::Problem;

    /// r(p) = sin-model residuals: nonlinear, so the gradient test means something.
    struct Curve {
        x: Vec<f64>,
        y: Vec<f64>,
    }

    impl Problem for Curve {
        fn n_params(&self) -> usize {
            3
        }
        fn n_residuals(&self) -> usize {
            self.x.len()
        }
        fn residuals(&mut self, p: &[f64], out: &mut [f64]) {
            for (o, (x, y)) in out.iter_mut().zip(self.x.iter().zip(&self.y)) {
                *o = p[0] * (p[1] * x).sin() + p[2] - y;
            }
        }
        fn jacobian(&mut self, p: &[f64], jac: &mut Mat<f64>) {
            for (i, x) in self.x.iter().enumerate() {
                jac[(i, 0)] = (p[1] * x).sin();
                jac[(i, 1)] = p[0] * x * (p[1] * x).cos();
                jac[(i, 2)] = 1.0;
            }
        }
    }

    #[test]
    fn the_step_direction_is_the_regularised_gradient_by_finite_differences() {
        let mut c = Curve {
            x: (0..9).map(|i| f64::from(i) * 0.4).collect(),
            y: (0..9).map(|i| (f64::from(i) * 0.5).cos()).collect(),
        };
        let p = [0.8, 1.3, -0.2];
        let lambda = 0.37;
        let mut r = vec![0.0; 9];
        c.residuals(&p, &mut r);
        let mut jac = Mat::<f64>::zeros(9, 3);
        c.jacobian(&p, &mut jac);
        let g = regularised_gradient(Jacobian::Dense(&jac).transpose_times(&r), &p, lambda);
        // g = ½ ∇(E_D + λ E_W) by central differences.
        let mut f = |q: &[f64]| -> f64 {
            let mut rr = vec![0.0; 9];
            c.residuals(q, &mut rr);
            sum_sq(&rr) + lambda * sum_sq(q)
        };
        let h = 1e-6;
        for j in 0..3 {
            let (mut a, mut b) = (p, p);
            a[j] += h;
            b[j] -= h;
            let fd = 0.5 * (f(&a) - f(&b)) / (2.0 * h);
            assert!((g[j] - fd).abs() < 1e-7, "∂/∂p{j}: {} vs {fd}", g[j]);
        }
    }

    #[test]
    fn the_dual_step_equals_the_primal_one() {
        // Fewer residuals than parameters through a dense Jacobian of 3 × 5: the dual formula
        // must give the primal step (JᵀJ + cI)⁻¹ g.
        let jac = Mat::<f64>::from_fn(3, 5, |i, j| ((i * 5 + j * 3) % 7) as f64 - 3.0);
        let g: Vec<f64> = (0..5).map(|j| (j as f64).sin()).collect();
        let c = 0.7;
        let jm = Jacobian::Dense(&jac);
        let mut gram_d = Mat::<f64>::zeros(3, 3);
        jm.gram_lower_into(true, gram_d.as_mut());
        let mut gram_p = Mat::<f64>::zeros(5, 5);
        jm.gram_lower_into(false, gram_p.as_mut());
        let jg = jm.times(&g, 3);
        let mut dual_solver = DampedSolver::new(3);
        dual_solver.load_gram(&gram_d);
        let y = dual_solver.solve(c, &[1.0; 3], &jg).unwrap();
        let jty = jm.transpose_times(&y);
        let dual: Vec<f64> = g.iter().zip(&jty).map(|(a, b)| (a - b) / c).collect();
        let mut primal_solver = DampedSolver::new(5);
        primal_solver.load_gram(&gram_p);
        let primal = primal_solver.solve(c, &[1.0; 5], &g).unwrap();
        for (a, b) in dual.iter().zip(&primal) {
            assert!((a - b).abs() < 1e-12, "{dual:?} vs {primal:?}");
        }
        // γ by the trace on either Gram matrix: the same nonzero eigenvalues.
        let lam = 0.3;
        let tr_d = dual_solver.trace_inverse(lam).unwrap();
        let tr_p = primal_solver.trace_inverse(lam).unwrap();
        assert!(((3.0 - lam * tr_d) - (5.0 - lam * tr_p)).abs() < 1e-12);
    }
}
