//! Getting frames in and tables out.
//!
//! [`frames`] opens image files, folders of images (sorted by name) and video files (decoded by
//! the `ffmpeg` program) as one stream of timestamped [`visuotact_image::Frame`]s, reporting a
//! frame that cannot be read by name and carrying on. [`table`] writes per-frame rows as CSV or
//! JSON lines, flushing as it goes. [`session`] writes session folders (frames, labels, force),
//! and [`force`] defines the force/torque packet layout shared by senders and receivers.
//! [`camera`] captures V4L2 cameras into the drop-oldest [`queue`] live runs read.
//!
//! ## Modules and what each owns
//!
//! frame sources (image files, folders, videos through `ffmpeg`), per-frame tables (CSV, JSON
//! lines; readers drop an unfinished last line), session folders and the crash-safe
//! `AppendLog`, the force/torque packet layout, the UDP `ForceReceiver` (counts malformed,
//! repeated, reordered and lost packets), force CSV tables, `camera` (V4L2 through ffmpeg's
//! v4l2 input: format negotiation, MJPEG splitting and decoding, YUYV conversion, re-opening;
//! `CameraError`), `queue` (the drop-oldest `LatestQueue` and the `Captured` frame a live run
//! carries), `guard` (the one output rule: no output on or inside an input, nor on another
//! output), `output` (the one way a file is written: an exclusively created temporary file
//! beside it, renamed over the name when whole; special files written through), `read`
//! (bounded reads: regular files only, size and decoded-pixel limits)

pub mod camera;
pub mod force;
pub mod frames;
pub mod guard;
pub mod output;
pub mod queue;
pub mod read;
pub mod session;
pub mod source;
pub mod table;

/// Any error of this crate: each module's error converts into it, for callers that handle them alike (`?` into one type).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// [`camera::CameraError`].
    #[error(transparent)]
    Camera(#[from] camera::CameraError),
    /// [`frames::FrameError`].
    #[error(transparent)]
    Frame(#[from] frames::FrameError),
    /// [`force::PacketError`].
    #[error(transparent)]
    Packet(#[from] force::PacketError),
    /// [`guard::OutputError`].
    #[error(transparent)]
    Output(#[from] guard::OutputError),
    /// [`table::TableError`].
    #[error(transparent)]
    Table(#[from] table::TableError),
}

/// A line to stderr, dropped when stderr cannot take it (a full disk, a closed stream):
/// `eprintln!` would panic and end the caller's run over a message.
pub fn stderr_line(args: std::fmt::Arguments<'_>) {
    use std::io::Write as _;
    let _ = writeln!(std::io::stderr().lock(), "{args}");
}
