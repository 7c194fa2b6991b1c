//! A detector as a user states it: a [`Preset`] (or `auto`, told from the first frame) with
//! any settings changed over it. The command line's detection options and the Python
//! package's keyword arguments both build a [`DetectorOptions`]; [`DetectorOptions::config`]
//! checks it and gives the [`DetectorConfig`].
//!
//! ```
//! use visuotact_vision::calibration::Preset;
//! use visuotact_vision::options::{DetectorOptions, Purpose, ThresholdChoice};
//!
//! let o = DetectorOptions {
//!     threshold: Some(ThresholdChoice::Fixed(0.4)),
//!     min_area_px: Some(12),
//!     ..DetectorOptions::default()
//! };
//! let (cfg, _) = o.config(Preset::Iats, Purpose::Tracking).unwrap();
//! assert_eq!(cfg.filter.min_area_px, 12);
//! let bad = DetectorOptions { threshold: Some(ThresholdChoice::Fixed(1.7)), ..o };
//! assert!(bad.config(Preset::Iats, Purpose::Tracking).is_err());
//! ```

use visuotact_image::RgbImage;

use crate::blobs::Connectivity;
use crate::calibration::Preset;
use crate::detect::{BlobFilter, Centroid, DetectorConfig};
use crate::features::FeatureSet;
use crate::preprocess::{Channel, CircleMask, Roi, Threshold};
use crate::sizing::MarkerSize;
use crate::ConfigError;

/// How the foreground is separated, as chosen (the adaptive window and offset are separate
/// options over the preset's).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ThresholdChoice {
    /// Otsu's level on every frame.
    Otsu,
    /// Otsu's level on every frame from an eighth of its pixels.
    OtsuSampled,
    /// Local mean minus an offset.
    Adaptive,
    /// A fixed level in 0..1 of full scale.
    Fixed(f64),
}

visuotact_image::from_str_by_parse!(ThresholdChoice, ConfigError);

impl ThresholdChoice {
    /// Parses `otsu`, `otsu-sampled`, `adaptive` or a level in 0..1.
    pub fn parse(s: &str) -> Result<Self, ConfigError> {
        match s {
            "otsu" => Ok(Self::Otsu),
            "otsu-sampled" => Ok(Self::OtsuSampled),
            "adaptive" => Ok(Self::Adaptive),
            other => other.parse::<f64>().map(Self::Fixed).map_err(|_| {
                ConfigError::unknown(
                    "threshold",
                    other,
                    "otsu, otsu-sampled, adaptive or a level in 0..1",
                )
            }),
        }
    }

    /// The threshold this choice makes of a preset's `base`: an adaptive choice keeps the
    /// base's window and offset when it is adaptive (else 31 px and −0.06).
    pub fn over(self, base: Threshold) -> Threshold {
        match self {
            ThresholdChoice::Otsu => Threshold::Otsu,
            ThresholdChoice::OtsuSampled => Threshold::OtsuSampled,
            ThresholdChoice::Fixed(level) => Threshold::Fixed { level },
            ThresholdChoice::Adaptive => match base {
                Threshold::Adaptive { .. } => base,
                _ => Threshold::Adaptive {
                    window_px: 31,
                    offset: -0.06,
                },
            },
        }
    }
}

/// What the detector serves, which settles what a preset leaves to its caller.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Purpose {
    /// Tracking markers (`calibrate`, Python): the preset's centroid and threshold.
    Tracking,
    /// Blob tables comparable with OpenCV, scikit-image and MATLAB `regionprops` (`blobs`):
    /// the pixel-mean centroid, and Otsu's level from every pixel where the preset samples it.
    BlobAnalysis,
}

/// A preset with settings changed over it; `None` keeps the preset's.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DetectorOptions {
    /// The starting settings; `None`: `auto` ([`Preset::for_frame`]).
    pub preset: Option<Preset>,
    /// The channel.
    pub channel: Option<Channel>,
    /// Invert the channel (dark markers on a bright background).
    pub invert: Option<bool>,
    /// The threshold.
    pub threshold: Option<ThresholdChoice>,
    /// Adaptive threshold window, pixels (odd).
    pub window_px: Option<usize>,
    /// Adaptive threshold offset in 0..1 of full scale.
    pub offset: Option<f64>,
    /// Grey-level opening.
    pub open: Option<bool>,
    /// Grey-level closing.
    pub close: Option<bool>,
    /// Morphology window side, pixels (odd).
    pub morph_size: Option<usize>,
    /// Smallest marker area, pixels.
    pub min_area_px: Option<u32>,
    /// Largest marker area, pixels.
    pub max_area_px: Option<u32>,
    /// Keep blobs touching the image border.
    pub keep_border: bool,
    /// The centroid; `None`: the caller's default.
    pub centroid: Option<Centroid>,
    /// Pixel connectivity.
    pub connectivity: Connectivity,
    /// Region of interest.
    pub roi: Option<Roi>,
    /// Circular mask.
    pub circle: Option<CircleMask>,
}

/// What [`DetectorOptions::config_for_frames`] chose.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameConfig {
    /// The preset (for `auto`, the one the first frame called for).
    pub preset: Preset,
    /// The detector.
    pub detector: DetectorConfig,
    /// The preset's feature set.
    pub features: FeatureSet,
    /// The markers' size in the first frame, when measured (tracking only).
    pub size: Option<MarkerSize>,
}

impl DetectorOptions {
    /// The preset: the one chosen, or for `auto` the one `first` frame calls for (markers
    /// darker than the skin: [`Preset::DarkMarkers`]; else, or without a frame,
    /// [`Preset::Iats`]). `first` is only called for `auto`.
    pub fn preset_for(&self, first: impl FnOnce() -> Option<RgbImage>) -> Preset {
        self.preset
            .unwrap_or_else(|| first().map_or(Preset::Iats, |f| Preset::for_frame(&f)))
    }

    /// The detector these options give over `preset` for `purpose`, and the preset's
    /// features.
    pub fn config(
        &self,
        preset: Preset,
        purpose: Purpose,
    ) -> Result<(DetectorConfig, FeatureSet), ConfigError> {
        let base = preset.config();
        let mut p = base.detector.preprocess;
        let default_centroid = match purpose {
            Purpose::Tracking => base.detector.centroid,
            Purpose::BlobAnalysis => {
                if p.threshold == Threshold::OtsuSampled {
                    p.threshold = Threshold::Otsu;
                }
                Centroid::Binary
            }
        };
        p.channel = self.channel.unwrap_or(p.channel);
        p.invert = self.invert.unwrap_or(p.invert);
        p.open = self.open.unwrap_or(p.open);
        p.close = self.close.unwrap_or(p.close);
        p.morph_size = self.morph_size.unwrap_or(p.morph_size);
        p.threshold = self.threshold_over(p.threshold)?;
        if let Some(r) = self.roi {
            if r.width == 0 || r.height == 0 {
                return Err(ConfigError::EmptyRegion {
                    width: r.width,
                    height: r.height,
                });
            }
            p.roi = Some(r);
        }
        p.circle = self.circle.or(p.circle);
        p.validate()?;
        let filter = BlobFilter {
            min_area_px: self.min_area_px.unwrap_or(BlobFilter::DEFAULT.min_area_px),
            max_area_px: self.max_area_px.unwrap_or(BlobFilter::DEFAULT.max_area_px),
            keep_border: self.keep_border,
            connectivity: self.connectivity,
        };
        if filter.min_area_px > filter.max_area_px {
            return Err(ConfigError::AreaRange {
                min_px: filter.min_area_px,
                max_px: filter.max_area_px,
            });
        }
        let centroid = self.centroid.unwrap_or(default_centroid);
        let cfg = DetectorConfig {
            preprocess: p,
            filter,
            centroid,
        };
        Ok((cfg, base.features))
    }

    /// Everything the options give for frames whose first is `first` (called at most once):
    /// the options are checked over the preset named, or for `auto` over either preset it may
    /// pick (an adaptive window refines dark-markers', not iats'); the preset chosen, its
    /// detector and features, and — for tracking — the opening and smallest blob sized from the
    /// markers of the first frame ([`DetectorOptions::sized`]). `calibrate` on the command line
    /// and `Sensor.calibrate` in Python both choose this way.
    pub fn config_for_frames(
        &self,
        purpose: Purpose,
        first: impl FnOnce() -> Option<RgbImage>,
    ) -> Result<FrameConfig, ConfigError> {
        match self.preset {
            Some(p) => {
                self.config(p, purpose)?;
            }
            None => {
                if let Err(e) = self.config(Preset::Iats, purpose) {
                    self.config(Preset::DarkMarkers, purpose).map_err(|_| e)?;
                }
            }
        }
        let needs_frame = self.preset.is_none() || purpose == Purpose::Tracking;
        let frame = if needs_frame { first() } else { None };
        let preset = self.preset_for(|| frame.clone());
        let (detector, features) = self.config(preset, purpose)?;
        let (detector, size) = match (&frame, purpose) {
            (Some(f), Purpose::Tracking) => self.sized(detector, f),
            _ => (detector, None),
        };
        Ok(FrameConfig {
            preset,
            detector,
            features,
            size,
        })
    }

    /// `cfg` with the opening and smallest blob that the markers of `frame` call for
    /// ([`MarkerSize`]) where these options leave them to the preset (an opening the preset
    /// has is dropped for markers too small for it; an opening it lacks is not added), and
    /// the size measured (`None`, and `cfg` unchanged, when too few markers are seen).
    pub fn sized(
        &self,
        mut cfg: DetectorConfig,
        frame: &RgbImage,
    ) -> (DetectorConfig, Option<MarkerSize>) {
        let Some(size) = MarkerSize::measure(frame, &cfg) else {
            return (cfg, None);
        };
        if self.open.is_none() && !size.opening() {
            cfg.preprocess.open = false;
        }
        if self.min_area_px.is_none() {
            cfg.filter.min_area_px = size.min_area_px().min(cfg.filter.max_area_px);
        }
        (cfg, Some(size))
    }

    /// The threshold chosen over the preset's `base`, with the adaptive window and offset.
    fn threshold_over(&self, base: Threshold) -> Result<Threshold, ConfigError> {
        let mut t = self.threshold.map_or(base, |c| c.over(base));
        match &mut t {
            Threshold::Adaptive { window_px, offset } => {
                *window_px = self.window_px.unwrap_or(*window_px);
                *offset = self.offset.unwrap_or(*offset);
            }
            _ if self.window_px.is_some() || self.offset.is_some() => {
                return Err(ConfigError::NotAdaptive)
            }
            _ => {}
        }
        Ok(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn options_change_the_preset_and_are_checked() {
        let (cfg, features) = DetectorOptions::default()
            .config(Preset::Cone, Purpose::BlobAnalysis)
            .unwrap();
        assert_eq!(
            cfg,
            DetectorConfig {
                centroid: Centroid::Binary,
                ..Preset::Cone.config().detector
            }
        );
        assert_eq!(features, FeatureSet::CONE);
        // Blob tables take Otsu from every pixel and the pixel mean; tracking, the preset's.
        let o = DetectorOptions::default();
        let (blobs, _) = o.config(Preset::Iats, Purpose::BlobAnalysis).unwrap();
        let (tracking, _) = o.config(Preset::Iats, Purpose::Tracking).unwrap();
        assert_eq!(
            (blobs.preprocess.threshold, blobs.centroid),
            (Threshold::Otsu, Centroid::Binary)
        );
        assert_eq!(tracking, Preset::Iats.config().detector);
        let sampled = DetectorOptions {
            threshold: Some(ThresholdChoice::OtsuSampled),
            ..DetectorOptions::default()
        };
        let (chosen, _) = sampled.config(Preset::Iats, Purpose::BlobAnalysis).unwrap();
        assert_eq!(chosen.preprocess.threshold, Threshold::OtsuSampled);
        let adaptive = DetectorOptions {
            threshold: Some(ThresholdChoice::Adaptive),
            window_px: Some(41),
            invert: Some(true),
            ..DetectorOptions::default()
        };
        let (cfg, _) = adaptive.config(Preset::Iats, Purpose::Tracking).unwrap();
        assert_eq!(
            cfg.preprocess.threshold,
            Threshold::Adaptive {
                window_px: 41,
                offset: -0.06
            }
        );
        assert!(cfg.preprocess.invert);
        let stray_window = DetectorOptions {
            window_px: Some(41),
            ..DetectorOptions::default()
        };
        assert!(stray_window
            .config(Preset::Iats, Purpose::Tracking)
            .is_err());
        let areas = DetectorOptions {
            min_area_px: Some(50),
            max_area_px: Some(10),
            ..DetectorOptions::default()
        };
        assert!(areas.config(Preset::Iats, Purpose::Tracking).is_err());
        assert_eq!(
            ThresholdChoice::parse("0.3").unwrap(),
            ThresholdChoice::Fixed(0.3)
        );
        assert!(ThresholdChoice::parse("high").is_err());
        assert_eq!(DetectorOptions::default().preset_for(|| None), Preset::Iats);
    }
}
