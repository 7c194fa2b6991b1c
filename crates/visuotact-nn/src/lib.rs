//! Levenberg–Marquardt least squares and the networks trained with it.
//!
//! [`lm`] is the generic solver (any residual/Jacobian problem, MATLAB `trainlm` schedule),
//! [`br`] the same with Bayesian regularisation (MATLAB `trainbr`),
//! [`nist`] reads the NIST StRD nonlinear regression problems it is verified on, [`dual`] gives
//! exact derivatives of those models by forward-mode automatic differentiation.

pub mod br;
pub mod dual;
pub mod fit;
pub mod lm;
pub mod metrics;
pub mod mlp;
pub mod model;
pub mod nist;
pub mod pca;
pub mod sweep;
