//! The messages between `augment` and its worker processes, one JSON object per line.

use std::io::Write;

use serde::{Deserialize, Serialize};

use crate::config::AugmentConfig;
use crate::profile::StageTimes;
use crate::render::UnitJob;
use crate::staging::Outcome;

/// Environment variable that tells a worker process its slot (logs, test hooks).
pub(super) const SLOT_ENV: &str = "DEXJOCO_WORKER_SLOT";

/// Parent -> worker messages.
#[derive(Debug, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub(super) enum ToWorker {
    /// The run's configuration, and the tasks whose scenes (and renderer) to load before the
    /// first job, while the parent still loads and simulates.
    Hello {
        config: Box<AugmentConfig>,
        preload: Vec<String>,
    },
    /// A unit to render.
    Job(Box<UnitJob>),
}

/// Worker -> parent messages.
#[derive(Debug, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub(super) enum FromWorker {
    /// A renderer is about to open (for a scene): its first frame is due within the
    /// first-frame deadline.
    Opening,
    /// The renderer opened on this EGL device (its label).
    Device(String),
    /// The renderer drew its first frame.
    Ready,
    /// No renderer could be opened or draw here; why.
    CannotRender(String),
    /// Frames rendered since the last message (0: about to commit a replay).
    Frames(u64),
    /// The unit is written.
    Done {
        outcomes: Vec<Outcome>,
        times: StageTimes,
    },
    /// The unit failed.
    Error(String),
}

/// Writes one message as a line and flushes it.
pub(super) fn send<T: Serialize>(out: &mut dyn Write, msg: &T) -> std::io::Result<()> {
    let mut line = serde_json::to_vec(msg).expect("serializes");
    line.push(b'\n');
    out.write_all(&line)?;
    out.flush()
}
