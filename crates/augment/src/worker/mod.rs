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
//! not at all. `serve` is the worker's side.

mod process;
mod protocol;
mod schedule;
mod serve;

use std::collections::BTreeMap;
use std::ffi::OsString;
use std::path::PathBuf;
use std::process::Command;
use std::sync::Arc;
use std::time::Duration;

use dexjoco_core::Progress;
use rayon::prelude::*;

use crate::config::AugmentConfig;
use crate::error::AugmentError;
use crate::inputs::Source;
use crate::profile::{EncoderClock, StageTimes};
use crate::render::{UnitInputs, UnitJob, close_renderer, render_unit};
use crate::run::TaskAssets;
use crate::staging::Outcome;

pub(crate) use process::WorkerPool;
pub use serve::serve_worker;

/// Environment variable of a test hook: `<task>/<episode>@<k>` makes a worker process die
/// (exit status 134, as a crash would end it, without a core file) after the first rendered
/// frames of that episode's units, on their first `k` attempts.
pub const FAULT_ENV: &str = "DEXJOCO_TEST_WORKER_ABORT";

/// Environment variable of a test hook: worker slots (`0,2`, or `all`) whose worker
/// processes open their renderer and then stall before their first frame, as a hung EGL
/// driver does.
pub const STALL_ENV: &str = "DEXJOCO_TEST_WORKER_STALL";

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
    /// Its arguments that make it a worker (it then calls [`serve_worker`]).
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

/// What the parent holds to run units itself.
pub(crate) struct LocalInputs<'a> {
    pub(crate) sources: &'a [Source],
    pub(crate) assets: &'a BTreeMap<String, Arc<TaskAssets>>,
}

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
        Executor::Threads => Ok(run_on_threads(jobs, local, config, total, progress)),
        // Nothing to render: the pool's workers, which have written nothing, end on drop.
        Executor::Processes(_) if jobs.is_empty() => Ok((Vec::new(), StageTimes::default())),
        Executor::Processes(w) => {
            schedule::run_on_processes(w, pool, jobs, config, cameras, total, progress)
        }
    }
}

fn run_on_threads(
    jobs: &[(usize, UnitJob)],
    local: &LocalInputs<'_>,
    config: &AugmentConfig,
    total: u64,
    progress: &dyn Progress,
) -> (Vec<UnitResult>, StageTimes) {
    let extra = std::sync::atomic::AtomicU64::new(0);
    // Units run side by side in this process: each unit's share of the finished encoders'
    // CPU time cannot be told apart, so it is taken once, for all of them.
    let encoders = EncoderClock::start();
    let attempts: Vec<Result<(Vec<Outcome>, StageTimes), String>> = jobs
        .par_iter()
        .map(|(i, job)| {
            let src = &local.sources[*i];
            let inputs = UnitInputs {
                src,
                assets: &local.assets[&src.spec.id],
                config,
                out: &config.out,
            };
            let mut first = None;
            for attempt in 0..2 {
                let mut job = job.clone();
                job.attempt = attempt;
                let mut done = 0;
                let r = render_unit(&job, &inputs, &mut |n| {
                    done += n;
                    progress.advance(n, "");
                    Ok(())
                });
                match r {
                    Ok(done) => return Ok(done),
                    Err(e) => {
                        tracing::warn!(unit = %job.key(), "unit failed (attempt {}): {e}", attempt + 1);
                        job.clear_staging(&config.out);
                        // The retry renders these frames again.
                        let more =
                            extra.fetch_add(done, std::sync::atomic::Ordering::SeqCst) + done;
                        progress.start(total + more);
                        progress.note(&format!("retrying {}: {e}", job.key()));
                        first = Some(e.to_string());
                    }
                }
            }
            Err(first.unwrap_or_default())
        })
        .collect();
    // Close every worker thread's renderer (and its EGL context) now, rather than at
    // process exit while other threads are still alive.
    rayon::broadcast(|_| close_renderer());
    let mut times = StageTimes::default();
    let results = attempts
        .into_iter()
        .map(|a| {
            a.map(|(outcomes, t)| {
                times.add(&t);
                outcomes
            })
        })
        .collect();
    times.encode_cpu = encoders.seconds();
    (results, times)
}

/// Gives one of `processes` rendering processes its share of the cores for Mesa's
/// llvmpipe, which otherwise gives each process a raster thread per core (N processes
/// would oversubscribe the cores N times over). A value the user set is kept; other
/// drivers ignore the variable.
pub fn share_llvmpipe_threads(cmd: &mut Command, processes: usize) {
    const LP_THREADS_ENV: &str = "LP_NUM_THREADS";
    if std::env::var_os(LP_THREADS_ENV).is_none() {
        let cores = std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get);
        cmd.env(
            LP_THREADS_ENV,
            (cores / processes.max(1)).max(1).to_string(),
        );
    }
}
