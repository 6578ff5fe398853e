//! Exit statuses (documented in `--help`) and errors that carry a hint.

use std::fmt;
use std::process::ExitCode;

/// The process exit status.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExitStatus {
    /// Everything worked.
    Success = 0,
    /// The command failed.
    Failure = 1,
    /// Bad flags or values (clap exits with 2 itself for what it parses).
    Usage = 2,
    /// Done, but some episodes were rejected.
    Partial = 3,
    /// The subcommand is not built yet.
    NotAvailable = 4,
}

impl From<ExitStatus> for ExitCode {
    fn from(s: ExitStatus) -> Self {
        ExitCode::from(s as u8)
    }
}

/// An error meant for the user, with an optional hint and its exit status.
#[derive(Debug)]
pub struct CliError {
    /// What went wrong.
    pub message: String,
    /// What to do about it.
    pub hint: Option<String>,
    /// Exit status to end with.
    pub status: ExitStatus,
}

impl fmt::Display for CliError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for CliError {}
