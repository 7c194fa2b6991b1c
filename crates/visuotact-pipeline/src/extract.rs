//! Tables of frames: [`extract`] writes the feature table of frames (image files, folders,
//! videos), [`features_table`] keeps it in memory, [`predict_table`] runs a model over a feature
//! table, and [`blobs_table`] writes every blob of every frame. Each is one pass over the frames
//! whose [`FrameSink`] hears of each frame skipped and may stop it; a stopped pass writes
//! nothing.

use std::path::{Path, PathBuf};

use rayon::prelude::*;
use visuotact_image::Frame;

use visuotact_io::table::{KeyedTable, TableFormat, TableWriter};
use visuotact_nn::model::Model;
use visuotact_vision::blobs::MomentConvention;
use visuotact_vision::detect::Detector;
use visuotact_vision::features::{FeatureExtractor, FrameFeatures, FrameSizeError, MmColumns};
use visuotact_vision::field::FieldDynamics;

use crate::replay::{Pass, ReplayError};
use crate::schema::{
    blob_row, feature_columns, feature_row_into, flags_of, missing_summary, BLOB_COLUMNS,
};
use crate::sink::FrameSink;
use crate::slip::{FieldFollower, SlipMonitor, SlipSettings};
use crate::table::InputSources;

/// What an extraction did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Extracted {
    /// Rows written.
    pub written: usize,
    /// Frames skipped (unreadable, or of another size).
    pub skipped: usize,
    /// Frames with markers not found.
    pub incomplete: usize,
    /// Marker-frames not found, in all.
    pub lost: usize,
}

/// Writes the feature table of `frames` (image files, folders, videos at `fps`) to `output`
/// in `format`: one row per frame ([`crate::schema`]). With `ex` following the frames in order
/// ([`FeatureExtractor::set_temporal_prior`]) and features holding x and y, each row ends with
/// the displacement field's dynamics over the sequence ([`FieldDynamics::NAMES`], as
/// `slip detect --frames` writes them; an increment spans the slip detector's lag), the frames
/// one after another; order-free, a batch of frames at a time on every core (the same table).
/// `obs` hears of the progress and of every frame skipped or with markers not found.
pub fn extract(
    ex: &mut FeatureExtractor,
    frames: &[PathBuf],
    fps: f64,
    (output, format): (&Path, TableFormat),
    obs: &mut dyn FrameSink,
) -> Result<Extracted, ReplayError> {
    let n_markers = ex.calibration().markers.len();
    let mut pass = Pass::open(frames, fps)?;
    let write_err = |source| ReplayError::Write {
        path: output.to_path_buf(),
        source,
    };
    let names = ex.column_names();
    let mm = MmColumns::of_sensor(ex.calibration(), &names);
    let mut columns = feature_columns(&names, &mm);
    // Frames in order: the field's dynamics over the sequence, as `slip detect --frames` gives
    // them (the displacements need x and y among the features).
    let mut dynamics = (ex.temporal_prior() && SlipMonitor::reads(ex.feature_set())).then(|| {
        columns.extend(FieldDynamics::NAMES.iter().map(|n| n.to_string()));
        FieldFollower::of_sensor(ex.calibration(), SlipSettings::default().lag_frames)
    });
    let mut out = TableWriter::create(output, format, columns).map_err(write_err)?;
    let mut done = Extracted::default();
    let mut first_skip: Option<String> = None;
    let mut row = Vec::new();
    let set = ex.feature_set();
    each_extracted(ex, &mut pass, obs, |frame, f, obs| {
        let f = match f {
            Ok(f) => f,
            Err(e) => {
                done.skipped += 1;
                let why = format!("frame {}: {e}", frame.id);
                obs.warn(&format!("{why}; skipped"));
                first_skip.get_or_insert(why);
                return Ok(());
            }
        };
        let missing = n_markers - f.found;
        if missing > 0 {
            done.incomplete += 1;
            done.lost += missing;
            let what = if missing * 2 >= n_markers {
                "; half or more: is the skin in view?"
            } else {
                ""
            };
            obs.warn(&format!(
                "frame {}: {missing} of {n_markers} markers not found ({}){what}",
                frame.id,
                missing_summary(f)
            ));
        }
        feature_row_into(&mut row, frame.timestamp_s, n_markers, f, &mm);
        if let Some(follower) = &mut dynamics {
            row.extend_from_slice(&follower.update_features(f, set).signals());
        }
        out.write_row(&frame.id, &row, &flags_of(f))
            .map_err(write_err)?;
        done.written += 1;
        Ok(())
    })?;
    done.skipped += pass.unreadable;
    if done.written == 0 {
        // A table of a header only is no result: nothing is left under the output's name.
        return Err(ReplayError::NothingExtracted {
            path: output.to_path_buf(),
            frames: done.skipped,
            why: first_skip.unwrap_or_else(|| "no frame could be read".into()),
        });
    }
    out.finish().map_err(write_err)?;
    Ok(done)
}

/// The most image bytes a batch of [`each_extracted`] holds (it takes at least one frame): four
/// frames per worker, short of this (64 frames of 4K video would be 1.6 GB).
const BATCH_BYTES: usize = 256 << 20;

/// Frames handed to `each` with their features, in order. Order-free (no temporal prior),
/// every frame is tracked on its own, so frames are read a batch at a time and a batch is
/// extracted in parallel, one copy of `ex` per worker: the same features as one after
/// another, sooner. Followed (the temporal prior), one frame after the other.
fn each_extracted(
    ex: &mut FeatureExtractor,
    pass: &mut Pass,
    obs: &mut dyn FrameSink,
    mut each: impl FnMut(
        &Frame,
        Result<&FrameFeatures, FrameSizeError>,
        &mut dyn FrameSink,
    ) -> Result<(), ReplayError>,
) -> Result<(), ReplayError> {
    if ex.temporal_prior() {
        let mut f = FrameFeatures::default();
        while let Some(frame) = pass.next(obs)? {
            let got = ex.extract_into(&frame.image, &mut f).map(|()| &f);
            each(&frame, got, obs)?;
        }
        return Ok(());
    }
    let size = 4 * rayon::current_num_threads().max(1);
    let mut batch: Vec<Frame> = Vec::with_capacity(size);
    loop {
        batch.clear();
        let mut bytes = 0;
        while batch.len() < size && bytes < BATCH_BYTES {
            match pass.next(obs)? {
                Some(frame) => {
                    bytes += frame.image.as_slice().len();
                    batch.push(frame);
                }
                None => break,
            }
        }
        if batch.is_empty() {
            return Ok(());
        }
        let shared: &FeatureExtractor = ex;
        let extracted: Vec<_> = batch
            .par_iter()
            .map_init(
                || shared.clone(),
                |worker, frame| {
                    let mut f = FrameFeatures::default();
                    worker.extract_into(&frame.image, &mut f).map(|()| f)
                },
            )
            .collect();
        for (frame, got) in batch.iter().zip(extracted) {
            each(frame, got.as_ref().map_err(Clone::clone), obs)?;
        }
    }
}

/// The features of `frames` (image files, folders, videos at `fps`) as a keyed table, one row
/// per frame read; `obs` hears of frames skipped and of the progress.
pub fn features_table(
    ex: &mut FeatureExtractor,
    frames: &[PathBuf],
    fps: f64,
    obs: &mut dyn FrameSink,
) -> Result<KeyedTable, ReplayError> {
    let (mut keys, mut rows) = (Vec::new(), Vec::new());
    let mut columns = ex.column_names();
    let mm = MmColumns::of_sensor(ex.calibration(), &columns);
    let mut pass = Pass::open(frames, fps)?;
    each_extracted(ex, &mut pass, obs, |frame, f, obs| {
        match f {
            Ok(f) => {
                keys.push(frame.id.clone());
                let mut row = Vec::with_capacity(f.values.len() + mm.names().len());
                row.extend_from_slice(&f.values);
                mm.values_into(&f.values, &mut row);
                rows.push(row);
            }
            Err(e) => obs.warn(&format!("frame {}: {e}; skipped", frame.id)),
        }
        Ok(())
    })?;
    columns.extend(mm.names().iter().cloned());
    Ok(KeyedTable {
        columns,
        text: vec![Vec::new(); rows.len()],
        keys,
        rows,
        dropped_partial_line: false,
    })
}

/// What [`predict_table`] wrote.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Predicted {
    /// Rows with an estimate.
    pub written: usize,
    /// Rows without (NaN, the reason in the flags).
    pub missing: usize,
    /// Of the estimates, rows with lost markers filled.
    pub filled: usize,
}

/// Estimates every row of `keys` with `model` from `sources` into the CSV at `output` (the
/// model's estimate columns; an ensemble's spreads too). Lost markers are filled by a model on
/// principal components; a missing reading, too many lost markers or a model without
/// components gives no estimate rather than a wrong one, with the reason in the flags. When no
/// row gets one, nothing is written ([`ReplayError::NoEstimate`], with the first reason).
pub fn predict_table(
    model: &Model,
    sources: &InputSources<'_>,
    keys: &[String],
    output: &Path,
) -> Result<Predicted, ReplayError> {
    let write_err = |source| ReplayError::Write {
        path: output.to_path_buf(),
        source,
    };
    let columns = model.estimate_columns();
    let nan = vec![f64::NAN; columns.len()];
    let mut out = TableWriter::create(output, TableFormat::Csv, columns).map_err(write_err)?;
    let mut done = Predicted::default();
    let mut x = Vec::with_capacity(model.feature_columns.len());
    let mut first_why = None;
    for (r, key) in keys.iter().enumerate() {
        sources.row_into(r, &mut x);
        let written = match model.estimate(&x) {
            Ok(e) => {
                done.written += 1;
                let note = if e.filled > 0 {
                    done.filled += 1;
                    format!("filled {} inputs", e.filled)
                } else {
                    String::new()
                };
                out.write_row(key, &e.into_row(), &note)
            }
            Err(why) => {
                done.missing += 1;
                let why = why.to_string();
                let row = out.write_row(key, &nan, &why);
                first_why.get_or_insert(why);
                row
            }
        };
        written.map_err(write_err)?;
    }
    if let (0, Some(why)) = (done.written, first_why) {
        return Err(ReplayError::NoEstimate {
            path: output.to_path_buf(),
            frames: done.missing,
            why,
        });
    }
    out.finish().map_err(write_err)?;
    Ok(done)
}

/// What [`blobs_table`] wrote.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BlobsWritten {
    /// Frames detected.
    pub frames: usize,
    /// Blobs written.
    pub blobs: usize,
    /// Frames that could not be read.
    pub skipped: usize,
}

/// Writes every blob `det` finds in `frames` to `output` in `format` (one row per blob,
/// [`crate::schema::BLOB_COLUMNS`]); `obs` hears of frames skipped and of the progress.
pub fn blobs_table(
    det: &mut Detector,
    conv: MomentConvention,
    frames: &[PathBuf],
    (output, format): (&Path, TableFormat),
    obs: &mut dyn FrameSink,
) -> Result<BlobsWritten, ReplayError> {
    let write_err = |source| ReplayError::Write {
        path: output.to_path_buf(),
        source,
    };
    let columns = BLOB_COLUMNS.iter().map(|s| s.to_string()).collect();
    let mut out = TableWriter::create(output, format, columns).map_err(write_err)?;
    let mut done = BlobsWritten::default();
    let mut blobs = Vec::new();
    let mut pass = Pass::open(frames, 25.0)?;
    while let Some(f) = pass.next(obs)? {
        let d = det.detect_into(&f.image, &mut blobs);
        let level = d.level.map_or(f64::NAN, f64::from);
        for (k, b) in blobs.iter().enumerate() {
            let row = blob_row(k, b, conv, level, f.timestamp_s);
            out.write_row(&f.id, &row, "").map_err(write_err)?;
        }
        done.frames += 1;
        done.blobs += blobs.len();
    }
    done.skipped = pass.unreadable;
    out.finish().map_err(write_err)?;
    Ok(done)
}

#[cfg(test)]
mod tests {
    use super::*;
    use visuotact_sim::iats::{render, IatsConfig, Touch};
    use visuotact_vision::features::FeatureSet;

    /// Order-free, frames are extracted a batch at a time in parallel: the table holds what one
    /// extractor gives frame after frame, in the frames' order, and a frame of another size is
    /// skipped in its place, its warning in order.
    #[test]
    fn a_parallel_pass_gives_what_one_frame_after_another_gives() {
        let cfg = IatsConfig::SEED000;
        let cal = crate::test_support::iats_sensor();
        let dir = std::env::temp_dir().join(format!("visuotact-par-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let mut images = Vec::new();
        for k in 0..21u32 {
            let touch = Touch {
                x_mm: 10.0 + 2.0 * f64::from(k),
                y_mm: 22.0,
                depth_mm: f64::from(k % 4),
                ..Touch::default()
            };
            let img = if k == 9 {
                visuotact_image::RgbImage::new(10, 10)
            } else {
                render(&cfg, &touch, 100 + u64::from(k)).unwrap().0
            };
            visuotact_io::frames::write_png(&dir.join(format!("f{k:02}.png")), &img).unwrap();
            images.push(img);
        }
        let mut one = FeatureExtractor::new(cal.clone(), FeatureSet::ALL).unwrap();
        let want: Vec<Option<Vec<f64>>> = images
            .iter()
            .map(|img| one.extract(img).ok().map(|f| f.values.clone()))
            .collect();
        let mut ex = FeatureExtractor::new(cal, FeatureSet::ALL).unwrap();
        let mut warnings = Vec::new();
        let table = features_table(&mut ex, std::slice::from_ref(&dir), 25.0, &mut |w: &str| {
            warnings.push(w.to_string())
        })
        .unwrap();
        assert_eq!(table.keys.len(), 20);
        assert!(
            warnings.len() == 1 && warnings[0].starts_with("frame f09.png"),
            "{warnings:?}"
        );
        let kept: Vec<&Vec<f64>> = want.iter().flatten().collect();
        for (k, (got, want)) in table.rows.iter().zip(kept).enumerate() {
            let n = want.len();
            let same = got[..n]
                .iter()
                .zip(want)
                .all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(same, "row {k} ({}) differs", table.keys[k]);
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
