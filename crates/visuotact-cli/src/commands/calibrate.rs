//! `visuotact calibrate`: still frames (or a data set's lightest frames) → sensor.json.

use std::path::PathBuf;

use anyhow::bail;
use visuotact_io::frames::FrameStream;
use visuotact_pipeline::calibrate::{
    calibrate_frames, CalibrateError, Calibrated, ReferenceSource,
};
use visuotact_vision::calibration::CalibrationConfig;
use visuotact_vision::features::FeatureSet;
use visuotact_vision::layout::LayoutChoice;
use visuotact_vision::options::Purpose;
use visuotact_vision::track::TrackParams;

use crate::progress::Reporter;

use crate::args::DetectorArgs;

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Still no-contact frames: image files, folders of images (natural order: image_2 before
    /// image_10), or a video. With `--reference lightest:N`, a whole data set.
    #[arg(required = true)]
    frames: Vec<PathBuf>,
    /// Sensor file to write.
    #[arg(short, long)]
    output: PathBuf,
    /// Use only the first N frames.
    #[arg(long, value_name = "N")]
    first: Option<usize>,
    #[command(flatten)]
    detector: DetectorArgs,
    /// Marker layout: auto (recognised: concentric annuli, rectangular grid, hexagonal/staggered
    /// array, rings of dots, irregular pattern), or one of grid, hex, dot-rings, irregular,
    /// rings, refused when it does not fit the markers.
    #[arg(long, default_value = "auto", value_parser = crate::args::choice::<LayoutChoice>(LayoutChoice::NAMES))]
    layout: LayoutChoice,
    /// Where the reference comes from: `still` (the mean of the frames given, which must be
    /// free of contact) or `lightest:N` (the N frames of the data set with the smallest
    /// deformation, for data sets with no contact-free frame; the sensor file says so).
    #[arg(long, default_value = "still", value_name = "still|lightest:N")]
    reference: String,
    /// Default feature set for `extract`: a list of x, y, area, ecc (default: the preset's).
    #[arg(long)]
    features: Option<String>,
    /// The distance between neighbouring markers on the skin, millimetres (the nearest
    /// neighbours; for annuli, the gap between ring radii): the sensor file stores millimetres
    /// per pixel, and feature tables carry displacements in mm beside px (docs/calibration.md).
    #[arg(long, value_name = "MM")]
    pitch_mm: Option<f64>,
    /// No progress lines while ranking a data set's frames (by default one every 2 s on
    /// stderr, also when it is not a terminal).
    #[arg(long, short)]
    quiet: bool,
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    if a.first == Some(0) {
        bail!("--first must be at least 1");
    }
    if let Some(p) = a.pitch_mm {
        if !(p.is_finite() && p > 0.0) {
            bail!("--pitch-mm {p}: expected the distance between neighbouring markers, a positive number of millimetres");
        }
    }
    let inputs: Vec<&std::path::Path> = a.frames.iter().map(PathBuf::as_path).collect();
    visuotact_io::guard::refuse_output_over_input(&a.output, &inputs)?;
    let open = || {
        let s = FrameStream::open(&a.frames, 25.0)?;
        Ok(match a.first {
            Some(n) => s.take_first(n),
            None => s,
        })
    };
    // Grey-level centroids: the partly covered edge pixels any threshold cuts off carry the
    // sub-pixel position (on the sensor zoo 5–10× less displacement error than the pixel mean).
    // Thin annuli (the cone preset) are steadiest with the grey-weighted centroid.
    let (detector, preset_features, size) =
        a.detector.config_for_frames(Purpose::Tracking, || {
            open().ok()?.next()?.ok().map(|f| f.image)
        })?;
    let features = match &a.features {
        Some(f) => FeatureSet::parse(f).map_err(|e| anyhow::anyhow!("--features: {e}"))?,
        None => preset_features,
    };
    let layout = a.layout;
    let source =
        ReferenceSource::parse(&a.reference).map_err(|e| anyhow::anyhow!("--reference: {e}"))?;
    let cfg = CalibrationConfig {
        detector,
        layout,
        features,
        track: TrackParams::DEFAULT,
    };
    if let Some(size) = &size {
        note!("{}", size.in_words(&cfg.detector));
    }
    // Only the ranking of a data set's frames is long enough to report (and to catch Ctrl-C).
    let reporter = matches!(source, ReferenceSource::Lightest(_)).then(|| {
        let r = Reporter::new(a.quiet);
        r.stage("ranking the frames by deformation");
        r
    });
    let mut progress = |done, total| {
        reporter
            .as_ref()
            .map_or(std::ops::ControlFlow::Continue(()), |r| {
                r.items(done, total, "frames")
            })
    };
    let mut done = calibrate_frames(open, source, &cfg, &mut progress).map_err(|e| match e {
        CalibrateError::Stopped { frames } => anyhow::anyhow!(
            "interrupted (Ctrl-C) after ranking {frames} frames: {} not written",
            a.output.display()
        ),
        e => e.into(),
    })?;
    done.calibration.marker_size = size;
    if let Some(p) = a.pitch_mm {
        done.calibration
            .set_pitch_mm(p)
            .map_err(|e| anyhow::anyhow!("--pitch-mm: {e}"))?;
    }
    write_sensor(a, &done.calibration)?;
    print_calibrated(&done);
    note!("wrote {}", a.output.display());
    Ok(())
}

/// What calibration found, for the user: the layout, the reference, the markers' jitter and
/// what was missing.
fn print_calibrated(done: &Calibrated) {
    let Calibrated {
        calibration: cal,
        report,
        selection,
        frames,
    } = done;
    let level = report
        .level
        .map_or("adaptive".to_string(), |t| format!("{t}"));
    let shape = cal.layout_in_words();
    note!(
        "calibrated {} markers ({}: {shape}, pitch {:.1} px) from {} frames of {}×{}; threshold {level}; {} blobs, {} off the layout",
        cal.markers.len(),
        cal.layout.name(),
        cal.pitch_px,
        frames,
        cal.image_width,
        cal.image_height,
        report.raw_blobs,
        report.off_grid.len()
    );
    if !cal.unnumbered.is_empty() {
        note!(
            "{} of those off the layout lie where pins of the array can be (a seam the numbering skipped): tracking follows them, never reports them",
            cal.unnumbered.len()
        );
    }
    if let Some(s) = cal.scale {
        note!(
            "scale: {:.5} mm per px (pitch {} mm over {:.2} px): feature tables carry displacements in mm beside px",
            s.mm_per_px,
            s.pitch_mm,
            cal.pitch_px
        );
    }
    if let Some(sel) = &selection {
        let note = if cal.reference.under_contact {
            " — taken under contact: features are relative to a lightly pressed skin"
        } else {
            ""
        };
        note!("reference from {}{note}", sel.in_words());
    }
    let mut jitter: Vec<f64> = cal.markers.iter().filter_map(|m| m.jitter_px).collect();
    jitter.sort_by(f64::total_cmp);
    if let Some(&worst) = jitter.last() {
        let median = jitter[jitter.len() / 2];
        note!(
            "marker jitter over the calibration frames: median {median:.3} px, worst {worst:.3} px"
        );
        if median > 0.5 && selection.is_none() {
            note!("warning: the calibration frames differ by {median:.2} px at the median marker: were they still and free of contact? (--reference lightest:N for a data set with none)");
        }
    }
    let never = cal.markers.iter().filter(|m| m.jitter_px.is_none()).count();
    if never > 0 {
        note!("warning: {never} markers were not matched in any single calibration frame (only in their mean)");
    }
    for (id, n) in report.missing_per_frame.iter().take(10) {
        note!("warning: frame {id}: {n} markers not found in this still frame");
    }
}

fn write_sensor(
    a: &Args,
    cal: &visuotact_vision::calibration::SensorCalibration,
) -> anyhow::Result<()> {
    crate::write_atomically(&a.output, &cal.to_json())
}
