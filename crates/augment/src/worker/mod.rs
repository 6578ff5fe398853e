//! Running units of work: on this process's threads, or on worker processes (each with
//! its own MuJoCo model and EGL renderer, so rendering scales over cores and GPUs).
//!
//! Worker processes speak JSON lines over their stdin/stdout (`protocol`). The parent
//! sends a `hello` with the run's configuration, then one `job` at a time; the worker
//! says which EGL device its renderer opened (`device`) and that it drew its first frame
//! (`ready`), then answers each job with `frames` (rendered frame counts, as they happen)
//! and `done` (the replays' outcomes and where the time went) or `error`.
//!
//! `process` starts and watches one worker: a worker that has not drawn its first frame
//! within the first-frame deadline (a hung EGL driver) is killed and named with its
//! device. `schedule` hands units to worker slots: a worker that dies mid-unit (a crash, a
//! kill) is replaced, its unit's staging removed and the unit retried once, then reported
//! as failed; a stalled worker's slot is retired and its unit goes to another worker;
//! when no slot can render, the run fails. Either way the unit's replays appear whole or
//! not at all. `serve` is the worker's side. `executor` says where units run and how
//! worker processes start; `threads` runs units on this process's threads instead.

mod executor;
mod process;
mod protocol;
mod schedule;
mod serve;
mod threads;

use dexjoco_core::Progress;

use crate::config::AugmentConfig;
use crate::error::AugmentError;
use crate::profile::StageTimes;
use crate::render::UnitJob;

pub use dexjoco_sim::share_llvmpipe_threads;
pub(crate) use executor::UnitResult;
pub use executor::{DEFAULT_FIRST_FRAME_TIMEOUT, Executor, WorkerProcesses};
pub(crate) use process::WorkerPool;
pub use serve::{FAULT_ENV, STALL_ENV, serve_worker};
pub(crate) use threads::LocalInputs;

/// Runs every job (index-aligned results), retrying a failed one once; also returns where
/// the rendering's time went, summed over the units.
pub(crate) fn run_jobs(
    executor: &Executor,
    pool: WorkerPool,
    jobs: &[(usize, UnitJob)],
    local: &LocalInputs<'_>,
    config: &AugmentConfig,
    cameras: usize,
    progress: &dyn Progress,
) -> Result<(Vec<UnitResult>, StageTimes), AugmentError> {
    let total: u64 = jobs.iter().map(|(_, j)| j.frames(cameras)).sum();
    progress.phase("render", total);
    match executor {
        Executor::Threads => Ok(threads::run_on_threads(
            jobs, local, config, total, progress,
        )),
        // Nothing to render: the pool's workers, which have written nothing, end on drop.
        Executor::Processes(_) if jobs.is_empty() => Ok((Vec::new(), StageTimes::default())),
        Executor::Processes(w) => {
            schedule::run_on_processes(w, pool, jobs, config, cameras, total, progress)
        }
    }
}
