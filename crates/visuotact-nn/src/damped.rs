//! The damped normal equations of one Levenberg–Marquardt iteration, `(G + μD) y = b` for a
//! symmetric positive semi-definite Gram matrix `G` (`JᵀJ`, or `JJᵀ` on the dual path), solved
//! for every μ trial of the iteration from one buffer of about `k²` numbers.
//!
//! The caller writes `G`'s lower triangle into the square the solver lends
//! ([`DampedSolver::gram_mut`]) and keeps it ([`DampedSolver::keep_gram`]). Then:
//!
//! - **Mixed precision** (systems of at least [`MIXED_MIN`] unknowns): `G`'s lower triangle is
//!   packed by columns at the front of the buffer and the single-precision factor of each trial
//!   lives behind it. A trial rounds `G + μD` to single precision, factorises it (Cholesky,
//!   faer's, half the time of double precision — the factorisation dominates a trial), and
//!   refines the solution with residuals `b − (G + μD) y` formed in double precision from the
//!   packed `G` until its backward error is that of a double factorisation (LAPACK `dsposv`'s
//!   test). Systems too ill-conditioned for single precision (the factorisation fails, or the
//!   residual stops shrinking) fall back to the following, until μ has grown by
//!   [`RETRY_FACTOR`]:
//! - **Double precision**: `G`'s strict lower triangle is kept in the strict upper one of the
//!   square (transposed), its diagonal and the [`BAND`] subdiagonals below it aside; every trial
//!   restores the lower triangle from there and factorises it in place. faer's Cholesky writes
//!   the factor into the lower triangle and, in its small diagonal kernels, scratch into upper
//!   entries fewer than 16 places from the diagonal (32 with AVX-512) — which is why the band is
//!   kept aside; a test factorises sizes across faer's block and recursion thresholds and checks
//!   that every trial solves the kept system. When that Cholesky fails too, LU with partial
//!   pivoting on the whole symmetric matrix solves it, as MATLAB's backslash does (a second
//!   matrix, made only then).
//!
//! Either way the solutions agree with a double factorisation's to the conditioning of the
//! system: tests compare both paths with a dense solve.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt;
use faer::linalg::solvers::Solve;
use faer::{Mat, MatMut, MatRef};
use rayon::prelude::*;

/// Subdiagonals of the Gram matrix kept beside the square on the double-precision path.
pub(crate) const BAND: usize = 64;

/// Systems with at least this many unknowns are solved in mixed precision first; smaller ones
/// factorise fast enough in double precision.
pub(crate) const MIXED_MIN: usize = 1024;

/// Refinement steps a mixed-precision solve may take before it falls back.
const REFINE_MAX: usize = 30;

/// After the mixed path fails at some μ, the trials of the iteration stay in double precision
/// until μ has grown by this factor (the damped system is then better conditioned).
const RETRY_FACTOR: f64 = 100.0;

/// Columns of `L⁻¹` made at a time by [`DampedSolver::trace_inverse`].
const INVERSE_BLOCK: usize = 256;

/// Numbers in the buffer of a `k`-unknown solver: the square, and on the mixed path room for
/// the packed triangle and a single-precision square with aligned columns behind it.
pub(crate) fn buffer_len(k: usize) -> usize {
    if k >= MIXED_MIN {
        k * k + 16 * k
    } else {
        k * k
    }
}

/// Start of column `j` of a `k × k` lower triangle packed by columns.
fn packed_start(j: usize, k: usize) -> usize {
    j * k - j * j.saturating_sub(1) / 2
}

/// What the buffer holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Layout {
    /// The square was lent out: its lower triangle receives `G`.
    Written,
    /// `G`'s lower triangle packed by columns, then the single-precision factor.
    Packed,
    /// The double-precision layout (see the module docs); `lower_is_gram`: the lower triangle
    /// still holds `G` (no trial has factorised it yet).
    Square { lower_is_gram: bool },
}

/// Solves the damped systems of one iteration; see the module docs.
pub(crate) struct DampedSolver {
    k: usize,
    buf: Vec<f64>,
    layout: Layout,
    gram_diag: Vec<f64>,
    /// Column sums of `|G|` (packed layout).
    abs_sums: Vec<f64>,
    /// `G[j + d, j]` for `d` in `1..=BAND` at `band[j * BAND + d − 1]` (square layout).
    band: Vec<f64>,
    scratch: MemBuffer,
    /// The single-precision factorisation's, made on first use.
    scratch32: Option<MemBuffer>,
    par: faer::Par,
    /// Systems solved by the LU fallback.
    pub(crate) fallbacks: usize,
    /// Systems of the mixed path that fell back to the double-precision factorisation.
    pub(crate) mixed_fallbacks: usize,
    /// Refinement steps taken by the mixed path, over all its systems.
    pub(crate) refinements: usize,
    /// The μ of this iteration's last trial that the mixed path could not solve.
    failed_mu: f64,
}

impl DampedSolver {
    pub(crate) fn new(k: usize) -> Self {
        let par = faer::get_global_parallelism();
        Self {
            k,
            buf: vec![0.0; buffer_len(k)],
            layout: Layout::Written,
            gram_diag: vec![0.0; k],
            abs_sums: Vec::new(),
            band: vec![0.0; k * BAND],
            scratch: MemBuffer::new(llt::factor::cholesky_in_place_scratch::<f64>(
                k,
                par,
                Default::default(),
            )),
            scratch32: None,
            par,
            fallbacks: 0,
            mixed_fallbacks: 0,
            refinements: 0,
            failed_mu: f64::INFINITY,
        }
    }

    fn square(&mut self) -> MatMut<'_, f64> {
        let k = self.k;
        MatMut::from_column_major_slice_mut(&mut self.buf[..k * k], k, k)
    }

    fn square_ref(&self) -> MatRef<'_, f64> {
        let k = self.k;
        MatRef::from_column_major_slice(&self.buf[..k * k], k, k)
    }

    /// The square whose lower triangle receives the Gram matrix (the upper triangle may be
    /// overwritten freely); call [`DampedSolver::keep_gram`] once it is written.
    pub(crate) fn gram_mut(&mut self) -> MatMut<'_, f64> {
        self.layout = Layout::Written;
        self.square()
    }

    /// Keeps the Gram matrix just written for every μ trial of the iteration.
    pub(crate) fn keep_gram(&mut self) {
        let k = self.k;
        for j in 0..k {
            self.gram_diag[j] = self.buf[j * k + j];
        }
        self.failed_mu = f64::INFINITY;
        if k < MIXED_MIN {
            self.keep_square();
            return;
        }
        self.pack();
        self.abs_sums = packed_symmetric_times(&self.buf, k, &vec![1.0; k], f64::abs);
    }

    /// The packed layout from a square whose lower triangle holds `G` (the iteration's
    /// column sums of `|G|` are kept from [`DampedSolver::keep_gram`]).
    fn pack(&mut self) {
        let k = self.k;
        for j in 1..k {
            let src = j * k + j;
            self.buf.copy_within(src..(j + 1) * k, packed_start(j, k));
        }
        self.layout = Layout::Packed;
    }

    /// The square layout from a square whose lower triangle holds `G`.
    fn keep_square(&mut self) {
        let k = self.k;
        mirror_triangle(self.square(), false);
        for j in 0..k {
            let col = &self.buf[j * k + j + 1..j * k + (j + 1 + BAND).min(k)];
            self.band[j * BAND..j * BAND + col.len()].copy_from_slice(col);
        }
        self.layout = Layout::Square {
            lower_is_gram: true,
        };
    }

    /// From the packed layout to the square one (the mixed path gave up).
    fn unpack(&mut self) {
        let k = self.k;
        for j in (1..k).rev() {
            let src = packed_start(j, k);
            self.buf.copy_within(src..src + k - j, j * k + j);
        }
        self.keep_square();
    }

    /// The kept Gram matrix's diagonal.
    pub(crate) fn gram_diag(&self) -> &[f64] {
        &self.gram_diag
    }

    /// Writes `G`'s lower triangle and keeps it (tests and small problems).
    #[cfg(test)]
    pub(crate) fn load_gram(&mut self, g: &Mat<f64>) {
        self.gram_mut().copy_from(g);
        self.keep_gram();
    }

    /// Square layout: the lower triangle back to `G + diag(shift)` from the kept copy.
    /// (The first trial after [`DampedSolver::keep_gram`] finds it there and sets only the
    /// diagonal.)
    fn restore(&mut self, shift: impl Fn(usize) -> f64) {
        let k = self.k;
        let lower_is_gram = self.layout
            == Layout::Square {
                lower_is_gram: true,
            };
        self.layout = Layout::Square {
            lower_is_gram: false,
        };
        for j in 0..k {
            self.buf[j * k + j] = self.gram_diag[j] + shift(j);
        }
        if lower_is_gram {
            return;
        }
        mirror_triangle(self.square(), true);
        for j in 0..k {
            let end = (j + 1 + BAND).min(k);
            self.buf[j * k + j + 1..j * k + end]
                .copy_from_slice(&self.band[j * BAND..j * BAND + end - j - 1]);
        }
    }

    /// Square layout: Cholesky of the restored lower triangle in place.
    fn factorise(&mut self) -> bool {
        let (k, par) = (self.k, self.par);
        let a = MatMut::from_column_major_slice_mut(&mut self.buf[..k * k], k, k);
        llt::factor::cholesky_in_place(
            a,
            Default::default(),
            par,
            MemStack::new(&mut self.scratch),
            Default::default(),
        )
        .is_ok()
    }

    /// `y` with `(G + μ·diag(d)) y = b`; `None` when no factorisation gives finite numbers.
    pub(crate) fn solve(&mut self, mu: f64, d: &[f64], b: &[f64]) -> Option<Vec<f64>> {
        let k = self.k;
        let retry = k >= MIXED_MIN && mu >= RETRY_FACTOR * self.failed_mu;
        if self.layout == Layout::Packed || retry {
            if self.layout != Layout::Packed {
                // The lower triangle back to G, packed again.
                self.restore(|_| 0.0);
                self.pack();
            }
            let shift: Vec<f64> = d.iter().map(|di| mu * di).collect();
            if let Some(y) = self.solve_mixed(&shift, b) {
                return Some(y);
            }
            self.failed_mu = mu;
            self.mixed_fallbacks += 1;
            self.unpack();
        }
        self.restore(|i| mu * d[i]);
        let mut y = Mat::<f64>::from_fn(k, 1, |i, _| b[i]);
        if self.factorise() {
            let a = MatRef::from_column_major_slice(&self.buf[..k * k], k, k);
            llt::solve::solve_in_place(a, y.as_mut(), self.par, MemStack::new(&mut self.scratch));
        } else {
            self.fallbacks += 1;
            // The kept G: the band and the diagonal aside, the rest in the upper triangle.
            let (a, diag, band) = (self.square_ref(), &self.gram_diag, &self.band);
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

    /// Packed layout: `y` with `(G + diag(shift)) y = b` in mixed precision (see the module
    /// docs): refined until `‖b − A y‖∞ ≤ ‖y‖∞ ‖A‖∞ ε √k` within [`REFINE_MAX`] steps; `None`
    /// when the single factorisation fails or the residual stops halving.
    fn solve_mixed(&mut self, shift: &[f64], b: &[f64]) -> Option<Vec<f64>> {
        let (k, par) = (self.k, self.par);
        let scratch = self.scratch32.get_or_insert_with(|| {
            MemBuffer::new(
                llt::factor::cholesky_in_place_scratch::<f32>(k, par, Default::default())
                    .or(llt::solve::solve_in_place_scratch::<f32>(k, 1, par)),
            )
        });
        let (packed, rest) = self.buf.split_at_mut(k * (k + 1) / 2);
        let packed = &*packed;
        let rest: &mut [f32] = bytemuck::cast_slice_mut(rest);
        // Columns 64-byte aligned for the factorisation's kernels.
        let skip = rest.as_ptr().align_offset(64).min(15);
        let stride = k.next_multiple_of(16);
        let mut low = MatMut::from_column_major_slice_with_stride_mut(
            &mut rest[skip..skip + stride * (k - 1) + k],
            k,
            k,
            stride,
        );
        low.as_mut()
            .par_col_iter_mut()
            .enumerate()
            .for_each(|(j, col)| {
                let Some(col) = col.try_as_col_major_mut() else {
                    return;
                };
                let col = &mut col.as_slice_mut()[j..];
                let src = &packed[packed_start(j, k)..packed_start(j + 1, k)];
                for (l, &g) in col.iter_mut().zip(src) {
                    *l = g as f32;
                }
                col[0] = (src[0] + shift[j]) as f32;
            });
        let factored = llt::factor::cholesky_in_place(
            low.as_mut(),
            Default::default(),
            par,
            MemStack::new(scratch),
            Default::default(),
        );
        if factored.is_err() {
            return None;
        }
        let a_norm = self
            .abs_sums
            .iter()
            .zip(shift)
            .fold(0.0f64, |m, (s, d)| m.max(s + d.abs()));
        let tolerance = a_norm * f64::EPSILON * (k as f64).sqrt();
        let inf_norm = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let mut y = vec![0.0; k];
        let mut r = b.to_vec();
        let mut c = Mat::<f32>::zeros(k, 1);
        let mut last = f64::INFINITY;
        for step in 0..=REFINE_MAX {
            let r_norm = inf_norm(&r);
            if !r_norm.is_finite() || r_norm > 0.5 * last {
                return None;
            }
            if r_norm == 0.0 || r_norm <= tolerance * inf_norm(&y) {
                self.refinements += step;
                return Some(y);
            }
            if step == REFINE_MAX {
                return None;
            }
            last = r_norm;
            // The correction in single precision, from the residual scaled to the unit.
            for (ci, &ri) in c.col_as_slice_mut(0).iter_mut().zip(&r) {
                *ci = (ri / r_norm) as f32;
            }
            llt::solve::solve_in_place(low.as_ref(), c.as_mut(), par, MemStack::new(scratch));
            for (yi, &ci) in y.iter_mut().zip(c.col_as_slice(0)) {
                *yi += f64::from(ci) * r_norm;
            }
            let gy = packed_symmetric_times(packed, k, &y, |g| g);
            for i in 0..k {
                r[i] = b[i] - gy[i] - shift[i] * y[i];
            }
        }
        None
    }

    /// `tr((G + shift·I)⁻¹)` as `‖L⁻¹‖²_F` from the Cholesky factor `L` of the shifted kept
    /// Gram matrix (in double precision), `L⁻¹` made [`INVERSE_BLOCK`] columns at a time
    /// (column `j` of `L⁻¹` starts at row `j`); `None` when the shifted matrix is not positive
    /// definite.
    pub(crate) fn trace_inverse(&mut self, shift: f64) -> Option<f64> {
        if self.layout == Layout::Packed {
            self.unpack();
        }
        let k = self.k;
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
                self.square_ref().submatrix(j0, j0, k - j0, k - j0),
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

/// `S x` for the symmetric `S` with `S[i, j] = f(G[i, j])`, `G` a `k × k` lower triangle packed
/// by columns at the front of `packed`: column ranges of about equal size in parallel, each
/// with its own sum, added at the end.
fn packed_symmetric_times(
    packed: &[f64],
    k: usize,
    x: &[f64],
    f: impl Fn(f64) -> f64 + Sync,
) -> Vec<f64> {
    let parts = 4 * rayon::current_num_threads();
    let total = packed_start(k, k);
    let mut bounds = vec![0];
    for j in 1..k {
        if packed_start(j, k) * parts >= total * bounds.len() {
            bounds.push(j);
        }
    }
    bounds.push(k);
    bounds
        .par_windows(2)
        .map(|w| {
            let mut out = vec![0.0; k];
            for j in w[0]..w[1] {
                let col = &packed[packed_start(j, k)..packed_start(j + 1, k)];
                let xj = x[j];
                let mut dot = f(col[0]) * xj;
                for ((&g, &xi), o) in col[1..].iter().zip(&x[j + 1..]).zip(&mut out[j + 1..]) {
                    let g = f(g);
                    dot += g * xi;
                    *o += g * xj;
                }
                out[j] += dot;
            }
            out
        })
        .reduce(
            || vec![0.0; k],
            |mut a, b| {
                for (ai, bi) in a.iter_mut().zip(&b) {
                    *ai += bi;
                }
                a
            },
        )
}

/// Copies a square matrix's strict upper triangle onto its strict lower one, transposed
/// (`upper_to_lower == false`: the other way round), by halves so that every copy is a block.
pub(crate) fn mirror_triangle(a: MatMut<'_, f64>, upper_to_lower: bool) {
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

#[cfg(test)]
mod tests {
    use super::*;
    use faer::linalg::solvers::DenseSolveCore;
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

    /// Seeded uniform numbers in [−0.5, 0.5).
    fn uniform(seed: u64) -> impl FnMut() -> f64 {
        let mut state = seed;
        move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        }
    }

    /// A symmetric positive definite `k × k` matrix `B Bᵀ + I` from a seeded `B`.
    fn spd(k: usize, seed: u64) -> Mat<f64> {
        let mut next = uniform(seed);
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
                let bm = Mat::<f64>::from_fn(k, 1, |i, _| b[i]);
                let resid = shifted(&g, mu) * Mat::<f64>::from_fn(k, 1, |i, _| y[i]) - &bm;
                let rel = resid.norm_l2() / bm.norm_l2();
                assert!(rel < 1e-12, "k {k} μ {mu}: relative residual {rel}");
            }
            assert_eq!(kept.fallbacks, 0);
            // tr((G + λI)⁻¹) by blocks of L⁻¹ equals the trace of the dense inverse.
            let lam = 0.5;
            let want = dense_trace_inverse(&g, lam);
            let got = kept.trace_inverse(lam).unwrap();
            assert!(
                (got - want).abs() < 1e-10 * want.abs(),
                "k {k}: {got} vs {want}"
            );
            assert_eq!(kept.gram_diag()[k - 1], g[(k - 1, k - 1)]);
        }
    }

    /// `G + μI`.
    fn shifted(g: &Mat<f64>, mu: f64) -> Mat<f64> {
        let mut damped = g.clone();
        for i in 0..g.nrows() {
            damped[(i, i)] += mu;
        }
        damped
    }

    /// `tr((G + λI)⁻¹)` from the dense inverse.
    fn dense_trace_inverse(g: &Mat<f64>, lam: f64) -> f64 {
        let inv = shifted(g, lam).partial_piv_lu().inverse();
        (0..g.nrows()).map(|i| inv[(i, i)]).sum()
    }

    /// `y` with `(G + μI) y = b` by a dense LU factorisation.
    fn dense_solution(g: &Mat<f64>, mu: f64, b: &[f64]) -> Vec<f64> {
        let y = shifted(g, mu)
            .partial_piv_lu()
            .solve(Mat::<f64>::from_fn(b.len(), 1, |i, _| b[i]));
        (0..b.len()).map(|i| y[(i, 0)]).collect()
    }

    fn max_rel_difference(a: &[f64], b: &[f64]) -> f64 {
        let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        a.iter()
            .zip(b)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs() / scale))
    }

    #[test]
    fn mixed_precision_solves_as_a_double_factorisation_does() {
        // Above MIXED_MIN; 1537 columns are not a multiple of the aligned stride.
        for k in [MIXED_MIN, 1537] {
            let g = spd(k, 3 * k as u64);
            let b: Vec<f64> = (0..k).map(|i| (i as f64 * 0.11).cos()).collect();
            let mut s = DampedSolver::new(k);
            s.load_gram(&g);
            assert_eq!(s.layout, Layout::Packed);
            for mu in [1e-3, 1e-2, 10.0] {
                let y = s.solve(mu, &vec![1.0; k], &b).unwrap();
                let want = dense_solution(&g, mu, &b);
                let diff = max_rel_difference(&y, &want);
                assert!(diff < 1e-11, "k {k} μ {mu}: {diff}");
            }
            assert_eq!((s.mixed_fallbacks, s.fallbacks), (0, 0));
            assert!(s.refinements >= 3, "{} refinements", s.refinements);
            // The double-precision path from the packed layout: the trace of the inverse,
            // then trials on the square layout.
            let lam = 0.5;
            let want = dense_trace_inverse(&g, lam);
            let got = s.trace_inverse(lam).unwrap();
            assert!((got - want).abs() < 1e-10 * want, "k {k}: {got} vs {want}");
            let y = s.solve(0.1, &vec![1.0; k], &b).unwrap();
            assert!(max_rel_difference(&y, &dense_solution(&g, 0.1, &b)) < 1e-11);
            assert_eq!(
                s.layout,
                Layout::Square {
                    lower_is_gram: false
                }
            );
        }
    }

    /// `(G + μI) y = b` to rounding level: `‖b − (G + μI) y‖∞ < 1e-12 ‖G + μI‖∞ ‖y‖∞`.
    fn assert_backward_stable(g: &Mat<f64>, mu: f64, y: &[f64], b: &[f64]) {
        let k = y.len();
        let a_norm = (0..k)
            .map(|j| (0..k).map(|i| g[(i, j)].abs()).sum::<f64>())
            .fold(0.0f64, f64::max)
            + mu;
        let y_norm = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let ym = Mat::<f64>::from_fn(k, 1, |i, _| y[i]);
        let r = g * &ym + &ym * mu;
        let worst = (0..k).fold(0.0f64, |m, i| m.max((r[(i, 0)] - b[i]).abs()));
        assert!(
            worst < 1e-12 * a_norm * y_norm,
            "μ {mu}: {worst} vs {}",
            a_norm * y_norm
        );
    }

    #[test]
    fn systems_too_ill_conditioned_for_single_precision_fall_back_to_double() {
        // G = B Bᵀ of rank k/2 damped by 1e-9: condition ≈ 1e11, beyond single precision.
        let k = MIXED_MIN + 76;
        let mut next = uniform(7);
        let half = Mat::<f64>::from_fn(k, k / 2, |_, _| next());
        let g = &half * half.transpose();
        let b: Vec<f64> = (0..k).map(|i| (i as f64 * 0.3).sin()).collect();
        let mut s = DampedSolver::new(k);
        s.load_gram(&g);
        let mu = 1e-9;
        let y = s.solve(mu, &vec![1.0; k], &b).unwrap();
        assert_eq!(s.mixed_fallbacks, 1);
        assert_backward_stable(&g, mu, &y, &b);
        // Ten times the μ: still double precision; a hundred times and more: mixed again.
        let before = s.refinements;
        let y = s.solve(mu * 10.0, &vec![1.0; k], &b).unwrap();
        assert_eq!(
            (s.layout, s.refinements),
            (
                Layout::Square {
                    lower_is_gram: false
                },
                before
            )
        );
        assert_backward_stable(&g, mu * 10.0, &y, &b);
        let y = s.solve(1.0, &vec![1.0; k], &b).unwrap();
        assert_eq!((s.layout, s.mixed_fallbacks), (Layout::Packed, 1));
        assert!(s.refinements > before);
        assert!(max_rel_difference(&y, &dense_solution(&g, 1.0, &b)) < 1e-11);
    }

    #[test]
    fn the_packed_symmetric_product_equals_the_dense_one() {
        let k = 300;
        let g = spd(k, 5);
        let mut buf = vec![0.0; k * (k + 1) / 2];
        for j in 0..k {
            for i in j..k {
                buf[packed_start(j, k) + i - j] = g[(i, j)];
            }
        }
        let x: Vec<f64> = (0..k).map(|i| (i as f64).sqrt() - 7.0).collect();
        let got = packed_symmetric_times(&buf, k, &x, |v| v);
        for i in 0..k {
            let want: f64 = (0..k).map(|j| g[(i, j)] * x[j]).sum();
            assert!((got[i] - want).abs() < 1e-12 * want.abs().max(1.0), "{i}");
        }
        let sums = packed_symmetric_times(&buf, k, &vec![1.0; k], f64::abs);
        let want: f64 = (0..k).map(|j| g[(j, 7)].abs()).sum();
        assert!((sums[7] - want).abs() < 1e-12 * want);
    }
}
