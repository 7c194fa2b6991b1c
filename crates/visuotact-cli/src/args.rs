//! Option groups several commands share, each turned into the library's typed config: marker
//! detection ([`DetectorArgs`]), force cleaning ([`ForceArgs`]), the training objective
//! ([`AlgorithmArg`]) and the training data ([`DataArgs`]).

use std::path::{Path, PathBuf};
use std::str::FromStr;

use anyhow::{bail, Context};
use visuotact_image::RgbImage;
use visuotact_io::table::KeyedTable;
use visuotact_nn::fit::{components_from_name, FieldInputs, FitConfig};
use visuotact_nn::mlp::Algorithm;
use visuotact_nn::model::is_marker_column;
use visuotact_pipeline::table::{
    training_table_from_files, Incomplete, JoinConfig, TrainingFiles, TrainingTable,
};
use visuotact_signal::clean::{BiasRemoval, CleanConfig};
use visuotact_signal::fir::{FiltFiltOptions, PadLen, Padding, Window};
use visuotact_vision::blobs::Connectivity;
use visuotact_vision::calibration::Preset;
use visuotact_vision::detect::{Centroid, DetectorConfig};
use visuotact_vision::features::FeatureSet;
use visuotact_vision::options::{DetectorOptions, Purpose, ThresholdChoice};
use visuotact_vision::preprocess::{Channel, CircleMask, Roi};
use visuotact_vision::sizing::MarkerSize;

/// Preprocessing and blob-filter options shared by commands that detect markers.
#[derive(clap::Args, Debug, Clone)]
pub(crate) struct DetectorArgs {
    /// Starting settings: auto (iats for markers brighter than the skin, dark-markers for
    /// darker ones, told from the first frame), iats (green, open, Otsu), cone (luma, open,
    /// fixed 0.25), dark-markers (luma, inverted, open, adaptive).
    #[arg(long, default_value = "auto", value_parser = clap::builder::PossibleValuesParser::new(Preset::CHOICES))]
    pub(crate) preset: String,
    /// Channel: green, luma601, mean, red, blue.
    #[arg(long)]
    channel: Option<String>,
    /// Invert the channel (dark markers on a bright background).
    #[arg(long, overrides_with = "no_invert")]
    invert: bool,
    /// Do not invert.
    #[arg(long)]
    no_invert: bool,
    /// Threshold: otsu (all pixels), otsu-sampled (Otsu on an eighth of the pixels: faster),
    /// adaptive, or a fixed level in 0..1 of full scale.
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
    #[arg(long, value_parser = choice::<Centroid>(Centroid::NAMES))]
    centroid: Option<Centroid>,
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

/// `--on` / `--no-on` as a choice over the preset's (`None`: neither given).
fn flag(on: bool, off: bool) -> Option<bool> {
    (on || off).then_some(on)
}

impl DetectorArgs {
    /// The options as the library states them.
    fn options(&self) -> anyhow::Result<DetectorOptions> {
        let roi = match &self.roi {
            Some(r) => {
                let v = numbers(r, 4, "roi")?;
                if v.iter().any(|x| *x < 0.0) {
                    bail!("--roi {r:?}: expects a non-negative corner and a positive size");
                }
                Some(Roi {
                    x: v[0] as usize,
                    y: v[1] as usize,
                    width: v[2] as usize,
                    height: v[3] as usize,
                })
            }
            None => None,
        };
        let circle = match &self.circle {
            Some(c) => {
                let v = numbers(c, 3, "circle")?;
                Some(CircleMask {
                    cx_px: v[0],
                    cy_px: v[1],
                    radius_px: v[2],
                })
            }
            None => None,
        };
        let channel = match &self.channel {
            Some(c) => Some(Channel::from_name(c).with_context(|| {
                format!(
                    "--channel {c:?}: expected one of {}",
                    Channel::ALL.map(Channel::name).join(", ")
                )
            })?),
            None => None,
        };
        Ok(DetectorOptions {
            preset: Preset::from_name(&self.preset),
            channel,
            invert: flag(self.invert, self.no_invert),
            threshold: self
                .threshold
                .as_deref()
                .map(ThresholdChoice::parse)
                .transpose()?,
            window_px: self.window,
            offset: self.offset,
            open: flag(self.open, self.no_open),
            close: flag(self.close, self.no_close),
            morph_size: self.morph_size,
            min_area_px: self.min_area,
            max_area_px: self.max_area,
            keep_border: self.keep_border,
            centroid: self.centroid,
            connectivity: if self.connectivity == 4 {
                Connectivity::Four
            } else {
                Connectivity::Eight
            },
            roi,
            circle,
        })
    }

    /// The detector configuration for frames whose first one `first` reads, with `--preset
    /// auto` resolved from it ([`DetectorOptions::preset_for`], saying so when it picks the
    /// dark-markers preset), for `purpose`; for tracking, the opening and smallest blob sized
    /// from its markers where no option set them ([`DetectorOptions::sized`]), with the size
    /// measured. The options are checked before any frame is read.
    pub(crate) fn config_for_frames(
        &self,
        purpose: Purpose,
        first: impl FnOnce() -> Option<RgbImage>,
    ) -> anyhow::Result<(DetectorConfig, FeatureSet, Option<MarkerSize>)> {
        let o = self.options()?;
        let c = o.config_for_frames(purpose, first)?;
        if o.preset.is_none() && c.preset == Preset::DarkMarkers {
            note!(
                "markers darker than the skin: preset dark-markers (--preset iats for the bright-marker one)"
            );
        }
        Ok((c.detector, c.features, c.size))
    }
}

/// Filter and bias options shared by `filter` and `dataset`.
#[derive(clap::Args, Debug, Clone)]
pub(crate) struct ForceArgs {
    /// Low-pass cutoff, Hz (FIR, windowed sinc).
    #[arg(long, default_value_t = 5.0)]
    pub(crate) cutoff_hz: f64,
    /// Filter length, taps.
    #[arg(long, default_value_t = 51)]
    pub(crate) taps: usize,
    /// Window: hamming, hann, rectangular, kaiser:BETA.
    #[arg(long, default_value = "hamming")]
    window: String,
    /// Padding at the ends: odd (scipy and MATLAB), even, constant, none.
    #[arg(long, default_value = "odd", value_parser = choice::<Padding>(Padding::NAMES))]
    padding: Padding,
    /// Padding length: scipy (3·taps), matlab (3·(taps − 1)) or a number of samples.
    #[arg(long, default_value = "scipy")]
    padlen: String,
    /// Bias removal: auto (detect no-contact periods), none, or time ranges `A:B,C:D` in
    /// seconds that are known to be free of contact.
    #[arg(long, default_value = "auto")]
    bias: String,
    /// Level change (N) beyond which a still period counts as contact, for `--bias auto`.
    #[arg(long, default_value_t = 0.25)]
    contact_threshold_n: f64,
}

impl ForceArgs {
    /// The cleaning these options ask for.
    pub(crate) fn config(&self) -> anyhow::Result<CleanConfig> {
        Ok(CleanConfig {
            cutoff_hz: self.cutoff_hz,
            taps: self.taps,
            window: Window::parse(&self.window)?,
            filtfilt: FiltFiltOptions {
                padding: self.padding,
                padlen: PadLen::parse(&self.padlen)
                    .map_err(|e| anyhow::anyhow!("--padlen: {e}"))?,
            },
            bias: BiasRemoval::parse(&self.bias, self.contact_threshold_n)
                .map_err(|e| anyhow::anyhow!("--bias: {e}"))?,
        })
    }
}

/// Clap's parser for one of a library type's named choices: its `NAMES` are the possible
/// values (listed in `--help`, a near miss suggested), each read by the type's `FromStr`; the
/// list lives once, beside the type.
pub(crate) fn choice<T>(
    names: &'static [&'static str],
) -> impl clap::builder::TypedValueParser<Value = T>
where
    T: FromStr + Clone + Send + Sync + 'static,
    T::Err: std::fmt::Display,
{
    clap::builder::TypedValueParser::try_map(clap::builder::PossibleValuesParser::new(names), |s| {
        s.parse::<T>().map_err(|e| e.to_string())
    })
}

/// The training objective and input reduction, shared by `train` and `sweep`.
#[derive(clap::Args, Debug, Clone)]
pub(crate) struct AlgorithmArg {
    /// trainbr (the default: Bayesian regularisation, LM on errors plus weights, every sample
    /// trains, no validation subset; on 280 simulated touches of four sensors it generalised
    /// best, docs/benchmarks.md) or trainlm (MATLAB's default: LM on the squared errors,
    /// 70/15/15 split, stopped by the validation subset).
    /// Set, it is the trainer of every network (`train` then tries no wide network).
    #[arg(long = "algorithm", value_parser = choice::<Algorithm>(Algorithm::NAMES))]
    pub(crate) name: Option<Algorithm>,
    /// Feed the network the K leading principal components of the scaled inputs (kept in the
    /// model file): auto (10 when there are over 20 inputs, otherwise the inputs themselves),
    /// 0 (the inputs themselves) or K.
    #[arg(long, value_name = "auto|K", default_value = "auto")]
    pub(crate) components: String,
    /// The field-summary columns of the feature table (`field_rms_px` … `field_spread_px`:
    /// how much the markers moved and where) as inputs: auto (the default: when there are
    /// over 20 markers' features, 5-fold cross-validation on the training frames chooses
    /// between the field summary beside the markers' principal components and the field
    /// summary alone, and the model file keeps both scores; which generalises better depends
    /// on the sensor: on 280 simulated touches of four sensors in three drawn variants each the
    /// default was 4.1–24× better in contact distance and 3.3–10× in depth than the best
    /// scikit-learn peer, and where both rules were measured it matched the better one,
    /// docs/benchmarks.md), yes (beside the markers' features), only (instead of them), or
    /// no. Tables extracted before the field summary existed have none.
    #[arg(long, default_value = "auto", value_parser = choice::<FieldInputs>(FieldInputs::NAMES))]
    pub(crate) field: FieldInputs,
    /// Refuse a training that needs more memory than this, GiB (default: the memory available
    /// when it starts).
    #[arg(long, value_name = "GIB")]
    pub(crate) max_memory_gib: Option<f64>,
}

impl AlgorithmArg {
    /// The trainer: the one set, or the default (trainbr).
    pub(crate) fn algorithm(&self) -> Algorithm {
        self.name.unwrap_or(FitConfig::default().algorithm)
    }

    /// Whether the field summary is an input.
    pub(crate) fn field(&self) -> FieldInputs {
        self.field
    }

    /// Refuses a training whose estimated peak memory exceeds `--max-memory-gib` (default: the
    /// memory available now); gives the estimate, bytes.
    pub(crate) fn check_memory(
        &self,
        sizes: (usize, usize, usize),
        cfg: &FitConfig,
    ) -> anyhow::Result<u64> {
        let limit = match self.max_memory_gib {
            Some(g) if g.is_finite() && g > 0.0 => (g * 1024f64.powi(3)) as u64,
            Some(g) => bail!("--max-memory-gib {g}: expected a positive number"),
            None => visuotact_io::guard::available_memory_bytes().unwrap_or(u64::MAX),
        };
        visuotact_nn::fit::check_training_memory(sizes, cfg, limit)
            .map_err(|e| anyhow::anyhow!("{e} (--max-memory-gib)"))
    }

    /// The number of components for `inputs` marker inputs (`None`: no projection).
    pub(crate) fn components(&self, inputs: usize) -> anyhow::Result<Option<usize>> {
        components_from_name(&self.components, inputs)
            .map_err(|e| anyhow::anyhow!("--components {e}"))
    }

    /// The components as the user set them for `inputs` marker inputs: `None` for `auto`
    /// (the training policy decides), else `Some` of [`AlgorithmArg::components`].
    pub(crate) fn wanted_components(&self, inputs: usize) -> anyhow::Result<Option<Option<usize>>> {
        visuotact_nn::plan::wanted_components(&self.components, inputs)
            .map_err(|e| anyhow::anyhow!("--components {e}"))
    }
}

/// The training data: features, labels, which targets, what to do with incomplete frames.
#[derive(clap::Args, Debug)]
pub(crate) struct DataArgs {
    /// Feature table from `extract` (per-marker columns `mNNN_…` are the inputs).
    #[arg(long)]
    pub(crate) features: PathBuf,
    /// Label table keyed by `frame` (a session's labels.csv).
    #[arg(long)]
    pub(crate) labels: PathBuf,
    /// Target columns of the labels, comma-separated (e.g. x_mm,y_mm,depth_mm).
    #[arg(long)]
    pub(crate) targets: String,
    #[command(flatten)]
    pub(crate) extra: ExtraInputs,
    /// Leave out frames with missing feature cells (lost markers) instead of filling them
    /// (models on principal components fill them from the markers found; others fail).
    #[arg(long)]
    pub(crate) drop_incomplete: bool,
}

/// Inputs besides the marker features, e.g. the reading of a pressure gauge on an inflatable
/// link: named columns of the feature table or of a readings table keyed by `frame`.
#[derive(clap::Args, Debug, Default)]
pub(crate) struct ExtraInputs {
    /// Extra input columns, comma-separated (e.g. gauge_kpa), looked up in the feature table,
    /// then in --readings.
    #[arg(long, value_name = "COLUMNS")]
    pub(crate) inputs: Option<String>,
    /// Table keyed by `frame` holding the extra inputs (a simulated cone session's labels.csv
    /// has the gauge reading `gauge_kpa`).
    #[arg(long, value_name = "TABLE", requires = "inputs")]
    pub(crate) readings: Option<PathBuf>,
}

impl ExtraInputs {
    /// The extra input names (empty without --inputs).
    fn names(&self) -> anyhow::Result<Vec<String>> {
        match &self.inputs {
            None => Ok(Vec::new()),
            Some(s) => {
                let names = column_names(s, "inputs")?;
                if let Some(c) = names.iter().find(|c| is_marker_column(c)) {
                    bail!("--inputs {c}: marker features are inputs already; name other columns");
                }
                Ok(names)
            }
        }
    }
}

/// The table at `path` ([`KeyedTable::read_noting`]), its notes printed.
pub(crate) fn read_table(path: &Path, text_columns: &[&str]) -> anyhow::Result<KeyedTable> {
    let mut notes = Vec::new();
    let t = KeyedTable::read_noting(path, text_columns, &mut notes)?;
    for n in notes {
        note!("note: {n}");
    }
    Ok(t)
}

/// A readings table keyed by `frame` (every column numeric), when one is given.
pub(crate) fn read_readings(path: Option<&Path>) -> anyhow::Result<Option<KeyedTable>> {
    path.map(|p| read_table(p, &[])).transpose()
}

impl DataArgs {
    /// The target names and the joined table; frames with missing inputs are kept (to be
    /// filled) when `fills(number of inputs)` says the model will fill them.
    pub(crate) fn load(
        &self,
        field: FieldInputs,
        fills: impl Fn(usize) -> bool,
    ) -> anyhow::Result<(Vec<String>, TrainingTable)> {
        let targets = parse_targets(&self.targets)?;
        let extra = self.extra.names()?;
        let cfg = JoinConfig {
            targets: &targets,
            extra_inputs: &extra,
            field,
            incomplete: if self.drop_incomplete {
                Incomplete::Drop
            } else {
                Incomplete::FillIf(&fills)
            },
        };
        let files = TrainingFiles {
            features: &self.features,
            labels: &self.labels,
            readings: self.extra.readings.as_deref(),
        };
        let j = training_table_from_files(files, &cfg)?;
        for note in &j.notes {
            note!("{note}");
        }
        Ok((targets, j))
    }
}

pub(crate) fn parse_list<T: std::str::FromStr>(s: &str, what: &str) -> anyhow::Result<Vec<T>> {
    s.split(',')
        .map(|p| {
            p.trim()
                .parse::<T>()
                .map_err(|_| anyhow::anyhow!("--{what}: {p:?} is not valid"))
        })
        .collect()
}

pub(crate) fn parse_targets(s: &str) -> anyhow::Result<Vec<String>> {
    column_names(s, "targets")
}

/// Column names from the comma-separated list of option `--what` (at least one).
fn column_names(s: &str, what: &str) -> anyhow::Result<Vec<String>> {
    let names: Vec<String> = s
        .split(',')
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .collect();
    if names.is_empty() {
        bail!("--{what} is empty");
    }
    Ok(names)
}

/// The file or folder a source option names (`video:FILE`, `frames:DIR`, `csv:FILE`), for the
/// output rule ([`visuotact_io::guard::refuse_outputs_over_inputs`]).
pub(crate) fn source_path(source: &str) -> Option<&std::path::Path> {
    ["video:", "frames:", "csv:"]
        .iter()
        .find_map(|p| source.strip_prefix(p))
        .map(std::path::Path::new)
}

/// A bag written alongside (`run --mcap`, `record --mcap`), with its topics.
#[derive(clap::Args, Debug, Clone)]
pub(crate) struct BagArgs {
    /// Also write an MCAP bag (ROS 2 profile; FILE.mcap or a rosbag2 folder) as frames are
    /// estimated or recorded: estimates, force sensor, markers, diagnostics; closed cleanly at
    /// the end (a killed run's bag stays readable to its last chunk as FILE.mcap.part~).
    #[arg(long, value_name = "FILE.mcap")]
    pub(crate) mcap: Option<PathBuf>,
    /// With --mcap: the frames too (PNG CompressedImage; costs a PNG encoding per frame).
    #[arg(long)]
    pub(crate) mcap_images: bool,
    #[command(flatten)]
    pub(crate) ros: RosArgs,
}

/// ROS 2 topic namespace and frame (`export mcap`, `run --mcap`).
#[derive(clap::Args, Debug, Clone)]
pub(crate) struct RosArgs {
    /// Topic namespace, one per sensor (e.g. /left_finger).
    #[arg(long, default_value = "/visuotact")]
    namespace: String,
    /// frame_id of the sensor frame (the image frame is FRAME_ID/image).
    #[arg(long, default_value = "visuotact")]
    frame_id: String,
}

impl RosArgs {
    pub(crate) fn config(&self, images: bool) -> visuotact_pipeline::output::OutputConfig {
        visuotact_pipeline::output::OutputConfig {
            namespace: self.namespace.clone(),
            frame_id: self.frame_id.clone(),
            images,
        }
    }
}
