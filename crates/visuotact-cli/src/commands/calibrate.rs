//! `visuotact calibrate`: still frames (or a data set's lightest frames) → sensor.json.

use std::path::PathBuf;

use anyhow::{bail, Context};
use visuotact_io::frames::FrameStream;
use visuotact_vision::calibration::{calibrate, CalibrationConfig, LightestFinder};
use visuotact_vision::features::FeatureSet;
use visuotact_vision::layout::{Layout, LayoutChoice};
use visuotact_vision::track::TrackConfig;

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
    #[arg(long, default_value = "auto", value_parser = ["auto", "grid", "hex", "dot-rings", "irregular", "rings"])]
    layout: String,
    /// Where the reference comes from: `still` (the mean of the frames given, which must be
    /// free of contact) or `lightest:N` (the N frames of the data set with the smallest
    /// deformation, for data sets with no contact-free frame; the sensor file says so).
    #[arg(long, default_value = "still", value_name = "still|lightest:N")]
    reference: String,
    /// Default feature set for `extract`: a list of x, y, area, ecc (default: the preset's).
    #[arg(long)]
    features: Option<String>,
}

/// Where the reference comes from.
enum ReferenceSource {
    Still,
    Lightest(usize),
}

fn reference_source(s: &str) -> anyhow::Result<ReferenceSource> {
    if s == "still" {
        return Ok(ReferenceSource::Still);
    }
    match s.strip_prefix("lightest:").map(str::parse::<usize>) {
        Some(Ok(n)) if n > 0 => Ok(ReferenceSource::Lightest(n)),
        _ => bail!("--reference {s:?}: expected still or lightest:N with N ≥ 1"),
    }
}

fn open_frames(a: &Args) -> anyhow::Result<FrameStream> {
    let mut stream = FrameStream::open(&a.frames, 25.0)?;
    if let Some(n) = a.first {
        if n == 0 {
            bail!("--first must be at least 1");
        }
        stream = stream.take_first(n);
    }
    Ok(stream)
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    // Grey-level centroids: the partly covered edge pixels any threshold cuts off carry the
    // sub-pixel position (on the sensor zoo 5–10× less displacement error than the pixel mean).
    // Thin annuli (the cone preset) are steadiest with the grey-weighted centroid.
    let (detector, preset_features) = a
        .detector
        .config_for_frames(None, || open_frames(a).ok()?.next()?.ok().map(|f| f.image))?;
    let features = match &a.features {
        Some(f) => FeatureSet::parse(f).map_err(|e| anyhow::anyhow!("--features: {e}"))?,
        None => preset_features,
    };
    let layout = LayoutChoice::parse(&a.layout).map_err(anyhow::Error::msg)?;
    let source = reference_source(&a.reference)?;
    let cfg = CalibrationConfig {
        detector,
        layout,
        features,
        track: TrackConfig::DEFAULT,
    };
    let open = || open_frames(a);
    let (frames, selection) = match source {
        ReferenceSource::Still => {
            let mut frames = Vec::new();
            for f in open()? {
                // A calibration built from a partial set would be silently different: any
                // unreadable frame stops it.
                frames.push(f.context("calibration frames must all be readable")?);
            }
            (frames, None)
        }
        ReferenceSource::Lightest(n) => {
            // Pass 1 keeps only each frame's blobs; pass 2 reads the chosen frames again.
            let mut finder = LightestFinder::new(&cfg)?;
            for f in open()? {
                let f = f.context("every frame must be readable to rank them")?;
                finder.add(&f.id, &f.image)?;
            }
            let sel = finder.choose(n)?;
            let mut frames = Vec::with_capacity(n);
            for f in open()? {
                let f = f.context("calibration frames must all be readable")?;
                if sel.chosen.contains(&f.id) {
                    frames.push(f);
                }
            }
            (frames, Some(sel))
        }
    };
    if frames.is_empty() {
        bail!("no frames could be read");
    }
    let (mut cal, report) = calibrate(frames.iter().map(|f| (f.id.as_str(), &f.image)), &cfg)?;
    if let Some(sel) = &selection {
        cal.reference = sel.reference_info();
    }
    write_sensor(a, &cal)?;
    let level = report
        .level
        .map_or("adaptive".to_string(), |t| format!("{t}"));
    let shape = match cal.layout {
        Layout::Rings => format!("{} concentric rings", cal.markers.len()),
        Layout::Irregular => "irregular pattern".to_string(),
        Layout::DotRings => format!("{} rings of dots", cal.grid_rows),
        Layout::Hex => format!("hexagonal, {} rows", cal.grid_rows),
        Layout::Grid => format!("{} rows × {} columns", cal.grid_rows, cal.grid_cols),
    };
    eprintln!(
        "calibrated {} markers ({}: {shape}, pitch {:.1} px) from {} frames of {}×{}; threshold {level}; {} blobs, {} off the layout",
        cal.markers.len(),
        cal.layout.name(),
        cal.pitch_px,
        frames.len(),
        cal.image_width,
        cal.image_height,
        report.raw_blobs,
        report.off_grid.len()
    );
    if let Some(sel) = &selection {
        eprintln!(
            "reference from the {} lightest of {} frames ({} usable): their deformation {:.3}–{:.3} px RMS (median frame {:.3} px); residual motion of the reference {:.3} px RMS, {:.3} px at worst{}",
            sel.chosen.len(),
            sel.considered,
            sel.usable,
            sel.deformation_px.first().copied().unwrap_or(0.0),
            sel.deformation_px.last().copied().unwrap_or(0.0),
            sel.median_deformation_px,
            sel.residual_px,
            sel.residual_max_px,
            if cal.reference.under_contact {
                " — taken under contact: features are relative to a lightly pressed skin"
            } else {
                ""
            }
        );
    }
    let mut jitter: Vec<f64> = cal.markers.iter().filter_map(|m| m.jitter_px).collect();
    jitter.sort_by(f64::total_cmp);
    if let Some(&worst) = jitter.last() {
        eprintln!(
            "marker jitter over the calibration frames: median {:.3} px, worst {:.3} px",
            jitter[jitter.len() / 2],
            worst
        );
    }
    let never = cal.markers.iter().filter(|m| m.jitter_px.is_none()).count();
    if never > 0 {
        eprintln!("warning: {never} markers were not matched in any single calibration frame (only in their mean)");
    }
    for (id, n) in report.missing_per_frame.iter().take(10) {
        eprintln!("warning: frame {id}: {n} markers not found in this still frame");
    }
    eprintln!("wrote {}", a.output.display());
    Ok(())
}

fn write_sensor(
    a: &Args,
    cal: &visuotact_vision::calibration::SensorCalibration,
) -> anyhow::Result<()> {
    crate::write_atomically(&a.output, &cal.to_json())
}
