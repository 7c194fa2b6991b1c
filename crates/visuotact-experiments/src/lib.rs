//! The experiments around the estimator, on the simulator and on the real sets of
//! `shared/reference/real`: what `visuotact demo`, `simulate`, `pattern` and `check-tracking`
//! run. The estimator itself (`visuotact-pipeline`) needs none of this; a program that only
//! estimates does not depend on this crate.
//!
//! ## Modules and what each owns
//!
//! `demo` (both papers' experiments as report structs: the 117-marker membrane's Table 3 and
//! random touches, the inflatable cone's Tables 5.1 and 5.2 with their sweeps, and, in
//! `demo::torque`, the torque from the T-shaped marker; `DemoConfig`, `DemoError`), `tables`
//! (those experiments laid out as the papers' tables, as text), `pages` (the HTML report page of
//! `demo --report`), `synth` (simulated session folders with exact truth, grid-pattern series;
//! `SimulateConfig`, `SimulateError`), `trackcheck` (simulated sensors tracked in memory against
//! the simulator's per-marker truth: lost markers, wrong identities, displacement error, per
//! motion band; `CheckConfig`, `CheckReport`), `scorecard` (the tracking scorecard: the zoo's
//! drawn variants through every protocol, per family × motion band, held to a baseline table),
//! `realcard` (the scorecard's real half: the real sets tracked as a user would, counts that
//! need no labels, held to a baseline table), `slipcheck` (simulated grasps that slip or hold,
//! tracked and run through a slip detector: the first alarm against the true slip frame)

pub mod demo;
pub mod pages;
pub mod realcard;
pub mod scorecard;
pub mod slipcheck;
pub mod synth;
pub mod tables;
pub mod trackcheck;

/// Any error of this crate: each module's error converts into it.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// [`trackcheck::CheckError`].
    #[error(transparent)]
    Check(#[from] trackcheck::CheckError),
    /// [`demo::DemoError`].
    #[error(transparent)]
    Demo(#[from] demo::DemoError),
    /// [`synth::SimulateError`].
    #[error(transparent)]
    Simulate(#[from] synth::SimulateError),
    /// [`realcard::RealCardError`].
    #[error(transparent)]
    RealCard(#[from] realcard::RealCardError),
}
