//! Where units run: on this process's threads or on worker processes, and how those
//! processes are started.

use std::ffi::OsString;
use std::path::PathBuf;
use std::time::Duration;

use crate::staging::Outcome;

/// How long a worker process may take from its start to its first rendered frame.
pub const DEFAULT_FIRST_FRAME_TIMEOUT: Duration = Duration::from_secs(120);

/// Where units run.
#[derive(Debug, Clone, Default)]
pub enum Executor {
    /// On this process's rayon threads (one shared process; tests and benchmarks).
    #[default]
    Threads,
    /// On worker processes.
    Processes(WorkerProcesses),
}

/// How to start worker processes.
#[derive(Debug, Clone)]
pub struct WorkerProcesses {
    /// The program (the `dexjoco-data` binary).
    pub program: PathBuf,
    /// Its arguments that make it a worker (it then calls [`serve_worker`](crate::serve_worker)).
    pub args: Vec<OsString>,
    /// Number of workers.
    pub count: usize,
    /// EGL device indices assigned to workers round-robin (`DEXJOCO_EGL_DEVICE`); empty:
    /// each picks the default device.
    pub egl_devices: Vec<usize>,
    /// A worker that has drawn no frame this long after it started is killed, and its slot
    /// retired ([`DEFAULT_FIRST_FRAME_TIMEOUT`]).
    pub first_frame_timeout: Duration,
}

impl WorkerProcesses {
    /// Workers of `program` started with `args`, `count` of them, on the default EGL device
    /// with the default first-frame deadline.
    pub fn new(program: PathBuf, args: Vec<OsString>, count: usize) -> Self {
        Self {
            program,
            args,
            count,
            egl_devices: Vec::new(),
            first_frame_timeout: DEFAULT_FIRST_FRAME_TIMEOUT,
        }
    }
}

/// A unit's final result: its outcomes, or why it failed twice.
pub(crate) type UnitResult = Result<Vec<Outcome>, String>;
