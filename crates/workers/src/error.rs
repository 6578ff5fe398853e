//! Why a run on worker processes stops.

/// Why a run on worker processes could not go on.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PoolError {
    /// A worker process could not be started.
    #[error("{0}")]
    Start(String),
    /// Offscreen rendering does not work on a device the workers would render on.
    #[error("offscreen rendering is unavailable on {device}: {reason}")]
    RenderingUnavailable {
        /// The EGL device, in words.
        device: String,
        /// Why no context opened there.
        reason: String,
    },
    /// Every worker was retired: none could render.
    #[error("{0}")]
    NoRenderer(String),
    /// A job failed in a way that concerns the whole run (its message).
    #[error("{0}")]
    RunWide(String),
    /// A slot of the schedule panicked.
    #[error("a worker slot of this process failed (a bug: please report it)")]
    Bug,
}
