//! The error types of this crate's readers and writers ([`FormatError`], and
//! [`DatasetError`] of the dataset writers), and the problem records (stable code + file,
//! episode, field, frame) that manifests and reports keep.

use std::path::PathBuf;

use dexjoco_core::{CoreError, Location};
use serde::{Deserialize, Serialize};

/// Why an input was rejected, as a stable machine-readable code (kept in the manifest).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ProblemCode {
    /// The file could not be read at all (permissions, dangling link, I/O error).
    Unreadable,
    /// The file is empty.
    EmptyFile,
    /// The file ends early (an MCAP without its footer, a cut chunk).
    Truncated,
    /// The file is damaged or not in the expected format.
    Corrupt,
    /// A required array or channel is absent.
    MissingArray,
    /// An array has an unexpected data type.
    WrongDtype,
    /// An array has unexpected dimensions.
    WrongDimensions,
    /// Arrays disagree on the number of frames, or there are none.
    WrongLength,
    /// `meta/episode_ends` does not say one episode of all the frames.
    EpisodeEndsMismatch,
    /// The task is not one of the 11 DexJoCo tasks, or cannot be told.
    UnknownTask,
    /// A NaN or infinite value.
    NotFinite,
    /// Timestamps not increasing at the stated rate.
    Timestamps,
    /// A quaternion that is not of unit norm.
    NotUnitQuaternion,
    /// A hand target outside the actuator's control range.
    HandOutOfRange,
    /// The table height offset dh outside [0, 0.05].
    TableOffsetOutOfRange,
    /// More frames than the task's step cap.
    TooLong,
    /// The same content was already given in this run (the first copy is kept).
    Duplicate,
    /// A name from the data (episode id, task, camera) that cannot be a file name: a
    /// path, `..`, a hidden name, a control character, too long
    /// ([`dexjoco_core::safe_name`]).
    UnsafeName,
}

impl ProblemCode {
    /// The code as written in manifests and reports.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Unreadable => "unreadable",
            Self::EmptyFile => "empty_file",
            Self::Truncated => "truncated",
            Self::Corrupt => "corrupt",
            Self::MissingArray => "missing_array",
            Self::WrongDtype => "wrong_dtype",
            Self::WrongDimensions => "wrong_dimensions",
            Self::WrongLength => "wrong_length",
            Self::EpisodeEndsMismatch => "episode_ends_mismatch",
            Self::UnknownTask => "unknown_task",
            Self::NotFinite => "not_finite",
            Self::Timestamps => "timestamps",
            Self::NotUnitQuaternion => "not_unit_quaternion",
            Self::HandOutOfRange => "hand_out_of_range",
            Self::TableOffsetOutOfRange => "table_offset_out_of_range",
            Self::TooLong => "too_long",
            Self::Duplicate => "duplicate",
            Self::UnsafeName => "unsafe_name",
        }
    }
}

impl std::fmt::Display for ProblemCode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// One problem found in an input: its code, where it is and what is wrong.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Problem {
    /// Machine-readable code.
    pub code: ProblemCode,
    /// The file or folder.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file: Option<PathBuf>,
    /// The episode id (or source name before an id exists).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub episode: Option<String>,
    /// The array or channel, with a column when one is meant (`state[37]`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub field: Option<String>,
    /// The frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame: Option<usize>,
    /// What is wrong, in words, with the location.
    pub message: String,
}

impl Problem {
    /// A problem at `at`; `detail` says what is wrong (the location is prefixed).
    pub fn new(code: ProblemCode, at: &Location, detail: impl std::fmt::Display) -> Self {
        Self {
            code,
            file: at.path.clone(),
            episode: at.episode.clone(),
            field: at.field.clone(),
            frame: at.frame,
            message: format!("{at}: {detail}"),
        }
    }

    /// The location it names.
    pub fn location(&self) -> Location {
        Location {
            path: self.file.clone(),
            episode: self.episode.clone(),
            field: self.field.clone(),
            frame: self.frame,
        }
    }
}

impl std::fmt::Display for Problem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "[{}] {}", self.code, self.message)
    }
}

/// Errors of reading and writing files.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FormatError {
    /// A file operation failed.
    #[error("{op} '{}': {source}", path.display())]
    Io {
        /// What was being done (`read`, `write`, `rename`...).
        op: &'static str,
        /// The path.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// An input has one problem that stops reading it.
    #[error("{0}")]
    Input(Box<Problem>),
    /// Zarr storage or codec failure while writing.
    #[error("{at}: zarr: {message}")]
    Zarr {
        /// Where.
        at: Location,
        /// What zarrs said.
        message: String,
    },
    /// MCAP writing failed.
    #[error("{at}: mcap: {source}")]
    Mcap {
        /// Where.
        at: Location,
        /// The cause.
        #[source]
        source: Box<::mcap::McapError>,
    },
    /// A manifest could not be read or written.
    #[error("manifest '{}': {message}", path.display())]
    Manifest {
        /// The manifest file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// Another process is writing the folder.
    #[error(
        "'{}' is in use by process {pid}@{host} (lock file '{}'); if no such run is going on, remove that file",
        path.display(),
        file.display()
    )]
    Locked {
        /// The folder.
        path: PathBuf,
        /// The lock file.
        file: PathBuf,
        /// The process holding it.
        pid: u32,
        /// The host it runs on.
        host: String,
    },
    /// A file or folder an earlier run wrote would be replaced, and the command was not
    /// given `--overwrite`.
    #[error(
        "'{}' already exists: pass --overwrite to replace it, or choose another --out",
        path.display()
    )]
    WouldReplace {
        /// The file or folder.
        path: PathBuf,
    },
    /// A symbolic link where dexjoco-data writes (it makes none): writing through it
    /// would write outside the folder.
    #[error(
        "'{}' is a symbolic link{}: dexjoco-data never writes through a link it did not make; \
         remove the link (or copy what it points to in its place) and run again",
        path.display(),
        target.as_ref().map_or(String::new(), |t| format!(" to '{}'", t.display()))
    )]
    Linked {
        /// The link.
        path: PathBuf,
        /// Where it points.
        target: Option<PathBuf>,
    },
    /// An episode breaks the core data model.
    #[error(transparent)]
    Core(#[from] CoreError),
}

impl FormatError {
    /// An input problem.
    pub fn input(code: ProblemCode, at: &Location, detail: impl std::fmt::Display) -> Self {
        Self::Input(Box::new(Problem::new(code, at, detail)))
    }

    /// The problems this error stands for, as recorded in a manifest.
    pub fn problems(&self) -> Vec<Problem> {
        match self {
            Self::Input(p) => vec![(**p).clone()],
            Self::Io { path, source, .. } => vec![Problem::new(
                if source.kind() == std::io::ErrorKind::UnexpectedEof {
                    ProblemCode::Truncated
                } else {
                    ProblemCode::Unreadable
                },
                &Location::default().path(path),
                format!("{self}"),
            )],
            Self::Core(e) => vec![core_problem(e)],
            other => vec![Problem::new(
                ProblemCode::Corrupt,
                &Location::default(),
                other.to_string(),
            )],
        }
    }
}

fn core_problem(e: &CoreError) -> Problem {
    let (code, at) = match e {
        CoreError::Width { at, .. } => (ProblemCode::WrongDimensions, at),
        CoreError::Length { at, .. } => (ProblemCode::WrongLength, at),
        CoreError::Ragged { at, .. } => (ProblemCode::WrongDimensions, at),
        CoreError::NotFinite { at, .. } => (ProblemCode::NotFinite, at),
        _ => {
            return Problem {
                code: ProblemCode::Corrupt,
                file: None,
                episode: None,
                field: None,
                frame: None,
                message: e.to_string(),
            };
        }
    };
    let mut p = Problem::new(code, at, "");
    p.message = e.to_string();
    p
}

/// Shorthand for results of this crate.
pub type Result<T, E = FormatError> = std::result::Result<T, E>;

/// Maps an I/O error of `op` on `path` into [`FormatError::Io`].
pub fn io_err(
    op: &'static str,
    path: impl Into<PathBuf>,
) -> impl FnOnce(std::io::Error) -> FormatError {
    let path = path.into();
    move |source| FormatError::Io { op, path, source }
}

/// Errors of the dataset writers ([`crate::dataset`]); each names the file, episode and
/// field it concerns when known.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DatasetError {
    /// A dataset read is not what its format says (the message names the file and
    /// the field).
    #[error("{0}")]
    Layout(String),
    /// A field of a dataset's metadata is missing, of the wrong type or out of range.
    #[error("file '{}': {field}: {message}", path.display())]
    Metadata {
        /// The metadata file (`meta/info.json`, an episodes file).
        path: PathBuf,
        /// The field (`chunks_size`, `features.action.shape`, a column).
        field: String,
        /// What is wrong and what to do.
        message: String,
    },
    /// An episode does not fit the dataset (layout, cameras, decoded frames).
    #[error("{at}: {message}")]
    Episode {
        /// Where.
        at: Box<Location>,
        /// What is wrong.
        message: String,
    },
    /// A video could not be decoded or joined.
    #[error("{at}: {source}")]
    Video {
        /// Episode and camera, or the joined file.
        at: Box<Location>,
        /// Why.
        source: Box<dexjoco_video::VideoError>,
    },
    /// Writing a Parquet file failed.
    #[error("file '{}': {source}", path.display())]
    Parquet {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: parquet::errors::ParquetError,
    },
    /// Writing a JSON metadata file failed.
    #[error("file '{}': {source}", path.display())]
    Json {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: serde_json::Error,
    },
    /// Writing the Zarr store failed.
    #[error("input '{}': writing Zarr: {source}", path.display())]
    Zarr {
        /// The store.
        path: PathBuf,
        /// Why.
        #[source]
        source: Box<ZarrWriteError>,
    },
    /// A file system operation failed (the message names the path).
    #[error(transparent)]
    Io(#[from] std::io::Error),
}

impl DatasetError {
    /// A problem of episode `id`.
    pub fn episode(id: &str, message: impl Into<String>) -> Self {
        Self::Episode {
            at: Location::episode(id).into(),
            message: message.into(),
        }
    }
}

/// What zarrs said when a dataset's Zarr store could not be written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ZarrWriteError {
    /// The store folder could not be opened.
    #[error(transparent)]
    Store(#[from] zarrs::filesystem::FilesystemStoreCreateError),
    /// Metadata could not be stored.
    #[error(transparent)]
    Storage(#[from] zarrs::storage::StorageError),
    /// An array could not be created or resized.
    #[error(transparent)]
    Create(#[from] zarrs::array::ArrayCreateError),
    /// Chunks could not be encoded or stored.
    #[error(transparent)]
    Array(#[from] zarrs::array::ArrayError),
    /// Groups or array metadata could not be made ([`crate::zarr_v2`]).
    #[error(transparent)]
    Layout(#[from] crate::zarr_v2::ZarrV2Error),
}
