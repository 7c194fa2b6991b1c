//! Where frames come from, as every front end writes it: `sim:KIND` (a simulated sensor),
//! `camera:/dev/videoN` (a V4L2 camera), `frames:PATH` or `video:PATH` (image files, a folder
//! or a video), or a bare path.
//!
//! ```
//! use std::path::PathBuf;
//! use visuotact_io::source::SourceSpec;
//!
//! assert_eq!(SourceSpec::parse("sim:cone"), SourceSpec::Sim("cone".into()));
//! assert_eq!(SourceSpec::parse("camera:/dev/video2"), SourceSpec::Camera("/dev/video2".into()));
//! assert_eq!(SourceSpec::parse("video:a.mp4"), SourceSpec::Frames(PathBuf::from("a.mp4")));
//! assert_eq!(SourceSpec::parse("session/frames"), SourceSpec::Frames(PathBuf::from("session/frames")));
//! ```

use std::path::PathBuf;

/// A frame source, parsed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SourceSpec {
    /// A simulated sensor of this kind (`iats`, `cone`).
    Sim(String),
    /// A V4L2 camera device.
    Camera(String),
    /// Image files, a folder of images or a video.
    Frames(PathBuf),
}

impl SourceSpec {
    /// Parses a source as written on the command line (see the module's documentation).
    pub fn parse(s: &str) -> Self {
        if let Some(kind) = s.strip_prefix("sim:") {
            return Self::Sim(kind.to_string());
        }
        if let Some(dev) = s.strip_prefix("camera:") {
            return Self::Camera(dev.to_string());
        }
        let path = s
            .strip_prefix("frames:")
            .or_else(|| s.strip_prefix("video:"))
            .unwrap_or(s);
        Self::Frames(PathBuf::from(path))
    }
}
