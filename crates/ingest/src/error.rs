//! The error type of the ingest stage: a file problem (from `dexjoco-formats`) or an
//! episode that fails validation.

use dexjoco_core::Location;
use dexjoco_formats::{FormatError, Problem, ProblemCode};

/// Errors of reading, validating and storing episodes.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum IngestError {
    /// Reading or writing a file failed, or an input has one problem that stops reading it.
    #[error(transparent)]
    Format(#[from] FormatError),
    /// An episode failed validation (every problem found is listed).
    #[error("{} problem(s); first: {}", .0.len(), .0.first().map(ToString::to_string).unwrap_or_default())]
    Invalid(Vec<Problem>),
}

impl IngestError {
    /// An input problem.
    pub fn input(code: ProblemCode, at: &Location, detail: impl std::fmt::Display) -> Self {
        Self::Format(FormatError::input(code, at, detail))
    }

    /// The problems this error stands for, as recorded in a manifest.
    pub fn problems(&self) -> Vec<Problem> {
        match self {
            Self::Format(e) => e.problems(),
            Self::Invalid(ps) => ps.clone(),
        }
    }
}

/// Shorthand for results of this crate.
pub type Result<T, E = IngestError> = std::result::Result<T, E>;
