//! Reading a dataset's data files: record batches streamed one at a time, every failure
//! naming the file.

use std::path::Path;

use parquet::arrow::arrow_reader::{ParquetRecordBatchReader, ParquetRecordBatchReaderBuilder};

use crate::EditError;

/// A data file (parquet) of a dataset.
#[derive(Debug, Clone, Copy)]
pub(crate) struct DataFile<'a>(pub &'a Path);

impl DataFile<'_> {
    /// `e` as an error naming the file.
    pub fn error(&self, e: &dyn std::fmt::Display) -> EditError {
        EditError::Selection(format!("data file '{}': {e}", self.0.display()))
    }

    /// Its record batches, read one at a time.
    pub fn batches(&self) -> Result<ParquetRecordBatchReader, EditError> {
        ParquetRecordBatchReaderBuilder::try_new(fs_err::File::open(self.0)?.into_parts().0)
            .and_then(|b| b.build())
            .map_err(|e| self.error(&e))
    }
}
