//! The feature table's columns, as `extract`, `record` and the Python package write them: a
//! frame id, the [`LEAD_COLUMNS`], the markers' features (then the field summary), and a
//! `flags` cell naming the markers not found (`m012:lost;m013:merged`).

use visuotact_vision::blobs::{Blob, MomentConvention};
use visuotact_vision::features::{FrameFeatures, MmColumns};
use visuotact_vision::track::MarkerStatus;

/// Leading columns before the per-marker features.
pub const LEAD_COLUMNS: [&str; 6] = [
    "timestamp_s",
    "n_found",
    "n_markers",
    "n_spurious",
    "shift_x_px",
    "shift_y_px",
];

/// The feature table's header after the frame column: the [`LEAD_COLUMNS`], then `features`
/// (the feature vector's, in pixels), then their millimetre twins `mm` (none for a sensor
/// without a scale).
pub fn feature_columns(features: &[String], mm: &MmColumns) -> Vec<String> {
    LEAD_COLUMNS
        .iter()
        .map(|s| s.to_string())
        .chain(features.iter().cloned())
        .chain(mm.names().iter().cloned())
        .collect()
}

/// One feature-table row into `row`: the [`LEAD_COLUMNS`] values, the marker features, then
/// their millimetre twins `mm`.
pub fn feature_row_into(
    row: &mut Vec<f64>,
    timestamp_s: f64,
    n_markers: usize,
    f: &FrameFeatures,
    mm: &MmColumns,
) {
    row.clear();
    row.extend_from_slice(&[
        timestamp_s,
        f.found as f64,
        n_markers as f64,
        f.spurious as f64,
        f.shift_px.0,
        f.shift_px.1,
    ]);
    row.extend_from_slice(&f.values);
    mm.values_into(&f.values, row);
}

/// A short account of the markers not found in a frame: counts by status, then the first few
/// marker ids (`2 lost, 1 merged: m012 m013 m025`; `… +7` when there are more).
pub fn missing_summary(f: &FrameFeatures) -> String {
    const SHOWN: usize = 4;
    let counts: Vec<String> = MarkerStatus::ALL
        .iter()
        .filter(|&&s| s != MarkerStatus::Ok)
        .filter_map(|&s| {
            let n = f.status.iter().filter(|&&x| x == s).count();
            (n > 0).then(|| format!("{n} {}", s.name()))
        })
        .collect();
    let ids: Vec<usize> = f
        .status
        .iter()
        .enumerate()
        .filter(|(_, s)| **s != MarkerStatus::Ok)
        .map(|(i, _)| i)
        .collect();
    let mut shown: Vec<String> = ids.iter().take(SHOWN).map(|i| format!("m{i:03}")).collect();
    if ids.len() > SHOWN {
        shown.push(format!("… +{}", ids.len() - SHOWN));
    }
    format!("{}: {}", counts.join(", "), shown.join(" "))
}

/// The `flags` cell of a frame's row: each marker not found, `m012:lost;m013:merged`.
pub fn flags_of(f: &FrameFeatures) -> String {
    f.status
        .iter()
        .enumerate()
        .filter(|(_, s)| **s != MarkerStatus::Ok)
        .map(|(i, s)| format!("m{i:03}:{}", s.name()))
        .collect::<Vec<_>>()
        .join(";")
}

/// The blob table's columns after the frame column (`visuotact blobs`): one row per blob.
pub const BLOB_COLUMNS: [&str; 15] = [
    "blob",
    "area_px",
    "x_px",
    "y_px",
    "eccentricity",
    "major_axis_px",
    "minor_axis_px",
    "orientation_rad",
    "bbox_x",
    "bbox_y",
    "bbox_w",
    "bbox_h",
    "touches_border",
    "level",
    "timestamp_s",
];

/// Blob `k`'s row of the blob table ([`BLOB_COLUMNS`]), its shape in `conv`; `level` is the
/// frame's threshold (NaN for adaptive thresholds).
pub fn blob_row(
    k: usize,
    b: &Blob,
    conv: MomentConvention,
    level: f64,
    timestamp_s: f64,
) -> [f64; 15] {
    let s = b.shape(conv);
    [
        k as f64,
        f64::from(b.area_px),
        b.x_px,
        b.y_px,
        s.eccentricity,
        s.major_axis_px,
        s.minor_axis_px,
        s.orientation_rad,
        f64::from(b.bbox.x0),
        f64::from(b.bbox.y0),
        f64::from(b.bbox.x1 - b.bbox.x0),
        f64::from(b.bbox.y1 - b.bbox.y0),
        f64::from(u8::from(b.touches_border)),
        level,
        timestamp_s,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_and_summary_name_the_missing_markers() {
        let mut f = FrameFeatures {
            status: vec![MarkerStatus::Ok; 8],
            ..FrameFeatures::default()
        };
        assert_eq!(flags_of(&f), "");
        f.status[2] = MarkerStatus::Lost;
        f.status[5] = MarkerStatus::Merged;
        assert_eq!(flags_of(&f), "m002:lost;m005:merged");
        assert_eq!(missing_summary(&f), "1 lost, 1 merged: m002 m005");
        for s in &mut f.status {
            *s = MarkerStatus::Lost;
        }
        assert_eq!(missing_summary(&f), "8 lost: m000 m001 m002 m003 … +4");
        let mut row = Vec::new();
        f.found = 0;
        f.values = vec![1.5, -2.0];
        let none = MmColumns::default();
        feature_row_into(&mut row, 0.25, 8, &f, &none);
        assert_eq!(row, [0.25, 0.0, 8.0, 0.0, 0.0, 0.0, 1.5, -2.0]);
        assert_eq!(feature_columns(&["a".into()], &none).len(), 7);
        // A sensor at 0.5 mm/px: the displacement's twin follows the pixel columns.
        let cols = ["m000_dx_px".to_string(), "m000_decc".to_string()];
        let mm = MmColumns::new(&cols, 0.5);
        assert_eq!(
            feature_columns(&cols, &mm)[6..],
            ["m000_dx_px", "m000_decc", "m000_dx_mm"]
        );
        feature_row_into(&mut row, 0.25, 8, &f, &mm);
        assert_eq!(row[6..], [1.5, -2.0, 0.75]);
    }
}
