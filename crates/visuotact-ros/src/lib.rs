//! visuotact in the robot's world: each frame's estimate, contact, markers, image and health
//! as standard ROS 2 messages ([`msg`], CDR-encoded by [`cdr`]) on documented topics
//! ([`topics`]), written to MCAP bags with the ROS 2 profile ([`bag`]) — live from a run
//! ([`sink::McapSink`]), while recording ([`sink::McapRecorder`]) or from a recorded session
//! ([`export::export_mcap`]) — or live over DDS and to the Foxglove app. Nothing of ROS needs
//! to be installed; the bags read in `ros2 bag`, Foxglove, RViz (played back), the `rosbags`
//! library and `mcap` + `mcap-ros2-support`.
//!
//! ## Modules and what each owns
//!
//! ROS 2 without ROS: `cdr` (XCDR1 little-endian), `msg` (WrenchStamped, PointStamped, Bool,
//! PointCloud2, CompressedImage, DiagnosticArray with their `ros2msg` schemas), `bag` (MCAP
//! with the ROS 2 profile: one file or a rosbag2 folder with `metadata.yaml`; chunks flushed
//! every second of stamps), `topics` (the documented topic mapping under a namespace: frame
//! parts → messages, and the `FrameTarget` of every ROS 2 target), `sink` (`McapSink`, the
//! pipeline's `LiveSink` into a bag; `McapRecorder`, its `RecordingTarget` into one), `dds`
//! (feature `dds`, default: `DdsSink` publishes the topics live with RustDDS, ROS 2 names and
//! default QoS, loopback unless told an interface), `foxglove` (feature `foxglove`, default:
//! `FoxgloveSink` serves the same topics live to the Foxglove app over its WebSocket protocol
//! with the official `foxglove` crate, CDR with `ros2msg` schemas), `export` (a session folder
//! → a bag, read by the pipeline's `session_export`). Frame parts, `FrameTarget`, `LiveSink`
//! and the session export live in the pipeline (`visuotact_pipeline::output`), shared with
//! the Rerun crate. Depends on pipeline; no clap

pub mod bag;
pub mod cdr;
#[cfg(feature = "dds")]
pub mod dds;
pub mod export;
#[cfg(feature = "foxglove")]
pub mod foxglove;
pub mod msg;
pub mod sink;
pub mod topics;

use std::path::PathBuf;

pub use bag::{Bag, BagConfig};
#[cfg(feature = "dds")]
pub use dds::{dds_sink, finish_dds, DdsConfig, DdsSink};
pub use export::{export_mcap, ExportSummary};
#[cfg(feature = "foxglove")]
pub use foxglove::{finish_foxglove, foxglove_sink, FoxgloveConfig, FoxgloveSink};
pub use sink::{finish_mcap, finish_recorder, mcap_recorder, mcap_sink, McapRecorder, McapSink};
pub use topics::{declare_frame_topics, declare_sensor_topics, Declare};

/// Errors of the ROS 2 outputs.
#[derive(Debug, thiserror::Error)]
pub enum RosError {
    /// A file could not be read or written.
    #[error("{}: {}", .0.display(), .1)]
    Io(PathBuf, #[source] std::io::Error),
    /// The MCAP writer failed.
    #[error("{}: {}", .0.display(), .1)]
    Mcap(PathBuf, String),
    /// The output exists already.
    #[error("{}: already exists; choose a new name", .0.display())]
    Exists(PathBuf),
    /// An unfinished bag of an earlier run holds the temporary name.
    #[error("{}: an unfinished bag of an earlier run (readable up to its last chunk; `mcap recover` rebuilds it): move or remove it first", .0.display())]
    Unfinished(PathBuf),
    /// A setting is out of range.
    #[error("{0}")]
    Config(String),
    /// One topic was given two types.
    #[error("topic {topic}: was {was}, now {now}")]
    TopicType {
        /// The topic.
        topic: String,
        /// Its first type.
        was: &'static str,
        /// The type written now.
        now: &'static str,
    },
    /// A session table could not be read.
    #[error(transparent)]
    Table(#[from] visuotact_io::table::TableError),
    /// DDS (live publishing) failed.
    #[error("DDS: {0}")]
    Dds(String),
    /// Reading a session or writing a frame's parts failed.
    #[error(transparent)]
    Output(#[from] visuotact_pipeline::output::OutputError),
}
