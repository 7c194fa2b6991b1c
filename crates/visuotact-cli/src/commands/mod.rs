//! One module per subcommand: options → library config → library call → printed result.
//! Command modules never import each other; what they share lives in `crate::args`,
//! `crate::files` and `crate::print`.

pub(crate) mod bench;
pub(crate) mod blobs;
pub(crate) mod calibrate;
pub(crate) mod dataset;
pub(crate) mod demo;
pub(crate) mod eval;
pub(crate) mod export;
pub(crate) mod extract;
pub(crate) mod filter;
pub(crate) mod pattern;
pub(crate) mod predict;
pub(crate) mod record;
pub(crate) mod replay;
pub(crate) mod run;
pub(crate) mod simulate;
pub(crate) mod slip;
pub(crate) mod sweep;
pub(crate) mod trackcheck;
pub(crate) mod train;
