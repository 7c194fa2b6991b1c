//! The one way the project writes a file: whole or not at all, never through what is already
//! there.
//!
//! [`OutputFile::create`] opens a temporary file in the destination's folder, created
//! exclusively under a random name (`.NAME.XXXXXX.part~`, `tempfile`'s `NamedTempFile`):
//! a leftover file, a symbolic link or a hard link of that name cannot be followed, and two runs
//! writing the same output never share one. [`OutputFile::finish`] flushes it, syncs it to the
//! disk and renames it over the final name; dropped unfinished (an error, a stop), it is
//! removed. While it is written, an advisory lock (`.NAME.lock~` beside it) refuses a second
//! writer of the same output with a message saying so. A destination that is not a regular file — a character device such as
//! `/dev/null`, a FIFO, a socket — is written through as it is, never replaced; a folder is
//! refused.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

/// A file being written to `path`; it takes that name at [`OutputFile::finish`].
pub struct OutputFile {
    path: PathBuf,
    inner: Inner,
    /// Held while the file is written (none for a special file written through).
    _lock: Option<WriteLock>,
}

/// An exclusive advisory lock on writing one output: `.NAME.lock~` beside it, locked with
/// [`File::try_lock`] (the name cut, at a character, to fit the system's 255 bytes). A second
/// writer of the same output — another run, or this one — is refused while it is held. The
/// lock file is removed while still locked, when the writer is done; a writer that locked a
/// file removed meanwhile locks the new one instead. A killed run's lock file is left behind,
/// unlocked: the next writer takes it.
struct WriteLock {
    file: File,
    path: PathBuf,
}

impl WriteLock {
    fn take(output: &Path) -> io::Result<Self> {
        let path = crate::guard::name_beside(output, ".", ".lock~");
        loop {
            if std::fs::symlink_metadata(&path).is_ok_and(|m| !m.is_file()) {
                return Err(io::Error::new(
                    io::ErrorKind::AlreadyExists,
                    format!("{} is in the way of its lock (not a file)", path.display()),
                ));
            }
            let file = std::fs::OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .open(&path)?;
            match file.try_lock() {
                Ok(()) => {}
                Err(std::fs::TryLockError::WouldBlock) => {
                    return Err(io::Error::new(
                        io::ErrorKind::ResourceBusy,
                        format!(
                            "another run is writing it now (it holds {}); wait for it to end",
                            path.display()
                        ),
                    ))
                }
                // A file system without locks (some network mounts): written unguarded,
                // as before the lock, rather than not at all.
                Err(std::fs::TryLockError::Error(e)) if e.kind() == io::ErrorKind::Unsupported => {
                    return Ok(Self { file, path });
                }
                Err(std::fs::TryLockError::Error(e)) => return Err(e),
            }
            if same_file(&file, &path) {
                return Ok(Self { file, path });
            }
            // The writer before us removed the file we locked: lock the name afresh.
        }
    }
}

/// Whether `path` names the open `file` itself (same device and inode).
fn same_file(file: &File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (file.metadata(), std::fs::metadata(path)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

impl Drop for WriteLock {
    fn drop(&mut self) {
        // Removed while locked: a writer waiting on this file sees it gone and starts afresh.
        let _ = std::fs::remove_file(&self.path);
        let _ = self.file.unlock();
    }
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
                    _lock: None,
                });
            }
        }
        let dir = path
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        std::fs::create_dir_all(dir).map_err(named)?;
        let lock = WriteLock::take(path).map_err(named)?;
        // As a plain create would: read-write for all, less the umask (a temporary file is
        // private by default; the output is not).
        let tmp = temp_beside(path, 0o666, |b, dir| b.tempfile_in(dir)).map_err(named)?;
        Ok(Self {
            path: path.to_path_buf(),
            inner: Inner::Temp(BufWriter::new(tmp)),
            _lock: Some(lock),
        })
    }

    /// Where the file goes.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Flushes, syncs and gives the file its name (over any regular file of that name).
    pub fn finish(self) -> io::Result<()> {
        let Self {
            path,
            inner,
            _lock: lock,
        } = self;
        let named = |e| named(&path, e);
        // The lock is let go only once the file has its name (dropped at the end).
        let _held = lock;
        match inner {
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

/// Makes a temporary file or folder beside `path` with `make`, under a random name
/// (`.NAME.XXXXXX.part~`, the name's first 40 characters: room to spare within 255 bytes)
/// created exclusively, with `mode` less the umask (as a plain create or mkdir gives).
fn temp_beside<T>(
    path: &Path,
    mode: u32,
    make: impl FnOnce(&tempfile::Builder<'_, '_>, &Path) -> io::Result<T>,
) -> io::Result<T> {
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    let stem: String = name.chars().take(40).collect();
    let prefix = format!(".{stem}.");
    let mut builder = tempfile::Builder::new();
    builder.prefix(&prefix).suffix(".part~");
    #[cfg(unix)]
    builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(mode));
    make(&builder, dir)
}

/// A new folder beside `path` to build an output of several files in (a data set), created
/// exclusively under a random name (`.NAME.XXXXXX.part~`; its folder created when missing)
/// with a plain mkdir's permissions;
/// removed with its contents when dropped. Rename it to `path` when whole.
pub fn temp_dir_beside(path: &Path) -> io::Result<tempfile::TempDir> {
    temp_beside(path, 0o777, |b, dir| {
        std::fs::create_dir_all(dir)?;
        b.tempdir_in(dir)
    })
}

/// An empty file created exclusively beside an output under a random name
/// (`.NAME.XXXXXX.part~`), for a writer that opens a path itself (the Rerun SDK's file sink):
/// removed when dropped, renamed onto the output by [`TempBeside::land`] when whole. A
/// killed run leaves only the hidden temporary name, never a torn output under the final one.
#[derive(Debug)]
pub struct TempBeside {
    path: tempfile::TempPath,
}

impl TempBeside {
    /// The temporary file beside `target`.
    pub fn new(target: &Path) -> io::Result<Self> {
        let file = temp_beside(target, 0o666, |b, dir| b.tempfile_in(dir))
            .map_err(|e| named(target, e))?;
        Ok(Self {
            path: file.into_temp_path(),
        })
    }

    /// Where the writer writes.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Renames the whole file onto `target`, which must not exist (never replaced: a file
    /// that appeared there meanwhile is another writer's); on failure the file is removed.
    pub fn land(self, target: &Path) -> io::Result<()> {
        self.path
            .persist_noclobber(target)
            .map_err(|e| named(target, e.error))
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

    /// A file another writer fills through its path lands whole under the target's name,
    /// never over a file there; dropped unlanded, it leaves nothing.
    #[test]
    fn a_temporary_file_beside_lands_whole_or_leaves_nothing() {
        let d = dir("temp-beside");
        let target = d.join("x.rrd");
        let t = TempBeside::new(&target).unwrap();
        assert!(t.path().is_file() && !target.exists());
        std::fs::write(t.path(), b"whole").unwrap();
        t.land(&target).unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"whole");
        let t = TempBeside::new(&target).unwrap();
        std::fs::write(t.path(), b"second").unwrap();
        let e = t.land(&target).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::AlreadyExists, "{e}");
        assert_eq!(std::fs::read(&target).unwrap(), b"whole");
        drop(TempBeside::new(&d.join("y.rrd")).unwrap());
        assert!(leftovers(&d).is_empty(), "{:?}", leftovers(&d));
        std::fs::remove_dir_all(&d).unwrap();
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
    fn unfinished_writes_leave_nothing_and_a_second_writer_is_refused() {
        let d = dir("unfinished");
        let out = d.join("t.csv");
        std::fs::write(&out, "old\n").unwrap();
        let mut a = OutputFile::create(&out).unwrap();
        let e = OutputFile::create(&out).err().unwrap();
        assert!(
            e.to_string().contains("t.csv") && e.to_string().contains("another run is writing it"),
            "{e}"
        );
        a.write_all(b"from a\n").unwrap();
        assert_eq!(leftovers(&d).len(), 1);
        // The old file stands until the writer finishes; then it is whole.
        assert_eq!(std::fs::read_to_string(&out).unwrap(), "old\n");
        a.finish().unwrap();
        assert_eq!(std::fs::read_to_string(&out).unwrap(), "from a\n");
        assert!(leftovers(&d).is_empty());
        // The lock went with the writer; the next one writes, and a dropped one leaves nothing.
        let names = || -> Vec<String> {
            let mut v: Vec<String> = std::fs::read_dir(&d)
                .unwrap()
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect();
            v.sort();
            v
        };
        assert_eq!(names(), ["t.csv"]);
        let b = OutputFile::create(&out).unwrap();
        drop(b);
        assert_eq!(names(), ["t.csv"]);
        // A killed run's lock file, unlocked, does not stand in the way.
        std::fs::write(d.join(".t.csv.lock~"), b"").unwrap();
        write_whole(&out, b"from c\n").unwrap();
        assert_eq!(std::fs::read_to_string(&out).unwrap(), "from c\n");
        assert_eq!(names(), ["t.csv"]);
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
