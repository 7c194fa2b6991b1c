//! Training tables: a feature table (from `extract`, `record` or `dataset`) joined on `frame`
//! with a label table, the model's inputs picked by name — the markers' features, the field
//! summary as [`FieldInputs`] says, and extra inputs (a gauge's reading) from the feature
//! table or a readings table. Frames with lost markers are kept for a model that fills them,
//! left out, or refused with the file, line, frame and column. `visuotact train`, `sweep` and
//! `predict` read their tables through it.

use std::collections::HashMap;

use visuotact_io::table::KeyedTable;
use visuotact_nn::fit::FieldInputs;
use visuotact_nn::model::{is_marker_column, unfillable};
use visuotact_vision::features::{is_mm_column, mm_twin, FIELD_COLUMNS, FIELD_COLUMNS_MM};

/// A table and the name its errors give it (a path, or "frames read with S").
#[derive(Clone, Copy, Debug)]
pub struct Named<'a> {
    /// The table.
    pub table: &'a KeyedTable,
    /// Its name in messages.
    pub name: &'a str,
}

/// Why a training table could not be joined.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum JoinError {
    /// A table does not read.
    #[error(transparent)]
    Read(#[from] visuotact_io::table::TableError),
    /// The feature table has no markers' columns.
    #[error("{features}: no per-marker feature columns (mNNN_…)")]
    NoMarkerColumns {
        /// The feature table.
        features: String,
    },
    /// The field summary alone was asked for and the table has none.
    #[error("{features}: no field-summary columns (field_rms_px …): extract the frames again, or train with --field no")]
    NoFieldColumns {
        /// The feature table.
        features: String,
    },
    /// An input is in neither table.
    #[error("{features}: no column `{column}`{also}: {what}")]
    NoInput {
        /// The feature table.
        features: String,
        /// The input.
        column: String,
        /// Where else it was looked for, or where to give it.
        also: String,
        /// What the input is for.
        what: String,
    },
    /// A target is not a label column.
    #[error("{labels}: no target column `{column}` (columns: {columns})")]
    NoTarget {
        /// The label table.
        labels: String,
        /// The target.
        column: String,
        /// The label table's columns.
        columns: String,
    },
    /// A frame misses an input nothing fills.
    #[error("{features}: line {line}, frame {frame}, column `{column}`: missing value ({why}); use --drop-incomplete to leave such frames out")]
    MissingInput {
        /// The feature table.
        features: String,
        /// Its line (the header is line 1).
        line: usize,
        /// The frame.
        frame: String,
        /// The input.
        column: String,
        /// Why it is missing.
        why: String,
    },
    /// A frame's target is missing.
    #[error("{labels}: frame {frame}, column `{column}`: missing target")]
    MissingTarget {
        /// The label table.
        labels: String,
        /// The frame.
        frame: String,
        /// The target.
        column: String,
    },
    /// Too few frames are left.
    #[error("only {frames} frames have both features ({features}) and labels ({labels}): too few to train")]
    TooFew {
        /// Frames left.
        frames: usize,
        /// The feature table.
        features: String,
        /// The label table.
        labels: String,
    },
}

/// Where a model's inputs come from: the feature table's columns, then the readings table's.
pub struct InputSources<'a> {
    features: &'a KeyedTable,
    /// Per input: `Ok(column)` in the feature table or `Err(column)` in the readings table.
    columns: Vec<Result<usize, usize>>,
    readings: Option<(&'a KeyedTable, HashMap<&'a str, usize>)>,
}

impl<'a> InputSources<'a> {
    /// Finds each of `names` (the feature table first); an error names both tables and says
    /// `what` the inputs are for.
    pub fn new(
        names: &[String],
        features: Named<'a>,
        readings: Option<Named<'a>>,
        what: &str,
    ) -> Result<Self, JoinError> {
        let columns = names
            .iter()
            .map(|c| {
                if let Some(i) = features.table.column(c) {
                    return Ok(Ok(i));
                }
                if let Some(i) = readings.and_then(|r| r.table.column(c)) {
                    return Ok(Err(i));
                }
                let also = match readings {
                    Some(r) => format!(" nor in {}", r.name),
                    None if is_marker_column(c) => String::new(),
                    None => " (give the table that has it with --readings)".to_string(),
                };
                Err(JoinError::NoInput {
                    features: features.name.to_string(),
                    column: c.clone(),
                    also,
                    what: what.to_string(),
                })
            })
            .collect::<Result<_, _>>()?;
        Ok(Self {
            features: features.table,
            columns,
            readings: readings.map(|r| (r.table, r.table.rows_by_key())),
        })
    }

    /// The inputs of feature row `r` into `x` (NaN where the readings have no such frame).
    pub fn row_into(&self, r: usize, x: &mut Vec<f64>) {
        let key = self.features.keys[r].as_str();
        let reading_row = self
            .readings
            .as_ref()
            .and_then(|(t, by_key)| by_key.get(key).map(|&i| &t.rows[i]));
        x.clear();
        x.extend(self.columns.iter().map(|c| match c {
            Ok(i) => self.features.rows[r][*i],
            Err(i) => reading_row.map_or(f64::NAN, |row| row[*i]),
        }));
    }
}

/// What to do with frames that miss inputs.
pub enum Incomplete<'a> {
    /// Leave them out.
    Drop,
    /// Keep them (the model fills them) when this holds for the number of marker inputs,
    /// unless [`unfillable`] says a frame cannot be filled (left out); otherwise refuse the
    /// table.
    FillIf(&'a dyn Fn(usize) -> bool),
}

/// Features and labels joined on `frame`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TrainingTable {
    /// Input rows (per-marker features, then the field summary and the extra inputs).
    pub x: Vec<Vec<f64>>,
    /// Target rows.
    pub t: Vec<Vec<f64>>,
    /// Names of the input columns: the markers' features, then the field summary and the
    /// extra inputs.
    pub feature_columns: Vec<String>,
    /// How many of the columns, at the end, are not markers' features.
    pub passthrough: usize,
    /// What was left out or kept, one line each (`note: …`, `warning: …`).
    pub notes: Vec<String>,
}

impl TrainingTable {
    /// How many of the columns are markers' features.
    pub fn marker_inputs(&self) -> usize {
        self.feature_columns.len() - self.passthrough
    }
}

/// How a training table is joined.
pub struct JoinConfig<'a> {
    /// Target columns of the labels.
    pub targets: &'a [String],
    /// Inputs besides the markers' features and the field summary.
    pub extra_inputs: &'a [String],
    /// Which of the markers' features and the field summary are inputs.
    pub field: FieldInputs,
    /// Frames with missing inputs.
    pub incomplete: Incomplete<'a>,
}

/// The input columns for `field` of a feature table (markers' features first).
fn input_names(
    features: Named<'_>,
    cfg: &JoinConfig<'_>,
    notes: &mut Vec<String>,
) -> Result<Vec<String>, JoinError> {
    let f = features.table;
    // A sensor with a scale wrote every length twice, in pixels and in millimetres: train on
    // the millimetres (comparable between sensors of one design), unitless features as they are.
    let in_mm = f
        .columns
        .iter()
        .any(|c| is_marker_column(c) && is_mm_column(c));
    let other_unit = |c: &str| {
        if in_mm {
            mm_twin(c).is_some()
        } else {
            is_mm_column(c)
        }
    };
    let mut names: Vec<String> = f
        .columns
        .iter()
        .filter(|c| is_marker_column(c) && !other_unit(c))
        .cloned()
        .collect();
    if names.is_empty() {
        return Err(JoinError::NoMarkerColumns {
            features: features.name.to_string(),
        });
    }
    if in_mm {
        notes.push(format!(
            "note: {} has displacements in millimetres (a sensor with a scale): the inputs are those ({} …), and the model needs a sensor with a scale",
            features.name, names[0]
        ));
    }
    let field_columns = if in_mm {
        FIELD_COLUMNS_MM
    } else {
        FIELD_COLUMNS
    };
    let has_field = field_columns.iter().all(|c| f.column(c).is_some());
    let field = cfg.field.resolve(names.len());
    let field_names = field_columns.iter().map(|c| (*c).to_string());
    match field {
        FieldInputs::No => {}
        FieldInputs::Only if !has_field => {
            return Err(JoinError::NoFieldColumns {
                features: features.name.to_string(),
            })
        }
        _ if !has_field => notes.push(format!(
            "note: {} has no field-summary columns (extracted by an older visuotact): the markers' features only",
            features.name
        )),
        FieldInputs::Yes | FieldInputs::Auto => names.extend(field_names),
        FieldInputs::Only => {
            names.clear();
            names.extend(field_names);
        }
    }
    names.extend(cfg.extra_inputs.iter().cloned());
    Ok(names)
}

/// Where each target sits among the labels' columns.
fn target_columns(labels: Named<'_>, targets: &[String]) -> Result<Vec<usize>, JoinError> {
    let l = labels.table;
    targets
        .iter()
        .map(|t| {
            l.column(t).ok_or_else(|| JoinError::NoTarget {
                labels: labels.name.to_string(),
                column: t.clone(),
                columns: l.columns.join(", "),
            })
        })
        .collect()
}

/// What a reader says of the tables whose unfinished last line was left out.
fn partial_line_notes(tables: &[Option<Named<'_>>]) -> Vec<String> {
    tables
        .iter()
        .flatten()
        .filter_map(|t| t.table.partial_line_note(t.name))
        .map(|n| format!("note: {n}"))
        .collect()
}

/// Joins `features` (and the extra inputs, from it or `readings`) with `labels` on `frame`.
pub fn training_table(
    features: Named<'_>,
    labels: Named<'_>,
    readings: Option<Named<'_>>,
    cfg: &JoinConfig<'_>,
) -> Result<TrainingTable, JoinError> {
    let mut notes = partial_line_notes(&[Some(features), Some(labels), readings]);
    let names = input_names(features, cfg, &mut notes)?;
    let marker_inputs = names.iter().filter(|c| is_marker_column(c)).count();
    let sources = InputSources::new(&names, features, readings, "an input named by --inputs")?;
    let l = labels.table;
    let tcols = target_columns(labels, cfg.targets)?;
    let by_key = l.rows_by_key();
    let drop = matches!(cfg.incomplete, Incomplete::Drop);
    let fill = match cfg.incomplete {
        Incomplete::Drop => false,
        Incomplete::FillIf(f) => f(marker_inputs),
    };
    let mut out = TrainingTable::default();
    let (mut unlabelled, mut dropped, mut filled_frames, mut filled_cells) = (0, 0, 0, 0);
    let mut xi = Vec::with_capacity(names.len());
    for (r, key) in features.table.keys.iter().enumerate() {
        let Some(&li) = by_key.get(key.as_str()) else {
            unlabelled += 1;
            continue;
        };
        sources.row_into(r, &mut xi);
        let missing = xi.iter().filter(|v| v.is_nan()).count();
        if missing > 0 && fill && unfillable(&names, &xi).is_none() {
            filled_frames += 1;
            filled_cells += missing;
        } else if let Some(c) = xi.iter().position(|v| v.is_nan()) {
            if drop || fill {
                dropped += 1;
                continue;
            }
            return Err(JoinError::MissingInput {
                features: features.name.to_string(),
                line: r + 2,
                frame: key.clone(),
                column: names[c].clone(),
                why: if is_marker_column(&names[c]) {
                    "a lost marker".to_string()
                } else {
                    format!("no reading `{}` for this frame", names[c])
                },
            });
        }
        let ti: Vec<f64> = tcols.iter().map(|&c| l.rows[li][c]).collect();
        if let Some(c) = ti.iter().position(|v| v.is_nan()) {
            return Err(JoinError::MissingTarget {
                labels: labels.name.to_string(),
                frame: key.clone(),
                column: cfg.targets[c].clone(),
            });
        }
        out.x.push(xi.clone());
        out.t.push(ti);
    }
    if unlabelled > 0 {
        notes.push(format!(
            "warning: {unlabelled} feature rows have no label in {} and were left out",
            labels.name
        ));
    }
    notes.extend(
        (dropped > 0)
            .then(|| format!("warning: {dropped} frames with missing inputs were left out")),
    );
    notes.extend((filled_frames > 0).then(|| {
        format!("{filled_frames} frames with lost markers kept: {filled_cells} inputs filled from the markers found")
    }));
    if out.x.len() < 10 {
        return Err(JoinError::TooFew {
            frames: out.x.len(),
            features: features.name.to_string(),
            labels: labels.name.to_string(),
        });
    }
    out.passthrough = names.len() - marker_inputs;
    out.feature_columns = names;
    out.notes = notes;
    Ok(out)
}

/// The files a training table is joined from: the feature table (its `flags` column is text),
/// the labels, and a readings table for extra inputs.
#[derive(Clone, Copy, Debug)]
pub struct TrainingFiles<'a> {
    /// Feature table from `extract`.
    pub features: &'a std::path::Path,
    /// Label table keyed by `frame`.
    pub labels: &'a std::path::Path,
    /// Table keyed by `frame` with extra inputs.
    pub readings: Option<&'a std::path::Path>,
}

/// Reads `files` and joins them ([`training_table`]), naming each file in errors and notes.
pub fn training_table_from_files(
    files: TrainingFiles<'_>,
    cfg: &JoinConfig<'_>,
) -> Result<TrainingTable, JoinError> {
    let f = KeyedTable::read(files.features, &["flags"])?;
    let l = KeyedTable::read(files.labels, &[])?;
    let r = files
        .readings
        .map(|p| KeyedTable::read(p, &[]))
        .transpose()?;
    let name = |p: &std::path::Path| p.display().to_string();
    let (f_name, l_name) = (name(files.features), name(files.labels));
    let r_name = files.readings.map(name);
    training_table(
        Named {
            table: &f,
            name: &f_name,
        },
        Named {
            table: &l,
            name: &l_name,
        },
        r.as_ref()
            .zip(r_name.as_deref())
            .map(|(table, name)| Named { table, name }),
        cfg,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(columns: &[&str], rows: Vec<(String, Vec<f64>)>) -> KeyedTable {
        KeyedTable {
            columns: columns.iter().map(|c| c.to_string()).collect(),
            text: vec![Vec::new(); rows.len()],
            keys: rows.iter().map(|(k, _)| k.clone()).collect(),
            rows: rows.into_iter().map(|(_, r)| r).collect(),
            dropped_partial_line: false,
        }
    }

    /// 12 frames of two markers' dx and the field summary; frame 3 lost marker 1.
    fn features() -> KeyedTable {
        let mut cols = vec!["n_found", "m000_dx_px", "m001_dx_px"];
        cols.extend(FIELD_COLUMNS);
        table(
            &cols,
            (0..12)
                .map(|k| {
                    let v = f64::from(k);
                    let lost = if k == 3 { f64::NAN } else { -v };
                    let mut row = vec![2.0, v, lost];
                    row.extend([v; 6]);
                    (format!("f{k}"), row)
                })
                .collect(),
        )
    }

    fn labels() -> KeyedTable {
        table(
            &["x_mm", "gauge_kpa"],
            (0..12)
                .map(|k| (format!("f{k}"), vec![f64::from(k) * 0.5, 100.0]))
                .collect(),
        )
    }

    #[test]
    fn inputs_are_picked_by_name_and_lost_markers_kept_or_refused() {
        let (f, l) = (features(), labels());
        let named = |table, name| Named { table, name };
        let targets = ["x_mm".to_string()];
        let extra = ["gauge_kpa".to_string()];
        let fills = |_: usize| true;
        let cfg = JoinConfig {
            targets: &targets,
            extra_inputs: &extra,
            field: FieldInputs::Yes,
            incomplete: Incomplete::FillIf(&fills),
        };
        let t = training_table(
            named(&f, "f.csv"),
            named(&l, "l.csv"),
            Some(named(&l, "l.csv")),
            &cfg,
        )
        .unwrap();
        assert_eq!(t.feature_columns.len(), 2 + 6 + 1);
        assert_eq!((t.marker_inputs(), t.passthrough), (2, 7));
        assert_eq!(t.x.len(), 12);
        assert_eq!(t.x[5][..3], [5.0, -5.0, 5.0]);
        assert_eq!(t.x[5][8], 100.0, "the gauge from the readings table");
        assert!(
            t.notes[0].starts_with("1 frames with lost markers kept"),
            "{:?}",
            t.notes
        );
        // Without filling, the lost marker is refused with its line, frame and column.
        let refuse = |_: usize| false;
        let cfg = JoinConfig {
            incomplete: Incomplete::FillIf(&refuse),
            extra_inputs: &[],
            ..cfg
        };
        let err = training_table(named(&f, "f.csv"), named(&l, "l.csv"), None, &cfg).unwrap_err();
        assert_eq!(
            err.to_string(),
            "f.csv: line 5, frame f3, column `m001_dx_px`: missing value (a lost marker); use --drop-incomplete to leave such frames out"
        );
        // The field summary alone; a target that is not there.
        let only = JoinConfig {
            field: FieldInputs::Only,
            incomplete: Incomplete::Drop,
            ..cfg
        };
        let t = training_table(named(&f, "f.csv"), named(&l, "l.csv"), None, &only).unwrap();
        assert_eq!(t.feature_columns, FIELD_COLUMNS.map(String::from));
        let wrong = ["y_mm".to_string()];
        let err = training_table(
            named(&f, "f.csv"),
            named(&l, "l.csv"),
            None,
            &JoinConfig {
                targets: &wrong,
                ..only
            },
        )
        .unwrap_err();
        assert!(matches!(err, JoinError::NoTarget { .. }), "{err}");
    }
}
