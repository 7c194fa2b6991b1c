//! The V4L2 format listing (`v4l2-ctl --list-formats-ext` / ffmpeg's): sizes out are sane.
#![no_main]

use libfuzzer_sys::fuzz_target;
use visuotact_io::camera::parse_formats;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    for f in parse_formats(&text) {
        assert!((1..=16384).contains(&f.width) && (1..=16384).contains(&f.height));
    }
});
