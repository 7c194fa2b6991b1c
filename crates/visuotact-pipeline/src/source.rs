//! One frame source for every loop over frames: `run` drives it from its capture thread,
//! `record` in its own loop, and `replay` and `extract` pass over files with it.
//!
//! A [`FrameSource`] opens what a [`SourceSpec`] names — image files, a folder or a video, a
//! V4L2 camera, a simulated camera looping over rendered frames — or a simulated rig that
//! `record` drives with its labels. Each call of [`FrameSource::next_frame`] gives one [`Next`]: a
//! frame, a frame dropped, a frame that did not read (with the reason), or the end. The source
//! paces ([`Pacing`]) and counts what it dropped; the caller decides what a skipped frame means
//! to it (a warning, a row of NaN).
//!
//! Every frame carries two times: its own (`Frame::timestamp_s`: a video's presentation time,
//! an image sequence's `index / fps`, a rig's time of the frame, a camera's arrival on the
//! source's clock) and the instant it was delivered, from which a live loop measures latency.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

#[cfg(feature = "sim")]
use rayon::prelude::*;
use visuotact_image::{Frame, RgbImage};
use visuotact_io::camera::{CameraError, CameraRequest};
use visuotact_io::frames::{FrameError, FrameStream};
use visuotact_io::queue::{Captured, LatestQueue};
use visuotact_io::source::SourceSpec;
#[cfg(feature = "sim")]
use visuotact_sim::{rig::LiveFrames, SimError};

use crate::rig::Rig;

/// When a source delivers its frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pacing {
    /// As fast as the caller asks for them: every frame is delivered (files, simulations
    /// estimated offline or as fast as they can be).
    Free,
    /// At the frame rate on the source's clock, as a camera would: frame `k` is delivered no
    /// earlier than `k / fps`. With `drop_late`, a frame more than one period late is dropped
    /// instead ([`Next::Dropped`]): a simulated camera that could not keep up loses it.
    Clock {
        /// Drop frames more than one period late.
        drop_late: bool,
    },
}

/// What to open and how to deliver it.
#[derive(Clone, Debug)]
pub struct SourceConfig {
    /// What delivers the frames.
    pub source: SourceSpec,
    /// Frame rate of image sequences and simulated cameras, frames per second (a video keeps
    /// its own timestamps; a camera its own rate).
    pub fps: f64,
    /// When frames are delivered (a camera delivers at its own rate whatever this says).
    pub pacing: Pacing,
    /// A camera's size and format.
    pub camera: CameraRequest,
    /// Frames a camera's driver holds before dropping the oldest.
    pub camera_queue: usize,
    /// End after this many frames delivered.
    pub max_frames: Option<u64>,
    /// Simulated cameras: seed.
    pub seed: u64,
    /// Simulated cameras: distinct frames looped over (the first [`SIM_FRAMES_UP_FRONT`]
    /// rendered when the source opens, the rest as the loop reaches them).
    pub sim_frames: usize,
}

/// Simulated frames rendered before a live run starts; later ones of a longer loop are
/// rendered as the loop reaches them, so memory stays bounded (about 240 MB for seed 000's
/// 640 × 480 frames).
pub const SIM_FRAMES_UP_FRONT: usize = 256;

impl Default for SourceConfig {
    fn default() -> Self {
        Self {
            source: "sim:iats".into(),
            fps: 25.0,
            pacing: Pacing::Free,
            camera: CameraRequest::default(),
            camera_queue: 2,
            max_frames: None,
            seed: 1,
            sim_frames: 100,
        }
    }
}

/// Why a source could not open or go on.
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    /// A setting is out of range, or the source cannot exist in this build.
    #[error("{0}")]
    Config(String),
    /// The simulated camera refused its settings.
    #[cfg(feature = "sim")]
    #[error("source {0}")]
    Sim(#[from] SimError),
    /// A simulated rig could not draw a frame.
    #[cfg(feature = "sim")]
    #[error("simulated frame {index}: {source}")]
    Render {
        /// The frame's index.
        index: u64,
        /// Why.
        source: SimError,
    },
    /// Frames could not be opened.
    #[error(transparent)]
    Frames(#[from] FrameError),
    /// The camera could not be opened.
    #[error(transparent)]
    Camera(#[from] CameraError),
}

/// A frame as a source delivers it.
#[derive(Clone, Debug)]
pub struct SourceFrame {
    /// The frame: its name, place in the source, own time and pixels.
    pub frame: Frame,
    /// When it was delivered (a camera: when it arrived).
    pub delivered: Instant,
    /// A simulated rig's truth for the frame (its label columns); empty otherwise.
    pub labels: Vec<f64>,
}

/// One step of a source.
#[derive(Debug)]
pub enum Next {
    /// A frame.
    Frame(SourceFrame),
    /// A frame was dropped: the caller could not keep up ([`Pacing::Clock`] with
    /// `drop_late`).
    Dropped,
    /// A frame did not read or render, and why; the source goes on with the next.
    Unreadable(String),
    /// No more frames.
    End,
}

/// What delivers the frames.
enum Kind {
    Files(Box<FrameStream>),
    Camera {
        queue: Arc<LatestQueue<Captured>>,
        thread: Option<JoinHandle<u64>>,
    },
    /// A simulated camera: the loop and its first frames, rendered.
    #[cfg(feature = "sim")]
    Loop(Box<LiveFrames>, Vec<(String, Arc<RgbImage>)>),
    /// A simulated rig, drawn at each frame's time with its labels, and its seed.
    Rig(Box<Rig>, u64),
}

/// A frame source (see the module's documentation).
pub struct FrameSource {
    kind: Kind,
    timing: Timing,
    /// The next frame's index (a rig: its number in the session).
    k: u64,
    /// Frames delivered, and at most how many.
    delivered: u64,
    max: u64,
    /// Frames this source dropped (paced too late).
    dropped: u64,
}

impl FrameSource {
    /// Opens `cfg.source`: its clock starts once it is ready to deliver (a simulated camera's
    /// first frames rendered; a camera starts capturing at once, and `stop` ends it).
    pub fn open(cfg: &SourceConfig, stop: &Arc<AtomicBool>) -> Result<Self, SourceError> {
        crate::rate("fps", cfg.fps).map_err(SourceError::Config)?;
        let kind = match cfg.source.clone() {
            #[cfg(not(feature = "sim"))]
            SourceSpec::Sim(kind) => {
                return Err(SourceError::Config(format!(
                    "source sim:{kind}: {}",
                    crate::rig::NO_SIMULATOR
                )))
            }
            #[cfg(feature = "sim")]
            SourceSpec::Sim(kind) => {
                let frames = LiveFrames::new(&kind, cfg.sim_frames, cfg.seed)?;
                let first = (0..frames.len().min(SIM_FRAMES_UP_FRONT))
                    .into_par_iter()
                    .map(|k| frames.frame(k).map(|(id, img)| (id, Arc::new(img))))
                    .collect::<Result<_, _>>()?;
                Kind::Loop(Box::new(frames), first)
            }
            SourceSpec::Camera(dev) => {
                let queue = Arc::new(LatestQueue::new(cfg.camera_queue.max(1)));
                let clock = Instant::now();
                let thread = visuotact_io::camera::spawn(
                    &dev,
                    cfg.camera,
                    cfg.fps,
                    queue.clone(),
                    stop.clone(),
                    clock,
                    cfg.max_frames.unwrap_or(u64::MAX),
                )?;
                let kind = Kind::Camera {
                    queue,
                    thread: Some(thread),
                };
                return Ok(Self::of(kind, cfg.pacing, cfg.fps, clock, cfg.max_frames));
            }
            SourceSpec::Frames(path) => Kind::Files(Box::new(FrameStream::open(&[path], cfg.fps)?)),
        };
        Ok(Self::of(
            kind,
            cfg.pacing,
            cfg.fps,
            Instant::now(),
            cfg.max_frames,
        ))
    }

    /// The source's clock: a frame's `delivered` instant minus this is its time in the run.
    pub fn clock(&self) -> Instant {
        self.timing.clock
    }

    /// Image files, folders and videos one after another (`fps`: the rate of image
    /// sequences), every frame delivered.
    pub fn files(paths: &[PathBuf], fps: f64) -> Result<Self, SourceError> {
        let stream = FrameStream::open(paths, fps)?;
        Ok(Self::of(
            Kind::Files(Box::new(stream)),
            Pacing::Free,
            fps,
            Instant::now(),
            None,
        ))
    }

    /// A simulated rig's frames (each one's noise from `seed`) from number `first` on, paced on
    /// `clock` (frame `k` is due at `k / fps - start_s`: a resumed session goes on where it
    /// stopped) and dropped when late.
    pub(crate) fn rig(
        (rig, seed): (Rig, u64),
        fps: f64,
        clock: Instant,
        (first, start_s): (u64, f64),
    ) -> Self {
        let mut s = Self::of(
            Kind::Rig(Box::new(rig), seed),
            Pacing::Clock { drop_late: true },
            fps,
            clock,
            None,
        );
        s.k = first;
        s.timing.start_s = start_s;
        s
    }

    fn of(kind: Kind, pacing: Pacing, fps: f64, clock: Instant, max: Option<u64>) -> Self {
        Self {
            kind,
            timing: Timing {
                pacing,
                fps,
                clock,
                start_s: 0.0,
            },
            k: 0,
            delivered: 0,
            max: max.unwrap_or(u64::MAX),
            dropped: 0,
        }
    }

    /// How many frames the source holds, when known (files).
    pub fn expected_frames(&self) -> Option<usize> {
        match &self.kind {
            Kind::Files(s) => s.expected_frames(),
            _ => None,
        }
    }

    /// Frames dropped so far: paced too late, or by a camera's driver while the caller was
    /// behind.
    pub fn dropped(&self) -> u64 {
        match &self.kind {
            Kind::Camera { queue, .. } => self.dropped + queue.dropped(),
            _ => self.dropped,
        }
    }

    /// The next step (see [`Next`]); an error ends the source.
    pub fn next_frame(&mut self) -> Result<Next, SourceError> {
        if self.delivered >= self.max {
            return Ok(Next::End);
        }
        let k = self.k;
        let drawn = match &mut self.kind {
            Kind::Files(stream) => match stream.next() {
                None => return Ok(Next::End),
                Some(Err(e)) => Err(e.to_string()),
                Some(Ok(frame)) => Ok((frame, Vec::new(), false)),
            },
            Kind::Camera { queue, .. } => {
                // A camera keeps its own time: it is never paced here.
                let Some(c) = queue.pop() else {
                    return Ok(Next::End);
                };
                self.k += 1;
                self.delivered += 1;
                let image = Arc::try_unwrap(c.image).unwrap_or_else(|a| (*a).clone());
                return Ok(Next::Frame(SourceFrame {
                    frame: frame(c.id, c.index, c.timestamp_s, image),
                    delivered: c.captured,
                    labels: Vec::new(),
                }));
            }
            #[cfg(feature = "sim")]
            Kind::Loop(frames, first) => {
                let at = (k % frames.len() as u64) as usize;
                // A camera's driver or decoder writes each frame just before it is delivered;
                // so does the simulated camera (a copy, not a shared buffer).
                let drawn = match first.get(at) {
                    Some((id, img)) => Ok((id.clone(), RgbImage::clone(img))),
                    None => frames.frame(at),
                };
                let t = k as f64 / self.timing.fps;
                drawn
                    .map(|(id, image)| (frame(format!("{id}#{k}"), k, t, image), vec![], false))
                    .map_err(|e| format!("simulated frame {at}: {e}"))
            }
            Kind::Rig(rig, seed) => {
                let t = k as f64 / self.timing.fps;
                if t > rig.total_s(self.timing.fps) {
                    return Ok(Next::End);
                }
                // A rig draws the frame at its time: it waits first, and a frame already late
                // is not drawn.
                if !self.timing.wait_for(k) {
                    return Ok(self.dropped_one());
                }
                let (image, labels) = rig
                    .frame(k as usize, t, crate::rig::frame_seed(*seed, k))
                    .map_err(|source| render_error(k, source))?;
                Ok((
                    frame(format!("frame_{k:06}.png"), k, t, image),
                    labels,
                    true,
                ))
            }
        };
        match drawn {
            Err(why) => {
                // A simulated camera's loop keeps the place of a frame it could not draw;
                // files number their own frames.
                self.k += u64::from(!matches!(self.kind, Kind::Files(_)));
                Ok(Next::Unreadable(why))
            }
            // Files and simulated cameras are read first, then delivered when due.
            Ok((_, _, false)) if !self.timing.wait_for(k) => Ok(self.dropped_one()),
            Ok((frame, labels, _)) => {
                self.k += 1;
                self.delivered += 1;
                Ok(Next::Frame(SourceFrame {
                    frame,
                    delivered: Instant::now(),
                    labels,
                }))
            }
        }
    }

    /// Frame `k` is dropped: too late.
    fn dropped_one(&mut self) -> Next {
        self.k += 1;
        self.dropped += 1;
        Next::Dropped
    }

    /// Stops a camera's capture thread (after `stop` was set) and waits for it; frames still
    /// queued are dropped. Other sources have nothing to stop.
    pub fn close(&mut self) {
        if let Kind::Camera { queue, thread } = &mut self.kind {
            queue.close();
            if let Some(t) = thread.take() {
                let _ = t.join();
            }
        }
    }
}

/// When frames are due.
struct Timing {
    pacing: Pacing,
    fps: f64,
    clock: Instant,
    /// The clock's time at the nominal time 0 (a resumed session's rig starts later).
    start_s: f64,
}

impl Timing {
    /// Whether frame `k` is more than one period late and the pacing drops late frames.
    fn is_late(&self, k: u64) -> bool {
        let Pacing::Clock { drop_late: true } = self.pacing else {
            return false;
        };
        self.clock.elapsed().as_secs_f64() > self.due_s(k) + 1.0 / self.fps
    }

    /// Waits until frame `k` is due on the clock; `false` (without waiting) when it is to be
    /// dropped as late. Free pacing never waits.
    fn wait_for(&self, k: u64) -> bool {
        if self.pacing == Pacing::Free {
            return true;
        }
        if self.is_late(k) {
            return false;
        }
        let wait = self.due_s(k) - self.clock.elapsed().as_secs_f64();
        if wait > 0.0 {
            std::thread::sleep(Duration::from_secs_f64(wait));
        }
        true
    }

    /// When frame `k` is due on the clock, s.
    fn due_s(&self, k: u64) -> f64 {
        k as f64 / self.fps - self.start_s
    }
}

impl Drop for FrameSource {
    fn drop(&mut self) {
        self.close();
    }
}

/// Frame number `k` of a source.
fn frame(id: String, k: u64, timestamp_s: f64, image: RgbImage) -> Frame {
    Frame {
        id,
        index: usize::try_from(k).unwrap_or(usize::MAX),
        timestamp_s,
        image,
    }
}

/// A rig's frame that could not be drawn.
#[cfg(feature = "sim")]
fn render_error(index: u64, source: SimError) -> SourceError {
    SourceError::Render { index, source }
}

/// Without a simulator there is no rig, so no frame of one to fail.
#[cfg(not(feature = "sim"))]
fn render_error(_: u64, e: SourceError) -> SourceError {
    e
}

#[cfg(test)]
mod tests {
    use std::path::{Path, PathBuf};

    use visuotact_image::RgbImage;
    use visuotact_io::frames::write_png;

    use super::{FrameSource, Next, Pacing, SourceConfig};

    /// A folder of `n` small PNGs (`f0.png`, …) and, when `broken`, a file between them that
    /// is no image.
    fn folder(name: &str, n: usize, broken: bool) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("visuotact-source-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        for k in 0..n {
            let img = RgbImage::from_fn(8, 6, |x, y| [(x * 20 + k) as u8, (y * 10) as u8, 7]);
            write_png(&d.join(format!("f{k}.png")), &img).unwrap();
        }
        if broken {
            std::fs::write(d.join("f0b.png"), b"not a png").unwrap();
        }
        d
    }

    fn steps(source: &mut FrameSource) -> Vec<String> {
        let mut out = Vec::new();
        loop {
            match source.next_frame().unwrap() {
                Next::Frame(f) => out.push(f.frame.id),
                Next::Dropped => out.push("dropped".into()),
                Next::Unreadable(why) => out.push(format!("unreadable: {why}")),
                Next::End => return out,
            }
        }
    }

    fn opened(path: &Path, (pacing, fps): (Pacing, f64), max_frames: Option<u64>) -> FrameSource {
        let cfg = SourceConfig {
            source: path.to_string_lossy().as_ref().into(),
            fps,
            pacing,
            max_frames,
            ..SourceConfig::default()
        };
        FrameSource::open(&cfg, &std::sync::Arc::default()).unwrap()
    }

    /// Files come in order; one that does not read is named with the reason and the source
    /// goes on; the count and the limit are the source's.
    #[test]
    fn files_give_every_frame_and_name_the_one_that_does_not_read() {
        let d = folder("files", 3, true);
        let mut source = FrameSource::files(std::slice::from_ref(&d), 25.0).unwrap();
        assert_eq!(source.expected_frames(), Some(4));
        let got = steps(&mut source);
        assert_eq!(got.len(), 4, "{got:?}");
        assert_eq!(got[0], "f0.png");
        assert!(
            got[1].starts_with("unreadable: ") && got[1].contains("f0b.png"),
            "{got:?}"
        );
        assert_eq!(&got[2..], ["f1.png", "f2.png"]);
        assert_eq!(source.dropped(), 0);
        let mut two = opened(&d, (Pacing::Free, 25.0), Some(2));
        let got_two = steps(&mut two);
        assert_eq!(got_two, got[..3], "two frames delivered, then the end");
        std::fs::remove_dir_all(&d).unwrap();
    }

    /// On the clock, frame `k` is not delivered before `k / fps`; with `drop_late`, frames
    /// more than one period late are dropped and counted, not delivered late.
    #[test]
    fn a_paced_source_waits_for_each_frame_and_drops_the_late_ones() {
        let d = folder("paced", 5, false);
        let mut paced = opened(&d, (Pacing::Clock { drop_late: false }, 100.0), None);
        let clock = paced.clock();
        assert_eq!(steps(&mut paced).len(), 5);
        assert!(clock.elapsed().as_secs_f64() >= 4.0 / 100.0);
        let mut late = opened(&d, (Pacing::Clock { drop_late: true }, 10.0), None);
        let Next::Frame(first) = late.next_frame().unwrap() else {
            panic!("frame 0 is due at once");
        };
        assert_eq!(first.frame.id, "f0.png");
        // At 10 fps, frames 1–4 are due by 0.4 s and late after 0.5 s.
        std::thread::sleep(std::time::Duration::from_millis(700));
        assert_eq!(steps(&mut late), ["dropped"; 4]);
        assert_eq!(late.dropped(), 4);
        std::fs::remove_dir_all(&d).unwrap();
    }

    /// The simulated camera loops over its frames, each named by its place in the loop and
    /// its number in the run.
    #[cfg(feature = "sim")]
    #[test]
    fn a_simulated_camera_loops_over_its_frames() {
        let cfg = SourceConfig {
            source: "sim:iats".into(),
            sim_frames: 2,
            max_frames: Some(3),
            ..SourceConfig::default()
        };
        let mut source = FrameSource::open(&cfg, &std::sync::Arc::default()).unwrap();
        assert_eq!(
            steps(&mut source),
            ["iats_0000#0", "iats_0001#1", "iats_0000#2"]
        );
    }
}
