//! Guards for outputs: a command never writes over what it reads, finds out that it cannot
//! write before it works, and knows how much memory there is.

use std::path::{Path, PathBuf};

/// Why an output was refused.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The output is one of the inputs, or a session's own file.
    #[error("{}: {why}; choose another output", output.display())]
    OverInput {
        /// The output.
        output: PathBuf,
        /// Which input it would destroy.
        why: String,
    },
    /// The output's folder cannot be created or written.
    #[error("{}: {why}", output.display())]
    NotWritable {
        /// The output.
        output: PathBuf,
        /// The system's reason.
        why: String,
    },
}

/// The files of a session folder (`record`, `simulate`) that hold what was measured.
pub const SESSION_FILES: [&str; 8] = [
    "session.json",
    "frames.csv",
    "labels.csv",
    "truth.csv",
    "force.csv",
    "features.csv",
    "estimates.csv",
    "references.csv",
];

/// `p` made absolute with links resolved as far as it exists (the output usually does not).
fn resolved(p: &Path) -> PathBuf {
    if let Ok(c) = p.canonicalize() {
        return c;
    }
    match (p.parent(), p.file_name()) {
        (Some(dir), Some(name)) if !dir.as_os_str().is_empty() => resolved(dir).join(name),
        _ => std::env::current_dir().map_or_else(|_| p.to_path_buf(), |d| d.join(p)),
    }
}

/// Refuses to write `output` over one of `inputs` (the same file or folder once paths are
/// resolved) or over a session's own files when an input is a session folder.
pub fn refuse_output_over_input(output: &Path, inputs: &[&Path]) -> Result<(), OutputError> {
    let out = resolved(output);
    let refuse = |why: String| {
        Err(OutputError::OverInput {
            output: output.to_path_buf(),
            why,
        })
    };
    if let Some(i) = inputs.iter().find(|i| resolved(i) == out) {
        return refuse(format!("the output is the input {}", i.display()));
    }
    let session_file = |i: &&&Path| {
        let dir = resolved(i);
        dir.join("frames.csv").is_file()
            && out.parent() == Some(dir.as_path())
            && SESSION_FILES
                .iter()
                .any(|f| out.file_name() == Some(f.as_ref()))
    };
    if let Some(i) = inputs.iter().find(session_file) {
        return refuse(format!(
            "would overwrite the session {}'s own file",
            i.display()
        ));
    }
    Ok(())
}

/// Checks that `output` can be written before any work: its folder is created and a probe
/// written and removed beside it (`-`, standard output, always can).
pub fn check_writable(output: &Path) -> Result<(), OutputError> {
    if output == Path::new("-") {
        return Ok(());
    }
    let fail = |why: String| OutputError::NotWritable {
        output: output.to_path_buf(),
        why,
    };
    let dir = output
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).map_err(|e| fail(format!("cannot create its folder: {e}")))?;
    crate::session::probe_writable(dir, 0).map_err(|e| fail(e.to_string()))
}

/// Memory available to a new allocation now, bytes (Linux `MemAvailable`; `None` elsewhere).
pub fn available_memory_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let kib: u64 = text
        .lines()
        .find(|l| l.starts_with("MemAvailable:"))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()?;
    Some(kib * 1024)
}
