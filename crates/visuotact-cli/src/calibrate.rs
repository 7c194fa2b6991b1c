//! `visuotact calibrate`: still frames → sensor.json.

use std::path::PathBuf;

use anyhow::{bail, Context};
use visuotact_io::frames::FrameStream;
use visuotact_vision::blobs::Connectivity;
use visuotact_vision::calibration::calibrate;
use visuotact_vision::detect::{BlobFilter, Centroid, DetectorConfig};
use visuotact_vision::features::FeatureSet;
use visuotact_vision::grid::Layout;
use visuotact_vision::preprocess::{Channel, CircleMask, PreprocessConfig, Roi, Threshold};

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Still no-contact frames: image files, folders of images, or a video.
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
    /// How to number markers: grid (rows top to bottom, then columns) or rings (smallest first).
    /// Default: rings for the cone preset, grid otherwise.
    #[arg(long, value_parser = ["grid", "rings"])]
    layout: Option<String>,
    /// Default feature set for `extract`: a list of x, y, area, ecc (default: the preset's).
    #[arg(long)]
    features: Option<String>,
}

/// Preprocessing and blob-filter options shared by commands that detect markers.
#[derive(clap::Args, Debug, Clone)]
pub(crate) struct DetectorArgs {
    /// Starting settings: iats (green, open, Otsu), cone (luma, open, fixed 0.25),
    /// dark-markers (luma, inverted, open, adaptive).
    #[arg(long, default_value = "iats", value_parser = ["iats", "cone", "dark-markers"])]
    preset: String,
    /// Channel: green, luma601, mean, red, blue.
    #[arg(long)]
    channel: Option<String>,
    /// Invert the channel (dark markers on a bright background).
    #[arg(long, overrides_with = "no_invert")]
    invert: bool,
    /// Do not invert.
    #[arg(long)]
    no_invert: bool,
    /// Threshold: otsu, adaptive, or a fixed level in 0..1 of full scale.
    #[arg(long)]
    threshold: Option<String>,
    /// Adaptive threshold window, pixels (odd).
    #[arg(long, value_name = "PX")]
    window: Option<usize>,
    /// Adaptive threshold offset in 0..1 of full scale, subtracted from the local mean.
    #[arg(long, allow_hyphen_values = true)]
    offset: Option<f64>,
    /// Grey-level opening (removes bright specks).
    #[arg(long, overrides_with = "no_open")]
    open: bool,
    /// No opening.
    #[arg(long)]
    no_open: bool,
    /// Grey-level closing (fills dark specks).
    #[arg(long, overrides_with = "no_close")]
    close: bool,
    /// No closing.
    #[arg(long)]
    no_close: bool,
    /// Morphology window side, pixels (odd).
    #[arg(long, value_name = "PX")]
    morph_size: Option<usize>,
    /// Smallest marker area, pixels.
    #[arg(long, value_name = "PX")]
    min_area: Option<u32>,
    /// Largest marker area, pixels.
    #[arg(long, value_name = "PX")]
    max_area: Option<u32>,
    /// Keep blobs touching the image border (markers cut by the frame).
    #[arg(long)]
    keep_border: bool,
    /// Blob centroid: binary (pixel mean, as OpenCV) or weighted (by grey level above the
    /// threshold; the cone preset's default).
    #[arg(long, value_parser = ["binary", "weighted"])]
    centroid: Option<String>,
    /// Pixel connectivity: 8 or 4.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u8).range(4..=8))]
    connectivity: u8,
    /// Region of interest x,y,width,height in pixels.
    #[arg(long, value_name = "X,Y,W,H")]
    roi: Option<String>,
    /// Circular mask cx,cy,radius in pixels.
    #[arg(long, value_name = "CX,CY,R")]
    circle: Option<String>,
}

fn numbers(s: &str, n: usize, what: &str) -> anyhow::Result<Vec<f64>> {
    let v: Result<Vec<f64>, _> = s.split(',').map(|p| p.trim().parse::<f64>()).collect();
    match v {
        Ok(v) if v.len() == n && v.iter().all(|x| x.is_finite()) => Ok(v),
        _ => bail!("--{what} expects {n} comma-separated numbers, got {s:?}"),
    }
}

impl DetectorArgs {
    /// The detector configuration these options describe.
    pub(crate) fn config(&self) -> anyhow::Result<(DetectorConfig, FeatureSet)> {
        let (mut p, features) = match self.preset.as_str() {
            "cone" => (PreprocessConfig::CONE, FeatureSet::CONE),
            "dark-markers" => (PreprocessConfig::DARK_MARKERS, FeatureSet::IATS),
            _ => (PreprocessConfig::IATS, FeatureSet::IATS),
        };
        if let Some(c) = &self.channel {
            p.channel = Channel::from_name(c).with_context(|| {
                format!(
                    "--channel {c:?}: expected one of {}",
                    Channel::ALL.map(Channel::name).join(", ")
                )
            })?;
        }
        if self.invert {
            p.invert = true;
        }
        if self.no_invert {
            p.invert = false;
        }
        if self.open {
            p.open = true;
        }
        if self.no_open {
            p.open = false;
        }
        if self.close {
            p.close = true;
        }
        if self.no_close {
            p.close = false;
        }
        if let Some(k) = self.morph_size {
            p.morph_size = k;
        }
        let (def_window, def_offset) = match p.threshold {
            Threshold::Adaptive { window_px, offset } => (window_px, offset),
            _ => (31, -0.06),
        };
        if let Some(t) = &self.threshold {
            p.threshold = match t.as_str() {
                "otsu" => Threshold::Otsu,
                "adaptive" => Threshold::Adaptive {
                    window_px: def_window,
                    offset: def_offset,
                },
                other => match other.parse::<f64>() {
                    Ok(level) => Threshold::Fixed { level },
                    Err(_) => {
                        bail!("--threshold {other:?}: expected otsu, adaptive or a level in 0..1")
                    }
                },
            };
        }
        if let Threshold::Adaptive { window_px, offset } = &mut p.threshold {
            if let Some(wn) = self.window {
                *window_px = wn;
            }
            if let Some(o) = self.offset {
                *offset = o;
            }
        } else if self.window.is_some() || self.offset.is_some() {
            bail!("--window and --offset apply to --threshold adaptive only");
        }
        if let Some(r) = &self.roi {
            let v = numbers(r, 4, "roi")?;
            if v.iter().any(|x| *x < 0.0) || v[2] < 1.0 || v[3] < 1.0 {
                bail!("--roi {r:?}: expects a non-negative corner and a positive size");
            }
            p.roi = Some(Roi {
                x: v[0] as usize,
                y: v[1] as usize,
                width: v[2] as usize,
                height: v[3] as usize,
            });
        }
        if let Some(c) = &self.circle {
            let v = numbers(c, 3, "circle")?;
            p.circle = Some(CircleMask {
                cx_px: v[0],
                cy_px: v[1],
                radius_px: v[2],
            });
        }
        p.validate().map_err(anyhow::Error::msg)?;
        let mut filter = BlobFilter::DEFAULT;
        if let Some(a) = self.min_area {
            filter.min_area_px = a;
        }
        if let Some(a) = self.max_area {
            filter.max_area_px = a;
        }
        if filter.min_area_px > filter.max_area_px {
            bail!(
                "--min-area {} exceeds --max-area {}",
                filter.min_area_px,
                filter.max_area_px
            );
        }
        filter.keep_border = self.keep_border;
        filter.connectivity = if self.connectivity == 4 {
            Connectivity::Four
        } else {
            Connectivity::Eight
        };
        // Thin concentric rings (the cone preset) jitter with every pixel noise flips at the
        // level; their grey-weighted centroids do not.
        let centroid = match self.centroid.as_deref() {
            Some("weighted") => Centroid::Weighted,
            Some(_) => Centroid::Binary,
            None if self.preset == "cone" => Centroid::Weighted,
            None => Centroid::Binary,
        };
        Ok((
            DetectorConfig {
                preprocess: p,
                filter,
                centroid,
            },
            features,
        ))
    }
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    let (detector, preset_features) = a.detector.config()?;
    let features = match &a.features {
        Some(f) => FeatureSet::parse(f).map_err(|e| anyhow::anyhow!("--features: {e}"))?,
        None => preset_features,
    };
    // Concentric rings share one centre at rest: numbering them as a grid would leave the
    // tracker to guess between them, so the cone preset implies rings.
    let layout = match a.layout.as_deref() {
        Some("rings") => Layout::Rings,
        Some(_) => Layout::Grid,
        None if a.detector.preset == "cone" => Layout::Rings,
        None => Layout::Grid,
    };
    let mut stream = FrameStream::open(&a.frames, 25.0)?;
    if let Some(n) = a.first {
        if n == 0 {
            bail!("--first must be at least 1");
        }
        stream = stream.take_first(n);
    }
    let mut frames = Vec::new();
    for f in stream {
        // A calibration built from a partial set would be silently different: any unreadable
        // frame stops it.
        frames.push(f.context("calibration frames must all be readable")?);
    }
    if frames.is_empty() {
        bail!("no frames could be read");
    }
    let (cal, report) = calibrate(
        frames.iter().map(|f| (f.id.as_str(), &f.image)),
        detector,
        layout,
        features,
    )?;
    write_sensor(a, &cal)?;
    let level = report
        .level
        .map_or("adaptive".to_string(), |t| format!("{t}"));
    eprintln!(
        "calibrated {} markers ({} rows × {} columns, pitch {:.1} px) from {} frames of {}×{}; threshold {level}; {} blobs, {} off the grid",
        cal.markers.len(),
        cal.grid_rows,
        cal.grid_cols,
        cal.pitch_px,
        frames.len(),
        cal.image_width,
        cal.image_height,
        report.raw_blobs,
        report.off_grid.len()
    );
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
