//! Levenberg–Marquardt least squares and the networks trained with it.
//!
//! [`lm`] is the generic solver (any residual/Jacobian problem, MATLAB `trainlm` schedule),
//! [`br`] the same with Bayesian regularisation (MATLAB `trainbr`),
//! [`nist`] reads the NIST StRD nonlinear regression problems it is verified on, [`dual`] gives
//! exact derivatives of those models by forward-mode automatic differentiation.

pub mod adam;
pub mod br;
mod damped;
pub mod dual;
pub mod fit;
pub mod lm;
pub mod metrics;
pub mod mlp;
pub mod model;
pub mod nist;
pub mod pca;
pub mod sweep;

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
