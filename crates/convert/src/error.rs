//! The conversion errors, each naming the file, episode and field it concerns.

use std::path::PathBuf;

use dexjoco_core::{CoreError, Location};
use dexjoco_video::VideoError;

/// Errors of conversion; each names the file, episode and field it concerns when known.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ConvertError {
    /// The selection config could not be read or is invalid.
    #[error("selection config '{path}': {message}")]
    Config {
        /// The config file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// An episode lacks something the selection asks for, or has an unexpected shape.
    #[error("{at}: {message}")]
    Episode {
        /// Where.
        at: Box<Location>,
        /// What is wrong.
        message: String,
    },
    /// The episode data is inconsistent.
    #[error(transparent)]
    Core(#[from] CoreError),
    /// A video could not be probed, decoded, encoded or joined.
    #[error("{at}: {source}")]
    Video {
        /// Episode and camera.
        at: Box<Location>,
        /// Why.
        source: Box<VideoError>,
    },
    /// The output folder exists and is not empty.
    #[error("output folder '{0}' is not empty")]
    OutputNotEmpty(PathBuf),
    /// The output folder may not be replaced, overwrite or not.
    #[error("output folder '{}' will not be replaced: {reason}", out.display())]
    OverwriteRefused {
        /// The output folder.
        out: PathBuf,
        /// Why.
        reason: String,
    },
    /// A replay whose record says its task failed (augment's `--keep-failed`).
    #[error(
        "file '{}', field 'success': the replay failed its task (kept by augment --keep-failed); --include-failed converts it",
        dir.join(dexjoco_formats::raw::REPLAY_RECORD).display()
    )]
    FailedReplay {
        /// The replay folder.
        dir: PathBuf,
    },
    /// A replay a render check flagged (blank frames, a frozen video, non-finite values).
    #[error(
        "file '{}', field 'flags': the replay failed render checks: {flags}; --include-flagged converts it",
        dir.join(dexjoco_formats::raw::REPLAY_RECORD).display()
    )]
    FlaggedReplay {
        /// The replay folder.
        dir: PathBuf,
        /// Each flag in one line ([`dexjoco_formats::raw::RenderFlag::describe`]), `; `-joined.
        flags: String,
    },
    /// Every episode failed; the first reason is given.
    #[error("none of the {count} episode(s) could be converted; the first: {first}")]
    AllFailed {
        /// Episodes that failed.
        count: usize,
        /// The first failure.
        first: String,
    },
    /// The output format cannot carry what the options ask for.
    #[error("--format {format}: {message}")]
    Unsupported {
        /// The `--format` name.
        format: &'static str,
        /// What it cannot carry, and what can.
        message: String,
    },
    /// Nothing to convert.
    #[error("no episodes to convert (all were excluded or the input is empty)")]
    NoEpisodes,
    /// The dataset writer failed, or an episode does not fit the dataset.
    #[error(transparent)]
    Dataset(#[from] dexjoco_formats::DatasetError),
    /// An input episode could not be read.
    #[error("input '{path}': {message}")]
    Input {
        /// The file or folder.
        path: PathBuf,
        /// Why.
        message: String,
    },
    /// A file system operation failed (the message names the path).
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// Reading or writing a file through `dexjoco-formats` failed.
    #[error(transparent)]
    Format(#[from] dexjoco_formats::FormatError),
}

impl ConvertError {
    pub(crate) fn episode(id: &str, message: impl Into<String>) -> Self {
        Self::Episode {
            at: Location::episode(id).into(),
            message: message.into(),
        }
    }
}
