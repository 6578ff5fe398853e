//! Running units of work: on this process's threads, or on worker processes (each with
//! its own MuJoCo model and EGL renderer, so rendering scales over cores and GPUs).
//!
//! Worker processes are `dexjoco-workers`' (JSON lines over stdin/stdout, first-frame and
//! silence deadlines, an EGL device each, a unit retried once after its worker died,
//! workers killed on drop); `protocol` is what augment says inside it: the `hello` with
//! the run's configuration, a unit to render, and a rendered unit's outcomes. `jobs` is
//! the schedule's view of the units, `serve` the worker's side, `threads` runs units on
//! this process's threads instead. A full disk anywhere (ENOSPC, EDQUOT) is run-wide: the
//! first stops the run.

mod executor;
mod jobs;
mod protocol;
mod serve;
mod threads;

use std::sync::atomic::AtomicU64;

use dexjoco_core::Progress;

use crate::config::AugmentConfig;
use crate::error::AugmentError;
use crate::profile::StageTimes;
use crate::render::UnitJob;

pub use dexjoco_render::share_llvmpipe_threads;
pub use dexjoco_workers::{DEFAULT_FIRST_FRAME_TIMEOUT, WorkerPool, WorkerProcesses};
pub use executor::Executor;
pub(crate) use executor::UnitResult;
pub use serve::{FAULT_ENV, STALL_ENV, serve_worker};
pub(crate) use threads::LocalInputs;

/// Starts the worker processes of `executor` ahead of the units (none for threads; no
/// more than `max_units`), preloading the scenes of `preload`.
pub(crate) fn start_pool(
    executor: &Executor,
    config: &AugmentConfig,
    preload: Vec<String>,
    max_units: usize,
) -> Result<WorkerPool, AugmentError> {
    match executor {
        Executor::Threads => Ok(WorkerPool::empty()),
        Executor::Processes(w) => {
            let hello = protocol::Hello {
                config: config.clone(),
                preload,
            };
            Ok(WorkerPool::start(w, &hello, max_units)?)
        }
    }
}

/// Runs every job (index-aligned results), retrying a failed one once; also returns where
/// the rendering's time went, summed over the units. A full disk stops the run.
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
        Executor::Threads => threads::run_on_threads(jobs, local, config, total, progress),
        // Nothing to render: the pool's workers, which have written nothing, end on drop.
        Executor::Processes(_) if jobs.is_empty() => Ok((Vec::new(), StageTimes::default())),
        Executor::Processes(w) => {
            let units = jobs::Units {
                hello: protocol::Hello {
                    config: config.clone(),
                    preload: Vec::new(),
                },
                jobs,
                cameras,
                total,
                progress,
                extra: AtomicU64::new(0),
            };
            let results = dexjoco_workers::run_jobs(w, pool, &units)?;
            let mut times = StageTimes::default();
            let results = results
                .into_iter()
                .map(|r| {
                    r.map(|done| {
                        times.add(&done.times);
                        done.outcomes
                    })
                })
                .collect();
            Ok((results, times))
        }
    }
}
