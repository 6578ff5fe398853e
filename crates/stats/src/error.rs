//! The stats errors, each naming the file or folder, and the row or field where it helps.

use std::path::PathBuf;

/// Errors of the stats stage. Each names the file or folder it is about, and the row or
/// field where that helps.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum StatsError {
    /// A file or folder could not be read or written.
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// A file of another stage could not be read (an augment report).
    #[error(transparent)]
    Format(#[from] dexjoco_formats::FormatError),
    /// A CSV file is malformed.
    #[error("file '{}': {source}", path.display())]
    Csv {
        /// The file.
        path: PathBuf,
        /// What the CSV reader said (it names the line).
        source: csv::Error,
    },
    /// A JSON file is malformed, or JSON could not be written.
    #[error("file '{}': {source}", path.display())]
    Json {
        /// The file.
        path: PathBuf,
        /// What the JSON reader said (it names line and column).
        source: serde_json::Error,
    },
    /// A value in an input is not what it should be.
    #[error("{}{}: {message}", path.display(), row.map(|r| format!(", row {r}")).unwrap_or_default())]
    Invalid {
        /// The file or folder.
        path: PathBuf,
        /// The data row (1-based, header not counted), when the input is a table.
        row: Option<usize>,
        /// What is wrong.
        message: String,
    },
    /// An input holds nothing to analyse.
    #[error("{}: {message}", path.display())]
    Empty {
        /// The file or folder.
        path: PathBuf,
        /// What was looked for.
        message: String,
    },
    /// Arrays of the same name have different widths across episodes of one task.
    #[error(
        "task '{task}', episode '{episode}', field '{array}': {found} values per frame where the task's other episodes have {expected}"
    )]
    Width {
        /// The task.
        task: String,
        /// The episode.
        episode: String,
        /// The array name.
        array: String,
        /// Width of the earlier episodes.
        expected: usize,
        /// Width of this one.
        found: usize,
    },
    /// A plot could not be drawn or written.
    #[error("plot '{}': {message}", path.display())]
    Plot {
        /// The output file.
        path: PathBuf,
        /// What the plotting backend said.
        message: String,
    },
}

impl StatsError {
    /// An [`StatsError::Invalid`] without a row.
    pub(crate) fn invalid(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Self::Invalid {
            path: path.into(),
            row: None,
            message: message.into(),
        }
    }
}
