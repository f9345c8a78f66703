//! Parquet tables as LeRobot reads them (through pyarrow and Hugging Face `datasets`):
//! one row group, snappy pages, lists in the standard three-level form.

use std::fs::File;
use std::path::Path;
use std::sync::Arc;

use parquet::basic::{Compression, LogicalType, Repetition, Type as Physical};
use parquet::data_type::{ByteArray, ByteArrayType, DoubleType, FloatType, Int64Type};
use parquet::file::metadata::KeyValue;
use parquet::file::properties::WriterProperties;
use parquet::file::writer::SerializedFileWriter;
use parquet::schema::types::Type;

use crate::DatasetError;

/// One column's values, row by row.
#[derive(Debug, Clone, PartialEq)]
pub enum Values {
    F32(Vec<f32>),
    F64(Vec<f64>),
    I64(Vec<i64>),
    Str(Vec<String>),
    /// A fixed-length list of float32 per row: `width` values per row, row-major.
    F32List {
        width: usize,
        values: Vec<f32>,
    },
    /// A list of strings per row.
    StrList(Vec<Vec<String>>),
}

impl Values {
    fn rows(&self) -> usize {
        match self {
            Values::F32(v) => v.len(),
            Values::F64(v) => v.len(),
            Values::I64(v) => v.len(),
            Values::Str(v) => v.len(),
            Values::F32List { width, values } => values.len() / (*width).max(1),
            Values::StrList(v) => v.len(),
        }
    }
}

/// A named column.
#[derive(Debug, Clone, PartialEq)]
pub struct Column {
    pub name: String,
    pub values: Values,
}

impl Column {
    pub fn new(name: impl Into<String>, values: Values) -> Self {
        Self {
            name: name.into(),
            values,
        }
    }
}

fn schema_err(e: impl std::fmt::Display) -> DatasetError {
    DatasetError::Parquet(e.to_string())
}

fn field(c: &Column) -> Result<Type, DatasetError> {
    fn required(name: &str, t: Physical) -> parquet::schema::types::PrimitiveTypeBuilder<'_> {
        Type::primitive_type_builder(name, t).with_repetition(Repetition::REQUIRED)
    }
    let list = |name: &str, element: Type| -> Result<Type, DatasetError> {
        let repeated = Type::group_type_builder("list")
            .with_repetition(Repetition::REPEATED)
            .with_fields(vec![Arc::new(element)])
            .build()
            .map_err(schema_err)?;
        Type::group_type_builder(name)
            .with_repetition(Repetition::REQUIRED)
            .with_logical_type(Some(LogicalType::List))
            .with_fields(vec![Arc::new(repeated)])
            .build()
            .map_err(schema_err)
    };
    let string = |name: &str| {
        required(name, Physical::BYTE_ARRAY)
            .with_logical_type(Some(LogicalType::String))
            .build()
            .map_err(schema_err)
    };
    match &c.values {
        Values::F32(_) => required(&c.name, Physical::FLOAT)
            .build()
            .map_err(schema_err),
        Values::F64(_) => required(&c.name, Physical::DOUBLE)
            .build()
            .map_err(schema_err),
        Values::I64(_) => required(&c.name, Physical::INT64)
            .build()
            .map_err(schema_err),
        Values::Str(_) => string(&c.name),
        Values::F32List { .. } => list(
            &c.name,
            required("element", Physical::FLOAT)
                .build()
                .map_err(schema_err)?,
        ),
        Values::StrList(_) => list(&c.name, string("element")?),
    }
}

/// Writes `columns` (equal row counts) as one parquet file at `path`, with the
/// key-value metadata `metadata`. Returns the file's size in bytes.
///
/// # Errors
/// [`DatasetError::Parquet`] for unequal row counts or a writer error,
/// [`DatasetError::Io`].
pub fn write_table(
    path: &Path,
    columns: &[Column],
    metadata: Vec<(String, String)>,
) -> Result<u64, DatasetError> {
    let rows = columns.first().map_or(0, |c| c.values.rows());
    if let Some(c) = columns.iter().find(|c| c.values.rows() != rows) {
        return Err(DatasetError::Parquet(format!(
            "{}: column {} has {} rows, the first {rows}",
            path.display(),
            c.name,
            c.values.rows()
        )));
    }
    let fields = columns
        .iter()
        .map(|c| field(c).map(Arc::new))
        .collect::<Result<Vec<_>, _>>()?;
    let schema = Type::group_type_builder("schema")
        .with_fields(fields)
        .build()
        .map_err(schema_err)?;
    let kv = metadata
        .into_iter()
        .map(|(k, v)| KeyValue::new(k, v))
        .collect();
    let props = WriterProperties::builder()
        .set_compression(Compression::SNAPPY)
        .set_key_value_metadata(Some(kv))
        .set_created_by("teleop export lerobot".to_owned())
        .build();
    let file = File::create(path).map_err(|e| DatasetError::io(path, e))?;
    let mut writer =
        SerializedFileWriter::new(file, Arc::new(schema), Arc::new(props)).map_err(schema_err)?;
    let mut group = writer.next_row_group().map_err(schema_err)?;
    let mut index = 0;
    while let Some(mut col) = group.next_column().map_err(schema_err)? {
        let c = columns
            .get(index)
            .ok_or_else(|| DatasetError::Parquet("more columns than given".to_owned()))?;
        index += 1;
        match &c.values {
            Values::F32(v) => {
                col.typed::<FloatType>()
                    .write_batch(v, None, None)
                    .map_err(schema_err)?;
            }
            Values::F64(v) => {
                col.typed::<DoubleType>()
                    .write_batch(v, None, None)
                    .map_err(schema_err)?;
            }
            Values::I64(v) => {
                col.typed::<Int64Type>()
                    .write_batch(v, None, None)
                    .map_err(schema_err)?;
            }
            Values::Str(v) => {
                let v: Vec<ByteArray> = v.iter().map(|s| ByteArray::from(s.as_str())).collect();
                col.typed::<ByteArrayType>()
                    .write_batch(&v, None, None)
                    .map_err(schema_err)?;
            }
            Values::F32List { width, values } => {
                let (def, rep) = list_levels(std::iter::repeat_n(*width, rows));
                col.typed::<FloatType>()
                    .write_batch(values, Some(&def), Some(&rep))
                    .map_err(schema_err)?;
            }
            Values::StrList(v) => {
                let (def, rep) = list_levels(v.iter().map(Vec::len));
                let flat: Vec<ByteArray> = v
                    .iter()
                    .flatten()
                    .map(|s| ByteArray::from(s.as_str()))
                    .collect();
                col.typed::<ByteArrayType>()
                    .write_batch(&flat, Some(&def), Some(&rep))
                    .map_err(schema_err)?;
            }
        }
        col.close().map_err(schema_err)?;
    }
    group.close().map_err(schema_err)?;
    writer.close().map_err(schema_err)?;
    Ok(std::fs::metadata(path)
        .map_err(|e| DatasetError::io(path, e))?
        .len())
}

/// Definition and repetition levels of a required list of required elements: a row
/// of `n > 0` elements is `def 1 x n`, `rep 0, 1, 1, ...`; an empty row `def 0, rep 0`.
fn list_levels(lengths: impl Iterator<Item = usize>) -> (Vec<i16>, Vec<i16>) {
    let (mut def, mut rep) = (Vec::new(), Vec::new());
    for n in lengths {
        if n == 0 {
            def.push(0);
            rep.push(0);
        }
        for i in 0..n {
            def.push(1);
            rep.push(i16::from(i > 0));
        }
    }
    (def, rep)
}

#[cfg(test)]
mod tests {
    use super::*;
    use parquet::file::reader::{FileReader, SerializedFileReader};

    #[test]
    fn every_column_kind_reads_back() {
        let dir = std::env::temp_dir().join(format!("teleop-pq-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let path = dir.join("t.parquet");
        let cols = vec![
            Column::new(
                "observation.state",
                Values::F32List {
                    width: 2,
                    values: vec![1.0, 2.0, 3.0, 4.0],
                },
            ),
            Column::new("timestamp", Values::F32(vec![0.0, 0.5])),
            Column::new("index", Values::I64(vec![7, 8])),
            Column::new("videos/top/from_timestamp", Values::F64(vec![0.25, 1.0])),
            Column::new("task", Values::Str(vec!["pick".into(), "pour".into()])),
            Column::new(
                "tasks",
                Values::StrList(vec![vec!["a".into()], vec!["b".into(), "c".into()]]),
            ),
        ];
        write_table(&path, &cols, vec![("k".into(), "v".into())]).expect("write");
        let reader = SerializedFileReader::new(File::open(&path).expect("open")).expect("reader");
        let meta = reader.metadata().file_metadata();
        assert_eq!(meta.num_rows(), 2);
        let kv = meta.key_value_metadata().expect("kv");
        assert!(
            kv.iter()
                .any(|k| k.key == "k" && k.value.as_deref() == Some("v"))
        );
        let rows: Vec<String> = reader
            .get_row_iter(None)
            .expect("rows")
            .map(|r| r.expect("row").to_string())
            .collect();
        assert!(
            rows[0].contains("observation.state: [1.0, 2.0]"),
            "{}",
            rows[0]
        );
        assert!(rows[1].contains("tasks: [\"b\", \"c\"]"), "{}", rows[1]);
        assert!(rows[1].contains("index: 8"), "{}", rows[1]);
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn unequal_columns_are_refused() {
        let dir = std::env::temp_dir().join(format!("teleop-pqe-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let err = write_table(
            &dir.join("t.parquet"),
            &[
                Column::new("a", Values::I64(vec![1, 2])),
                Column::new("b", Values::I64(vec![1])),
            ],
            vec![],
        )
        .expect_err("unequal");
        assert!(err.to_string().contains("column b has 1 rows"), "{err}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
