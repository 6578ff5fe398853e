//! Where units run: on this process's threads or on worker processes (`dexjoco-workers`).

use dexjoco_workers::WorkerProcesses;

use crate::error::AugmentError;
use crate::staging::Outcome;

/// Where units run.
#[derive(Debug, Clone, Default)]
pub enum Executor {
    /// On this process's rayon threads (one shared process; tests and benchmarks).
    #[default]
    Threads,
    /// On worker processes.
    Processes(WorkerProcesses),
}

impl Executor {
    /// Opens an offscreen context on every EGL device the run's units will render on
    /// (each worker's assigned device, else the default one), each within the first-frame
    /// deadline, and closes it: a machine that cannot render fails in seconds, naming the
    /// device, before any work is spent.
    pub(crate) fn check_renderer(&self) -> Result<(), AugmentError> {
        let probe = match self {
            Self::Threads => {
                dexjoco_workers::probe_renderer(None, dexjoco_workers::DEFAULT_FIRST_FRAME_TIMEOUT)
            }
            Self::Processes(w) => w.check_renderer(),
        };
        probe.map_err(AugmentError::from)
    }
}

/// A unit's final result: its outcomes, or why it failed twice.
pub(crate) type UnitResult = Result<Vec<Outcome>, String>;
