//! Errors of the dataset commands: each names the dataset, episode, column or file.

use std::path::PathBuf;

/// Why a dataset command failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EditError {
    /// Reading or writing the dataset's files.
    #[error(transparent)]
    Dataset(#[from] dexjoco_formats::error::DatasetError),
    /// Staging or renaming the output folder.
    #[error(transparent)]
    Files(#[from] dexjoco_formats::error::FormatError),
    /// Cutting or joining videos.
    #[error("{context}: {source}")]
    Video {
        /// Which video of which episode.
        context: String,
        /// Why.
        source: dexjoco_video::VideoError,
    },
    /// A selection or split that cannot be applied (an unknown column, an index out of
    /// range, nothing left).
    #[error("{0}")]
    Selection(String),
    /// The output exists (and `--overwrite` was not given) or overlaps the source.
    #[error("output '{}': {message}", path.display())]
    Refused {
        /// The output.
        path: PathBuf,
        /// Why.
        message: String,
    },
    /// A file of the dataset could not be read or written.
    #[error(transparent)]
    Io(#[from] std::io::Error),
}
