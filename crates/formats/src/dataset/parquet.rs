//! Small helpers over arrow/parquet for the LeRobot writers: column builders and file
//! writing with snappy.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use arrow_array::builder::{Float64Builder, Int64Builder, ListBuilder, StringBuilder};
use arrow_array::{
    ArrayRef, FixedSizeListArray, Float32Array, Int64Array, RecordBatch, StringArray,
};
use arrow_schema::{DataType, Field, Schema, SchemaRef};
use parquet::arrow::ArrowWriter;
use parquet::basic::Compression;
use parquet::errors::ParquetError;
use parquet::file::properties::WriterProperties;

use crate::error::DatasetError;

/// Maps a parquet error of the file at `path` into [`DatasetError::Parquet`].
pub(crate) fn parquet_err(path: &Path) -> impl Fn(ParquetError) -> DatasetError + '_ {
    move |source| DatasetError::Parquet {
        path: path.to_path_buf(),
        source,
    }
}

/// Snappy compression, as lerobot writes its files.
pub fn props() -> WriterProperties {
    WriterProperties::builder()
        .set_compression(Compression::SNAPPY)
        .build()
}

/// A `fixed_size_list<float32>[width]` column of row-major values.
pub(crate) fn f32_vectors(values: &[f64], width: usize) -> ArrayRef {
    let flat = Float32Array::from_iter_values(values.iter().map(|v| *v as f32));
    let field = Arc::new(Field::new("item", DataType::Float32, true));
    Arc::new(
        FixedSizeListArray::try_new(field, width as i32, Arc::new(flat), None).expect("whole rows"),
    )
}

/// A `float32` column.
pub(crate) fn f32_column(values: impl IntoIterator<Item = f32>) -> ArrayRef {
    Arc::new(Float32Array::from_iter_values(values))
}

/// An `int64` column.
pub(crate) fn i64_column(values: impl IntoIterator<Item = i64>) -> ArrayRef {
    Arc::new(Int64Array::from_iter_values(values))
}

/// A `string` column.
pub(crate) fn string_column<S: AsRef<str>>(values: impl IntoIterator<Item = S>) -> ArrayRef {
    Arc::new(StringArray::from_iter_values(values))
}

/// A `list<string>` column.
pub(crate) fn string_lists(values: &[Vec<String>]) -> ArrayRef {
    let mut b = ListBuilder::new(StringBuilder::new());
    for v in values {
        for s in v {
            b.values().append_value(s);
        }
        b.append(true);
    }
    Arc::new(b.finish())
}

/// A `list<double>` column.
pub(crate) fn f64_lists(values: &[Vec<f64>]) -> ArrayRef {
    let mut b = ListBuilder::new(Float64Builder::new());
    for v in values {
        b.values().append_slice(v);
        b.append(true);
    }
    Arc::new(b.finish())
}

/// A `list<int64>` column.
pub(crate) fn i64_lists(values: &[Vec<i64>]) -> ArrayRef {
    let mut b = ListBuilder::new(Int64Builder::new());
    for v in values {
        b.values().append_slice(v);
        b.append(true);
    }
    Arc::new(b.finish())
}

/// `list<list<list<double>>>` of per-channel values shaped C x 1 x 1 (image statistics).
pub(crate) fn f64_channel_lists(values: &[Vec<f64>]) -> ArrayRef {
    let mut b = ListBuilder::new(ListBuilder::new(ListBuilder::new(Float64Builder::new())));
    for v in values {
        for x in v {
            let mid = b.values();
            mid.values().values().append_value(*x);
            mid.values().append(true);
            mid.append(true);
        }
        b.append(true);
    }
    Arc::new(b.finish())
}

/// Builds a schema from the columns' own types (all nullable) with schema metadata.
pub(crate) fn batch(
    columns: Vec<(String, ArrayRef)>,
    metadata: HashMap<String, String>,
) -> RecordBatch {
    let fields: Vec<Field> = columns
        .iter()
        .map(|(n, a)| Field::new(n, a.data_type().clone(), true))
        .collect();
    let schema: SchemaRef = Arc::new(Schema::new_with_metadata(fields, metadata));
    RecordBatch::try_new(schema, columns.into_iter().map(|(_, a)| a).collect())
        .expect("columns of one length")
}

/// Writes one record batch as a whole parquet file (one row group).
pub fn write_file(path: &Path, batch: &RecordBatch) -> Result<(), DatasetError> {
    let file = fs_err::File::create(path)?;
    let err = parquet_err(path);
    let mut w = ArrowWriter::try_new(file, batch.schema(), Some(props())).map_err(&err)?;
    w.write(batch).map_err(&err)?;
    w.close().map_err(&err)?;
    Ok(())
}
