//! `visuotact predict`: a model over a feature table (or frames read with a sensor file) →
//! estimates, with the reason in the flags where there is none.

use std::path::PathBuf;

use anyhow::bail;
use visuotact_pipeline::extract::{features_table, predict_table, Predicted};
use visuotact_pipeline::table::{InputSources, Named};
use visuotact_vision::features::FeatureExtractor;

use crate::args::read_readings;
use crate::progress::{pass_error, FramePass, Reporter};

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Model file from `train`.
    #[arg(long)]
    model: PathBuf,
    /// Feature table from `extract` (or give --sensor and frames).
    #[arg(long, conflicts_with_all = ["sensor", "frames"])]
    features: Option<PathBuf>,
    /// Sensor file: extract features from FRAMES with it, then estimate.
    #[arg(long, requires = "frames")]
    sensor: Option<PathBuf>,
    /// Frames (image files, folders, videos) when --sensor is given.
    frames: Vec<PathBuf>,
    /// Table keyed by `frame` holding inputs of the model that are not in the feature table
    /// (e.g. a pressure gauge's `gauge_kpa`).
    #[arg(long, value_name = "TABLE", requires = "features")]
    readings: Option<PathBuf>,
    /// Output table (`-` for standard output).
    #[arg(short, long)]
    output: PathBuf,
    /// No progress lines (by default one every 2 s on stderr, also when it is not a terminal).
    #[arg(long, short)]
    quiet: bool,
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    let mut inputs = vec![a.model.as_path()];
    inputs.extend(a.features.as_deref());
    inputs.extend(a.readings.as_deref());
    inputs.extend(a.sensor.as_deref());
    inputs.extend(a.frames.iter().map(PathBuf::as_path));
    visuotact_io::guard::refuse_output_over_input(&a.output, &inputs)?;
    let model = crate::load_model(&a.model)?;
    let (f, source) = match (&a.features, &a.sensor) {
        (Some(p), _) => (
            crate::args::read_table(p, &["flags"])?,
            p.display().to_string(),
        ),
        (None, Some(sensor)) => {
            let set = visuotact_pipeline::feature_set_of(&model.feature_columns)?;
            let cal = crate::load_sensor(sensor)?;
            visuotact_pipeline::estimator::require_scale(&cal, &model.feature_columns)
                .map_err(|e| anyhow::anyhow!("{}: {e}", sensor.display()))?;
            let mut ex = FeatureExtractor::new(cal, set)?;
            let reporter = Reporter::new(a.quiet);
            reporter.stage("features");
            let mut pass = FramePass::new(&reporter, usize::MAX);
            (
                features_table(&mut ex, &a.frames, 25.0, &mut pass)
                    .map_err(|e| pass_error(e, &a.output))?,
                format!("frames read with {}", sensor.display()),
            )
        }
        (None, None) => bail!("give --features TABLE, or --sensor SENSOR FRAMES..."),
    };
    if f.keys.is_empty() {
        bail!(
            "{source}: no row to estimate (a header only, or no frame could be read): {} not written",
            a.output.display()
        );
    }
    let readings = read_readings(a.readings.as_deref())?;
    let r_name = a.readings.as_ref().map(|p| p.display().to_string());
    let sources = InputSources::new(
        &model.feature_columns,
        Named {
            table: &f,
            name: &source,
        },
        readings
            .as_ref()
            .zip(r_name.as_deref())
            .map(|(table, name)| Named { table, name }),
        &format!(
            "the model {} was trained on other inputs",
            a.model.display()
        ),
    )?;
    let Predicted {
        written,
        missing,
        filled,
    } = predict_table(&model, &sources, &f.keys, &a.output)?;
    let filled_note = if filled > 0 {
        format!(" ({filled} with lost markers filled)")
    } else {
        String::new()
    };
    note!("{written} estimates{filled_note}, {missing} frames without");
    Ok(())
}
