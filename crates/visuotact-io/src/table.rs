//! Per-frame tables written as they are produced: CSV or JSON lines.
//!
//! A row is the frame id, numeric cells and one free-text `flags` cell. Non-finite numbers are
//! missing values: empty in CSV, `null` in JSON. A table file is written as one
//! [`crate::output::OutputFile`] (a temporary file beside it, created exclusively) and takes
//! its name only at [`TableWriter::finish`]: a run that fails or is stopped leaves no torn
//! table under the final name and no temporary behind. Standard output (`-`) gets every row as
//! it comes.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::output::OutputFile;

/// Table layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum TableFormat {
    /// Comma-separated values with a header row.
    #[default]
    Csv,
    /// One JSON object per line.
    Jsonl,
}

visuotact_image::names_from_str!(TableFormat, "table format");

impl TableFormat {
    /// The names [`TableFormat::from_name`] and `FromStr` read (each is also what `name` writes,
    /// where the type has one).
    pub const NAMES: &'static [&'static str] = &["csv", "jsonl"];

    /// Parses `csv` or `jsonl`.
    pub fn from_name(s: &str) -> Option<Self> {
        match s {
            "csv" => Some(Self::Csv),
            "jsonl" | "json" | "ndjson" => Some(Self::Jsonl),
            _ => None,
        }
    }
}

/// Appends one CSV row of [`TableWriter`]'s layout (`frame`, the values — empty where not
/// finite — and `flags`) to `line`, without the line end.
pub fn push_csv_row(line: &mut String, frame: &str, values: &[f64], flags: &str) {
    line.push_str(&csv_escape(frame));
    for v in values {
        line.push(',');
        if v.is_finite() {
            line.push_str(&format_number(*v));
        }
    }
    line.push(',');
    line.push_str(&csv_escape(flags));
}

/// Writes rows of `frame`, numeric columns and `flags`.
pub struct TableWriter {
    out: TableOut,
    path: PathBuf,
    format: TableFormat,
    columns: Vec<String>,
    line: String,
}

fn csv_escape(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

impl TableWriter {
    /// Creates `path` (`-` for standard output) with the given numeric column names; the file
    /// appears under its name at [`TableWriter::finish`].
    pub fn create(path: &Path, format: TableFormat, columns: Vec<String>) -> std::io::Result<Self> {
        let out = if path.as_os_str() == "-" {
            TableOut::Stdout(std::io::stdout())
        } else {
            TableOut::File(OutputFile::create(path)?)
        };
        let mut w = Self {
            out,
            path: path.to_path_buf(),
            format,
            columns,
            line: String::new(),
        };
        if format == TableFormat::Csv {
            let mut header = String::from("frame");
            for c in &w.columns {
                header.push(',');
                header.push_str(&csv_escape(c));
            }
            header.push_str(",flags\n");
            w.out.write_all(header.as_bytes())?;
            w.out.flush()?;
        }
        Ok(w)
    }

    /// Flushes the rows and gives the table its name (over any file of that name).
    pub fn finish(self) -> std::io::Result<()> {
        match self.out {
            TableOut::Stdout(mut s) => s.flush(),
            TableOut::File(f) => f.finish(),
        }
    }

    /// Where the table goes.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Appends one row; `values` must have one entry per column.
    pub fn write_row(&mut self, frame: &str, values: &[f64], flags: &str) -> std::io::Result<()> {
        assert_eq!(
            values.len(),
            self.columns.len(),
            "row width must match the header"
        );
        self.line.clear();
        match self.format {
            TableFormat::Csv => push_csv_row(&mut self.line, frame, values, flags),
            TableFormat::Jsonl => {
                self.line.push_str("{\"frame\":");
                self.line
                    .push_str(&serde_json::to_string(frame).unwrap_or_default());
                for (c, v) in self.columns.iter().zip(values) {
                    self.line.push(',');
                    self.line
                        .push_str(&serde_json::to_string(c).unwrap_or_default());
                    self.line.push(':');
                    if v.is_finite() {
                        self.line.push_str(&format_number(*v));
                    } else {
                        self.line.push_str("null");
                    }
                }
                self.line.push_str(",\"flags\":");
                self.line
                    .push_str(&serde_json::to_string(flags).unwrap_or_default());
                self.line.push('}');
            }
        }
        self.line.push('\n');
        self.out.write_all(self.line.as_bytes())?;
        // Standard output gets every row as it comes; a file is whole only when finished.
        match &mut self.out {
            TableOut::Stdout(s) => s.flush(),
            TableOut::File(_) => Ok(()),
        }
    }
}

/// Where a table's rows go: standard output as they come, or a file that takes its name when
/// finished (dropped unfinished, it leaves nothing behind).
enum TableOut {
    Stdout(std::io::Stdout),
    File(OutputFile),
}

impl Write for TableOut {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        match self {
            Self::Stdout(s) => s.write(buf),
            Self::File(f) => f.write(buf),
        }
    }

    fn flush(&mut self) -> std::io::Result<()> {
        match self {
            Self::Stdout(s) => s.flush(),
            Self::File(f) => f.flush(),
        }
    }
}

/// Shortest text that reads back as the same `f64` (integers without a decimal point).
pub fn format_number(v: f64) -> String {
    if v == v.trunc() && v.abs() < 1e15 {
        format!("{}", v as i64)
    } else {
        format!("{v}")
    }
}

/// A CSV table keyed by its `frame` column, every other column numeric (empty cells and the
/// text `NaN` are missing values, NaN); non-numeric columns named in `text_columns` are skipped.
#[derive(Clone, Debug, PartialEq)]
pub struct KeyedTable {
    /// Column names, without `frame` and skipped text columns.
    pub columns: Vec<String>,
    /// The `frame` value of each row.
    pub keys: Vec<String>,
    /// Values, one row per key.
    pub rows: Vec<Vec<f64>>,
    /// Cells of the `text_columns` the file has (in the order asked for), one row per key;
    /// a text column the file lacks reads as an empty cell.
    pub text: Vec<Vec<String>>,
    /// Whether an unfinished last line (no line end: a writer stopped mid-row) was left out.
    pub dropped_partial_line: bool,
}

/// Why a table file does not read: the file, the line at fault when there is one, and what
/// is wrong (with the line and column in words).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{}: {why}", path.display())]
pub struct TableError {
    /// The file.
    pub path: std::path::PathBuf,
    /// The line at fault (from 1, the header being line 1).
    pub line: Option<usize>,
    /// What is wrong.
    pub why: String,
}

impl TableError {
    /// An error about `path` (at `line`, when one is at fault).
    pub fn new(path: &Path, line: Option<usize>, why: String) -> Self {
        Self {
            path: path.to_path_buf(),
            line,
            why,
        }
    }
}

/// The text of a table a writer may have been killed while appending to: complete lines only.
/// Returns the text up to the last line end and whether a partial line was cut off.
pub fn complete_lines(text: &str) -> (&str, bool) {
    match text.rfind('\n') {
        Some(i) if i + 1 < text.len() => (&text[..=i], true),
        Some(_) => (text, false),
        None => ("", !text.is_empty()),
    }
}

/// The number in `cell` at `line`, column `column` of `path`. `missing_ok`: an empty cell or
/// `nan` reads as NaN (a value not measured); otherwise it is an error. Infinite values are
/// always errors.
pub(crate) fn cell_number(
    path: &Path,
    (line, column): (usize, &str),
    cell: &str,
    missing_ok: bool,
) -> Result<f64, TableError> {
    let fail = |why: String| {
        TableError::new(
            path,
            Some(line),
            format!("line {line}, column `{column}`: {why}"),
        )
    };
    let cell = cell.trim();
    if missing_ok && (cell.is_empty() || cell.eq_ignore_ascii_case("nan")) {
        return Ok(f64::NAN);
    }
    let v: f64 = cell
        .parse()
        .map_err(|_| fail(format!("{cell:?} is not a number")))?;
    if v.is_infinite() || (!missing_ok && v.is_nan()) {
        return Err(fail(if missing_ok {
            "infinite value".to_string()
        } else {
            "not a finite number".to_string()
        }));
    }
    Ok(v)
}

/// The column a table is keyed by: `frame`, or where a table has none, the first of the other
/// names data sets give the frame's file (a TacTip data set's `image_name`, the Franka
/// TacTip sets' `sensor_image`).
pub const KEY_COLUMNS: [&str; 6] = [
    "frame",
    "image_name",
    "sensor_image",
    "image",
    "filename",
    "file",
];

/// Where the key is among `header`'s columns ([`KEY_COLUMNS`]), or why there is none.
fn key_column(header: &[String]) -> Result<usize, String> {
    KEY_COLUMNS
        .iter()
        .find_map(|k| header.iter().position(|h| h == k))
        .ok_or_else(|| {
            format!(
                "no `frame` column (nor {}; columns: {})",
                KEY_COLUMNS[1..].join(", "),
                header.join(", ")
            )
        })
}

/// The columns read as numbers: all but the key, the `text_columns` and those whose `first`
/// cell is words, not a number (a name or a note).
fn numeric_columns(
    header: &[String],
    key: usize,
    text_columns: &[&str],
    first: Option<&csv::StringRecord>,
) -> Vec<usize> {
    let words = |i: usize| {
        first.is_some_and(|r| {
            let c = r.get(i).unwrap_or("").trim();
            !c.is_empty() && !c.eq_ignore_ascii_case("nan") && c.parse::<f64>().is_err()
        })
    };
    (0..header.len())
        .filter(|&i| i != key && !text_columns.contains(&header[i].as_str()) && !words(i))
        .collect()
}

impl KeyedTable {
    /// Reads `path`; errors name the file, the line and the column. The key is the first of
    /// [`KEY_COLUMNS`] the header has; a column whose first cell is not a number (a name, a
    /// note) is left out unless it is one of `text_columns`.
    pub fn read(path: &Path, text_columns: &[&str]) -> Result<Self, TableError> {
        let text = crate::read::text_of_file(path)
            .map_err(|e| TableError::new(path, None, format!("cannot read: {e}")))?;
        Self::from_text(&text, path, text_columns)
    }

    /// Reads `path` ([`KeyedTable::read`]); an unfinished last line left out is said in
    /// `notes`, naming the file ([`partial_line_note`]): what every reader that reports to a
    /// user calls.
    pub fn read_noting(
        path: &Path,
        text_columns: &[&str],
        notes: &mut Vec<String>,
    ) -> Result<Self, TableError> {
        let t = Self::read(path, text_columns)?;
        notes.extend(t.partial_line_note(&path.display().to_string()));
        Ok(t)
    }

    /// Parses a table already in memory; `path` is the name errors give it.
    pub fn from_text(text: &str, path: &Path, text_columns: &[&str]) -> Result<Self, TableError> {
        let fail = |line, why| TableError::new(path, line, why);
        let (text, dropped_partial_line) = complete_lines(text);
        if text.is_empty() {
            return Err(fail(
                None,
                "empty table (no complete header line)".to_string(),
            ));
        }
        let mut rd = csv::ReaderBuilder::new()
            .has_headers(true)
            .from_reader(text.as_bytes());
        let header: Vec<String> = rd
            .headers()
            .map_err(|e| fail(None, format!("bad header: {e}")))?
            .iter()
            .map(str::to_string)
            .collect();
        let key_col = key_column(&header).map_err(|why| fail(None, why))?;
        let records: Vec<csv::StringRecord> = rd
            .records()
            .enumerate()
            .map(|(n, rec)| rec.map_err(|e| fail(Some(n + 2), format!("line {}: {e}", n + 2))))
            .collect::<Result<_, _>>()?;
        let keep = numeric_columns(&header, key_col, text_columns, records.first());
        let columns = keep.iter().map(|&i| header[i].clone()).collect();
        let text_at: Vec<Option<usize>> = text_columns
            .iter()
            .map(|c| header.iter().position(|h| h == c))
            .collect();
        let (mut keys, mut rows, mut text) = (Vec::new(), Vec::new(), Vec::new());
        let mut seen = std::collections::HashMap::new();
        for (n, rec) in records.into_iter().enumerate() {
            let line = n + 2;
            if rec.len() != header.len() {
                return Err(fail(
                    Some(line),
                    format!(
                        "line {line}: {} cells, the header has {}",
                        rec.len(),
                        header.len()
                    ),
                ));
            }
            if let Some(first) = seen.insert(rec[key_col].to_string(), line) {
                return Err(fail(
                    Some(line),
                    format!(
                        "line {line}: frame `{}` again (first on line {first}): each frame once",
                        &rec[key_col]
                    ),
                ));
            }
            keys.push(rec[key_col].to_string());
            text.push(
                text_at
                    .iter()
                    .map(|i| i.map_or_else(String::new, |i| rec[i].to_string()))
                    .collect(),
            );
            let row = keep
                .iter()
                .map(|&i| cell_number(path, (line, &header[i]), &rec[i], true))
                .collect::<Result<_, _>>()?;
            rows.push(row);
        }
        Ok(Self {
            columns,
            keys,
            rows,
            text,
            dropped_partial_line,
        })
    }

    /// Row index of each key.
    pub fn rows_by_key(&self) -> std::collections::HashMap<&str, usize> {
        self.keys
            .iter()
            .enumerate()
            .map(|(i, k)| (k.as_str(), i))
            .collect()
    }

    /// Index of a column.
    pub fn column(&self, name: &str) -> Option<usize> {
        self.columns.iter().position(|c| c == name)
    }

    /// The note a reader of the table at `name` gives when its unfinished last line was left
    /// out ([`partial_line_note`]), so that no reader drops it in silence.
    pub fn partial_line_note(&self, name: &str) -> Option<String> {
        partial_line_note(self.dropped_partial_line, name)
    }
}

/// `NAME: an unfinished last line (no line end) was left out` when `dropped`: the one wording
/// of what a table reader says of a row a writer was killed in the middle of.
pub fn partial_line_note(dropped: bool, name: &str) -> Option<String> {
    dropped.then(|| format!("{name}: an unfinished last line (no line end) was left out"))
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn a_data_sets_image_name_keys_it_and_its_name_columns_are_left_out() {
        let text = "image_name,data_name,pose_2,move_1\nframe_0_0.png,frame_0,0.75,-0.1\nframe_1_0.png,frame_1,-0.3,nan\n";
        let t = KeyedTable::from_text(text, Path::new("targets.csv"), &[]).unwrap();
        assert_eq!(t.keys, ["frame_0_0.png", "frame_1_0.png"]);
        assert_eq!(t.columns, ["pose_2", "move_1"]);
        assert_eq!(t.rows[0], [0.75, -0.1]);
        assert!(t.rows[1][1].is_nan());
        // The Franka TacTip sets key theirs by `sensor_image`.
        let franka = "sensor_image,pose_z,shear_x\nimage_1.png,0.5,3.4\n";
        let t = KeyedTable::from_text(franka, Path::new("labels.csv"), &[]).unwrap();
        assert_eq!((t.keys[0].as_str(), t.columns.len()), ("image_1.png", 2));
        // Words further down a column of numbers are still an error, with the line.
        let bad = "frame,x_mm\na,1\nb,oops\n";
        let e = KeyedTable::from_text(bad, Path::new("l.csv"), &[]).unwrap_err();
        assert!(
            e.to_string()
                .contains("line 3, column `x_mm`: \"oops\" is not a number"),
            "{e}"
        );
        let none = KeyedTable::from_text("name,x\na,1\n", Path::new("l.csv"), &[]).unwrap_err();
        assert!(
            none.to_string()
                .contains("no `frame` column (nor image_name"),
            "{none}"
        );
    }

    #[test]
    fn a_frame_twice_is_an_error_naming_both_lines() {
        let d = std::env::temp_dir().join(format!("visuotact-dup-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let p = d.join("l.csv");
        std::fs::write(&p, "frame,x_mm\na,1\nb,2\na,3\n").unwrap();
        let e = KeyedTable::read(&p, &[]).unwrap_err().to_string();
        assert!(
            e.contains("line 4: frame `a` again (first on line 2)"),
            "{e}"
        );
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_table_takes_its_name_only_when_finished() {
        let d = std::env::temp_dir().join(format!("visuotact-part-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        let p = d.join("t.csv");
        let parts = || {
            std::fs::read_dir(&d)
                .unwrap()
                .filter(|e| {
                    e.as_ref()
                        .unwrap()
                        .file_name()
                        .to_string_lossy()
                        .ends_with(".part~")
                })
                .count()
        };
        let mut w = TableWriter::create(&p, TableFormat::Csv, vec!["x".into()]).unwrap();
        w.write_row("a", &[1.5], "").unwrap();
        assert!(!p.exists() && parts() == 1);
        w.finish().unwrap();
        assert_eq!(
            std::fs::read_to_string(&p).unwrap(),
            "frame,x,flags\na,1.5,\n"
        );
        assert_eq!(parts(), 0);
        // A table dropped unfinished (an error, Ctrl-C) leaves the old file and no temporary.
        let mut w = TableWriter::create(&p, TableFormat::Csv, vec!["y".into()]).unwrap();
        w.write_row("b", &[2.0], "").unwrap();
        drop(w);
        assert_eq!(parts(), 0);
        assert!(std::fs::read_to_string(&p).unwrap().starts_with("frame,x,"));
        std::fs::remove_dir_all(&d).unwrap();
    }
}
