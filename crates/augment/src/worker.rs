//! Running units of work: on this process's threads, or on worker processes (each with
//! its own MuJoCo model and EGL renderer, so rendering scales over cores and GPUs).
//!
//! Worker processes speak JSON lines over their stdin/stdout. The parent sends a `hello`
//! with the run's configuration, then one `job` at a time; the worker answers with
//! `frames` (rendered frame counts, as they happen) and then `done` (the replays'
//! outcomes) or `error`. A worker that dies mid-unit (a crash, a kill) is replaced; its
//! unit's staging is removed and the unit retried once, then reported as failed. Either
//! way the unit's replays appear whole or not at all.

use std::collections::{BTreeMap, VecDeque};
use std::ffi::OsString;
use std::io::{BufRead, BufReader, Write};
use std::path::PathBuf;
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
use std::sync::{Arc, Mutex};

use dexjoco_core::{Progress, TaskSet};
use dexjoco_formats::Source as FoundSource;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::config::AugmentConfig;
use crate::error::AugmentError;
use crate::inputs::{Source, check_fields};
use crate::render::{UnitInputs, UnitJob, close_renderer, preload_renderer, render_unit};
use crate::run::{TaskAssets, load_assets};
use crate::staging::Outcome;

/// Environment variable of a test hook: `<task>/<episode>@<k>` makes a worker process die
/// (exit status 134, as a crash would end it, without a core file) after the first rendered
/// frames of that episode's units, on their first `k` attempts.
pub const FAULT_ENV: &str = "DEXJOCO_TEST_WORKER_ABORT";

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
}

/// A unit's final result: its outcomes, or why it failed twice.
pub(crate) type UnitResult = Result<Vec<Outcome>, String>;

/// What the parent holds to run units itself.
pub(crate) struct LocalInputs<'a> {
    pub(crate) sources: &'a [Source],
    pub(crate) assets: &'a BTreeMap<String, Arc<TaskAssets>>,
}

/// Runs every job (index-aligned results), retrying a failed one once.
pub(crate) fn run_jobs(
    executor: &Executor,
    pool: WorkerPool,
    jobs: &[(usize, UnitJob)],
    local: &LocalInputs<'_>,
    config: &AugmentConfig,
    cameras: usize,
    progress: &dyn Progress,
) -> Result<Vec<UnitResult>, AugmentError> {
    let total: u64 = jobs.iter().map(|(_, j)| j.frames(cameras)).sum();
    progress.phase("render", total);
    match executor {
        Executor::Threads => {
            let extra = std::sync::atomic::AtomicU64::new(0);
            let results = jobs
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
                            Ok(o) => return Ok(o),
                            Err(e) => {
                                tracing::warn!(unit = %job.key(), "unit failed (attempt {}): {e}", attempt + 1);
                                job.clear_staging(&config.out);
                                // The retry renders these frames again.
                                let more = extra.fetch_add(done, std::sync::atomic::Ordering::SeqCst) + done;
                                progress.start(total + more);
                                progress.note(&format!("retrying {}: {e}", job.key()));
                                first = Some(e.to_string());
                            }
                        }
                    }
                    Err(first.unwrap_or_default())
                })
                .collect();
            // Close every worker thread's renderer (and its EGL context) now, rather than
            // at process exit while other threads are still alive.
            rayon::broadcast(|_| close_renderer());
            Ok(results)
        }
        // Nothing to render: the pool's workers, which have written nothing, end on drop.
        Executor::Processes(_) if jobs.is_empty() => Ok(Vec::new()),
        Executor::Processes(w) => run_on_processes(w, pool, jobs, config, cameras, total, progress),
    }
}

/// Parent -> worker messages.
#[derive(Debug, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
enum ToWorker {
    /// The run's configuration, and the tasks whose scenes (and renderer) to load before the
    /// first job, while the parent still loads and simulates.
    Hello {
        config: Box<AugmentConfig>,
        preload: Vec<String>,
    },
    Job(Box<UnitJob>),
}

/// Worker -> parent messages.
#[derive(Debug, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
enum FromWorker {
    Frames(u64),
    Done(Vec<Outcome>),
    Error(String),
}

/// One running worker process.
struct Worker {
    child: Child,
    stdin: ChildStdin,
    stdout: BufReader<ChildStdout>,
}

impl Worker {
    fn spawn(
        w: &WorkerProcesses,
        slot: usize,
        config: &AugmentConfig,
        preload: &[String],
    ) -> Result<Self, AugmentError> {
        let mut cmd = Command::new(&w.program);
        cmd.args(&w.args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit());
        if !w.egl_devices.is_empty() {
            let dev = w.egl_devices[slot % w.egl_devices.len()];
            cmd.env(dexjoco_sim::EGL_DEVICE_ENV, dev.to_string());
        }
        share_llvmpipe_threads(&mut cmd, w.count);
        let mut child = cmd.spawn().map_err(|e| {
            AugmentError::Input(format!(
                "cannot start a worker process '{}': {e}",
                w.program.display()
            ))
        })?;
        let stdin = child.stdin.take().expect("piped");
        let stdout = BufReader::new(child.stdout.take().expect("piped"));
        let mut worker = Self {
            child,
            stdin,
            stdout,
        };
        worker
            .send(&ToWorker::Hello {
                config: Box::new(config.clone()),
                preload: preload.to_vec(),
            })
            .map_err(|e| AugmentError::Input(format!("worker process {slot}: {e}")))?;
        Ok(worker)
    }

    fn send(&mut self, msg: &ToWorker) -> std::io::Result<()> {
        let mut line = serde_json::to_vec(msg).expect("serializes");
        line.push(b'\n');
        self.stdin.write_all(&line)?;
        self.stdin.flush()
    }

    /// The next message, or why there is none (the worker ended).
    fn receive(&mut self) -> Result<FromWorker, String> {
        let mut line = String::new();
        match self.stdout.read_line(&mut line) {
            Ok(0) => Err(self.ended()),
            Ok(_) => serde_json::from_str(&line)
                .map_err(|e| format!("unreadable message from a worker process ({e}): {line}")),
            Err(e) => Err(format!("{e}; {}", self.ended())),
        }
    }

    /// Reaps the process and says how it ended.
    fn ended(&mut self) -> String {
        match self.child.wait() {
            Ok(s) => format!("the worker process ended ({s})"),
            Err(e) => format!("the worker process ended ({e})"),
        }
    }

    fn close(mut self) {
        drop(self.stdin);
        let _ = self.child.wait();
    }
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

/// Worker processes started ahead of the jobs: they load their scenes and renderers while
/// the parent loads and simulates, so that loading is not paid twice in a row. Workers
/// not taken by [`WorkerPool::into_slots`] (nothing to render, or the run stopped before
/// rendering) are ended on drop: they have written nothing.
pub(crate) struct WorkerPool {
    workers: Vec<Worker>,
}

impl WorkerPool {
    /// Starts `w.count` workers (no more than `max_units`, the most units the run can
    /// have) that preload the scenes of `tasks`; none for the thread executor.
    pub(crate) fn start(
        executor: &Executor,
        config: &AugmentConfig,
        tasks: &[String],
        max_units: usize,
    ) -> Result<Self, AugmentError> {
        let mut workers = Vec::new();
        if let Executor::Processes(w) = executor {
            for slot in 0..w.count.min(max_units).max(1) {
                workers.push(Worker::spawn(w, slot, config, tasks)?);
            }
        }
        Ok(Self { workers })
    }

    /// One entry per slot: the started workers first, `None` for slots that start theirs
    /// when they take a job; workers beyond `slots` are ended.
    fn into_slots(mut self, slots: usize) -> Vec<Option<Worker>> {
        let keep = slots.min(self.workers.len());
        let mut out: Vec<Option<Worker>> = self.workers.drain(..keep).map(Some).collect();
        out.resize_with(slots, || None);
        out
    }
}

impl Drop for WorkerPool {
    fn drop(&mut self) {
        for wk in &mut self.workers {
            let _ = wk.child.kill();
            let _ = wk.child.wait();
        }
    }
}

fn run_on_processes(
    w: &WorkerProcesses,
    pool: WorkerPool,
    jobs: &[(usize, UnitJob)],
    config: &AugmentConfig,
    cameras: usize,
    total: u64,
    progress: &dyn Progress,
) -> Result<Vec<UnitResult>, AugmentError> {
    // Biggest units first, so the last ones to finish are small.
    let mut order: Vec<usize> = (0..jobs.len()).collect();
    order.sort_by_key(|&k| std::cmp::Reverse(jobs[k].1.frames(cameras)));
    let queue: Mutex<VecDeque<(usize, u32)>> =
        Mutex::new(order.into_iter().map(|k| (k, 0)).collect());
    let results: Mutex<Vec<Option<UnitResult>>> = Mutex::new(vec![None; jobs.len()]);
    let first_errors: Mutex<BTreeMap<usize, String>> = Mutex::new(BTreeMap::new());
    let extra_frames = Mutex::new(0u64);
    let fatal: Mutex<Option<AugmentError>> = Mutex::new(None);
    let started = pool.into_slots(w.count.min(jobs.len()).max(1));
    std::thread::scope(|scope| {
        for (slot, first) in started.into_iter().enumerate() {
            let (queue, results, first_errors, extra_frames, fatal) =
                (&queue, &results, &first_errors, &extra_frames, &fatal);
            scope.spawn(move || {
                let mut worker: Option<Worker> = first;
                loop {
                    let Some((k, attempt)) = queue.lock().expect("queue").pop_front() else {
                        break;
                    };
                    if worker.is_none() {
                        match Worker::spawn(w, slot, config, &[]) {
                            Ok(wk) => worker = Some(wk),
                            Err(e) => {
                                fatal.lock().expect("fatal").get_or_insert(e);
                                break;
                            }
                        }
                    }
                    let wk = worker.as_mut().expect("spawned");
                    let mut job = jobs[k].1.clone();
                    job.attempt = attempt;
                    let mut done = 0u64;
                    let outcome = match wk.send(&ToWorker::Job(Box::new(job.clone()))) {
                        Err(e) => Err(format!("{e}; {}", wk.ended())),
                        Ok(()) => loop {
                            match wk.receive() {
                                Ok(FromWorker::Frames(n)) => {
                                    done += n;
                                    progress.advance(n, "");
                                }
                                Ok(FromWorker::Done(o)) => break Ok(o),
                                Ok(FromWorker::Error(e)) => break Err(e),
                                Err(e) => {
                                    // Crashed or killed: start a fresh one for the next job.
                                    worker = None;
                                    break Err(e);
                                }
                            }
                        },
                    };
                    match outcome {
                        Ok(o) => results.lock().expect("results")[k] = Some(Ok(o)),
                        Err(reason) => {
                            job.clear_staging(&config.out);
                            tracing::warn!(unit = %job.key(), "unit failed (attempt {}): {reason}", attempt + 1);
                            if attempt == 0 {
                                first_errors.lock().expect("errors").insert(k, reason.clone());
                                let mut extra = extra_frames.lock().expect("frames");
                                *extra += done;
                                progress.start(total + *extra);
                                progress.note(&format!("retrying {}: {reason}", job.key()));
                                queue.lock().expect("queue").push_back((k, 1));
                            } else {
                                results.lock().expect("results")[k] = Some(Err(reason));
                            }
                        }
                    }
                }
                if let Some(wk) = worker {
                    wk.close();
                }
            });
        }
    });
    if let Some(e) = fatal.into_inner().expect("fatal") {
        return Err(e);
    }
    Ok(results
        .into_inner()
        .expect("results")
        .into_iter()
        .map(|r| r.unwrap_or_else(|| Err("not run".into())))
        .collect())
}

/// The worker side: reads the `hello` and `job` lines from `input`, renders each unit,
/// answers on `output`. Returns when `input` ends.
pub fn serve_worker(input: impl BufRead, mut output: impl Write) -> Result<(), AugmentError> {
    let mut lines = input.lines();
    let io = |e: std::io::Error| AugmentError::Input(format!("worker: {e}"));
    let Some(first) = lines.next() else {
        return Ok(());
    };
    let (config, preload) = match serde_json::from_str::<ToWorker>(&first.map_err(io)?) {
        Ok(ToWorker::Hello { config, preload }) => (*config, preload),
        _ => return Err(AugmentError::Input("worker: expected a hello first".into())),
    };
    let tasks = TaskSet::with_dir(config.tasks_dir.as_deref())
        .map_err(|e| AugmentError::Input(format!("task specs: {e}")))?;
    let fault = std::env::var(FAULT_ENV).ok();
    let mut sources: BTreeMap<PathBuf, Source> = BTreeMap::new();
    let mut assets: BTreeMap<String, Arc<TaskAssets>> = BTreeMap::new();
    // The scenes this run will need, and this worker's renderer, before the first job.
    // A failure here is not fatal: the job that needs the scene reports it.
    for task in &preload {
        let Some(spec) = tasks.get(task) else {
            continue;
        };
        match load_assets(&config, spec) {
            Ok(a) => {
                if let Err(e) = preload_renderer(&a, &config) {
                    tracing::debug!(task, "renderer not preloaded: {e}");
                }
                assets.insert(task.clone(), Arc::new(a));
            }
            Err(e) => tracing::debug!(task, "scene not preloaded: {e}"),
        }
    }
    let send = |out: &mut dyn Write, msg: &FromWorker| -> Result<(), AugmentError> {
        let mut line = serde_json::to_vec(msg).expect("serializes");
        line.push(b'\n');
        out.write_all(&line).map_err(io)?;
        out.flush().map_err(io)
    };
    for line in lines {
        let job = match serde_json::from_str::<ToWorker>(&line.map_err(io)?) {
            Ok(ToWorker::Job(j)) => *j,
            _ => return Err(AugmentError::Input("worker: expected a job".into())),
        };
        let result = (|| -> Result<Vec<Outcome>, AugmentError> {
            let src = load_source(&mut sources, &job, &tasks)?;
            if !assets.contains_key(&job.task) {
                assets.insert(job.task.clone(), Arc::new(load_assets(&config, &src.spec)?));
            }
            let inputs = UnitInputs {
                src,
                assets: &assets[&job.task],
                config: &config,
                out: &config.out,
            };
            let abort = fault
                .as_deref()
                .and_then(|f| f.rsplit_once('@'))
                .filter(|(key, k)| {
                    *key == job.key() && k.parse::<u32>().is_ok_and(|k| job.attempt < k)
                })
                .is_some();
            render_unit(&job, &inputs, &mut |n| {
                // The parent reads every message; a failed write means it has ended (killed):
                // stop at once, before anything more is written or renamed into place.
                if send(&mut output, &FromWorker::Frames(n)).is_err() {
                    tracing::debug!("the augment run that started this worker has ended");
                    std::process::exit(1);
                }
                if abort && n > 0 {
                    tracing::warn!("{FAULT_ENV}: dying mid-unit, as a crash would");
                    std::process::exit(134);
                }
                Ok(())
            })
        })();
        let msg = match result {
            Ok(o) => FromWorker::Done(o),
            Err(e) => FromWorker::Error(e.to_string()),
        };
        send(&mut output, &msg)?;
    }
    close_renderer();
    Ok(())
}

/// The job's episode, read once per worker through the one reader.
fn load_source<'a>(
    cache: &'a mut BTreeMap<PathBuf, Source>,
    job: &UnitJob,
    tasks: &TaskSet,
) -> Result<&'a Source, AugmentError> {
    if !cache.contains_key(&job.path) {
        let found = FoundSource {
            path: job.path.clone(),
            kind: job.kind,
        };
        let episode = found.read(tasks)?.episode;
        let spec = tasks
            .get(&episode.task)
            .cloned()
            .ok_or_else(|| AugmentError::Input(format!("unknown task '{}'", episode.task)))?;
        check_fields(&episode).map_err(AugmentError::Input)?;
        cache.insert(
            job.path.clone(),
            Source {
                hash: crate::fingerprint::episode_hash(&episode),
                episode,
                spec,
                path: job.path.clone(),
                kind: job.kind,
            },
        );
    }
    let src = &cache[&job.path];
    if src.episode.id != job.episode || src.spec.id != job.task || src.hash != job.source_hash {
        return Err(AugmentError::Input(format!(
            "'{}' holds episode '{}/{}' (content {}), the job expected '{}' (content {}): did the input change during the run?",
            job.path.display(),
            src.spec.id,
            src.episode.id,
            src.hash,
            job.key(),
            job.source_hash
        )));
    }
    Ok(src)
}
