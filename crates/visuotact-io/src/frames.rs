//! Frame sources: image files, folders and videos.
//!
//! - Image files: PNG, JPEG, PPM/PGM/PNM (decoded by the `image` crate; grey images become RGB
//!   with equal channels). A frame's id is its file name.
//! - Folders: every image file inside, in natural order (`image_2` before `image_10`, see
//!   [`natural_cmp`]); a folder with none is an error.
//! - Videos (`.avi .mp4 .mkv .mov .webm .m4v .mpg .mpeg`): decoded by the `ffmpeg` program to
//!   raw RGB; size and rate from `ffprobe`. A frame's id is its 0-based index (prefixed with the
//!   file name when several inputs are given).
//!
//! Timestamps are `index / fps` in seconds from the start of the stream: the video's own rate,
//! or the rate given for image sequences (25 fps by default, seed 001's camera).
//! A frame that cannot be decoded comes out as an `Err` naming it; the stream goes on.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, Stdio};

use rayon::prelude::*;
use visuotact_image::{Frame, RgbImage};

/// Errors from opening or reading frames. Each names the file or frame.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    /// A path that does not exist or cannot be read.
    #[error("{path}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A folder without image files.
    #[error("{0}: folder has no image files (png, jpg, jpeg, ppm, pgm, pnm)")]
    EmptyFolder(PathBuf),
    /// No inputs at all.
    #[error("no frames given")]
    NoInputs,
    /// A file that is neither an image nor a known video type.
    #[error("{0}: not an image (png, jpg, jpeg, ppm, pgm, pnm) or video (avi, mp4, mkv, mov, webm, m4v, mpg) file")]
    Unsupported(PathBuf),
    /// An image that cannot be decoded.
    #[error("frame {frame}: cannot decode image: {message}")]
    Decode {
        /// The frame's id (file path).
        frame: String,
        /// What the decoder said.
        message: String,
    },
    /// Two images whose frame ids (their file names, as text) are the same: rows of every
    /// table would be joined wrongly.
    #[error("{} and {}: both give the frame id `{id}`; frames must have distinct file names", first.display(), second.display())]
    SameId {
        /// The id.
        id: String,
        /// The first image.
        first: PathBuf,
        /// The second.
        second: PathBuf,
    },
    /// ffmpeg missing, failing to open the video, or stopping early.
    #[error("{path}: {message}")]
    Video {
        /// The video file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
}

const IMAGE_EXT: [&str; 6] = ["png", "jpg", "jpeg", "ppm", "pgm", "pnm"];
const VIDEO_EXT: [&str; 8] = ["avi", "mp4", "mkv", "mov", "webm", "m4v", "mpg", "mpeg"];

/// Whether `p` names a video file by its extension (avi, mp4, mkv, mov, webm, m4v, mpg, mpeg).
pub fn is_video_path(p: &Path) -> bool {
    VIDEO_EXT.contains(&ext_of(p).as_str())
}

/// Whether `p` names an image file by its extension (png, jpg, jpeg, ppm, pgm, pnm).
pub fn is_image_path(p: &Path) -> bool {
    IMAGE_EXT.contains(&ext_of(p).as_str())
}

fn ext_of(p: &Path) -> String {
    p.extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

/// One expanded input.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Input {
    /// An image file.
    Image(PathBuf),
    /// A video file.
    Video(PathBuf),
}

/// Expands files and folders into a list of inputs (folders in natural order).
pub fn expand_inputs(paths: &[PathBuf]) -> Result<Vec<Input>, FrameError> {
    if paths.is_empty() {
        return Err(FrameError::NoInputs);
    }
    let mut out = Vec::new();
    for p in paths {
        let meta = std::fs::metadata(p).map_err(|source| FrameError::Io {
            path: p.clone(),
            source,
        })?;
        if meta.is_dir() {
            let mut files: Vec<PathBuf> = std::fs::read_dir(p)
                .map_err(|source| FrameError::Io {
                    path: p.clone(),
                    source,
                })?
                .filter_map(|e| e.ok().map(|e| e.path()))
                // Every image name but a folder's: a dangling link or a pipe named like a
                // frame is read, fails and is reported by name, not passed over in silence.
                .filter(|f| !f.is_dir() && IMAGE_EXT.contains(&ext_of(f).as_str()))
                .collect();
            if files.is_empty() {
                return Err(FrameError::EmptyFolder(p.clone()));
            }
            files.sort_by(|a, b| natural_cmp(&a.to_string_lossy(), &b.to_string_lossy()));
            out.extend(files.into_iter().map(Input::Image));
        } else {
            let e = ext_of(p);
            if IMAGE_EXT.contains(&e.as_str()) {
                out.push(Input::Image(p.clone()));
            } else if VIDEO_EXT.contains(&e.as_str()) {
                out.push(Input::Video(p.clone()));
            } else {
                return Err(FrameError::Unsupported(p.clone()));
            }
        }
    }
    Ok(out)
}

/// Natural order of names: runs of digits compare by their value (`image_2` < `image_10`,
/// `frame_007` = `frame_7` by value, then the shorter run first), everything else by
/// character; names equal that way fall back to plain byte order.
///
/// ```
/// use visuotact_io::frames::natural_cmp;
/// let mut v = vec!["image_10.png", "image_2.png", "image_1.png", "image_100.png"];
/// v.sort_by(|a, b| natural_cmp(a, b));
/// assert_eq!(v, ["image_1.png", "image_2.png", "image_10.png", "image_100.png"]);
/// ```
pub fn natural_cmp(a: &str, b: &str) -> std::cmp::Ordering {
    use std::cmp::Ordering;
    let (ab, bb) = (a.as_bytes(), b.as_bytes());
    let (mut i, mut j) = (0, 0);
    while i < ab.len() && j < bb.len() {
        if ab[i].is_ascii_digit() && bb[j].is_ascii_digit() {
            let (si, sj) = (i, j);
            while i < ab.len() && ab[i].is_ascii_digit() {
                i += 1;
            }
            while j < bb.len() && bb[j].is_ascii_digit() {
                j += 1;
            }
            // Compare the values: strip leading zeros, then longer is larger, then digits.
            let da = &ab[si..i];
            let db = &bb[sj..j];
            let ta = &da[da.iter().position(|&c| c != b'0').unwrap_or(da.len())..];
            let tb = &db[db.iter().position(|&c| c != b'0').unwrap_or(db.len())..];
            let ord = ta
                .len()
                .cmp(&tb.len())
                .then_with(|| ta.cmp(tb))
                .then_with(|| da.len().cmp(&db.len()));
            if ord != Ordering::Equal {
                return ord;
            }
        } else {
            let ord = ab[i].cmp(&bb[j]);
            if ord != Ordering::Equal {
                return ord;
            }
            i += 1;
            j += 1;
        }
    }
    (ab.len() - i).cmp(&(bb.len() - j)).then_with(|| a.cmp(b))
}

/// Decodes one image file into RGB.
pub fn read_image(path: &Path) -> Result<RgbImage, FrameError> {
    let frame = path.display().to_string();
    let bytes =
        crate::read::bytes_of_file(path, crate::read::MAX_IMAGE_BYTES).map_err(|source| {
            FrameError::Io {
                path: path.to_path_buf(),
                source,
            }
        })?;
    let decode_err = |message: String| FrameError::Decode {
        frame: frame.clone(),
        message,
    };
    let mut reader = image::ImageReader::new(std::io::Cursor::new(&bytes))
        .with_guessed_format()
        .map_err(|e| decode_err(e.to_string()))?;
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(4 * crate::read::MAX_IMAGE_PIXELS * 2);
    reader.limits(limits);
    let decoder = reader
        .into_decoder()
        .map_err(|e| decode_err(e.to_string()))?;
    // The size the header claims is checked before anything is allocated (a small file can
    // claim gigapixels).
    let (w, h) = image::ImageDecoder::dimensions(&decoder);
    if u64::from(w) * u64::from(h) > crate::read::MAX_IMAGE_PIXELS {
        return Err(decode_err(format!(
            "{w}×{h} pixels, beyond the limit of {} pixels",
            crate::read::MAX_IMAGE_PIXELS
        )));
    }
    // And so is the memory decoding takes: the decoder's buffer (16-bit and alpha channels
    // make it up to 8 bytes a pixel) and, unless it is 8-bit RGB already, the RGB copy.
    let pixels = u64::from(w) * u64::from(h);
    let color = image::ImageDecoder::color_type(&decoder);
    let rgb_copy = if color == image::ColorType::Rgb8 {
        0
    } else {
        3
    };
    let needed = pixels * (u64::from(color.bytes_per_pixel()) + rgb_copy);
    if needed > crate::read::MAX_DECODED_BYTES {
        return Err(decode_err(format!(
            "{w}×{h} pixels of {color:?} need {} MiB to decode, beyond the limit of {} MiB",
            needed >> 20,
            crate::read::MAX_DECODED_BYTES >> 20
        )));
    }
    let img = image::DynamicImage::from_decoder(decoder)
        .map_err(|e| decode_err(e.to_string()))?
        .into_rgb8();
    let (w, h) = img.dimensions();
    RgbImage::from_vec(w as usize, h as usize, img.into_raw()).map_err(|e| FrameError::Decode {
        frame,
        message: e.to_string(),
    })
}

/// Writes an RGB image as PNG, as one [`crate::output::OutputFile`]: a full disk or a kill
/// never leaves a torn PNG under the frame's name.
pub fn write_png(path: &Path, img: &RgbImage) -> Result<(), FrameError> {
    let failed = |e: String| FrameError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::other(e),
    };
    let mut out = crate::output::OutputFile::create(path).map_err(|e| failed(e.to_string()))?;
    rgb_into(image::codecs::png::PngEncoder::new(&mut out), img)
        .map_err(|e| failed(e.to_string()))?;
    out.finish().map_err(|e| failed(e.to_string()))
}

/// Encodes an RGB image with `encoder`.
fn rgb_into(encoder: impl image::ImageEncoder, img: &RgbImage) -> image::ImageResult<()> {
    encoder.write_image(
        img.as_slice(),
        u32::try_from(img.width()).unwrap_or(u32::MAX),
        u32::try_from(img.height()).unwrap_or(u32::MAX),
        image::ExtendedColorType::Rgb8,
    )
}

/// An RGB image as PNG bytes, encoded fast (live outputs send one per frame).
pub fn png_bytes_from_rgb(img: &RgbImage) -> Result<Vec<u8>, image::ImageError> {
    let mut out = Vec::new();
    rgb_into(
        image::codecs::png::PngEncoder::new_with_quality(
            &mut out,
            image::codecs::png::CompressionType::Fast,
            image::codecs::png::FilterType::Sub,
        ),
        img,
    )?;
    Ok(out)
}

/// Size and rate of a video, from `ffprobe`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VideoInfo {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Frames per second.
    pub fps: f64,
    /// Frames the container announces, when it says.
    pub frames: Option<usize>,
}

fn tool_missing(path: &Path, tool: &str, e: &std::io::Error) -> FrameError {
    FrameError::Video {
        path: path.to_path_buf(),
        message: if e.kind() == std::io::ErrorKind::NotFound {
            format!("cannot decode video: the `{tool}` program is not installed (Debian package `ffmpeg`)")
        } else {
            format!("cannot run {tool}: {e}")
        },
    }
}

/// Probes a video's size and frame rate.
pub fn probe_video(path: &Path) -> Result<VideoInfo, FrameError> {
    if !path.is_file() {
        return Err(FrameError::Io {
            path: path.to_path_buf(),
            source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
        });
    }
    let out = Command::new("ffprobe")
        .args([
            "-v",
            "error",
            "-select_streams",
            "v:0",
            "-show_entries",
            "stream=width,height,avg_frame_rate,r_frame_rate,nb_frames",
            "-of",
            "default=noprint_wrappers=1",
        ])
        .arg(path)
        .output()
        .map_err(|e| tool_missing(path, "ffprobe", &e))?;
    let text = String::from_utf8_lossy(&out.stdout);
    let err = String::from_utf8_lossy(&out.stderr);
    video_info_from_probe(path, &text, &err)
}

/// The size, rate and frame count of `path` from `ffprobe`'s `key=value` lines (`text`) and
/// its messages (`err`): a stream without a size, a zero size or one over
/// [`crate::read::MAX_IMAGE_PIXELS`] per frame is refused, a rate that does not parse is
/// 25 fps.
pub fn video_info_from_probe(path: &Path, text: &str, err: &str) -> Result<VideoInfo, FrameError> {
    let field = |k: &str| {
        text.lines().find_map(|l| {
            l.strip_prefix(k)
                .and_then(|v| v.strip_prefix('='))
                .map(str::trim)
        })
    };
    let bad = |what: &str| FrameError::Video {
        path: path.to_path_buf(),
        message: format!(
            "ffmpeg cannot open it as a video ({what}){}",
            if err.trim().is_empty() {
                String::new()
            } else {
                format!(": {}", err.trim())
            }
        ),
    };
    let width: usize = field("width")
        .and_then(|v| v.parse().ok())
        .ok_or_else(|| bad("no video stream"))?;
    let height: usize = field("height")
        .and_then(|v| v.parse().ok())
        .ok_or_else(|| bad("no frame size"))?;
    let rate = |s: &str| -> Option<f64> {
        let (a, b) = s.split_once('/').unwrap_or((s, "1"));
        let (a, b): (f64, f64) = (a.parse().ok()?, b.parse().ok()?);
        // A rate written past f64's range (`3000e530/1`, `5/9E7296`) is no rate.
        (b > 0.0 && a > 0.0)
            .then_some(a / b)
            .filter(|r| r.is_finite() && *r > 0.0)
    };
    let fps = field("avg_frame_rate")
        .and_then(rate)
        .or_else(|| field("r_frame_rate").and_then(rate))
        .unwrap_or(25.0);
    if width == 0 || height == 0 {
        return Err(bad("zero frame size"));
    }
    let pixels = (width as u64).checked_mul(height as u64);
    if pixels.is_none_or(|p| p > crate::read::MAX_IMAGE_PIXELS) {
        return Err(FrameError::Video {
            path: path.to_path_buf(),
            message: format!(
                "frames of {width}×{height}: over the limit of {} pixels a frame",
                crate::read::MAX_IMAGE_PIXELS
            ),
        });
    }
    let frames = field("nb_frames").and_then(|v| v.parse().ok());
    Ok(VideoInfo {
        width,
        height,
        fps,
        frames,
    })
}

/// Frames of one video, decoded by a child `ffmpeg` process.
pub struct VideoFrames {
    path: PathBuf,
    info: VideoInfo,
    child: Option<Child>,
    stdout: Option<ChildStdout>,
    index: usize,
    prefix: Option<String>,
    done: bool,
}

impl VideoFrames {
    /// Opens `path`; `prefix` is put before frame ids (`name#index`) when several inputs mix.
    pub fn open(path: &Path, prefix: Option<String>) -> Result<Self, FrameError> {
        let info = probe_video(path)?;
        let mut child = Command::new("ffmpeg")
            .args(["-nostdin", "-v", "error", "-i"])
            .arg(path)
            .args(["-f", "rawvideo", "-pix_fmt", "rgb24", "-"])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| tool_missing(path, "ffmpeg", &e))?;
        let stdout = child.stdout.take();
        Ok(Self {
            path: path.to_path_buf(),
            info,
            child: Some(child),
            stdout,
            index: 0,
            prefix,
            done: false,
        })
    }

    /// Size and rate.
    pub fn info(&self) -> VideoInfo {
        self.info
    }

    /// Fewer frames decoded than the container announces (a file cut short): said once, at
    /// the end, as an error item the stream's readers report (a frame or two of slack).
    fn short(&self) -> Option<FrameError> {
        let announced = self.info.frames?;
        (self.index + 1 + announced / 50 < announced).then(|| FrameError::Video {
            path: self.path.clone(),
            message: format!(
                "only {} of the {announced} frames the file announces could be decoded: is it cut short?",
                self.index
            ),
        })
    }

    fn finish(&mut self) -> Option<FrameError> {
        self.done = true;
        self.stdout = None;
        let child = self.child.take()?;
        let out = child.wait_with_output().ok()?;
        if out.status.success() {
            return None;
        }
        let err = String::from_utf8_lossy(&out.stderr);
        Some(FrameError::Video {
            path: self.path.clone(),
            message: format!(
                "ffmpeg stopped after {} frames: {}",
                self.index,
                err.lines().last().unwrap_or("unknown error").trim()
            ),
        })
    }
}

impl Iterator for VideoFrames {
    type Item = Result<Frame, FrameError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let n = self.info.width * self.info.height * 3;
        let mut buf = vec![0u8; n];
        let mut got = 0;
        let stdout = self.stdout.as_mut()?;
        while got < n {
            match stdout.read(&mut buf[got..]) {
                Ok(0) => break,
                Ok(k) => got += k,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => {
                    self.done = true;
                    return Some(Err(FrameError::Video {
                        path: self.path.clone(),
                        message: format!("reading ffmpeg output: {e}"),
                    }));
                }
            }
        }
        if got < n {
            let err = self.finish();
            if got > 0 {
                return Some(Err(FrameError::Video {
                    path: self.path.clone(),
                    message: format!("frame {} truncated ({got} of {n} bytes)", self.index),
                }));
            }
            return err.or_else(|| self.short()).map(Err);
        }
        let index = self.index;
        self.index += 1;
        let id = match &self.prefix {
            Some(p) => format!("{p}#{index}"),
            None => index.to_string(),
        };
        let image = RgbImage::from_vec(self.info.width, self.info.height, buf).ok()?;
        Some(Ok(Frame {
            id,
            index,
            timestamp_s: index as f64 / self.info.fps,
            image,
        }))
    }
}

impl Drop for VideoFrames {
    fn drop(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// An image's frame id: its file name, as text.
fn image_id(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// How many images are decoded at once (in parallel) by [`FrameStream`].
const DECODE_BATCH: usize = 32;

/// All frames of a list of inputs, in order, as one stream.
pub struct FrameStream {
    inputs: Vec<Input>,
    next_input: usize,
    image_fps: f64,
    video: Option<VideoFrames>,
    decoded: std::collections::VecDeque<Result<Frame, FrameError>>,
    index: usize,
    multi: bool,
    limit: Option<usize>,
}

impl FrameStream {
    /// Opens files and folders; `image_fps` sets image-sequence timestamps.
    pub fn open(paths: &[PathBuf], image_fps: f64) -> Result<Self, FrameError> {
        let inputs = expand_inputs(paths)?;
        // Image ids are file names (as text: names that are not UTF-8 may collide), so two
        // folders holding the same names, or two such names, are refused.
        let mut seen = std::collections::HashMap::new();
        for i in &inputs {
            if let Input::Image(p) = i {
                let id = image_id(p);
                if let Some(first) = seen.insert(id.clone(), p) {
                    return Err(FrameError::SameId {
                        id,
                        first: first.clone(),
                        second: p.clone(),
                    });
                }
            }
        }
        // Video frame ids are bare indices unless several inputs could make them collide.
        let multi = inputs.len() > 1 && inputs.iter().any(|i| matches!(i, Input::Video(_)));
        Ok(Self {
            inputs,
            next_input: 0,
            image_fps: if image_fps > 0.0 { image_fps } else { 25.0 },
            video: None,
            decoded: Default::default(),
            index: 0,
            multi,
            limit: None,
        })
    }

    /// Stops after `n` frames.
    pub fn take_first(mut self, n: usize) -> Self {
        self.limit = Some(n);
        self
    }

    /// The expanded inputs.
    pub fn inputs(&self) -> &[Input] {
        &self.inputs
    }

    /// How many frames the stream gives, when known before decoding: every image, and each
    /// video's count where its container announces one (asked of `ffprobe`); `None` when a
    /// video does not say. Call it before iterating.
    pub fn expected_frames(&self) -> Option<usize> {
        let mut n = 0usize;
        for i in &self.inputs {
            n += match i {
                Input::Image(_) => 1,
                Input::Video(p) => probe_video(p).ok()?.frames?,
            };
        }
        Some(self.limit.map_or(n, |l| n.min(l)))
    }
}

impl Iterator for FrameStream {
    type Item = Result<Frame, FrameError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.limit.is_some_and(|l| self.index >= l) {
            return None;
        }
        loop {
            if let Some(f) = self.decoded.pop_front() {
                self.index += 1;
                return Some(f);
            }
            if let Some(v) = self.video.as_mut() {
                match v.next() {
                    Some(Ok(mut f)) => {
                        f.index = self.index;
                        self.index += 1;
                        return Some(Ok(f));
                    }
                    Some(Err(e)) => {
                        self.index += 1;
                        return Some(Err(e));
                    }
                    None => self.video = None,
                }
            }
            let input = self.inputs.get(self.next_input)?.clone();
            match input {
                Input::Video(p) => {
                    self.next_input += 1;
                    let prefix = self.multi.then(|| {
                        p.file_name()
                            .map(|n| n.to_string_lossy().into_owned())
                            .unwrap_or_default()
                    });
                    match VideoFrames::open(&p, prefix) {
                        Ok(v) => self.video = Some(v),
                        Err(e) => return Some(Err(e)),
                    }
                }
                Input::Image(_) => {
                    // Decode the run of images that follows, a batch at a time, in parallel.
                    let mut batch = Vec::new();
                    while batch.len() < DECODE_BATCH {
                        match self.inputs.get(self.next_input) {
                            Some(Input::Image(p)) => {
                                batch.push(p.clone());
                                self.next_input += 1;
                            }
                            _ => break,
                        }
                    }
                    let base = self.index;
                    let fps = self.image_fps;
                    let frames: Vec<_> = batch
                        .par_iter()
                        .enumerate()
                        .map(|(k, p)| {
                            read_image(p).map(|image| Frame {
                                id: image_id(p),
                                index: base + k,
                                timestamp_s: (base + k) as f64 / fps,
                                image,
                            })
                        })
                        .collect();
                    self.decoded.extend(frames);
                }
            }
        }
    }
}

#[cfg(test)]
mod natural_order_tests {
    use super::*;
    use std::cmp::Ordering;

    #[test]
    fn digits_compare_by_value() {
        assert_eq!(natural_cmp("a2", "a10"), Ordering::Less);
        assert_eq!(natural_cmp("a10", "a2"), Ordering::Greater);
        assert_eq!(natural_cmp("a007", "a7"), Ordering::Greater);
        assert_eq!(natural_cmp("a7b", "a7"), Ordering::Greater);
        assert_eq!(natural_cmp("x", "x"), Ordering::Equal);
        assert_eq!(natural_cmp("frame_9_b", "frame_10_a"), Ordering::Less);
        assert_eq!(
            natural_cmp("99999999999999999999999", "100000000000000000000000"),
            Ordering::Less
        );
    }

    #[test]
    fn folders_list_in_natural_order() {
        let dir = std::env::temp_dir().join(format!("vt-natural-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for k in [1, 10, 100, 2, 20, 3] {
            std::fs::write(dir.join(format!("image_{k}.png")), b"").unwrap();
        }
        let got: Vec<String> = expand_inputs(std::slice::from_ref(&dir))
            .unwrap()
            .into_iter()
            .map(|i| match i {
                Input::Image(p) | Input::Video(p) => {
                    p.file_name().unwrap().to_string_lossy().into_owned()
                }
            })
            .collect();
        std::fs::remove_dir_all(&dir).unwrap();
        assert_eq!(
            got,
            [
                "image_1.png",
                "image_2.png",
                "image_3.png",
                "image_10.png",
                "image_20.png",
                "image_100.png"
            ]
        );
    }
}

#[cfg(test)]
mod limit_tests {
    use super::*;

    /// CRC-32 (IEEE), as PNG chunks carry it.
    fn crc32(bytes: &[u8]) -> u32 {
        let mut c = 0xffff_ffffu32;
        for &b in bytes {
            c ^= u32::from(b);
            for _ in 0..8 {
                c = if c & 1 == 1 {
                    (c >> 1) ^ 0xedb8_8320
                } else {
                    c >> 1
                };
            }
        }
        !c
    }

    fn chunk(kind: &[u8], data: &[u8]) -> Vec<u8> {
        let mut out = (data.len() as u32).to_be_bytes().to_vec();
        let body = [kind, data].concat();
        out.extend(&body);
        out.extend(crc32(&body).to_be_bytes());
        out
    }

    /// A PNG header of `side`² pixels of `depth` bits, colour type `color`, with no pixel data.
    fn header_only_png(side: u32, depth: u8, color: u8) -> Vec<u8> {
        let mut ihdr = side.to_be_bytes().to_vec();
        ihdr.extend(side.to_be_bytes());
        ihdr.extend([depth, color, 0, 0, 0]);
        [
            b"\x89PNG\r\n\x1a\n".to_vec(),
            chunk(b"IHDR", &ihdr),
            // An empty zlib stream: nothing to inflate.
            chunk(b"IDAT", &[0x78, 0x9c, 0x03, 0, 0, 0, 0, 1]),
            chunk(b"IEND", &[]),
        ]
        .concat()
    }

    /// A 100 000 × 100 000 PNG header with no pixel data (a decompression bomb's shape), and
    /// a 16 000² 16-bit RGB one (fewer pixels than the limit, but 1.5 GiB to decode, 2.76 GB
    /// taken before): refused from the header, naming the limit, before a pixel is allocated.
    #[test]
    fn an_image_claiming_too_many_pixels_is_refused_before_decoding() {
        let d = std::env::temp_dir().join(format!("visuotact-bomb-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let p = d.join("bomb.png");
        for (png, says) in [
            (
                header_only_png(100_000, 8, 2),
                "100000×100000 pixels, beyond the limit",
            ),
            (
                header_only_png(16_000, 16, 2),
                "16000×16000 pixels of Rgb16 need 2197 MiB to decode, beyond the limit of 1024 MiB",
            ),
        ] {
            std::fs::write(&p, png).unwrap();
            let e = read_image(&p).unwrap_err().to_string();
            assert!(e.contains(says), "{e}");
        }
        std::fs::remove_dir_all(&d).unwrap();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn probes_of_impossible_frame_sizes_are_refused_by_name() {
        let p = Path::new("v.mp4");
        let ok = video_info_from_probe(
            p,
            "width=640\nheight=480\navg_frame_rate=30000/1001\nnb_frames=12\n",
            "",
        )
        .unwrap();
        assert_eq!((ok.width, ok.height, ok.frames), (640, 480, Some(12)));
        assert!((ok.fps - 29.97).abs() < 0.01, "{}", ok.fps);
        let odd_rate = video_info_from_probe(p, "width=4\nheight=2\navg_frame_rate=0/0\n", "");
        assert_eq!(odd_rate.unwrap().fps, 25.0);
        // Found by the fuzz target `video_probe`: a rate that overflows to infinity.
        for rate in ["3000e530/1", "1e308/1e-308", "5/9E7296"] {
            let text = format!("width=640\nheight=480\navg_frame_rate={rate}\nr_frame_rate=30/1\n");
            let v = video_info_from_probe(p, &text, "").unwrap();
            assert_eq!(v.fps, 30.0, "{rate}");
        }
        for (text, why) in [
            ("width=4294967296\nheight=4294967296\n", "over the limit"),
            ("width=18446744073709551615\nheight=2\n", "over the limit"),
            ("width=100000\nheight=100000\n", "over the limit"),
            ("width=0\nheight=10\n", "zero frame size"),
            ("height=10\n", "no video stream"),
            ("width=-3\nheight=10\n", "no video stream"),
        ] {
            let e = video_info_from_probe(p, text, "").unwrap_err().to_string();
            assert!(e.contains("v.mp4") && e.contains(why), "{text:?}: {e}");
        }
    }
}
