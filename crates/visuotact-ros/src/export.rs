//! A recorded or simulated session folder into a bag ([`export_mcap`]): the session read as
//! frame parts ([`visuotact_pipeline::session_export`]) and written as ROS 2 messages.

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

use visuotact_pipeline::session_export::{ExportConfig, SessionExport};

use crate::bag::{Bag, BagConfig};
use crate::RosError;

/// What an export wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportSummary {
    /// The bag (file or folder).
    pub path: PathBuf,
    /// Frames exported.
    pub frames: usize,
    /// Messages written.
    pub messages: u64,
    /// Parts of the session that were not there (said, not an error).
    pub notes: Vec<String>,
}

/// Exports `session` into a bag at `out` ([`Bag::create`] with `bag`'s chunking);
/// `progress(done, total)` hears of each frame and may stop the export
/// ([`visuotact_pipeline::output::OutputError::Stopped`]). A failed or stopped export leaves
/// nothing behind.
pub fn export_mcap(
    session: &Path,
    out: &Path,
    (cfg, bag): (&ExportConfig, &BagConfig),
    progress: &mut dyn FnMut(usize, usize) -> ControlFlow<()>,
) -> Result<ExportSummary, RosError> {
    let plan = SessionExport::read(session, cfg)?;
    let mut bag = Bag::create(out, bag)?;
    if let Err(e) = plan.write_to(&mut bag, cfg, progress) {
        bag.discard();
        return Err(e.into());
    }
    let messages = bag.messages();
    let path = bag.finish()?;
    Ok(ExportSummary {
        path,
        frames: plan.frames(),
        messages,
        notes: plan.notes().to_vec(),
    })
}
