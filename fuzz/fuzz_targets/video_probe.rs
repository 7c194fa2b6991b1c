//! A video's `ffprobe` answer: read into a frame size, rate and count or refused naming the
//! file, never a panic; a size that is accepted fits the per-frame pixel limit (a probe of
//! 2^32 × 2^32 wrapped the frame size) and the rate is a positive number.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use visuotact_io::frames::video_info_from_probe;
use visuotact_io::read::MAX_IMAGE_PIXELS;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    match video_info_from_probe(Path::new("fuzzed.mp4"), &text, "") {
        Ok(v) => {
            assert!(v.width > 0 && v.height > 0);
            assert!((v.width as u64) * (v.height as u64) <= MAX_IMAGE_PIXELS);
            assert!(v.fps.is_finite() && v.fps > 0.0, "{}", v.fps);
        }
        Err(e) => assert!(e.to_string().contains("fuzzed.mp4"), "{e}"),
    }
});
