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
        source: dexjoco_render::RenderError,
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
    Randomization(#[from] dexjoco_render::RenderError),
    /// The task's dynamics randomization cannot be sampled or applied to the scene.
    #[error(transparent)]
    Dynamics(#[from] dexjoco_sim::SimError),
    /// The disk is full (ENOSPC, EDQUOT): the run stopped at the first write that failed.
    #[error(
        "the disk is full, the run stopped: {message}{}{}; what was written before is kept: free space \
         (or augment into another --out) and run again to render the rest",
        free.map(|b| format!("; {} free", human_bytes(b))).unwrap_or_default(),
        needed.map(|b| format!(", the replays still to render need about {}", human_bytes(b))).unwrap_or_default()
    )]
    OutOfSpace {
        /// What failed (the file named).
        message: String,
        /// Bytes free on the output's file system.
        free: Option<u64>,
        /// Bytes the rest of the run needs, estimated from the replays written.
        needed: Option<u64>,
    },
}

/// Bytes in words (`3.2 MB`).
fn human_bytes(b: u64) -> String {
    const UNITS: [&str; 5] = ["B", "kB", "MB", "GB", "TB"];
    let mut v = b as f64;
    let mut unit = 0;
    while v >= 1000.0 && unit + 1 < UNITS.len() {
        v /= 1000.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{b} B")
    } else {
        format!("{v:.1} {}", UNITS[unit])
    }
}

impl From<dexjoco_workers::PoolError> for AugmentError {
    fn from(e: dexjoco_workers::PoolError) -> Self {
        use dexjoco_workers::PoolError;
        match e {
            PoolError::RenderingUnavailable { device, reason } => {
                Self::RenderingUnavailable { device, reason }
            }
            // A unit's failure is run-wide only when the disk is full.
            PoolError::RunWide(message) => Self::OutOfSpace {
                message,
                free: None,
                needed: None,
            },
            e => Self::Input(e.to_string()),
        }
    }
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
pub(crate) fn sim_err<E: Into<dexjoco_render::RenderError>>(
    episode: &str,
) -> impl FnOnce(E) -> AugmentError + '_ {
    move |source| AugmentError::Sim {
        episode: episode.into(),
        source: source.into(),
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
