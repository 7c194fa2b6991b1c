//! `visuotact predict`: a model over a feature table (or frames read with a sensor file) →
//! estimates, with the reason in the flags where there is none.

use std::path::{Path, PathBuf};

use anyhow::bail;
use visuotact_io::frames::FrameStream;
use visuotact_io::table::{KeyedTable, TableFormat, TableWriter};
use visuotact_pipeline::table::{InputSources, Named};
use visuotact_vision::features::FeatureExtractor;

use crate::args::read_readings;

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
}

/// Features of frames extracted with a sensor file, as a keyed table.
fn features_from_frames(
    sensor: &Path,
    frames: &[PathBuf],
    columns: &[String],
) -> anyhow::Result<KeyedTable> {
    let cal = crate::load_sensor(sensor)?;
    let mut ex = FeatureExtractor::new(cal, visuotact_pipeline::feature_set_of(columns)?)?;
    let names = ex.column_names();
    let (mut keys, mut rows) = (Vec::new(), Vec::new());
    for item in FrameStream::open(frames, 25.0)? {
        let frame = match item {
            Ok(f) => f,
            Err(e) => {
                eprintln!("warning: {e}; skipped");
                continue;
            }
        };
        match ex.extract(&frame.image) {
            Ok(f) => {
                keys.push(frame.id);
                rows.push(f.values);
            }
            Err(e) => eprintln!("warning: frame {}: {e}; skipped", frame.id),
        }
    }
    let n_rows = rows.len();
    Ok(KeyedTable {
        columns: names,
        keys,
        text: vec![Vec::new(); n_rows],
        rows,
        dropped_partial_line: false,
    })
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    let model = crate::load_model(&a.model)?;
    let (f, source) = match (&a.features, &a.sensor) {
        (Some(p), _) => (
            KeyedTable::read(p, &["flags"]).map_err(anyhow::Error::msg)?,
            p.display().to_string(),
        ),
        (None, Some(sensor)) => (
            features_from_frames(sensor, &a.frames, &model.feature_columns)?,
            format!("frames read with {}", sensor.display()),
        ),
        (None, None) => bail!("give --features TABLE, or --sensor SENSOR FRAMES..."),
    };
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
    // An ensemble also writes each target's spread (standard deviation over its networks).
    let columns = model.estimate_columns();
    let width = columns.len();
    let mut out = TableWriter::create(&a.output, TableFormat::Csv, columns)?;
    let (mut written, mut missing, mut filled) = (0, 0, 0);
    let mut x = Vec::with_capacity(model.feature_columns.len());
    for (r, key) in f.keys.iter().enumerate() {
        sources.row_into(r, &mut x);
        // Lost markers are filled by a model on principal components; a missing reading, too
        // many lost markers or a model without components: no estimate rather than a wrong one,
        // and the reason in the flags.
        match model.estimate(&x) {
            Ok(e) => {
                let note = if e.filled > 0 {
                    filled += 1;
                    format!("filled {} inputs", e.filled)
                } else {
                    String::new()
                };
                out.write_row(key, &e.into_row(), &note)?;
                written += 1;
            }
            Err(why) => {
                out.write_row(key, &vec![f64::NAN; width], &why.to_string())?;
                missing += 1;
            }
        }
    }
    let filled_note = if filled > 0 {
        format!(" ({filled} with lost markers filled)")
    } else {
        String::new()
    };
    eprintln!("{written} estimates{filled_note}, {missing} frames without");
    Ok(())
}
