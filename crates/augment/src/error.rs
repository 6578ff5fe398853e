//! Errors of the augment stage.

use std::path::PathBuf;

/// What can go wrong while augmenting.
#[derive(Debug, thiserror::Error)]
pub enum AugmentError {
    /// Reading or writing a file through `dexjoco-formats` failed.
    #[error(transparent)]
    Format(#[from] dexjoco_formats::FormatError),
    /// Simulation or rendering failed.
    #[error("episode '{episode}': {source}")]
    Sim {
        /// Episode id.
        episode: String,
        /// The cause.
        source: dexjoco_sim::SimError,
    },
    /// Encoding a video failed.
    #[error("episode '{episode}': {source}")]
    Video {
        /// Episode id.
        episode: String,
        /// The cause.
        source: dexjoco_video::VideoError,
    },
    /// A file could not be read or written.
    #[error("cannot {action} '{}': {source}", path.display())]
    Io {
        /// What was being done.
        action: &'static str,
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A bad input (episode, field, frame named in the message).
    #[error("{0}")]
    Input(String),
    /// The output folder was made with other settings.
    #[error(
        "'{}' was made with other settings: {}; augment into another --out, or pass --overwrite to start clean (it removes only what augment wrote there)",
        out.display(),
        differences.join("; ")
    )]
    SettingsChanged {
        /// The output folder.
        out: PathBuf,
        /// What differs, `setting: now (was before)`.
        differences: Vec<String>,
    },
    /// A value of an option does not fit the inputs (a `--camera` a task's scene lacks):
    /// a usage error, found before any work is spent.
    #[error("{0}")]
    Usage(String),
    /// Offscreen rendering does not work on a device the run would render on, found by
    /// a probe before any work is spent.
    #[error("offscreen rendering is unavailable on {device}: {reason}")]
    RenderingUnavailable {
        /// The EGL device, in words.
        device: String,
        /// Why no context opened there.
        reason: String,
    },
    /// The scene's randomization (its camera pool, table looks, dynamics entries) cannot
    /// be used.
    #[error(transparent)]
    Randomization(#[from] dexjoco_sim::SimError),
}

/// Maps an I/O error with the file it concerns.
pub(crate) fn io_err(
    action: &'static str,
    path: &std::path::Path,
) -> impl FnOnce(std::io::Error) -> AugmentError + use<> {
    let path = path.to_path_buf();
    move |source| AugmentError::Io {
        action,
        path,
        source,
    }
}

/// Maps a simulation error with the episode it concerns.
pub(crate) fn sim_err(episode: &str) -> impl FnOnce(dexjoco_sim::SimError) -> AugmentError + '_ {
    move |source| AugmentError::Sim {
        episode: episode.into(),
        source,
    }
}

/// Maps a video error with the episode it concerns.
pub(crate) fn video_err(
    episode: &str,
) -> impl FnOnce(dexjoco_video::VideoError) -> AugmentError + '_ {
    move |source| AugmentError::Video {
        episode: episode.into(),
        source,
    }
}
