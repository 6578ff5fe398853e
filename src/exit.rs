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
    /// Done, but some inputs (episodes, replays, tasks) were left out; each is named.
    Partial = 3,
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

/// The error's message and its causes, each once: a cause whose text its parent's
/// message already holds (`#[error("...: {source}")]`) is left out.
pub fn messages(err: &anyhow::Error) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    let mut parent = String::new();
    for e in err.chain() {
        let text = e.to_string();
        if lines.is_empty() || !parent.contains(&text) {
            lines.push(text.clone());
        }
        parent = text;
    }
    lines
}

/// The error and its causes (each once) on one line, joined by `: `.
pub fn one_line(err: &anyhow::Error) -> String {
    messages(err).join(": ")
}

/// Whether an error (or one of its causes) is a folder locked by another run.
pub fn is_locked(err: &anyhow::Error) -> bool {
    use dexjoco_formats::FormatError;
    err.chain().any(|e| {
        matches!(e.downcast_ref(), Some(FormatError::Locked { .. }))
            || matches!(
                e.downcast_ref(),
                Some(dexjoco_ingest::IngestError::Format(
                    FormatError::Locked { .. }
                ))
            )
            || matches!(
                e.downcast_ref(),
                Some(dexjoco_convert::ConvertError::Format(
                    FormatError::Locked { .. }
                ))
            )
            || matches!(
                e.downcast_ref(),
                Some(dexjoco_augment::AugmentError::Format(
                    FormatError::Locked { .. }
                ))
            )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cause_the_message_embeds_is_printed_once() {
        let io = std::io::Error::other("disk full");
        let err = anyhow::Error::new(dexjoco_formats::FormatError::Io {
            op: "write",
            path: "out/x".into(),
            source: io,
        })
        .context("augmenting into out");
        assert_eq!(
            messages(&err),
            ["augmenting into out", "write 'out/x': disk full"]
        );
        assert_eq!(
            one_line(&err),
            "augmenting into out: write 'out/x': disk full"
        );
        // A cause with text of its own stays.
        let err = anyhow::anyhow!("low").context("high");
        assert_eq!(messages(&err), ["high", "low"]);
    }
}
