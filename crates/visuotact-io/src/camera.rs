//! V4L2 cameras (`camera:/dev/videoN`): listing, format negotiation, and capture through the
//! `ffmpeg` program's v4l2 input, which hands over the camera's own bytes (`-c:v copy`):
//! MJPEG frames, split here and decoded with the `image` crate, or raw YUYV 4:2:2, converted
//! here (BT.601 limited range, as ffmpeg and V4L2 drivers define it). Frames are timestamped
//! when they arrive. A camera that disappears is reported and re-opened once a second; the run
//! goes on.

use std::io::Read;
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use visuotact_image::RgbImage;

use crate::queue::{Captured, LatestQueue};

/// Why a camera could not be opened or a frame not decoded.
#[derive(Debug, thiserror::Error)]
pub enum CameraError {
    /// No such device.
    #[error("camera {dev} does not exist; cameras here: {available}")]
    NoDevice {
        /// The device asked for.
        dev: String,
        /// The devices there are, with their names.
        available: String,
    },
    /// The `ffmpeg` program could not be run.
    #[error("the `ffmpeg` program is needed for cameras (Debian package `ffmpeg`): {0}")]
    Ffmpeg(std::io::Error),
    /// The camera offers nothing matching the request.
    #[error("camera {dev} offers no format matching {wanted}; it offers {offered}")]
    NoFormat {
        /// The device.
        dev: String,
        /// What was asked for.
        wanted: String,
        /// What it offers.
        offered: String,
    },
    /// A size or format request that does not parse.
    #[error("{0}")]
    Request(String),
    /// A frame that does not decode.
    #[error("{0}")]
    Frame(String),
    /// Reading the camera's bytes failed.
    #[error("reading the camera: {0}")]
    Read(#[from] std::io::Error),
}

/// Pixel formats visuotact captures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PixelFormat {
    /// Motion-JPEG: one JPEG per frame.
    Mjpeg,
    /// YUYV 4:2:2, two bytes per pixel.
    Yuyv,
}

/// One format a camera offers: pixel format and frame size.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CameraFormat {
    /// Pixel format.
    pub pixel: PixelFormat,
    /// Frame width, pixels.
    pub width: usize,
    /// Frame height, pixels.
    pub height: usize,
}

/// Formats from `ffmpeg -f v4l2 -list_formats all -i DEV` output (lines such as
/// `Compressed:       mjpeg :          Motion-JPEG : 640x480 320x240`).
pub fn parse_formats(text: &str) -> Vec<CameraFormat> {
    let mut out = Vec::new();
    for line in text.lines() {
        let Some(rest) = line.split("] ").nth(1) else {
            continue;
        };
        // "Compressed:  mjpeg :  Motion-JPEG : 640x480 …" (the description may hold colons).
        let Some((_, fields)) = rest.split_once(':') else {
            continue;
        };
        let cells: Vec<&str> = fields.split(" : ").map(str::trim).collect();
        if cells.len() < 3 {
            continue;
        }
        let pixel = match cells[0] {
            "mjpeg" => PixelFormat::Mjpeg,
            "yuyv422" => PixelFormat::Yuyv,
            _ => continue,
        };
        for size in cells[cells.len() - 1].split_whitespace() {
            if let Some((w, h)) = size.split_once('x') {
                let size = (w.parse::<usize>(), h.parse::<usize>());
                // A size no camera has (0, or beyond 16384) would size buffers wrongly.
                if let (Ok(width @ 1..=16384), Ok(height @ 1..=16384)) = size {
                    out.push(CameraFormat {
                        pixel,
                        width,
                        height,
                    });
                }
            }
        }
    }
    out
}

/// Picks the format to capture: the requested size (or the largest offered up to 640×480 when
/// none is requested — seed 001's webcam), MJPEG before YUYV (less USB bandwidth at the same
/// rate), unless a pixel format is requested.
pub fn negotiate(
    offered: &[CameraFormat],
    size: Option<(usize, usize)>,
    pixel: Option<PixelFormat>,
) -> Option<CameraFormat> {
    let ok_pixel = |f: &&CameraFormat| pixel.is_none_or(|p| f.pixel == p);
    let rank = |f: &CameraFormat| u8::from(f.pixel == PixelFormat::Mjpeg);
    match size {
        Some((w, h)) => offered
            .iter()
            .filter(ok_pixel)
            .filter(|f| (f.width, f.height) == (w, h))
            .max_by_key(|f| rank(f))
            .copied(),
        None => offered
            .iter()
            .filter(ok_pixel)
            .filter(|f| f.width * f.height <= 640 * 480)
            .max_by_key(|f| (f.width * f.height, rank(f)))
            .copied(),
    }
}

/// RGB from a YUYV 4:2:2 buffer (Y0 U Y1 V per pixel pair; BT.601, limited range).
pub fn rgb_from_yuyv(buf: &[u8], width: usize, height: usize) -> Result<RgbImage, CameraError> {
    if !width.is_multiple_of(2) || buf.len() != width * height * 2 {
        return Err(CameraError::Frame(format!(
            "YUYV frame of {} bytes for {width}×{height} (expected {} and an even width)",
            buf.len(),
            width * height * 2
        )));
    }
    let mut rgb = Vec::with_capacity(width * height * 3);
    let px = |y: u8, u: u8, v: u8| -> [u8; 3] {
        let c = 1.164_383 * (f32::from(y) - 16.0);
        let (d, e) = (f32::from(u) - 128.0, f32::from(v) - 128.0);
        let clamp = |x: f32| x.round().clamp(0.0, 255.0) as u8;
        [
            clamp(c + 1.596_027 * e),
            clamp(c - 0.391_762 * d - 0.812_968 * e),
            clamp(c + 2.017_232 * d),
        ]
    };
    for q in buf.chunks_exact(4) {
        rgb.extend_from_slice(&px(q[0], q[1], q[3]));
        rgb.extend_from_slice(&px(q[2], q[1], q[3]));
    }
    RgbImage::from_vec(width, height, rgb).map_err(|e| CameraError::Frame(e.to_string()))
}

/// RGB from one JPEG frame of an MJPEG stream.
pub fn rgb_from_mjpeg(jpeg: &[u8]) -> Result<RgbImage, CameraError> {
    let img = image::load_from_memory_with_format(jpeg, image::ImageFormat::Jpeg)
        .map_err(|e| CameraError::Frame(format!("MJPEG frame does not decode: {e}")))?
        .to_rgb8();
    let (w, h) = (img.width() as usize, img.height() as usize);
    RgbImage::from_vec(w, h, img.into_raw()).map_err(|e| CameraError::Frame(e.to_string()))
}

/// Splits a byte stream of concatenated JPEGs (SOI `FF D8` … EOI `FF D9`) into frames. A
/// frame that does not end within [`MjpegSplitter::LARGEST`] bytes is dropped (a stream of
/// junk never grows the buffer without bound) and counted.
#[derive(Default)]
pub struct MjpegSplitter {
    buf: Vec<u8>,
    /// Unterminated frames dropped so far.
    pub dropped: u64,
}

impl MjpegSplitter {
    /// The largest frame kept, bytes.
    pub const LARGEST: usize = 64 << 20;

    /// Adds bytes; returns the complete frames they finish.
    pub fn push(&mut self, bytes: &[u8]) -> Vec<Vec<u8>> {
        self.buf.extend_from_slice(bytes);
        let mut frames = Vec::new();
        loop {
            let Some(start) = self.buf.windows(2).position(|w| w == [0xFF, 0xD8]) else {
                // Keep a trailing FF: it may start the next marker.
                let keep = usize::from(self.buf.last() == Some(&0xFF));
                self.buf.drain(..self.buf.len() - keep);
                break;
            };
            let Some(end) = self.buf[start + 2..]
                .windows(2)
                .position(|w| w == [0xFF, 0xD9])
            else {
                self.buf.drain(..start);
                if self.buf.len() > Self::LARGEST {
                    self.buf.clear();
                    self.dropped += 1;
                }
                break;
            };
            let end = start + 2 + end + 2;
            frames.push(self.buf[start..end].to_vec());
            self.buf.drain(..end);
        }
        frames
    }
}

/// `/dev/videoN` devices and their names (from sysfs).
pub fn list_devices() -> Vec<(String, String)> {
    let mut out: Vec<(String, String)> = std::fs::read_dir("/sys/class/video4linux")
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| {
            let name = std::fs::read_to_string(e.path().join("name"))
                .unwrap_or_default()
                .trim()
                .to_string();
            (format!("/dev/{}", e.file_name().to_string_lossy()), name)
        })
        .collect();
    // /dev/video2 before /dev/video10.
    out.sort_by(|a, b| crate::frames::natural_cmp(&a.0, &b.0));
    out
}

fn offered_formats(dev: &str) -> Result<Vec<CameraFormat>, CameraError> {
    let o = Command::new("ffmpeg")
        .args([
            "-hide_banner",
            "-f",
            "v4l2",
            "-list_formats",
            "all",
            "-i",
            dev,
        ])
        .output()
        .map_err(CameraError::Ffmpeg)?;
    Ok(parse_formats(&String::from_utf8_lossy(&o.stderr)))
}

/// What to ask a camera for.
#[derive(Clone, Copy, Debug, Default)]
pub struct CameraRequest {
    /// Frame size; `None`: the largest offered up to 640×480.
    pub size: Option<(usize, usize)>,
    /// Pixel format; `None`: MJPEG when offered, else YUYV.
    pub pixel: Option<PixelFormat>,
}

impl CameraRequest {
    /// Parses `--camera-size WxH` and `--camera-format mjpeg|yuyv`.
    pub fn parse(size: Option<&str>, format: Option<&str>) -> Result<Self, CameraError> {
        let size = match size {
            Some(s) => {
                let bad =
                    || CameraError::Request(format!("size {s:?}: expected WxH, e.g. 640x480"));
                let (w, h) = s.split_once('x').ok_or_else(bad)?;
                Some((w.parse().map_err(|_| bad())?, h.parse().map_err(|_| bad())?))
            }
            None => None,
        };
        let pixel = match format {
            Some("mjpeg") => Some(PixelFormat::Mjpeg),
            Some("yuyv") => Some(PixelFormat::Yuyv),
            Some(f) => {
                return Err(CameraError::Request(format!(
                    "format {f:?}: expected mjpeg or yuyv"
                )))
            }
            None => None,
        };
        Ok(Self { size, pixel })
    }
}

/// Starts capturing from `dev` into `queue` until `stop` or `max` frames; the thread returns
/// the number of frames captured. A camera that stops sending is re-opened once a second.
pub fn spawn(
    dev: &str,
    req: CameraRequest,
    fps: f64,
    queue: Arc<LatestQueue<Captured>>,
    stop: Arc<AtomicBool>,
    clock: Instant,
    max: u64,
) -> Result<std::thread::JoinHandle<u64>, CameraError> {
    if !Path::new(dev).exists() {
        let list = list_devices();
        return Err(CameraError::NoDevice {
            dev: dev.to_string(),
            available: if list.is_empty() {
                "none".to_string()
            } else {
                list.iter()
                    .map(|(d, n)| format!("{d} ({n})"))
                    .collect::<Vec<_>>()
                    .join(", ")
            },
        });
    }
    let offered = offered_formats(dev)?;
    let fmt = negotiate(&offered, req.size, req.pixel).ok_or_else(|| CameraError::NoFormat {
        dev: dev.to_string(),
        wanted: format!("{req:?}"),
        offered: format!("{offered:?}"),
    })?;
    crate::stderr_line(format_args!(
        "camera {dev}: {:?} {}×{} at {fps} fps",
        fmt.pixel, fmt.width, fmt.height
    ));
    let dev = dev.to_string();
    Ok(std::thread::spawn(move || {
        let mut k = 0u64;
        while !stop.load(Ordering::Relaxed) && k < max {
            match capture_once(&dev, fmt, fps, &queue, &stop, clock, &mut k, max) {
                Ok(()) if stop.load(Ordering::Relaxed) || k >= max => break,
                Ok(()) => crate::stderr_line(format_args!(
                    "warning: camera {dev} stopped sending; re-opening"
                )),
                Err(e) => {
                    crate::stderr_line(format_args!("warning: camera {dev}: {e}; re-opening"))
                }
            }
            std::thread::sleep(Duration::from_secs(1));
        }
        queue.close();
        k
    }))
}

#[allow(
    clippy::too_many_arguments,
    reason = "the capture loop's whole state, passed once per (re)open"
)]
fn capture_once(
    dev: &str,
    fmt: CameraFormat,
    fps: f64,
    queue: &LatestQueue<Captured>,
    stop: &AtomicBool,
    clock: Instant,
    k: &mut u64,
    max: u64,
) -> Result<(), CameraError> {
    let (input, output) = match fmt.pixel {
        PixelFormat::Mjpeg => ("mjpeg", "mjpeg"),
        PixelFormat::Yuyv => ("yuyv422", "rawvideo"),
    };
    let size = format!("{}x{}", fmt.width, fmt.height);
    let mut child = Command::new("ffmpeg")
        .args([
            "-hide_banner",
            "-loglevel",
            "error",
            "-f",
            "v4l2",
            "-input_format",
            input,
        ])
        .args([
            "-video_size",
            &size,
            "-framerate",
            &format!("{fps}"),
            "-i",
            dev,
        ])
        .args(["-c:v", "copy", "-f", output, "-"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .map_err(CameraError::Ffmpeg)?;
    let Some(mut out) = child.stdout.take() else {
        return Err(CameraError::Frame("ffmpeg gave no output".to_string()));
    };
    let mut split = MjpegSplitter::default();
    let frame_len = fmt.width * fmt.height * 2;
    let mut raw = Vec::with_capacity(frame_len);
    let mut buf = vec![0u8; 1 << 16];
    let push = |img: RgbImage, k: &mut u64| {
        let captured = Instant::now();
        queue.push(Captured {
            id: format!("{}#{k}", dev.rsplit('/').next().unwrap_or(dev)),
            index: *k,
            timestamp_s: (captured - clock).as_secs_f64(),
            captured,
            image: Arc::new(img),
        });
        *k += 1;
    };
    while !stop.load(Ordering::Relaxed) && *k < max {
        let n = out.read(&mut buf)?;
        if n == 0 {
            break;
        }
        match fmt.pixel {
            PixelFormat::Mjpeg => {
                for jpeg in split.push(&buf[..n]) {
                    match rgb_from_mjpeg(&jpeg) {
                        Ok(img) => push(img, k),
                        Err(e) => crate::stderr_line(format_args!(
                            "warning: camera {dev}: {e}; frame skipped"
                        )),
                    }
                }
            }
            PixelFormat::Yuyv => {
                let mut rest = &buf[..n];
                while !rest.is_empty() {
                    let take = (frame_len - raw.len()).min(rest.len());
                    raw.extend_from_slice(&rest[..take]);
                    rest = &rest[take..];
                    if raw.len() == frame_len {
                        push(rgb_from_yuyv(&raw, fmt.width, fmt.height)?, k);
                        raw.clear();
                    }
                }
            }
        }
    }
    let _ = child.kill();
    let _ = child.wait();
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What ffmpeg 5–7 prints for a UVC webcam like seed 001's.
    const LISTING: &str = "\
[video4linux2,v4l2 @ 0x55] Compressed:       mjpeg :          Motion-JPEG : 1280x720 640x480 320x240
[video4linux2,v4l2 @ 0x55] Raw       :     yuyv422 :           YUYV 4:2:2 : 640x480 320x240 1280x720
[video4linux2,v4l2 @ 0x55] Raw       :        nv12 :         Y/CbCr 4:2:0 : 640x480
/dev/video0: Immediate exit requested";

    #[test]
    fn formats_are_parsed_and_negotiated() {
        let f = parse_formats(LISTING);
        assert_eq!(f.len(), 6);
        let want = |p, w, h| CameraFormat {
            pixel: p,
            width: w,
            height: h,
        };
        // Default: the largest up to 640×480, MJPEG first.
        assert_eq!(
            negotiate(&f, None, None),
            Some(want(PixelFormat::Mjpeg, 640, 480))
        );
        assert_eq!(
            negotiate(&f, Some((1280, 720)), Some(PixelFormat::Yuyv)),
            Some(want(PixelFormat::Yuyv, 1280, 720))
        );
        assert_eq!(negotiate(&f, Some((800, 600)), None), None);
        assert_eq!(negotiate(&parse_formats("no camera"), None, None), None);
        let r = CameraRequest::parse(Some("1280x720"), Some("yuyv")).unwrap();
        assert_eq!(
            negotiate(&f, r.size, r.pixel),
            Some(want(PixelFormat::Yuyv, 1280, 720))
        );
        assert!(CameraRequest::parse(Some("1280"), None).is_err());
        assert!(CameraRequest::parse(None, Some("h264")).is_err());
    }

    #[test]
    fn yuyv_buffers_decode_to_known_colours() {
        // Pairs: black (16,128,128), white (235,128,128), BT.601 red (81,90,240), grey 128.
        let buf = [
            16, 128, 235, 128, // black, white (shared U, V)
            81, 90, 81, 240, // red, red
        ];
        let img = rgb_from_yuyv(&buf, 2, 2).unwrap();
        assert_eq!(img.get(0, 0), [0, 0, 0]);
        assert_eq!(img.get(1, 0), [255, 255, 255]);
        let r = img.get(0, 1);
        assert!(r[0] >= 253 && r[1] <= 2 && r[2] <= 2, "{r:?}");
        assert!(rgb_from_yuyv(&buf[..6], 2, 2).is_err());
        assert!(rgb_from_yuyv(&buf, 1, 4).is_err());
    }

    #[test]
    fn mjpeg_streams_split_and_decode() {
        // Two 8×8 JPEGs, fed in awkward pieces.
        let jpeg = |v: u8| {
            let mut out = Vec::new();
            let enc = image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 95);
            image::ImageEncoder::write_image(
                enc,
                &[v; 8 * 8 * 3],
                8,
                8,
                image::ExtendedColorType::Rgb8,
            )
            .unwrap();
            out
        };
        let (a, b) = (jpeg(40), jpeg(200));
        let stream: Vec<u8> = [&a[..], &b[..]].concat();
        let mut s = MjpegSplitter::default();
        let mut frames = Vec::new();
        for piece in stream.chunks(7) {
            frames.extend(s.push(piece));
        }
        assert_eq!(frames, vec![a.clone(), b.clone()]);
        let img = rgb_from_mjpeg(&frames[1]).unwrap();
        assert_eq!((img.width(), img.height()), (8, 8));
        assert!(img.get(4, 4)[0].abs_diff(200) <= 3);
        assert!(rgb_from_mjpeg(&a[..a.len() / 2]).is_err());
    }
}
