//! A column-at-a-time Parquet table: the few column kinds a LeRobot data set uses, each
//! `REQUIRED` (no nulls; a missing number is NaN): `int64`, `float`, `double`, UTF-8 strings,
//! and fixed-shape nested lists of `float`, `double`, `int64` or strings (`list<…>` per
//! dimension, the three-level LIST layout pyarrow writes and reads).

use std::path::Path;
use std::sync::Arc;

use parquet::basic::{LogicalType, Repetition, Type as PhysicalType};
use parquet::data_type::{ByteArray, ByteArrayType, DoubleType, FloatType, Int64Type};
use parquet::file::metadata::KeyValue;
use parquet::file::properties::WriterProperties;
use parquet::file::writer::SerializedFileWriter;
use parquet::schema::types::{Type, TypePtr};

use crate::LeRobotError;

/// A column's values, row after row (a list column: `shape`'s product per row, row-major).
#[derive(Clone, Debug, PartialEq)]
pub enum Values {
    /// `int64`.
    I64(Vec<i64>),
    /// `float`.
    F32(Vec<f32>),
    /// `double`.
    F64(Vec<f64>),
    /// UTF-8 strings.
    Str(Vec<String>),
}

impl Values {
    fn len(&self) -> usize {
        match self {
            Self::I64(v) => v.len(),
            Self::F32(v) => v.len(),
            Self::F64(v) => v.len(),
            Self::Str(v) => v.len(),
        }
    }

    fn physical(&self) -> PhysicalType {
        match self {
            Self::I64(_) => PhysicalType::INT64,
            Self::F32(_) => PhysicalType::FLOAT,
            Self::F64(_) => PhysicalType::DOUBLE,
            Self::Str(_) => PhysicalType::BYTE_ARRAY,
        }
    }
}

/// One column: a name, the shape of each row's value (`[]` a scalar) and the values.
#[derive(Clone, Debug, PartialEq)]
pub struct Column {
    /// Column name (dots and slashes allowed, as LeRobot names them).
    pub name: String,
    /// Each row's shape.
    pub shape: Vec<usize>,
    /// All rows' values.
    pub values: Values,
}

impl Column {
    /// A scalar column.
    pub fn scalar(name: &str, values: Values) -> Self {
        Self {
            name: name.into(),
            shape: Vec::new(),
            values,
        }
    }

    /// A column of `shape`d values.
    pub fn list(name: &str, shape: &[usize], values: Values) -> Self {
        Self {
            name: name.into(),
            shape: shape.to_vec(),
            values,
        }
    }

    fn per_row(&self) -> usize {
        self.shape.iter().product()
    }

    fn schema(&self) -> Result<TypePtr, LeRobotError> {
        let leaf_name = if self.shape.is_empty() {
            self.name.as_str()
        } else {
            "element"
        };
        let mut b = Type::primitive_type_builder(leaf_name, self.values.physical())
            .with_repetition(Repetition::REQUIRED);
        if matches!(self.values, Values::Str(_)) {
            b = b.with_logical_type(Some(LogicalType::String));
        }
        let mut t = Arc::new(b.build()?);
        for (d, _) in self.shape.iter().enumerate().rev() {
            let list = Type::group_type_builder("list")
                .with_repetition(Repetition::REPEATED)
                .with_fields(vec![t])
                .build()?;
            let name = if d == 0 {
                self.name.as_str()
            } else {
                "element"
            };
            t = Arc::new(
                Type::group_type_builder(name)
                    .with_repetition(Repetition::REQUIRED)
                    .with_logical_type(Some(LogicalType::List))
                    .with_fields(vec![Arc::new(list)])
                    .build()?,
            );
        }
        Ok(t)
    }

    /// Repetition levels of one row's leaves: 0 for the first, then one more than the
    /// outermost dimension whose index changed.
    fn rep_levels(&self, rows: usize) -> Vec<i16> {
        let n = self.per_row();
        let mut one = vec![0_i16; n];
        let mut idx = vec![0_usize; self.shape.len()];
        for level in one.iter_mut().skip(1) {
            let mut d = self.shape.len() - 1;
            loop {
                idx[d] += 1;
                if idx[d] < self.shape[d] {
                    break;
                }
                idx[d] = 0;
                d -= 1;
            }
            *level = d as i16 + 1;
        }
        one.repeat(rows)
    }
}

/// Writes `columns` (all with the same number of rows) as one row group into `path`, with
/// `metadata` as the file's key-value metadata.
pub fn write_table(
    path: &Path,
    columns: &[Column],
    metadata: &[(&str, String)],
) -> Result<(), LeRobotError> {
    let rows = columns.first().map_or(0, |c| {
        if c.per_row() == 0 {
            0
        } else {
            c.values.len() / c.per_row()
        }
    });
    for c in columns {
        if c.per_row() == 0 || c.values.len() != rows * c.per_row() {
            return Err(LeRobotError::Invalid(format!(
                "{}: column {} holds {} values, expected {} rows × {}",
                path.display(),
                c.name,
                c.values.len(),
                rows,
                c.per_row()
            )));
        }
    }
    let fields = columns
        .iter()
        .map(Column::schema)
        .collect::<Result<Vec<_>, _>>()?;
    let schema = Arc::new(
        Type::group_type_builder("schema")
            .with_fields(fields)
            .build()?,
    );
    let kv = metadata
        .iter()
        .map(|(k, v)| KeyValue::new((*k).to_string(), v.clone()))
        .collect();
    let props = Arc::new(
        WriterProperties::builder()
            .set_key_value_metadata(Some(kv))
            .set_created_by(format!("visuotact {}", env!("CARGO_PKG_VERSION")))
            .build(),
    );
    let file = std::fs::File::create(path).map_err(|e| LeRobotError::Io(path.into(), e))?;
    let mut writer = SerializedFileWriter::new(file, schema, props)?;
    let mut group = writer.next_row_group()?;
    for c in columns {
        let Some(mut col) = group.next_column()? else {
            break;
        };
        let rep = (!c.shape.is_empty()).then(|| c.rep_levels(rows));
        let def = rep.as_ref().map(|r| vec![c.shape.len() as i16; r.len()]);
        let (def, rep) = (def.as_deref(), rep.as_deref());
        match &c.values {
            Values::I64(v) => col.typed::<Int64Type>().write_batch(v, def, rep)?,
            Values::F32(v) => col.typed::<FloatType>().write_batch(v, def, rep)?,
            Values::F64(v) => col.typed::<DoubleType>().write_batch(v, def, rep)?,
            Values::Str(v) => {
                let bytes: Vec<ByteArray> = v.iter().map(|s| ByteArray::from(s.as_str())).collect();
                col.typed::<ByteArrayType>().write_batch(&bytes, def, rep)?
            }
        };
        col.close()?;
    }
    group.close()?;
    writer.close()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repetition_levels_follow_the_outermost_changed_dimension() {
        let c = Column::list("x", &[2, 3], Values::F64(vec![0.0; 12]));
        assert_eq!(c.rep_levels(2), [0, 2, 2, 1, 2, 2, 0, 2, 2, 1, 2, 2]);
        let c = Column::list("x", &[3, 1, 1], Values::F64(vec![0.0; 3]));
        assert_eq!(c.rep_levels(1), [0, 1, 1]);
    }

    #[test]
    fn a_column_of_the_wrong_length_is_refused() {
        let dir = std::env::temp_dir().join(format!("vt-pq-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let cols = [
            Column::scalar("a", Values::I64(vec![1, 2])),
            Column::list("b", &[2], Values::F32(vec![1.0, 2.0, 3.0])),
        ];
        let e = write_table(&dir.join("t.parquet"), &cols, &[]).unwrap_err();
        assert!(e.to_string().contains("column b holds 3 values"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
