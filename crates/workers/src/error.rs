//! Why a run on worker processes stops.

/// Why a run on worker processes could not go on.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PoolError {
    /// A worker process could not be started.
    #[error("cannot start a worker process '{}': {source}", program.display())]
    Spawn {
        /// The program.
        program: std::path::PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A worker process ended before it took its greeting.
    #[error("worker process {slot} ended at once")]
    EndedAtOnce {
        /// Its slot.
        slot: usize,
    },
    /// Offscreen rendering does not work on a device the workers would render on.
    #[error("offscreen rendering is unavailable on {device}: {reason}")]
    RenderingUnavailable {
        /// The EGL device, in words.
        device: String,
        /// Why no context opened there.
        reason: String,
    },
    /// Every worker was retired: none could render.
    #[error("no worker process could render ({}); hint: {hint}", retired.join("; "))]
    NoRenderer {
        /// Why each worker was retired (its own words or its deadline).
        retired: Vec<String>,
        /// What to try.
        hint: &'static str,
    },
    /// A job failed in a way that concerns the whole run (its message).
    #[error("{0}")]
    RunWide(String),
    /// A slot of the schedule panicked.
    #[error("a worker slot of this process failed (a bug: please report it)")]
    Bug,
}
