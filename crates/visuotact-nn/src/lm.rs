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

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt;
use faer::linalg::matmul::triangular::{matmul, BlockStructure};
use faer::linalg::solvers::Solve;
use faer::{Accum, Mat, MatMut};

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

/// Copies a square matrix's strict upper triangle onto its strict lower one, transposed
/// (`upper_to_lower == false`: the other way round), by halves so that every copy is a block.
fn mirror_triangle(a: MatMut<'_, f64>, upper_to_lower: bool) {
    let k = a.nrows();
    if k <= 64 {
        let mut a = a;
        for j in 0..k {
            for i in j + 1..k {
                if upper_to_lower {
                    a[(i, j)] = a[(j, i)];
                } else {
                    a[(j, i)] = a[(i, j)];
                }
            }
        }
        return;
    }
    let h = k / 2;
    let (a11, mut a12, mut a21, a22) = a.split_at_mut(h, h);
    if upper_to_lower {
        a21.copy_from(a12.as_ref().transpose());
    } else {
        a12.copy_from(a21.as_ref().transpose());
    }
    rayon::join(
        || mirror_triangle(a11, upper_to_lower),
        || mirror_triangle(a22, upper_to_lower),
    );
}

/// Solves the damped systems `(G + μD) y = b` of one iteration for a symmetric Gram matrix `G`
/// in a single `k × k` buffer: the caller writes `G`'s lower triangle ([`DampedSolver::gram_mut`])
/// and [`DampedSolver::keep_gram`] keeps its strict lower triangle in the strict upper one
/// (transposed), its diagonal and the [`BAND`] subdiagonals below it aside; every μ trial then
/// restores the lower triangle from there and factorises it in place. faer's Cholesky writes
/// the factor into the lower triangle and, in its small diagonal kernels, scratch into upper
/// entries fewer than 16 places from the diagonal (32 with AVX-512) — which is why the band
/// is kept aside; a test factorises sizes across faer's block and recursion thresholds and
/// checks that every trial solves the kept system. One matrix of `k²` numbers, not two.
///
/// When Cholesky fails (the matrix is not positive definite in floating point) it falls back,
/// as MATLAB's backslash does, to LU with partial pivoting on the whole symmetric matrix (a
/// second matrix, made only then).
pub(crate) struct DampedSolver {
    a: Mat<f64>,
    gram_diag: Vec<f64>,
    /// `G[j + d, j]` for `d` in `1..=BAND` at `band[j * BAND + d − 1]`.
    band: Vec<f64>,
    /// The lower triangle still holds the kept Gram matrix (no trial has factorised it yet).
    lower_is_gram: bool,
    scratch: MemBuffer,
    par: faer::Par,
    /// Systems solved by the LU fallback.
    pub(crate) fallbacks: usize,
}

/// Subdiagonals of the Gram matrix kept beside the buffer (see [`DampedSolver`]).
pub(crate) const BAND: usize = 64;

/// Columns of `L⁻¹` made at a time by [`DampedSolver::trace_inverse`].
const INVERSE_BLOCK: usize = 256;

impl DampedSolver {
    pub(crate) fn new(k: usize) -> Self {
        let par = faer::get_global_parallelism();
        Self {
            a: Mat::<f64>::zeros(k, k),
            gram_diag: vec![0.0; k],
            band: vec![0.0; k * BAND],
            lower_is_gram: false,
            scratch: MemBuffer::new(llt::factor::cholesky_in_place_scratch::<f64>(
                k,
                par,
                Default::default(),
            )),
            par,
            fallbacks: 0,
        }
    }

    /// The buffer whose lower triangle receives the Gram matrix (the upper triangle may be
    /// overwritten freely); call [`DampedSolver::keep_gram`] once it is written.
    pub(crate) fn gram_mut(&mut self) -> MatMut<'_, f64> {
        self.a.as_mut()
    }

    /// Keeps the Gram matrix just written for every μ trial of the iteration.
    pub(crate) fn keep_gram(&mut self) {
        mirror_triangle(self.a.as_mut(), false);
        let k = self.a.nrows();
        for j in 0..k {
            self.gram_diag[j] = self.a[(j, j)];
            let col = &self.a.col_as_slice(j)[j + 1..(j + 1 + BAND).min(k)];
            self.band[j * BAND..j * BAND + col.len()].copy_from_slice(col);
        }
        self.lower_is_gram = true;
    }

    /// The kept Gram matrix's diagonal.
    pub(crate) fn gram_diag(&self) -> &[f64] {
        &self.gram_diag
    }

    /// Writes `G`'s lower triangle and keeps it (tests and small problems).
    #[cfg(test)]
    pub(crate) fn load_gram(&mut self, g: &Mat<f64>) {
        self.a.copy_from(g);
        self.keep_gram();
    }

    /// The lower triangle back to `G + diag(shift)` from the kept copy.
    /// (The first trial after [`DampedSolver::keep_gram`] finds it there and sets only the
    /// diagonal.)
    fn restore(&mut self, shift: impl Fn(usize) -> f64) {
        let k = self.a.nrows();
        if std::mem::take(&mut self.lower_is_gram) {
            for j in 0..k {
                self.a[(j, j)] = self.gram_diag[j] + shift(j);
            }
            return;
        }
        mirror_triangle(self.a.as_mut(), true);
        for j in 0..k {
            self.a[(j, j)] = self.gram_diag[j] + shift(j);
            let end = (j + 1 + BAND).min(k);
            self.a.col_as_slice_mut(j)[j + 1..end]
                .copy_from_slice(&self.band[j * BAND..j * BAND + end - j - 1]);
        }
    }

    /// Cholesky of the restored lower triangle in place.
    fn factorise(&mut self) -> bool {
        llt::factor::cholesky_in_place(
            self.a.as_mut(),
            Default::default(),
            self.par,
            MemStack::new(&mut self.scratch),
            Default::default(),
        )
        .is_ok()
    }

    /// `y` with `(G + μ·diag(d)) y = b`; `None` when neither factorisation gives finite numbers.
    pub(crate) fn solve(&mut self, mu: f64, d: &[f64], b: &[f64]) -> Option<Vec<f64>> {
        let k = self.a.nrows();
        self.restore(|i| mu * d[i]);
        let mut y = Mat::<f64>::from_fn(k, 1, |i, _| b[i]);
        if self.factorise() {
            llt::solve::solve_in_place(
                self.a.as_ref(),
                y.as_mut(),
                self.par,
                MemStack::new(&mut self.scratch),
            );
        } else {
            self.fallbacks += 1;
            // The kept G: the band and the diagonal aside, the rest in the upper triangle.
            let (a, diag, band) = (&self.a, &self.gram_diag, &self.band);
            let kept = |i: usize, j: usize| match i - j {
                0 => diag[i] + mu * d[i],
                o if o <= BAND => band[j * BAND + o - 1],
                _ => a[(j, i)],
            };
            let full = Mat::<f64>::from_fn(k, k, |i, j| kept(i.max(j), i.min(j)));
            y = full.partial_piv_lu().solve(&y);
        }
        let y: Vec<f64> = (0..k).map(|i| y[(i, 0)]).collect();
        y.iter().all(|v| v.is_finite()).then_some(y)
    }

    /// `tr((G + shift·I)⁻¹)` as `‖L⁻¹‖²_F` from the Cholesky factor `L` of the shifted kept
    /// Gram matrix, `L⁻¹` made [`INVERSE_BLOCK`] columns at a time (column `j` of `L⁻¹` starts
    /// at row `j`); `None` when the shifted matrix is not positive definite.
    pub(crate) fn trace_inverse(&mut self, shift: f64) -> Option<f64> {
        let k = self.a.nrows();
        self.restore(|_| shift);
        if !self.factorise() {
            return None;
        }
        let mut x = Mat::<f64>::zeros(k, INVERSE_BLOCK.min(k));
        let mut sum = 0.0f64;
        for j0 in (0..k).step_by(INVERSE_BLOCK) {
            let w = INVERSE_BLOCK.min(k - j0);
            let mut xb = x.as_mut().submatrix_mut(j0, 0, k - j0, w);
            xb.fill(0.0);
            for c in 0..w {
                xb[(c, c)] = 1.0;
            }
            faer::linalg::triangular_solve::solve_lower_triangular_in_place(
                self.a.as_ref().submatrix(j0, j0, k - j0, k - j0),
                xb.as_mut(),
                self.par,
            );
            for c in 0..w {
                sum += xb.as_ref().col(c).iter().map(|v| v * v).sum::<f64>();
            }
        }
        sum.is_finite().then_some(sum)
    }
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

/// Levenberg–Marquardt settings that cannot work; the message says which.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct LmConfigError(pub String);

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
            return Err(LmConfigError(format!(
                "mu must be positive, got {}",
                self.mu
            )));
        }
        if !(self.mu_inc > 1.0 && self.mu_inc.is_finite()) {
            return Err(LmConfigError(format!(
                "mu_inc must exceed 1, got {}",
                self.mu_inc
            )));
        }
        if !(self.mu_dec > 0.0 && self.mu_dec < 1.0) {
            return Err(LmConfigError(format!(
                "mu_dec must lie in (0, 1), got {}",
                self.mu_dec
            )));
        }
        if self.mu_max.is_nan() || self.mu_max < self.mu {
            return Err(LmConfigError(format!(
                "mu_max ({}) must be at least mu ({})",
                self.mu_max, self.mu
            )));
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
    use faer::linalg::solvers::DenseSolveCore;

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
    fn cholesky_failure_falls_back_to_lu() {
        // Symmetric but indefinite (eigenvalues 3 and −1): Cholesky fails, LU solves it.
        let g = Mat::<f64>::from_fn(2, 2, |i, j| if i == j { 1.0 } else { 2.0 });
        let mut s = DampedSolver::new(2);
        s.load_gram(&g);
        let y = s.solve(0.0, &[1.0, 1.0], &[3.0, 0.0]).unwrap();
        // [[1, 2], [2, 1]] y = [3, 0] → y = [−1, 2].
        assert!(
            (y[0] + 1.0).abs() < 1e-12 && (y[1] - 2.0).abs() < 1e-12,
            "{y:?}"
        );
        assert_eq!(s.fallbacks, 1);
        // Positive definite once damped: Cholesky, no fallback; only the lower triangle is read.
        let mut lower = g.clone();
        lower[(0, 1)] = f64::NAN;
        s.load_gram(&lower);
        let y = s.solve(2.0, &[1.0, 1.0], &[3.0, 0.0]).unwrap();
        // [[3, 2], [2, 3]] y = [3, 0] → y = [9/5, −6/5].
        assert!(
            (y[0] - 1.8).abs() < 1e-12 && (y[1] + 1.2).abs() < 1e-12,
            "{y:?}"
        );
        assert_eq!(s.fallbacks, 1);
        // Singular even for LU: no step.
        s.load_gram(&Mat::<f64>::zeros(2, 2));
        assert!(s.solve(0.0, &[1.0, 1.0], &[1.0, 1.0]).is_none());
    }

    /// A symmetric positive definite `k × k` matrix `B Bᵀ + I` from a seeded `B`.
    fn spd(k: usize, seed: u64) -> Mat<f64> {
        let mut state = seed;
        let mut next = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let b = Mat::<f64>::from_fn(k, k, |_, _| next());
        let mut g = &b * b.transpose();
        for i in 0..k {
            g[(i, i)] += 1.0;
        }
        g
    }

    #[test]
    fn every_mu_trial_solves_the_kept_system_in_one_buffer() {
        // Sizes on both sides of faer's blocked and recursive Cholesky; each trial must solve
        // (G + μI) y = b exactly as a fresh factorisation does, however many came before it
        // (the factor of one trial overwrites the lower triangle the next one restores).
        for k in [5, 70, 300, 700] {
            let g = spd(k, k as u64);
            let b: Vec<f64> = (0..k).map(|i| (i as f64 * 0.37).sin()).collect();
            let mut kept = DampedSolver::new(k);
            // Only the lower triangle is written: the upper is garbage until kept.
            let mut buf = kept.gram_mut();
            for j in 0..k {
                for i in 0..k {
                    buf[(i, j)] = if i >= j { g[(i, j)] } else { f64::NAN };
                }
            }
            kept.keep_gram();
            for mu in [1e-3, 1e-2, 10.0, 1e-3] {
                let y = kept.solve(mu, &vec![1.0; k], &b).unwrap();
                let mut damped = g.clone();
                for i in 0..k {
                    damped[(i, i)] += mu;
                }
                let bm = Mat::<f64>::from_fn(k, 1, |i, _| b[i]);
                let resid = &damped * Mat::<f64>::from_fn(k, 1, |i, _| y[i]) - &bm;
                let rel = resid.norm_l2() / bm.norm_l2();
                assert!(rel < 1e-12, "k {k} μ {mu}: relative residual {rel}");
            }
            assert_eq!(kept.fallbacks, 0);
            // tr((G + λI)⁻¹) by blocks of L⁻¹ equals the trace of the dense inverse.
            let lam = 0.5;
            let mut shifted = g.clone();
            for i in 0..k {
                shifted[(i, i)] += lam;
            }
            let inv = shifted.partial_piv_lu().inverse();
            let want: f64 = (0..k).map(|i| inv[(i, i)]).sum();
            let got = kept.trace_inverse(lam).unwrap();
            assert!(
                (got - want).abs() < 1e-10 * want.abs(),
                "k {k}: {got} vs {want}"
            );
            assert_eq!(kept.gram_diag()[k - 1], g[(k - 1, k - 1)]);
        }
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
