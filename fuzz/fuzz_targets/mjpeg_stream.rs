//! A camera's MJPEG byte stream, cut into reads anywhere: frames out are whole JPEG spans,
//! decoding them is a value or an error, and the splitter never panics.
#![no_main]

use libfuzzer_sys::fuzz_target;
use visuotact_io::camera::{rgb_from_mjpeg, MjpegSplitter};

fuzz_target!(|data: &[u8]| {
    let mut s = MjpegSplitter::default();
    let mut rest = data;
    while let Some((&n, tail)) = rest.split_first() {
        let take = (usize::from(n) + 1).min(tail.len());
        for f in s.push(&tail[..take]) {
            assert!(f.len() >= 4);
            assert_eq!(&f[..2], &[0xFF, 0xD8]);
            assert_eq!(&f[f.len() - 2..], &[0xFF, 0xD9]);
            let _ = rgb_from_mjpeg(&f);
        }
        rest = &tail[take..];
    }
    // A whole input as one JPEG.
    let _ = rgb_from_mjpeg(data);
});
