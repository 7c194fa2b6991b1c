//! A raw YUYV frame of any length for a claimed size: an image of that size or an error.
#![no_main]

use libfuzzer_sys::fuzz_target;
use visuotact_io::camera::rgb_from_yuyv;

fuzz_target!(|data: &[u8]| {
    let [w, h, rest @ ..] = data else {
        return;
    };
    let (w, h) = (usize::from(*w), usize::from(*h));
    if let Ok(img) = rgb_from_yuyv(rest, w, h) {
        assert_eq!((img.width(), img.height()), (w, h));
    }
});
