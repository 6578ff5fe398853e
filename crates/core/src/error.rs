//! Where a problem is ([`Location`]: file, episode, field, frame) and the core errors
//! that name it.

use std::fmt;
use std::path::PathBuf;

/// Where a problem is: file, episode, field and frame, each when known.
///
/// Displayed as `file 'x', episode 'y', field 'z', frame 12`, leaving out what is unknown.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Location {
    /// The file or folder the data came from.
    pub path: Option<PathBuf>,
    /// The episode id.
    pub episode: Option<String>,
    /// The array (field) name, e.g. `action` or `state[7]`.
    pub field: Option<String>,
    /// The frame index within the episode.
    pub frame: Option<usize>,
}

impl Location {
    /// A location in one episode.
    pub fn episode(id: impl Into<String>) -> Self {
        Self {
            episode: Some(id.into()),
            ..Self::default()
        }
    }

    /// The same location in a field.
    pub fn field(mut self, field: impl Into<String>) -> Self {
        self.field = Some(field.into());
        self
    }

    /// The same location at a frame.
    pub fn frame(mut self, frame: usize) -> Self {
        self.frame = Some(frame);
        self
    }

    /// The same location in a file.
    pub fn path(mut self, path: impl Into<PathBuf>) -> Self {
        self.path = Some(path.into());
        self
    }
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut parts = Vec::new();
        if let Some(p) = &self.path {
            parts.push(format!("file '{}'", p.display()));
        }
        if let Some(e) = &self.episode {
            parts.push(format!("episode '{e}'"));
        }
        if let Some(x) = &self.field {
            parts.push(format!("field '{x}'"));
        }
        if let Some(i) = self.frame {
            parts.push(format!("frame {i}"));
        }
        if parts.is_empty() {
            f.write_str("(unknown location)")
        } else {
            f.write_str(&parts.join(", "))
        }
    }
}

/// Errors of the core data model.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CoreError {
    /// An array does not have the width the layout asks for.
    #[error("{at}: expected {expected} values per frame, found {found}")]
    Width {
        /// Where.
        at: Location,
        /// Width the layout asks for.
        expected: usize,
        /// Width found.
        found: usize,
    },
    /// Arrays of one episode disagree on the number of frames.
    #[error("{at}: {found} frames where the episode has {expected}")]
    Length {
        /// Where.
        at: Location,
        /// Frames in the episode.
        expected: usize,
        /// Frames in this array.
        found: usize,
    },
    /// A flat buffer is not a whole number of frames.
    #[error("{at}: {len} values are not a whole number of frames of width {width}")]
    Ragged {
        /// Where.
        at: Location,
        /// Values in the buffer.
        len: usize,
        /// Frame width.
        width: usize,
    },
    /// A value is NaN or infinite.
    #[error("{at}: value {value} is not finite")]
    NotFinite {
        /// Where (field names the column, e.g. `action[3]`).
        at: Location,
        /// The value.
        value: f64,
    },
}
