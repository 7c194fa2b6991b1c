//! Levenberg–Marquardt least squares and the networks trained with it.
//!
//! [`lm`] is the generic solver (any residual/Jacobian problem, MATLAB `trainlm` schedule),
//! [`br`] the same with Bayesian regularisation (MATLAB `trainbr`),
//! [`nist`] reads the NIST StRD nonlinear regression problems it is verified on, [`dual`] gives
//! exact derivatives of those models by forward-mode automatic differentiation.
//!
//! ## Modules and what each owns
//!
//! `logistic` (L2-regularised logistic regression by Newton's method, matched to scikit-learn;
//! the slip detector's fit), `br` (Bayesian regularisation, MATLAB `trainbr`: LM on β·E_D + α·E_W through the dual
//! system, γ from the trace of the shifted Gram inverse, α and β re-estimated each epoch;
//! `mlp::Settle` stops it once E_D and γ have settled), `adam` (mini-batch Adam on the MSE plus
//! an L2 penalty with early stopping, batched forward and backward passes as faer products over
//! the parameter vector's own layout, gradient tested against finite differences: the trainer
//! for tables too large for LM), `pca` (principal-component input reduction kept in the model
//! file; scores fitted to the inputs present when markers are lost; `fill_missing` reconstructs
//! lost inputs for networks that read every marker), `lm` (generic Levenberg–Marquardt: trainlm
//! schedule, Marquardt scaling option, dual system when residuals < parameters, structured
//! `DualJacobian` hook, `Problem::normal_equations` for primal systems built over blocks
//! without the whole Jacobian, outcome struct and stopping callback), `damped` (the damped
//! systems of one LM iteration from one buffer of k² + 16k numbers: the Gram matrix packed,
//! each μ-trial factorised in single precision and refined in double to `dsposv`'s test; where
//! that fails, the double-precision path — the Gram matrix kept in the square's upper triangle,
//! each trial's in-place faer Cholesky in the lower — with LU fallback), `dual` (forward-mode
//! AD), `nist` (StRD parser and models), `mlp` (tanh/linear feed-forward nets, Nguyen–Widrow,
//! back-propagated Jacobian and its layer form `JJᵀ = Σ (DDᵀ)∘(AAᵀ)` for the dual system, `JᵀJ`
//! over blocks of 256 samples for the primal one (the wide first layer's own blocks as
//! symmetric weighted Gram matrices, lower triangles only, its other columns by hidden unit),
//! so that memory does not grow with the samples, mapminmax, 70/15/15 split with early
//! stopping), `fit` (a model from a table, with the memory it will need stated before it
//! starts: `FitConfig` with `Default` = `visuotact train`'s defaults, `auto` and `paper`
//! presets; scaling, projection, ensemble members in parallel; a typed `FitError` naming the
//! sample and column; `candidate_inputs`/`choose_inputs`/`fit_choosing`: the input sets
//! compared by k-fold cross-validation — one held-out fold from `LARGE_TABLE` frames, where the
//! wide network (every marker feature, 64 → 64, Adam, lost markers filled) joins the candidates
//! — scores kept in the model file; `FitProgress` reported by every network of an ensemble as
//! they train in parallel, which the callback can stop), `model` (the versioned model file: the
//! projection reads the markers' features, the field summary and extra inputs pass by it;
//! `Model::estimate` fills lost markers or says why it cannot; `estimate_into` /
//! `estimate_each_into` with an `EstimateScratch` allocate nothing per frame; the spread is the
//! larger of the networks' standard deviation and `heldout`'s figure), `heldout` (the held-out
//! training samples' estimates and errors kept in the model file: the RMS error of the 30 whose
//! estimates lie nearest a new one, allocation-free lookup), `sweep`
//! (architecture sweeps on every core: `architectures` specs, mean and best figures per size,
//! networks ranked by scaled validation MSE), `metrics` (MSE, R, MPE, accuracy)

pub mod adam;
pub mod br;
mod damped;
pub mod dual;
pub mod fit;
pub mod heldout;
pub mod lm;
pub mod logistic;
pub mod metrics;
pub mod mlp;
pub mod model;
pub mod nist;
pub mod pca;
pub mod plan;
pub mod sweep;
pub mod tansig;

/// Any error of this crate: each module's error converts into it, for callers that handle them alike (`?` into one type).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// [`model::EstimateError`].
    #[error(transparent)]
    Estimate(#[from] model::EstimateError),
    /// [`fit::FitError`].
    #[error(transparent)]
    Fit(#[from] fit::FitError),
    /// [`lm::LmConfigError`].
    #[error(transparent)]
    LmConfig(#[from] lm::LmConfigError),
    /// [`model::ModelFileError`].
    #[error(transparent)]
    ModelFile(#[from] model::ModelFileError),
    /// [`nist::NistError`].
    #[error(transparent)]
    Nist(#[from] nist::NistError),
    /// [`pca::ProjectionError`].
    #[error(transparent)]
    Projection(#[from] pca::ProjectionError),
    /// [`sweep::SpecError`].
    #[error(transparent)]
    Spec(#[from] sweep::SpecError),
}
