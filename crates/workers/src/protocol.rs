//! The messages between a parent and its worker processes, one JSON object per line: the
//! parent sends a `hello` (the run's configuration), then one `job` at a time; the worker
//! tells what its renderer does (`opening`, `device`, `ready`, `cannot_render`), how far a
//! job has come (`progress`) and how it ended (`done` or `failed`).

use std::io::Write;

use serde::{Deserialize, Serialize};

/// Environment variable that tells a worker process its slot (logs, test hooks).
pub const SLOT_ENV: &str = "DEXJOCO_WORKER_SLOT";

/// Parent -> worker messages; `H` is the stage's configuration, `J` its job.
#[derive(Debug, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ToWorker<H, J> {
    /// The run's configuration (first, once).
    Hello(H),
    /// A job, and which attempt at it this is (0, then 1 for the retry).
    Job {
        /// 0 for the first attempt.
        attempt: u32,
        /// The job.
        job: J,
    },
}

/// Worker -> parent messages; `D` is what a finished job gives.
#[derive(Debug, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FromWorker<D> {
    /// A renderer is about to open: its first frame is due within the first-frame
    /// deadline.
    Opening,
    /// The renderer opened, on this device, in words (`EGL device 0 (NVIDIA H200)`,
    /// `the Warp renderer (warp 3.17.0 on cuda:0 (NVIDIA H200))`).
    Device(String),
    /// The renderer drew its first frame.
    Ready,
    /// No renderer could be opened or draw here; why.
    CannotRender(String),
    /// Work done on the job since the last message (frames, steps; 0: a heartbeat, sent
    /// before anything is renamed into place).
    Progress(u64),
    /// The job is finished.
    Done(D),
    /// The job failed.
    Failed(Failure),
}

/// Why a job failed, and whether the run can go on.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Failure {
    /// What happened (one line, naming the file, episode, server...).
    pub message: String,
    /// Whether it concerns the whole run (a full disk, a policy server that answers
    /// badly): the run stops; otherwise only this job failed (retried once).
    pub run_wide: bool,
}

impl Failure {
    /// A failure of this job only.
    pub fn job(message: impl Into<String>) -> Self {
        Self {
            message: message.into(),
            run_wide: false,
        }
    }

    /// A failure that stops the run.
    pub fn run_wide(message: impl Into<String>) -> Self {
        Self {
            message: message.into(),
            run_wide: true,
        }
    }
}

/// Writes one message as a line and flushes it.
pub fn send<T: Serialize>(out: &mut dyn Write, msg: &T) -> std::io::Result<()> {
    let mut line = serde_json::to_vec(msg).expect("messages serialize");
    line.push(b'\n');
    out.write_all(&line)?;
    out.flush()
}
