//! A session's `frames.csv`: read into frames or refused naming the file, never a panic. A
//! frame that reads names one plain file inside the session's `frames/` or `reference/` (no
//! folder, no `..`, not absolute: a session is a closed world) and has a finite timestamp.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::{Component, Path, PathBuf};
use std::sync::OnceLock;
use visuotact_io::session::frame_index;

/// One session folder, shared by every run (what the checks assert holds whatever
/// `frames.csv` holds, so runs in parallel may overwrite each other's): `frames/`,
/// `reference/` and a file beside the session that no frame may reach.
fn session() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let root = std::env::temp_dir().join("visuotact-fuzz-session-index");
        let dir = root.join("s");
        for sub in ["frames", "reference"] {
            std::fs::create_dir_all(dir.join(sub)).unwrap();
        }
        std::fs::write(root.join("secret.png"), b"outside").unwrap();
        std::fs::write(dir.join("frames/f0.png"), b"inside").unwrap();
        dir
    })
}

fuzz_target!(|data: &[u8]| {
    let dir = session();
    let index = dir.join("frames.csv");
    std::fs::write(&index, data).unwrap();
    let mut notes = Vec::new();
    match frame_index(dir, &mut notes) {
        Ok(frames) => {
            // What is said is said of the index, by name.
            for n in &notes {
                assert!(n.contains("frames.csv"), "{n}");
            }
            for f in frames {
                let mut parts = Path::new(&f.name).components();
                assert!(
                    matches!(
                        (parts.next(), parts.next()),
                        (Some(Component::Normal(_)), None)
                    ),
                    "{:?}",
                    f.name
                );
                assert!(!f.name.contains('\\'), "{:?}", f.name);
                assert!(f.timestamp_s.is_finite());
            }
        }
        Err(e) => assert!(e.to_string().contains("frames.csv"), "{e}"),
    }
});
