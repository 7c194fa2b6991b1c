//! Debug: track a folder with a sensor file; per frame, markers without a position split into
//! the outer ring (reference radius over 85 % of the layout's) and the inside.
use std::path::Path;
use visuotact_vision::calibration::SensorCalibration;
use visuotact_vision::features::{FeatureExtractor, FeatureSet, FrameFeatures};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let cal = SensorCalibration::from_json(&std::fs::read_to_string(&args[1]).unwrap(), &args[1])
        .unwrap();
    let n = cal.markers.len() as f64;
    let c = cal
        .markers
        .iter()
        .fold((0.0, 0.0), |a, m| (a.0 + m.x_px / n, a.1 + m.y_px / n));
    let r = |m: &visuotact_vision::calibration::ReferenceMarker| (m.x_px - c.0).hypot(m.y_px - c.1);
    let rmax = cal.markers.iter().map(r).fold(0.0, f64::max);
    let mut fx = FeatureExtractor::new(cal.clone(), FeatureSet::default()).unwrap();
    let mut out = FrameFeatures::default();
    let (mut outer, mut inner, mut frames) = (0, 0, 0);
    let mut entries: Vec<_> = std::fs::read_dir(&args[2])
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for p in entries
        .iter()
        .take(args.get(3).map_or(usize::MAX, |s| s.parse().unwrap()))
    {
        let frame = visuotact_io::frames::read_image(Path::new(p)).unwrap();
        fx.extract_into(&frame, &mut out).unwrap();
        let t = fx.last_track();
        let (mut o, mut i) = (0, 0);
        for (k, m) in cal.markers.iter().enumerate() {
            if !t.status[k].has_position() {
                if r(m) > 0.85 * rmax {
                    o += 1
                } else {
                    i += 1
                }
            }
        }
        if o + i > 0 && args.len() > 4 {
            println!("{} outer {o} inner {i}", p.display());
        }
        outer += o;
        inner += i;
        frames += 1;
    }
    println!(
        "frames {frames}: missing outer {outer} inner {inner} of {} pin-frames",
        frames * cal.markers.len()
    );
}
