//! `visuotact calibrate`: still frames (or a data set's lightest frames) → sensor.json.

use std::path::PathBuf;

use anyhow::{bail, Context};
use visuotact_image::RgbImage;
use visuotact_io::frames::FrameStream;
use visuotact_vision::blobs::Connectivity;
use visuotact_vision::calibration::{calibrate, CalibrationConfig, LightestFinder, Preset};
use visuotact_vision::detect::{BlobFilter, Centroid, DetectorConfig};
use visuotact_vision::features::FeatureSet;
use visuotact_vision::layout::{Layout, LayoutChoice};
use visuotact_vision::preprocess::{
    marker_polarity, Channel, CircleMask, Polarity, Roi, Threshold,
};
use visuotact_vision::track::TrackConfig;

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

/// Preprocessing and blob-filter options shared by commands that detect markers.
#[derive(clap::Args, Debug, Clone)]
pub(crate) struct DetectorArgs {
    /// Starting settings: auto (iats for markers brighter than the skin, dark-markers for
    /// darker ones, told from the first frame), iats (green, open, Otsu), cone (luma, open,
    /// fixed 0.25), dark-markers (luma, inverted, open, adaptive).
    #[arg(long, default_value = "auto", value_parser = ["auto", "iats", "cone", "dark-markers"])]
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
    /// Blob centroid: binary (pixel mean, as OpenCV; `blobs`' default), weighted (by grey level
    /// above the threshold) or grey (grey-level centroid of the marker and its edge over a
    /// fitted background; `calibrate`'s default).
    #[arg(long, value_parser = ["binary", "weighted", "grey"])]
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
    /// The detector configuration for frames whose first one `first` reads: as
    /// [`DetectorArgs::config`], with `--preset auto` resolved from the markers' polarity in
    /// that frame (`dark-markers` for markers darker than the skin, saying so; `iats`
    /// otherwise, or without a readable frame). The options are checked, and the frame read,
    /// only when needed: an explicit preset never reads it.
    pub(crate) fn config_for_frames(
        &self,
        default_centroid: Centroid,
        first: impl FnOnce() -> Option<RgbImage>,
    ) -> anyhow::Result<(DetectorConfig, FeatureSet)> {
        let checked = self.config(default_centroid)?;
        if self.preset != "auto" {
            return Ok(checked);
        }
        if !first().is_some_and(|f| marker_polarity(&f) == Polarity::Dark) {
            return Ok(checked);
        }
        eprintln!(
            "markers darker than the skin: preset dark-markers (--preset iats for the bright-marker one)"
        );
        Self {
            preset: "dark-markers".to_string(),
            ..self.clone()
        }
        .config(default_centroid)
    }

    /// The detector configuration these options describe; `default_centroid` when
    /// `--centroid` is not given. `--preset auto` reads as `iats` here
    /// ([`DetectorArgs::config_for_frames`] resolves it).
    pub(crate) fn config(
        &self,
        default_centroid: Centroid,
    ) -> anyhow::Result<(DetectorConfig, FeatureSet)> {
        // `auto` (resolved by the caller) reads as `iats`.
        let base = Preset::from_name(&self.preset)
            .unwrap_or(Preset::Iats)
            .config();
        let (mut p, features) = (base.detector.preprocess, base.features);
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
        let centroid = match self.centroid.as_deref() {
            Some("weighted") => Centroid::Weighted,
            Some("grey") => Centroid::Grey,
            Some(_) => Centroid::Binary,
            None => default_centroid,
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
    let default_centroid = Preset::from_name(&a.detector.preset)
        .map_or(Centroid::Grey, |p| p.config().detector.centroid);
    // Frames that cannot be read are reported where they are read below.
    let (detector, preset_features) = a.detector.config_for_frames(default_centroid, || {
        open_frames(a).ok()?.next()?.ok().map(|f| f.image)
    })?;
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
