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
//! // As text again, the way it parses; from a string with `parse` or `into`.
//! assert_eq!(SourceSpec::Sim("cone".into()).to_string(), "sim:cone");
//! let s: SourceSpec = "camera:/dev/video0".parse().unwrap();
//! assert_eq!(s, SourceSpec::from("camera:/dev/video0"));
//! let odd = SourceSpec::Frames(PathBuf::from("sim:folder"));
//! assert_eq!(SourceSpec::parse(&odd.to_string()), odd);
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

/// Parsing never fails: anything that is not `sim:` or `camera:` is a path.
impl std::str::FromStr for SourceSpec {
    type Err = std::convert::Infallible;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Ok(Self::parse(s))
    }
}

impl From<&str> for SourceSpec {
    fn from(s: &str) -> Self {
        Self::parse(s)
    }
}

impl From<String> for SourceSpec {
    fn from(s: String) -> Self {
        Self::parse(&s)
    }
}

/// As [`SourceSpec::parse`] reads it back: `sim:KIND`, `camera:DEVICE`, or the path — written
/// `frames:PATH` where the bare path would read as something else (`sim:x`, `video:y`).
impl std::fmt::Display for SourceSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Sim(kind) => write!(f, "sim:{kind}"),
            Self::Camera(dev) => write!(f, "camera:{dev}"),
            Self::Frames(path) => {
                let p = path.display().to_string();
                if Self::parse(&p) == *self {
                    write!(f, "{p}")
                } else {
                    write!(f, "frames:{p}")
                }
            }
        }
    }
}
