//! Levenberg–Marquardt for any least-squares problem `min ‖r(p)‖²`.
//!
//! Each iteration solves `(JᵀJ + μD) δ = −Jᵀr` (D = I as MATLAB's `trainlm`, or
//! D = diag(JᵀJ), Marquardt's scaling) with a Cholesky factorisation (faer's, in place); when
//! there are fewer residuals than parameters it solves the smaller dual system
//! `δ = −Jᵀ (JJᵀ + μI)⁻¹ r`, which is the same step for D = I. A Cholesky factorisation that
//! fails (not positive definite in floating point) falls back to LU with partial pivoting, as
//! MATLAB's backslash does; a step that is still not finite raises μ and tries again. A step
//! that lowers the cost is taken and μ shrinks by `mu_dec`; otherwise μ grows by `mu_inc` until
//! `mu_max`.
//!
//! A problem whose Jacobian has structure can hand the solver a [`DualJacobian`] instead of the
//! dense matrix: the dual system then needs only `JJᵀ` and products `Jᵀv`, which a network
//! forms layer by layer far faster than from `J` itself (see [`crate::mlp`]).
//!
//! Not converging is an outcome ([`StopReason`]), never an error; the caller's callback sees
//! every iteration and can stop the solver.

use faer::linalg::matmul::triangular::{matmul, BlockStructure};
use faer::{Accum, Mat, MatMut};

use crate::damped::DampedSolver;

/// The lower triangle of `JJᵀ` (dual) or `JᵀJ` into `out`: a symmetric product computes half
/// the entries, and the Cholesky factorisation reads only that half.
pub(crate) fn gram_lower_into(jac: &Mat<f64>, dual: bool, out: MatMut<'_, f64>) {
    let par = faer::get_global_parallelism();
    let (lhs, rhs) = if dual {
        (jac.as_ref(), jac.transpose())
    } else {
        (jac.transpose(), jac.as_ref())
    };
    matmul(
        out,
        BlockStructure::TriangularLower,
        Accum::Replace,
        lhs,
        BlockStructure::Rectangular,
        rhs,
        BlockStructure::Rectangular,
        1.0,
        par,
    );
}

/// A least-squares problem: residuals and their Jacobian at a parameter vector.
pub trait Problem {
    /// Number of parameters.
    fn n_params(&self) -> usize;
    /// Number of residuals.
    fn n_residuals(&self) -> usize;
    /// Residuals at `p` into `out` (length [`Problem::n_residuals`]).
    fn residuals(&mut self, p: &[f64], out: &mut [f64]);
    /// Jacobian `∂rᵢ/∂pⱼ` at `p` into `jac` (n_residuals × n_params).
    fn jacobian(&mut self, p: &[f64], jac: &mut Mat<f64>);
    /// The Jacobian at `p` in the problem's own structured form, used when the solver takes
    /// the dual system (fewer residuals than parameters); the solver then never asks for the
    /// dense one. `None` (the default): the dense Jacobian is used.
    fn dual_jacobian(&mut self, p: &[f64]) -> Option<Box<dyn DualJacobian>> {
        let _ = p;
        None
    }
    /// The normal equations at `p` for the primal system (at least as many residuals as
    /// parameters), built without holding the whole Jacobian — e.g. accumulated over blocks of
    /// residuals, so that memory does not grow with their number: the lower triangle of `JᵀJ`
    /// into `gram` (n_params × n_params; its upper part may be overwritten) and `Jᵀv` into
    /// `jtv` for `v` of length n_residuals. Both must equal those of the dense
    /// [`Problem::jacobian`] to rounding. `false` (the default): not available, and the solver
    /// forms the dense Jacobian instead.
    fn normal_equations(
        &mut self,
        p: &[f64],
        v: &[f64],
        gram: MatMut<'_, f64>,
        jtv: &mut [f64],
    ) -> bool {
        let _ = (p, v, gram, jtv);
        false
    }
}

/// A Jacobian `J` (n_residuals × n_params) known through the two products the dual system
/// needs. Both must equal those of the dense [`Problem::jacobian`] to rounding.
pub trait DualJacobian {
    /// The lower triangle of `JJᵀ` into `out` (n_residuals × n_residuals; the upper part is
    /// neither read nor needed).
    fn gram_lower_into(&self, out: MatMut<'_, f64>);
    /// `Jᵀv` into `out` (length n_params) for `v` of length n_residuals.
    fn transpose_times(&self, v: &[f64], out: &mut [f64]);
    /// `Jv` into `out` (length n_residuals) for `v` of length n_params (the regularised dual
    /// system of [`crate::br`] needs it).
    fn times(&self, v: &[f64], out: &mut [f64]);
}

/// `J` as the solver holds it in one iteration.
pub(crate) enum Jacobian<'a> {
    Dense(&'a Mat<f64>),
    /// The structured form and the number of parameters.
    Structured(&'a dyn DualJacobian, usize),
}

impl Jacobian<'_> {
    /// `Jv`.
    pub(crate) fn times(&self, v: &[f64], m: usize) -> Vec<f64> {
        match *self {
            Jacobian::Dense(jac) => {
                let vm = Mat::<f64>::from_fn(v.len(), 1, |i, _| v[i]);
                let g = jac * &vm;
                (0..g.nrows()).map(|i| g[(i, 0)]).collect()
            }
            Jacobian::Structured(sj, _) => {
                let mut out = vec![0.0; m];
                sj.times(v, &mut out);
                out
            }
        }
    }

    /// `Jᵀv`.
    pub(crate) fn transpose_times(&self, v: &[f64]) -> Vec<f64> {
        match *self {
            Jacobian::Dense(jac) => {
                let vm = Mat::<f64>::from_fn(v.len(), 1, |i, _| v[i]);
                let g = jac.transpose() * &vm;
                (0..g.nrows()).map(|i| g[(i, 0)]).collect()
            }
            Jacobian::Structured(sj, n) => {
                let mut out = vec![0.0; n];
                sj.transpose_times(v, &mut out);
                out
            }
        }
    }

    /// The lower triangle of `JJᵀ` (dual) or `JᵀJ` into `out`.
    pub(crate) fn gram_lower_into(&self, dual: bool, out: MatMut<'_, f64>) {
        match *self {
            Jacobian::Dense(jac) => gram_lower_into(jac, dual, out),
            Jacobian::Structured(sj, _) => sj.gram_lower_into(out),
        }
    }
}

/// Damping matrix.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Damping {
    /// μ·I, as MATLAB `trainlm`.
    Identity,
    /// μ·diag(JᵀJ) (Marquardt 1963): invariant to the scale of each parameter.
    Marquardt,
}

/// Solver settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LmConfig {
    /// Initial μ.
    pub mu: f64,
    /// μ factor after a successful step.
    pub mu_dec: f64,
    /// μ factor after a failed step.
    pub mu_inc: f64,
    /// Stop when μ exceeds this.
    pub mu_max: f64,
    /// Stop when ‖Jᵀr‖ falls below this.
    pub min_grad: f64,
    /// Stop after this many iterations (epochs).
    pub max_iterations: usize,
    /// Stop when a step changes every parameter by less than this relative amount.
    pub min_relative_step: f64,
    /// Damping matrix.
    pub damping: Damping,
}

/// Levenberg–Marquardt settings that cannot work: which one, and the value given.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LmConfigError {
    /// `mu` is not a positive finite number.
    #[error("mu must be positive, got {0}")]
    Mu(f64),
    /// `mu_inc` does not exceed 1 (μ could never grow).
    #[error("mu_inc must exceed 1, got {0}")]
    MuInc(f64),
    /// `mu_dec` is not in (0, 1) (μ could never shrink).
    #[error("mu_dec must lie in (0, 1), got {0}")]
    MuDec(f64),
    /// `mu_max` is below `mu`.
    #[error("mu_max ({mu_max}) must be at least mu ({mu})")]
    MuMax {
        /// The ceiling given.
        mu_max: f64,
        /// The starting μ.
        mu: f64,
    },
}

impl LmConfig {
    /// MATLAB `trainlm` defaults: μ = 1e−3, ×0.1 / ×10, μ_max 1e10, min gradient 1e−7,
    /// 1000 epochs.
    pub const TRAINLM: Self = Self {
        mu: 1e-3,
        mu_dec: 0.1,
        mu_inc: 10.0,
        mu_max: 1e10,
        min_grad: 1e-7,
        max_iterations: 1000,
        min_relative_step: 0.0,
        damping: Damping::Identity,
    };

    /// For precise curve fitting (NIST StRD): Marquardt scaling, iterate until steps stop
    /// changing the parameters.
    pub const PRECISE: Self = Self {
        mu: 1e-3,
        mu_dec: 0.1,
        mu_inc: 10.0,
        mu_max: 1e16,
        min_grad: 0.0,
        max_iterations: 10_000,
        min_relative_step: 1e-15,
        damping: Damping::Marquardt,
    };
}

impl LmConfig {
    /// Checks that μ can grow and shrink: `mu > 0`, `mu_inc > 1`, `0 < mu_dec < 1`,
    /// `mu_max ≥ mu`.
    pub fn validate(&self) -> Result<(), LmConfigError> {
        if !(self.mu > 0.0 && self.mu.is_finite()) {
            return Err(LmConfigError::Mu(self.mu));
        }
        if !(self.mu_inc > 1.0 && self.mu_inc.is_finite()) {
            return Err(LmConfigError::MuInc(self.mu_inc));
        }
        if !(self.mu_dec > 0.0 && self.mu_dec < 1.0) {
            return Err(LmConfigError::MuDec(self.mu_dec));
        }
        if self.mu_max.is_nan() || self.mu_max < self.mu {
            return Err(LmConfigError::MuMax {
                mu_max: self.mu_max,
                mu: self.mu,
            });
        }
        Ok(())
    }
}

impl Default for LmConfig {
    fn default() -> Self {
        Self::TRAINLM
    }
}

/// Why the solver stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopReason {
    /// ‖Jᵀr‖ below `min_grad`.
    MinGradient,
    /// `max_iterations` reached.
    MaxIterations,
    /// μ exceeded `mu_max`: no step lowers the cost.
    MuMax,
    /// The last step changed no parameter by more than `min_relative_step`.
    SmallStep,
    /// The residuals are exactly zero.
    ZeroResidual,
    /// The callback asked to stop.
    Callback,
    /// Residuals or Jacobian are not finite at the start.
    NonFinite,
    /// The settings cannot work ([`LmConfig::validate`] says why); nothing was done.
    InvalidConfig,
}

/// What the callback sees after each iteration.
#[derive(Clone, Copy, Debug)]
pub struct Progress<'a> {
    /// Iterations done.
    pub iteration: usize,
    /// Current sum of squared residuals.
    pub cost: f64,
    /// Current μ.
    pub mu: f64,
    /// ‖Jᵀr‖ at the start of the iteration.
    pub gradient_norm: f64,
    /// Current parameters.
    pub params: &'a [f64],
}

/// The callback's answer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Control {
    /// Keep going.
    Continue,
    /// Stop now (the outcome says [`StopReason::Callback`]).
    Stop,
}

/// The result of a run.
#[derive(Clone, Debug, PartialEq)]
pub struct LmOutcome {
    /// Best parameters found.
    pub params: Vec<f64>,
    /// Their sum of squared residuals.
    pub cost: f64,
    /// Iterations done.
    pub iterations: usize,
    /// Residual evaluations.
    pub evaluations: usize,
    /// Final μ.
    pub mu: f64,
    /// Why it stopped.
    pub reason: StopReason,
    /// Damped systems that Cholesky could not factorise (not positive definite in floating
    /// point) and LU with partial pivoting solved instead.
    pub lu_fallbacks: usize,
}

pub(crate) fn sum_sq(r: &[f64]) -> f64 {
    r.iter().map(|v| v * v).sum()
}

/// A run's sizes and working vectors: the point and its residuals (evaluated once), and the
/// trial copies each step fills.
pub(crate) struct Start {
    pub(crate) n: usize,
    pub(crate) m: usize,
    /// Fewer residuals than parameters: the dual system.
    pub(crate) dual: bool,
    pub(crate) p: Vec<f64>,
    pub(crate) r: Vec<f64>,
    pub(crate) p_new: Vec<f64>,
    pub(crate) r_new: Vec<f64>,
}

impl Start {
    pub(crate) fn at<P: Problem>(problem: &mut P, p0: &[f64]) -> Self {
        let (n, m) = (problem.n_params(), problem.n_residuals());
        assert_eq!(p0.len(), n, "starting point must have n_params entries");
        let p = p0.to_vec();
        let mut r = vec![0.0; m];
        problem.residuals(&p, &mut r);
        Self {
            n,
            m,
            dual: m < n,
            p,
            r,
            p_new: vec![0.0; n],
            r_new: vec![0.0; m],
        }
    }
}

/// How one epoch's search along μ ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Step {
    /// A step lowered the objective; `small` when it was below the smallest relative step.
    Accepted {
        /// The step was below [`LmConfig::min_relative_step`].
        small: bool,
    },
    /// No step lowered the objective and the last was below the smallest relative step.
    Small,
    /// μ grew past its largest value without a better point.
    MuMax,
}

impl Start {
    /// Tries damped steps from μ up until one lowers `objective(p_new, r_new)` below `cost`:
    /// `solve(μ)` gives the step (`None`: the damped system did not solve). An accepted step
    /// becomes the point, `cost` its objective, and μ shrinks; each refused one grows μ.
    /// `small_step`: a refused step below this relative size ends the search (`Step::Small`).
    pub(crate) fn damped_step<P: Problem>(
        &mut self,
        problem: &mut P,
        (mu, cost): (&mut f64, &mut f64),
        cfg: &LmConfig,
        small_step: Option<f64>,
        mut solve: impl FnMut(f64) -> Option<Vec<f64>>,
        objective: impl Fn(&[f64], &[f64]) -> f64,
    ) -> (Step, usize) {
        let mut evaluations = 0;
        while *mu <= cfg.mu_max {
            let Some(step) = solve(*mu).filter(|s| s.iter().all(|v| v.is_finite())) else {
                *mu *= cfg.mu_inc;
                continue;
            };
            let mut max_rel = 0.0f64;
            for ((pn, &pi), &si) in self.p_new.iter_mut().zip(&self.p).zip(&step) {
                *pn = pi + si;
                max_rel = max_rel.max(si.abs() / pi.abs().max(1e-300));
            }
            problem.residuals(&self.p_new, &mut self.r_new);
            evaluations += 1;
            let small = small_step.is_some_and(|s| max_rel < s);
            let c = objective(&self.p_new, &self.r_new);
            if c.is_finite() && c < *cost {
                std::mem::swap(&mut self.p, &mut self.p_new);
                std::mem::swap(&mut self.r, &mut self.r_new);
                *cost = c;
                *mu = (*mu * cfg.mu_dec).max(1e-300);
                return (Step::Accepted { small }, evaluations);
            }
            if small {
                return (Step::Small, evaluations);
            }
            *mu *= cfg.mu_inc;
        }
        (Step::MuMax, evaluations)
    }
}

/// Why not to start: settings that do not validate, or a start whose objective is not finite.
pub(crate) fn start_stop(cfg: &LmConfig, finite: bool) -> Option<StopReason> {
    if cfg.validate().is_err() {
        Some(StopReason::InvalidConfig)
    } else if !finite {
        Some(StopReason::NonFinite)
    } else {
        None
    }
}

/// Why to stop before an epoch, from the gradient's norm: not finite, or below the smallest.
pub(crate) fn gradient_stop(gnorm: f64, cfg: &LmConfig) -> Option<StopReason> {
    if !gnorm.is_finite() {
        Some(StopReason::NonFinite)
    } else if gnorm < cfg.min_grad {
        Some(StopReason::MinGradient)
    } else {
        None
    }
}

/// The Jacobian at `p`: the problem's structured form when it gave one (the dual system),
/// otherwise the dense matrix, made in `dense` on first use and reused.
pub(crate) fn jacobian_at<'a, P: Problem>(
    problem: &mut P,
    p: &[f64],
    structured: &'a Option<Box<dyn DualJacobian>>,
    dense: &'a mut Option<Mat<f64>>,
) -> Jacobian<'a> {
    let (n, m) = (problem.n_params(), problem.n_residuals());
    match structured {
        Some(sj) => Jacobian::Structured(sj.as_ref(), n),
        None => {
            let jac = dense.get_or_insert_with(|| Mat::<f64>::zeros(m, n));
            problem.jacobian(p, jac);
            Jacobian::Dense(jac)
        }
    }
}

/// The primal system at `p`: the lower triangle of `JᵀJ` into `gram` and `Jᵀr` returned, from
/// the problem's own [`Problem::normal_equations`] when it has them, otherwise from the dense
/// Jacobian, made in `dense` on first use and reused.
pub(crate) fn normal_system<P: Problem>(
    problem: &mut P,
    (p, r): (&[f64], &[f64]),
    dense: &mut Option<Mat<f64>>,
    mut gram: MatMut<'_, f64>,
) -> Vec<f64> {
    let mut g = vec![0.0; problem.n_params()];
    if dense.is_none() && problem.normal_equations(p, r, gram.as_mut(), &mut g) {
        return g;
    }
    let jac = jacobian_at(problem, p, &None, dense);
    jac.gram_lower_into(false, gram);
    jac.transpose_times(r)
}

/// One iteration's system at `p` with residuals `r`, kept in `solver`: on the dual path the
/// Jacobian (the problem's `structured` one, or the dense one made in `dense`) and `JJᵀ`, on
/// the primal path `JᵀJ` alone ([`normal_system`]); and the gradient `Jᵀr`.
pub(crate) fn system_at<'a, P: Problem>(
    problem: &mut P,
    (p, r, dual): (&[f64], &[f64], bool),
    (structured, dense): (&'a Option<Box<dyn DualJacobian>>, &'a mut Option<Mat<f64>>),
    solver: &mut DampedSolver,
) -> (Option<Jacobian<'a>>, Vec<f64>) {
    let out = if dual {
        let jac = jacobian_at(problem, p, structured, dense);
        let g = jac.transpose_times(r);
        jac.gram_lower_into(true, solver.gram_mut());
        (Some(jac), g)
    } else {
        (
            None,
            normal_system(problem, (p, r), dense, solver.gram_mut()),
        )
    };
    solver.keep_gram();
    out
}

/// Minimises `‖r(p)‖²` from `p0`, calling `callback` after every iteration.
pub fn minimize<P: Problem>(
    problem: &mut P,
    p0: &[f64],
    cfg: &LmConfig,
    mut callback: impl FnMut(&Progress<'_>) -> Control,
) -> LmOutcome {
    let mut st = Start::at(problem, p0);
    let (n, m, dual) = (st.n, st.m, st.dual);
    // The dense Jacobian, allocated only if the problem gives no structured one.
    let mut dense: Option<Mat<f64>> = None;
    let mut evaluations = 1;
    let mut cost = sum_sq(&st.r);
    let mut mu = cfg.mu;
    let mut fallbacks = 0;
    // Every exit gives why and after how many iterations; the outcome is built once below.
    let (reason, iterations) = 'run: {
        if let Some(stop) = start_stop(cfg, cost.is_finite()) {
            break 'run (stop, 0);
        }
        // The Gram matrix and the solver's buffers, once the settings and the start are known
        // to be usable: allocated once, reused by every iteration and μ trial.
        let k = if dual { m } else { n };
        let mut solver = DampedSolver::new(k);
        for iteration in 0..cfg.max_iterations {
            if cost == 0.0 {
                break 'run (StopReason::ZeroResidual, iteration);
            }
            let structured = dual.then(|| problem.dual_jacobian(&st.p)).flatten();
            let with = (&structured, &mut dense);
            let (jac, g) = system_at(problem, (&st.p, &st.r, dual), with, &mut solver);
            let gnorm = g.iter().map(|v| v * v).sum::<f64>().sqrt();
            if let Some(stop) = gradient_stop(gnorm, cfg) {
                break 'run (stop, iteration);
            }
            let diag: Vec<f64> = match (cfg.damping, dual) {
                (Damping::Marquardt, false) => {
                    solver.gram_diag().iter().map(|d| d.max(1e-300)).collect()
                }
                _ => vec![1.0; k],
            };
            // Dual: δ = −Jᵀ (JJᵀ + μI)⁻¹ r; primal: δ = −(JᵀJ + μD)⁻¹ Jᵀr.
            let rhs = if dual { st.r.clone() } else { g };
            let solve = |mu: f64| {
                let step = solver.solve(mu, &diag, &rhs).map(|y| {
                    let d = match &jac {
                        Some(jac) => jac.transpose_times(&y),
                        None => y,
                    };
                    d.iter().map(|v| -v).collect()
                });
                fallbacks = solver.fallbacks;
                step
            };
            let (step, evals) = st.damped_step(
                problem,
                (&mut mu, &mut cost),
                cfg,
                Some(cfg.min_relative_step),
                solve,
                |_, r| sum_sq(r),
            );
            evaluations += evals;
            match step {
                Step::MuMax => break 'run (StopReason::MuMax, iteration + 1),
                Step::Small | Step::Accepted { small: true } => {
                    break 'run (StopReason::SmallStep, iteration + 1)
                }
                Step::Accepted { small: false } => {}
            }
            let progress = Progress {
                iteration: iteration + 1,
                cost,
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
    LmOutcome {
        params: st.p,
        cost,
        iterations,
        evaluations,
        mu,
        reason,
        lu_fallbacks: fallbacks,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// r(p) = A p − b for a fixed A (m × n).
    struct Linear {
        a: Mat<f64>,
        b: Vec<f64>,
    }

    impl Problem for Linear {
        fn n_params(&self) -> usize {
            self.a.ncols()
        }
        fn n_residuals(&self) -> usize {
            self.a.nrows()
        }
        fn residuals(&mut self, p: &[f64], out: &mut [f64]) {
            for (i, o) in out.iter_mut().enumerate() {
                *o = (0..p.len()).map(|j| self.a[(i, j)] * p[j]).sum::<f64>() - self.b[i];
            }
        }
        fn jacobian(&mut self, _p: &[f64], jac: &mut Mat<f64>) {
            jac.copy_from(&self.a);
        }
    }

    fn linear(m: usize, n: usize) -> Linear {
        let a = Mat::from_fn(m, n, |i, j| {
            ((i * 7 + j * 3) % 11) as f64 - 5.0 + if i == j { 10.0 } else { 0.0 }
        });
        let b = (0..m).map(|i| (i as f64).sin()).collect();
        Linear { a, b }
    }

    #[test]
    fn overdetermined_linear_problem_reaches_the_least_squares_solution() {
        let mut prob = linear(12, 4);
        let out = minimize(&mut prob, &[0.0; 4], &LmConfig::TRAINLM, |_| {
            Control::Continue
        });
        // At the optimum the gradient Aᵀr vanishes.
        let mut r = vec![0.0; 12];
        prob.residuals(&out.params, &mut r);
        for j in 0..4 {
            let g: f64 = (0..12).map(|i| prob.a[(i, j)] * r[i]).sum();
            assert!(g.abs() < 1e-6, "gradient {g}");
        }
        assert_eq!(out.reason, StopReason::MinGradient);
    }

    #[test]
    fn underdetermined_problem_uses_the_dual_system_and_fits_exactly() {
        let mut prob = linear(3, 8);
        let out = minimize(&mut prob, &[0.0; 8], &LmConfig::TRAINLM, |_| {
            Control::Continue
        });
        assert!(out.cost < 1e-12, "cost {}", out.cost);
    }

    #[test]
    fn callback_can_stop_and_sees_decreasing_cost() {
        let mut prob = linear(12, 4);
        let mut costs = Vec::new();
        let out = minimize(&mut prob, &[5.0; 4], &LmConfig::TRAINLM, |p| {
            costs.push(p.cost);
            if p.iteration == 2 {
                Control::Stop
            } else {
                Control::Continue
            }
        });
        assert_eq!((out.reason, out.iterations), (StopReason::Callback, 2));
        assert!(costs.windows(2).all(|w| w[1] <= w[0]));
    }

    #[test]
    fn settings_that_cannot_work_are_an_outcome() {
        let mut pr = linear(6, 3);
        for cfg in [
            LmConfig {
                mu: 0.0,
                ..LmConfig::TRAINLM
            },
            LmConfig {
                mu_inc: 1.0,
                ..LmConfig::TRAINLM
            },
            LmConfig {
                mu_dec: 1.5,
                ..LmConfig::TRAINLM
            },
        ] {
            let out = minimize(&mut pr, &[0.0; 3], &cfg, |_| Control::Continue);
            assert_eq!((out.reason, out.iterations), (StopReason::InvalidConfig, 0));
        }
    }

    #[test]
    fn non_finite_start_is_an_outcome() {
        let mut prob = linear(4, 2);
        let out = minimize(&mut prob, &[f64::NAN, 0.0], &LmConfig::TRAINLM, |_| {
            Control::Continue
        });
        assert_eq!(out.reason, StopReason::NonFinite);
    }
}
