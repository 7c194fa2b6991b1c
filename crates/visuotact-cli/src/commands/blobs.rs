//! `visuotact blobs`: the raw detection, one row per blob (no calibration needed).

use std::path::PathBuf;

use anyhow::Context;
use visuotact_io::frames::FrameStream;
use visuotact_io::table::{TableFormat, TableWriter};
use visuotact_vision::blobs::MomentConvention;
use visuotact_vision::detect::Detector;

use crate::args::DetectorArgs;

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Frames: image files, folders of images, or videos.
    #[arg(required = true)]
    frames: Vec<PathBuf>,
    /// Output table (`-` for standard output); one row per blob, `frame` repeated.
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    detector: DetectorArgs,
    /// Shape convention: pixel (scikit-image, OpenCV) or matlab (regionprops, +1/12).
    #[arg(long, default_value = "pixel", value_parser = ["pixel", "matlab"])]
    moments: String,
    /// Table format: csv or jsonl.
    #[arg(long, default_value = "csv", value_parser = ["csv", "jsonl"])]
    format: String,
}

const COLUMNS: [&str; 15] = [
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

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    // The pixel-mean centroid of OpenCV, scikit-image and MATLAB regionprops by default.
    let (cfg, _) =
        a.detector
            .config_for_frames(Some(visuotact_vision::detect::Centroid::Binary), || {
                FrameStream::open(&a.frames, 25.0)
                    .ok()?
                    .next()?
                    .ok()
                    .map(|f| f.image)
            })?;
    let mut det = Detector::new(cfg).map_err(anyhow::Error::msg)?;
    let conv = if a.moments == "matlab" {
        MomentConvention::Matlab
    } else {
        MomentConvention::Pixel
    };
    let mut out = TableWriter::create(
        &a.output,
        TableFormat::from_name(&a.format).unwrap_or_default(),
        COLUMNS.iter().map(|s| s.to_string()).collect(),
    )
    .with_context(|| format!("{}: cannot create output", a.output.display()))?;
    let (mut frames, mut blobs_total, mut skipped) = (0usize, 0usize, 0usize);
    let mut blobs = Vec::new();
    for item in FrameStream::open(&a.frames, 25.0)? {
        let f = match item {
            Ok(f) => f,
            Err(e) => {
                eprintln!("warning: {e}; skipped");
                skipped += 1;
                continue;
            }
        };
        let d = det.detect_into(&f.image, &mut blobs);
        let level = d.level.map_or(f64::NAN, f64::from);
        for (k, b) in blobs.iter().enumerate() {
            let s = b.shape(conv);
            let row = [
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
                f.timestamp_s,
            ];
            out.write_row(&f.id, &row, "")
                .with_context(|| format!("{}: write failed", a.output.display()))?;
        }
        frames += 1;
        blobs_total += blobs.len();
    }
    eprintln!("{frames} frames, {blobs_total} blobs, {skipped} frames skipped");
    if frames == 0 {
        anyhow::bail!("no frame could be read");
    }
    Ok(())
}
