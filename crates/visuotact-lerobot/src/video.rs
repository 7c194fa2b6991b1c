//! Frames into one MP4 through `ffmpeg` (raw RGB on its standard input), as LeRobot encodes
//! its videos: by default SVT-AV1, `yuv420p`, a keyframe every 2 frames, CRF 30.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};

use crate::LeRobotError;

/// How the video is encoded.
#[derive(Clone, Debug, PartialEq)]
pub struct VideoConfig {
    /// The `ffmpeg` program.
    pub ffmpeg: PathBuf,
    /// Encoder (`libsvtav1` as LeRobot; `libx264` where AV1 is missing).
    pub encoder: String,
    /// Constant rate factor (quality; lower is better).
    pub crf: u32,
    /// Frames between keyframes (2: any frame decodes fast, as LeRobot seeks).
    pub gop: u32,
}

impl Default for VideoConfig {
    fn default() -> Self {
        Self {
            ffmpeg: "ffmpeg".into(),
            encoder: "libsvtav1".into(),
            crf: 30,
            gop: 2,
        }
    }
}

impl VideoConfig {
    /// The codec name LeRobot's `info.json` records for the encoder.
    pub fn codec(&self) -> &str {
        match self.encoder.as_str() {
            "libsvtav1" | "libaom-av1" | "librav1e" => "av1",
            "libx264" => "h264",
            "libx265" => "hevc",
            other => other,
        }
    }
}

/// An `ffmpeg` process encoding `width × height` RGB frames at `fps` into `path`.
pub struct Encoder {
    child: Option<Child>,
    stdin: Option<ChildStdin>,
    path: PathBuf,
    frame_bytes: usize,
    /// Frames written.
    pub frames: usize,
}

impl Encoder {
    /// Starts `ffmpeg`.
    pub fn start(
        cfg: &VideoConfig,
        path: &Path,
        (width, height): (u32, u32),
        fps: u32,
    ) -> Result<Self, LeRobotError> {
        let mut child = Command::new(&cfg.ffmpeg)
            .args(["-hide_banner", "-loglevel", "error", "-nostdin", "-y"])
            .args(["-f", "rawvideo", "-pix_fmt", "rgb24"])
            .args(["-s", &format!("{width}x{height}"), "-r", &fps.to_string()])
            .args(["-i", "-", "-c:v", &cfg.encoder, "-pix_fmt", "yuv420p"])
            .args(["-g", &cfg.gop.to_string(), "-crf", &cfg.crf.to_string()])
            .arg(path)
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| {
                LeRobotError::Video(format!(
                    "cannot start {}: {e} (install ffmpeg, e.g. apt-get install ffmpeg, or \
                     export without video)",
                    cfg.ffmpeg.display()
                ))
            })?;
        let stdin = child.stdin.take();
        Ok(Self {
            child: Some(child),
            stdin,
            path: path.to_path_buf(),
            frame_bytes: width as usize * height as usize * 3,
            frames: 0,
        })
    }

    /// One frame, `width × height × 3` bytes of RGB.
    pub fn push(&mut self, rgb: &[u8]) -> Result<(), LeRobotError> {
        if rgb.len() != self.frame_bytes {
            return Err(LeRobotError::Video(format!(
                "{}: frame {} has {} bytes, expected {}",
                self.path.display(),
                self.frames,
                rgb.len(),
                self.frame_bytes
            )));
        }
        let Some(stdin) = self.stdin.as_mut() else {
            return Err(LeRobotError::Video("ffmpeg's input is closed".into()));
        };
        if stdin.write_all(rgb).is_err() {
            // ffmpeg stopped: its own message says why.
            return Err(self.failure());
        }
        self.frames += 1;
        Ok(())
    }

    fn failure(&mut self) -> LeRobotError {
        match self.wait() {
            Ok(out) => LeRobotError::Video(format!(
                "ffmpeg writing {}: {}",
                self.path.display(),
                String::from_utf8_lossy(&out.stderr).trim()
            )),
            Err(e) => e,
        }
    }

    /// Closes ffmpeg's input and waits for it.
    fn wait(&mut self) -> Result<std::process::Output, LeRobotError> {
        drop(self.stdin.take());
        let child = self
            .child
            .take()
            .ok_or_else(|| LeRobotError::Video("ffmpeg was already waited for".into()))?;
        child
            .wait_with_output()
            .map_err(|e| LeRobotError::Video(format!("ffmpeg: {e}")))
    }

    /// Closes the input and waits for `ffmpeg` to finish the file: the frames written.
    pub fn finish(mut self) -> Result<usize, LeRobotError> {
        let out = self.wait()?;
        if !out.status.success() {
            return Err(LeRobotError::Video(format!(
                "ffmpeg writing {}: {} ({})",
                self.path.display(),
                String::from_utf8_lossy(&out.stderr).trim(),
                out.status
            )));
        }
        Ok(self.frames)
    }
}
