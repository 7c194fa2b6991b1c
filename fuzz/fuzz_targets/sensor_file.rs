//! A sensor file: loaded or refused with the file's name, never a panic; one that loads builds
//! a feature extractor or says why, and that extractor takes a frame of the file's size.
#![no_main]

use libfuzzer_sys::fuzz_target;
use visuotact_image::RgbImage;
use visuotact_vision::calibration::SensorCalibration;
use visuotact_vision::features::FeatureExtractor;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    match SensorCalibration::from_json(&text, "fuzzed.json") {
        Ok(cal) => {
            let (w, h) = (cal.image_width, cal.image_height);
            let features = cal.features;
            if let Ok(mut ex) = FeatureExtractor::new(cal, features) {
                // A frame only where it is small enough to make every run fast.
                if w * h <= 640 * 480 {
                    let frame = RgbImage::new(w, h);
                    let _ = ex.extract(&frame);
                }
            }
        }
        Err(e) => assert!(e.to_string().contains("fuzzed.json"), "{e}"),
    }
});
