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

/// Refuses to write `output` over one of `inputs`: see [`refuse_outputs_over_inputs`].
pub fn refuse_output_over_input(output: &Path, inputs: &[&Path]) -> Result<(), OutputError> {
    refuse_outputs_over_inputs(&[output], inputs)
}

/// The one rule for every command's outputs, primary and secondary, checked before anything
/// is written (paths resolved through `..` and symbolic links, `-` for standard output left
/// out). An output is refused when it
/// - is one of `inputs`, or lies inside an input folder (a frame folder, a bag folder) — except
///   inside a session folder, where only the session's own files ([`SESSION_FILES`]) and its
///   `frames/` are refused, so that results can be kept beside the session;
/// - is another output, or lies inside one.
pub fn refuse_outputs_over_inputs(outputs: &[&Path], inputs: &[&Path]) -> Result<(), OutputError> {
    let outputs: Vec<&Path> = outputs
        .iter()
        .copied()
        .filter(|o| *o != Path::new("-"))
        .collect();
    let resolved_inputs: Vec<(PathBuf, &Path)> = inputs.iter().map(|i| (resolved(i), *i)).collect();
    let resolved_outputs: Vec<PathBuf> = outputs.iter().map(|o| resolved(o)).collect();
    for (k, (output, out)) in outputs.iter().zip(&resolved_outputs).enumerate() {
        let refuse = |why: String| {
            Err(OutputError::OverInput {
                output: output.to_path_buf(),
                why,
            })
        };
        for (input, named) in &resolved_inputs {
            if out == input {
                return refuse(format!("the output is the input {}", named.display()));
            }
            if !out.starts_with(input) || !input.is_dir() {
                continue;
            }
            let inside = out.strip_prefix(input).unwrap_or(out);
            let session = input.join("frames.csv").is_file();
            let own = inside.starts_with("frames")
                || SESSION_FILES.iter().any(|f| inside == Path::new(f));
            if session && own {
                return refuse(format!(
                    "would overwrite the session {}'s own file",
                    named.display()
                ));
            }
            if !session {
                return refuse(format!(
                    "it lies inside the input folder {}",
                    named.display()
                ));
            }
        }
        for (other, o) in outputs.iter().zip(&resolved_outputs).take(k) {
            if out == o || out.starts_with(o) || o.starts_with(out) {
                return refuse(format!(
                    "it is, or shares a folder with, the output {}",
                    other.display()
                ));
            }
        }
    }
    Ok(())
}

/// The temporary name an output at `path` is written under until it is whole (`NAME.part~`
/// beside it): bags take their name only when finished. A name too long for the suffix within
/// the system's 255 bytes is cut, at a character, to make room (two such names alike in their
/// first 249 bytes then share a temporary name, which a bag refuses while one holds it).
pub fn part_path(path: &Path) -> PathBuf {
    name_beside(path, "", ".part~")
}

/// `prefix` + `path`'s name + `suffix` beside it, the name cut at a character so that the
/// whole fits the system's 255 bytes.
pub fn name_beside(path: &Path, prefix: &str, suffix: &str) -> PathBuf {
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    let mut cut = name.len().min(255 - prefix.len() - suffix.len());
    while !name.is_char_boundary(cut) {
        cut -= 1;
    }
    path.with_file_name(format!("{prefix}{}{suffix}", &name[..cut]))
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

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("visuotact-guard-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn a_temporary_name_fits_the_systems_limit() {
        let d = dir("long");
        assert_eq!(part_path(&d.join("s.mcap")), d.join("s.mcap.part~"));
        for long in ["a".repeat(255), format!("{}.mcap", "é".repeat(125))] {
            let out = d.join(&long);
            let part = part_path(&out);
            let name = part.file_name().unwrap().to_str().unwrap();
            assert!(name.len() <= 255 && name.ends_with(".part~"), "{name}");
            assert!(long.starts_with(name.trim_end_matches(".part~")));
            // The system takes it.
            std::fs::write(&part, b"x").unwrap();
            std::fs::remove_file(&part).unwrap();
        }
    }

    #[test]
    fn outputs_over_inputs_inside_input_folders_or_over_each_other_are_refused() {
        let d = dir("rule");
        let frames = d.join("frames");
        std::fs::create_dir_all(&frames).unwrap();
        std::fs::write(frames.join("f0.png"), b"x").unwrap();
        let labels = d.join("l.csv");
        std::fs::write(&labels, b"frame\n").unwrap();
        let refused =
            |outs: &[&Path], ins: &[&Path]| refuse_outputs_over_inputs(outs, ins).is_err();
        // A frame in an input folder, by name or through `..`.
        assert!(refused(&[&frames.join("f0.png")], &[&frames]));
        assert!(refused(&[&frames.join("../frames/new.csv")], &[&frames]));
        // A secondary output over an input file, or over the primary output.
        let out = d.join("p.csv");
        assert!(refused(&[&out, &labels], &[&frames, &labels]));
        assert!(refused(&[&out, &out], &[&labels]));
        // A symbolic link to the input.
        let link = d.join("link.csv");
        std::os::unix::fs::symlink(&labels, &link).unwrap();
        assert!(refused(&[&link], &[&labels]));
        // Beside the inputs, and standard output, are fine.
        assert!(!refused(
            &[&out, &d.join("r.html"), Path::new("-")],
            &[&frames, &labels]
        ));
        // In a session folder: its own files no, a new file yes.
        let session = d.join("session");
        std::fs::create_dir_all(session.join("frames")).unwrap();
        std::fs::write(session.join("frames.csv"), b"frame\n").unwrap();
        assert!(refused(&[&session.join("labels.csv")], &[&session]));
        assert!(refused(&[&session.join("frames/x.png")], &[&session]));
        assert!(!refused(&[&session.join("est.csv")], &[&session]));
        std::fs::remove_dir_all(&d).unwrap();
    }
}
