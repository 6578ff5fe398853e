//! The evaluation's errors: each names the server, file, task or episode concerned.

use std::path::PathBuf;

/// Errors of `eval`.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EvalError {
    /// The policy server cannot be reached, stopped answering, or said it failed.
    #[error("policy server {uri}: {message}")]
    Server {
        /// The websocket address.
        uri: String,
        /// What happened.
        message: String,
        /// What to do about it.
        hint: Option<String>,
    },
    /// The server answered something the protocol does not allow (no `actions`, a chunk
    /// of the wrong shape, NaN in it).
    #[error("policy server {uri}: {message}")]
    Answer {
        /// The websocket address.
        uri: String,
        /// What is wrong with the answer.
        message: String,
    },
    /// An evaluation config (`--config`) cannot be used.
    #[error("evaluation config '{}': {message}", path.display())]
    Config {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// Bad options or inputs (exit code 2 at the command line).
    #[error("{0}")]
    Usage(String),
    /// The simulation or rendering failed.
    #[error("{what}: {source}")]
    Sim {
        /// The task or episode.
        what: String,
        /// The cause.
        #[source]
        source: dexjoco_render::RenderError,
    },
    /// Writing a video failed.
    #[error("{what}: {source}")]
    Video {
        /// The episode.
        what: String,
        /// The cause.
        #[source]
        source: dexjoco_video::VideoError,
    },
    /// A file operation failed.
    #[error(transparent)]
    Format(#[from] dexjoco_formats::FormatError),
    /// A file operation failed.
    #[error("{action} '{}': {source}", path.display())]
    Io {
        /// What was being done.
        action: &'static str,
        /// The path.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// A worker process could not be talked to (a message it or the parent sent).
    #[error("{0}")]
    Worker(String),
    /// The worker processes could not be started or run.
    #[error(transparent)]
    Pool(#[from] dexjoco_workers::PoolError),
    /// Episodes failed on the worker processes: each episode and what its worker said.
    #[error("{}", failures.iter().map(|(k, why)| format!("episode {k}: {why}")).collect::<Vec<_>>().join("; "))]
    EpisodesFailed {
        /// (episode index, the worker's reason), in episode order.
        failures: Vec<(usize, String)>,
    },
    /// An episode's rollout could not be made into a raw episode.
    #[error("episode {episode}: {source}")]
    Rollout {
        /// The episode index.
        episode: usize,
        /// The cause.
        #[source]
        source: dexjoco_core::CoreError,
    },
    /// A record of an earlier run in the output folder cannot be used.
    #[error("'{}': {message}", path.display())]
    Record {
        /// The record file.
        path: PathBuf,
        /// What is wrong, and what to do.
        message: String,
    },
}

impl EvalError {
    /// What to do about it, when there is something to say.
    pub fn hint(&self) -> Option<&str> {
        match self {
            Self::Server { hint, .. } => hint.as_deref(),
            Self::Answer { .. } => Some(
                "the server must answer each observation with {\"actions\": array (horizon, 22) \
                 for one arm or (horizon, 44) for two: xyz, rotation vector, 16 hand joints per arm}",
            ),
            _ => None,
        }
    }
}

/// Maps an I/O error with the path it concerns.
pub(crate) fn io_err(
    action: &'static str,
    path: &std::path::Path,
) -> impl FnOnce(std::io::Error) -> EvalError + use<> {
    let path = path.to_path_buf();
    move |source| EvalError::Io {
        action,
        path,
        source,
    }
}

/// Maps a simulation error with what it concerns.
pub(crate) fn sim_err<E: Into<dexjoco_render::RenderError>>(
    what: &str,
) -> impl FnOnce(E) -> EvalError + '_ {
    move |source| EvalError::Sim {
        what: what.into(),
        source: source.into(),
    }
}

/// The error, its causes and its hint on one line (for a worker's report).
pub fn one_line(e: &EvalError) -> String {
    let mut s = e.to_string();
    let mut source = std::error::Error::source(e);
    while let Some(c) = source {
        let text = c.to_string();
        if !s.contains(&text) {
            s.push_str(": ");
            s.push_str(&text);
        }
        source = c.source();
    }
    if let Some(h) = e.hint() {
        s.push_str(&format!(" (hint: {h})"));
    }
    s
}
