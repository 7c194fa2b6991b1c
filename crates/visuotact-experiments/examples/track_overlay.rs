//! Debug: track one frame with a sensor file and write a CSV per marker (status, position, the
//! reference position) and per blob, for drawing an overlay.
//! Usage: track_overlay SENSOR.json FRAME.png OUT_PREFIX
use std::fmt::Write as _;
use std::path::Path;
use visuotact_vision::calibration::SensorCalibration;
use visuotact_vision::features::{FeatureExtractor, FeatureSet, FrameFeatures};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let cal = SensorCalibration::from_json(&std::fs::read_to_string(&args[1]).unwrap(), &args[1])
        .unwrap();
    let mut fx = FeatureExtractor::new(cal.clone(), FeatureSet::default()).unwrap();
    let mut out = FrameFeatures::default();
    let frame = visuotact_io::frames::read_image(Path::new(&args[2])).unwrap();
    fx.extract_into(&frame, &mut out).unwrap();
    let t = fx.last_track();
    let blobs = fx.last_blobs();
    let mut m = String::from("id,status,x,y,ref_x,ref_y\n");
    for (k, r) in cal.markers.iter().enumerate() {
        let p = t.position_px(k, blobs).unwrap_or((f64::NAN, f64::NAN));
        writeln!(
            m,
            "{k},{},{:.2},{:.2},{:.2},{:.2}",
            t.status[k].name(),
            p.0,
            p.1,
            r.x_px + t.shift_px.0,
            r.y_px + t.shift_px.1
        )
        .unwrap();
    }
    std::fs::write(format!("{}_markers.csv", args[3]), m).unwrap();
    let mut owner = vec![None; blobs.len()];
    for (k, a) in t.assignment.iter().enumerate() {
        if let Some(j) = a {
            owner[*j] = Some(k);
        }
    }
    let mut b = String::from("x,y,area,owner\n");
    for (j, bl) in blobs.iter().enumerate() {
        writeln!(
            b,
            "{:.2},{:.2},{},{}",
            bl.x_px,
            bl.y_px,
            bl.area_px,
            owner[j].map_or(-1, |k| k as i64)
        )
        .unwrap();
    }
    std::fs::write(format!("{}_blobs.csv", args[3]), b).unwrap();
}
