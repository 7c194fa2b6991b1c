//! The one way the project writes a file: whole or not at all, never through what is already
//! there.
//!
//! [`OutputFile::create`] opens a temporary file in the destination's folder, created
//! exclusively under a random name (`.NAME.XXXXXX.part~`, `tempfile`'s `NamedTempFile`):
//! a leftover file, a symbolic link or a hard link of that name cannot be followed, and two runs
//! writing the same output never share one. [`OutputFile::finish`] flushes it, syncs it to the
//! disk and renames it over the final name; dropped unfinished (an error, a stop), it is
//! removed. A destination that is not a regular file — a character device such as
//! `/dev/null`, a FIFO, a socket — is written through as it is, never replaced; a folder is
//! refused.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

/// A file being written to `path`; it takes that name at [`OutputFile::finish`].
pub struct OutputFile {
    path: PathBuf,
    inner: Inner,
}

enum Inner {
    /// A temporary file beside the destination.
    Temp(BufWriter<tempfile::NamedTempFile>),
    /// A special file written through.
    Direct(BufWriter<File>),
}

/// `e` naming the file it happened to.
fn named(path: &Path, e: io::Error) -> io::Error {
    io::Error::new(e.kind(), format!("{}: cannot write: {e}", path.display()))
}

impl OutputFile {
    /// Starts writing `path` (its folder created when missing). Errors name the file.
    pub fn create(path: &Path) -> io::Result<Self> {
        let named = |e| named(path, e);
        if let Ok(meta) = std::fs::metadata(path) {
            if meta.is_dir() {
                return Err(named(io::Error::new(
                    io::ErrorKind::IsADirectory,
                    "it is a folder",
                )));
            }
            if !meta.is_file() {
                let f = std::fs::OpenOptions::new()
                    .write(true)
                    .open(path)
                    .map_err(named)?;
                return Ok(Self {
                    path: path.to_path_buf(),
                    inner: Inner::Direct(BufWriter::new(f)),
                });
            }
        }
        let dir = path
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        std::fs::create_dir_all(dir).map_err(named)?;
        let name = path.file_name().unwrap_or_default().to_string_lossy();
        // Short enough that a name at the system's limit still has room (255 bytes).
        let stem: String = name.chars().take(40).collect();
        let prefix = format!(".{stem}.");
        let mut builder = tempfile::Builder::new();
        builder.prefix(&prefix).suffix(".part~");
        // As a plain create would: read-write for all, less the umask (a temporary file is
        // private by default; the output is not).
        #[cfg(unix)]
        builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
        let tmp = builder.tempfile_in(dir).map_err(named)?;
        Ok(Self {
            path: path.to_path_buf(),
            inner: Inner::Temp(BufWriter::new(tmp)),
        })
    }

    /// Where the file goes.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Flushes, syncs and gives the file its name (over any regular file of that name).
    pub fn finish(self) -> io::Result<()> {
        let path = self.path;
        let named = |e| named(&path, e);
        match self.inner {
            Inner::Direct(mut w) => w.flush().map_err(named),
            Inner::Temp(w) => {
                let tmp = w.into_inner().map_err(|e| named(e.into_error()))?;
                tmp.as_file().sync_all().map_err(named)?;
                tmp.persist(&path).map_err(|e| named(e.error))?;
                Ok(())
            }
        }
    }
}

impl Write for OutputFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        match &mut self.inner {
            Inner::Temp(w) => w.write(buf),
            Inner::Direct(w) => w.write(buf),
        }
    }

    fn flush(&mut self) -> io::Result<()> {
        match &mut self.inner {
            Inner::Temp(w) => w.flush(),
            Inner::Direct(w) => w.flush(),
        }
    }
}

/// Writes `bytes` to `path` as one [`OutputFile`].
pub fn write_whole(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let mut f = OutputFile::create(path)?;
    f.write_all(bytes).map_err(|e| named(path, e))?;
    f.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(name: &str) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("visuotact-output-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn leftovers(d: &Path) -> Vec<String> {
        std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".part~"))
            .collect()
    }

    #[test]
    fn a_leftover_link_under_the_old_temporary_name_is_never_followed() {
        let d = dir("links");
        let labels = d.join("labels.csv");
        std::fs::write(&labels, "frame,y\na,1\n").unwrap();
        let out = d.join("m.json");
        // What the old fixed temporary name would have followed.
        std::os::unix::fs::symlink(&labels, d.join("m.json.part~")).unwrap();
        std::fs::hard_link(&labels, d.join(".m.json.part~")).unwrap();
        write_whole(&out, b"{}").unwrap();
        assert_eq!(std::fs::read_to_string(&labels).unwrap(), "frame,y\na,1\n");
        // The permissions a plain create gives (0666 less the umask), not a private file's.
        let mode = |p: &Path| {
            std::os::unix::fs::PermissionsExt::mode(&std::fs::metadata(p).unwrap().permissions())
        };
        let plain = d.join("plain");
        File::create(&plain).unwrap();
        assert_eq!(mode(&out), mode(&plain));
        assert_eq!(std::fs::read_to_string(&out).unwrap(), "{}");
        assert!(!std::fs::symlink_metadata(&out)
            .unwrap()
            .file_type()
            .is_symlink());
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn unfinished_writes_leave_nothing_and_two_writers_do_not_share_a_file() {
        let d = dir("unfinished");
        let out = d.join("t.csv");
        std::fs::write(&out, "old\n").unwrap();
        let mut a = OutputFile::create(&out).unwrap();
        let mut b = OutputFile::create(&out).unwrap();
        a.write_all(b"from a\n").unwrap();
        b.write_all(b"from b\n").unwrap();
        assert_eq!(leftovers(&d).len(), 2);
        drop(b);
        // The old file stands until a writer finishes; the one that does is whole.
        assert_eq!(std::fs::read_to_string(&out).unwrap(), "old\n");
        a.finish().unwrap();
        assert_eq!(std::fs::read_to_string(&out).unwrap(), "from a\n");
        assert!(leftovers(&d).is_empty());
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn special_files_are_written_through_and_folders_refused() {
        let null = Path::new("/dev/null");
        write_whole(null, b"gone").unwrap();
        assert!(!std::fs::metadata(null).unwrap().is_file());
        let d = dir("special");
        let e = OutputFile::create(&d).err().unwrap();
        assert!(e.to_string().contains("it is a folder"), "{e}");
        // A name at the system's 255-byte limit still gets a temporary name beside it.
        let long = d.join("x".repeat(251) + ".csv");
        write_whole(&long, b"a").unwrap();
        assert_eq!(std::fs::read(&long).unwrap(), b"a");
        std::fs::remove_dir_all(&d).unwrap();
    }
}
