//! visuotact sessions as a [LeRobot](https://github.com/huggingface/lerobot) v3.0 data set,
//! one episode per session, laid out and described as LeRobot's `LeRobotDatasetMetadata` and
//! `LeRobotDataset` read them:
//!
//! | path | content |
//! |---|---|
//! | `data/chunk-000/file-000.parquet` | one row per frame: `timestamp` (float32, `frame_index / fps`), `frame_index`, `episode_index`, `index`, `task_index` (int64), `observation.tactile.capture_time_s` (float64, the frame's own time on the session clock), and as float32 lists `observation.tactile.features` (`features.csv` less its timestamp), `observation.tactile.estimate` (`estimates.csv`), `observation.force` (the force sensor at the frame's time, interpolated; `fx_n`…`tz_nm`) |
//! | `videos/observation.images.tactile/chunk-000/file-000.mp4` | the frames, all episodes one after another at `fps` (ffmpeg; SVT-AV1 as LeRobot) |
//! | `meta/info.json` | `codebase_version` `v3.0`, counts, `fps`, `splits`, path templates, every feature's dtype, shape and names, the video's `info` |
//! | `meta/episodes/chunk-000/file-000.parquet` | per episode: `episode_index`, `tasks`, `length`, `data/…` and `videos/…/` chunk and file indices, `dataset_from_index`/`dataset_to_index`, the video's `from_timestamp`/`to_timestamp`, `meta/episodes/…`, and `stats/FEATURE/{min,max,mean,std,count}` |
//! | `meta/tasks.parquet` | the task text as the (pandas) index, `task_index` |
//! | `meta/stats.json` | the data set's statistics per feature ([`stats`]) |
//!
//! A table a session lacks is left out of every episode (said in [`LeRobotSummary::notes`]);
//! sessions whose tables have different columns are refused. Numbers a table does not have
//! for a frame are NaN, as in visuotact's own tables.
//!
//! ## Modules and what each owns
//!
//! Sessions as LeRobot v3.0 data sets: `episode` (a session's frames with its tables aligned,
//! force interpolated at frame times), `table` (REQUIRED Parquet columns and fixed-shape lists
//! through the `parquet` crate's low-level writer — no Arrow), `video` (ffmpeg fed raw RGB,
//! SVT-AV1 as LeRobot), `stats` (min/max/mean/std/count, Chan's merge), `export_lerobot` (data,
//! episodes, tasks, info.json, stats.json). Depends on io only; no clap

pub mod episode;
pub mod stats;
pub mod table;
pub mod video;

mod write;

use std::path::PathBuf;

pub use episode::Episode;
pub use video::VideoConfig;
pub use write::export_lerobot;

/// The video feature's key.
pub const IMAGE_KEY: &str = "observation.images.tactile";

/// LeRobot's format version written.
pub const CODEBASE_VERSION: &str = "v3.0";

/// Errors of the LeRobot export.
#[derive(Debug, thiserror::Error)]
pub enum LeRobotError {
    /// A file could not be read or written.
    #[error("{}: {}", .0.display(), .1)]
    Io(PathBuf, #[source] std::io::Error),
    /// The output exists already.
    #[error("{}: already exists; choose a new folder", .0.display())]
    Exists(PathBuf),
    /// The progress callback stopped the export.
    #[error("stopped after {0} frames: nothing written")]
    Stopped(usize),
    /// The sessions or settings do not make a data set (the message says why).
    #[error("{0}")]
    Invalid(String),
    /// A session table could not be read.
    #[error(transparent)]
    Table(#[from] visuotact_io::table::TableError),
    /// A frame could not be read.
    #[error("{}: {}", .0.display(), .1)]
    Frame(PathBuf, String),
    /// Encoding the video failed.
    #[error("{0}")]
    Video(String),
    /// Writing Parquet failed.
    #[error("parquet: {0}")]
    Parquet(#[from] parquet::errors::ParquetError),
}

/// How sessions are exported.
#[derive(Clone, Debug, PartialEq)]
pub struct LeRobotConfig {
    /// Frames per second (`None`: the first session's `fps` in `session.json`, else its
    /// median frame interval, rounded).
    pub fps: Option<u32>,
    /// The task every episode performs, in words.
    pub task: String,
    /// `robot_type` in `info.json`.
    pub robot_type: Option<String>,
    /// The frames as video (`None`: no video feature; sessions need not have saved frames).
    pub video: Option<VideoConfig>,
}

impl Default for LeRobotConfig {
    fn default() -> Self {
        Self {
            fps: None,
            task: "touch the tactile sensor".into(),
            robot_type: None,
            video: Some(VideoConfig::default()),
        }
    }
}

/// What an export wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct LeRobotSummary {
    /// The data set's folder.
    pub path: PathBuf,
    /// Episodes (sessions).
    pub episodes: usize,
    /// Frames (rows).
    pub frames: usize,
    /// The data set's rate.
    pub fps: u32,
    /// The features written, as `info.json` names them.
    pub features: Vec<String>,
    /// Parts of the sessions that were not there (said, not an error).
    pub notes: Vec<String>,
}
