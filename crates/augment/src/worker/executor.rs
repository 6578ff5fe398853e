//! Where units run: on this process's threads or on worker processes, and how those
//! processes are started.

use std::ffi::OsString;
use std::path::PathBuf;
use std::time::Duration;

use std::collections::BTreeSet;

use crate::error::AugmentError;
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

impl Executor {
    /// Opens an offscreen context on every EGL device the run's units will render on
    /// (each worker's assigned device, else the default one), each within the first-frame
    /// deadline, and closes it: a machine that cannot render fails in seconds, naming the
    /// device, before any work is spent.
    pub(crate) fn check_renderer(&self) -> Result<(), AugmentError> {
        let (devices, deadline): (BTreeSet<Option<usize>>, Duration) = match self {
            Self::Threads => ([None].into(), DEFAULT_FIRST_FRAME_TIMEOUT),
            Self::Processes(w) if w.egl_devices.is_empty() => {
                ([None].into(), w.first_frame_timeout)
            }
            Self::Processes(w) => (
                w.egl_devices
                    .iter()
                    .take(w.count.max(1))
                    .map(|&d| Some(d))
                    .collect(),
                w.first_frame_timeout,
            ),
        };
        devices
            .into_iter()
            .try_for_each(|d| probe_within(d, deadline))
    }
}

/// Probes `device` (`None`: the default one) on a thread of its own, so that a hung
/// driver fails the run at the deadline rather than hanging it.
fn probe_within(device: Option<usize>, deadline: Duration) -> Result<(), AugmentError> {
    let words = device.map_or_else(
        || "the default EGL device".to_owned(),
        |i| format!("EGL device {i}"),
    );
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(dexjoco_sim::probe_renderer(device));
    });
    let reason = match rx.recv_timeout(deadline) {
        Ok(Ok(opened)) => {
            tracing::debug!(
                "renderer probe: an offscreen context opens on EGL device {} ({})",
                opened.index,
                opened.label()
            );
            return Ok(());
        }
        Ok(Err(dexjoco_sim::SimError::Egl(why))) => why,
        Ok(Err(e)) => e.to_string(),
        Err(_) => format!(
            "no offscreen context opened within {} s (--first-frame-timeout)",
            deadline.as_secs_f64()
        ),
    };
    Err(AugmentError::RenderingUnavailable {
        device: words,
        reason,
    })
}

/// A unit's final result: its outcomes, or why it failed twice.
pub(crate) type UnitResult = Result<Vec<Outcome>, String>;
