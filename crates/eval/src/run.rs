//! A whole evaluation run: the episodes' initial states (drawn from `--seed` as
//! `scripted` draws its resets, or given), the episodes a previous run left to do, the
//! episodes run here or on worker processes (each with its own connection to the policy
//! server), the marker and the run's record. One writer per output folder (its `.lock`).

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use dexjoco_core::{Progress, TaskSpec};
use dexjoco_formats::DirLock;
use dexjoco_sim::{SceneSource, TaskEnv, load_task_scene};
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

use crate::config::EvalConfig;
use crate::episode::run_episode;
use crate::error::{EvalError, io_err, sim_err};
use crate::inference::Inference;
use crate::output::{
    EpisodeRecord, RUN_RECORD, STAGING, WORKER_CONFIG, commit_episode, done_episodes, staging_dir,
    write_marker,
};
use crate::protocol::PolicyClient;
use crate::stage::{Stage, run_spec};

/// The initial states of the run's episodes: the given ones, else drawn one after the
/// other from `seed` as `dexjoco-data scripted --seed` draws its resets (so a scripted
/// plan of reset `k` is a plan for episode `k`).
pub fn initial_states(config: &EvalConfig, spec: &TaskSpec) -> Result<Vec<Vec<f64>>, EvalError> {
    let n = config.options.episodes;
    if let Some(given) = &config.initial_states {
        if given.len() < n {
            return Err(EvalError::Usage(format!(
                "--resets-from gives {} initial states for {n} episodes",
                given.len()
            )));
        }
        return Ok(given[..n].to_vec());
    }
    let source = SceneSource::from_option(config.scene_dir.clone());
    let scene = load_task_scene(&source, spec).map_err(sim_err(&spec.id))?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(config.options.seed);
    (0..n)
        .map(|_| {
            TaskEnv::sample_initial_state(&scene, spec, &mut || rng.random::<f64>())
                .map_err(sim_err(&spec.id))
        })
        .collect()
}

/// Where the episodes run.
#[derive(Debug, Clone)]
pub enum Executor {
    /// In this process, one after the other.
    InProcess,
    /// On `workers` processes started as `program args... <slot>`, each running the
    /// episodes of its slot (see [`serve_worker`]).
    Processes {
        /// The program (`dexjoco-data`).
        program: PathBuf,
        /// Its arguments before the slot number.
        args: Vec<String>,
        /// How many.
        workers: usize,
    },
}

/// What a run did.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct EvalSummary {
    /// The output folder.
    pub out: PathBuf,
    /// Every episode of the run that is complete, by index.
    pub episodes: Vec<EpisodeRecord>,
    /// Episodes the run asked for.
    pub total: usize,
    /// Episodes evaluated by this invocation (the others were there already).
    pub evaluated_now: usize,
    /// The marker file, when every episode is complete.
    pub marker: Option<PathBuf>,
    /// The server's metadata.
    pub server_metadata: serde_json::Value,
}

impl EvalSummary {
    /// Successful episodes.
    pub fn successes(&self) -> usize {
        self.episodes.iter().filter(|e| e.success).count()
    }
}

/// What worker processes read (`<out>/.eval-worker.json`).
#[derive(Debug, Serialize, Deserialize)]
struct WorkerJob {
    config: EvalConfig,
    todo: Vec<usize>,
    states: Vec<Vec<f64>>,
}

/// What a worker says on stdout, one JSON line per episode.
#[derive(Debug, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
enum WorkerLine {
    Done { episode: usize, success: bool },
    Error { message: String },
}

/// Runs the evaluation: the episodes not already in `config.out`, then the marker
/// (`success_rate_<n>_<episodes>.txt`) once every episode is complete, and the run's
/// record.
pub fn evaluate(
    config: &EvalConfig,
    executor: &Executor,
    progress: &dyn Progress,
) -> Result<EvalSummary, EvalError> {
    let out = &config.out;
    let spec = run_spec(config)?;
    config.task.check(&spec, config.options.rand_full)?;
    let states = initial_states(config, &spec)?;
    // The server first: no server, nothing to do (and nothing written).
    let client = connect(config)?;
    let metadata = crate::wire::to_json(client.metadata());
    fs_err::create_dir_all(out).map_err(io_err("create", out))?;
    let _lock = DirLock::acquire(out)?;
    let staging = out.join(STAGING);
    if staging.exists() {
        fs_err::remove_dir_all(&staging).map_err(io_err("remove", &staging))?;
    }
    let done = done_episodes(out)?;
    check_same_run(config, &states, &done)?;
    let todo: Vec<usize> = (0..config.options.episodes)
        .filter(|k| !done.contains_key(k))
        .collect();
    progress.start(config.options.episodes as u64);
    let mut successes = done.values().filter(|(_, r)| r.success).count();
    progress.advance(done.len() as u64, &tally(successes, done.len()));
    let mut finished = done.len();
    let mut on_done = |success: bool| {
        finished += 1;
        successes += usize::from(success);
        progress.advance(1, &tally(successes, finished));
    };
    let result = match executor {
        Executor::Processes { workers, .. } if *workers > 1 && todo.len() > 1 => {
            client.close();
            let job = WorkerJob {
                config: config.clone(),
                todo: todo.clone(),
                states: states.clone(),
            };
            run_on_processes(executor, &job, &mut on_done)
        }
        _ => run_episodes(config, &todo, &states, client, &metadata, |r| {
            on_done(r.success);
            Ok(())
        }),
    };
    let _ = fs_err::remove_dir_all(&staging);
    let _ = fs_err::remove_file(out.join(WORKER_CONFIG));
    result?;
    finish(config, out, &metadata, todo.len())
}

fn tally(successes: usize, finished: usize) -> String {
    format!("{successes} of {finished} successful")
}

fn connect(config: &EvalConfig) -> Result<PolicyClient, EvalError> {
    PolicyClient::connect(
        &config.uri,
        std::time::Duration::from_secs_f64(config.options.server_wait_secs),
        std::time::Duration::from_secs_f64(config.options.deadline_secs),
    )
}

/// Refuses to add episodes to a folder holding another run's (another task, seed or
/// initial state for the same index).
fn check_same_run(
    config: &EvalConfig,
    states: &[Vec<f64>],
    done: &std::collections::BTreeMap<usize, (PathBuf, EpisodeRecord)>,
) -> Result<(), EvalError> {
    for (k, (path, r)) in done {
        let same = r.task == config.task.task
            && r.seed == config.options.seed
            && r.step_cap == config.options.step_cap
            && states.get(*k).is_some_and(|s| s == &r.reset);
        if !same {
            return Err(EvalError::Usage(format!(
                "'{}' holds episode {k} of another run (task {}, seed {}, step cap or another initial \
                 state): choose another --output, or remove the folder",
                path.display(),
                r.task,
                r.seed
            )));
        }
    }
    Ok(())
}

/// The marker (when every episode is complete) and the run's record.
fn finish(
    config: &EvalConfig,
    out: &Path,
    metadata: &serde_json::Value,
    evaluated_now: usize,
) -> Result<EvalSummary, EvalError> {
    let done = done_episodes(out)?;
    let episodes: Vec<EpisodeRecord> = done.into_values().map(|(_, r)| r).collect();
    let total = config.options.episodes;
    let complete = (0..total).all(|k| episodes.iter().any(|e| e.episode == k));
    let mut summary = EvalSummary {
        out: out.to_path_buf(),
        episodes,
        total,
        evaluated_now,
        marker: None,
        server_metadata: metadata.clone(),
    };
    if complete {
        summary.marker = Some(write_marker(out, summary.successes(), total)?);
    }
    let record = serde_json::json!({
        "written_by": "dexjoco-data eval",
        "version": env!("CARGO_PKG_VERSION"),
        "config": config,
        "server_metadata": metadata,
        "episodes": total,
        "complete": complete,
        "successes": summary.successes(),
        "success_rate": summary.successes() as f64 / total.max(1) as f64,
    });
    let bytes = serde_json::to_vec_pretty(&record).expect("serializable");
    dexjoco_formats::write_atomic(&out.join(RUN_RECORD), &bytes)?;
    Ok(summary)
}

/// Runs episodes `todo` in this process over `client`, committing each as it completes.
fn run_episodes(
    config: &EvalConfig,
    todo: &[usize],
    states: &[Vec<f64>],
    client: PolicyClient,
    metadata: &serde_json::Value,
    mut on_done: impl FnMut(&EpisodeRecord) -> Result<(), EvalError>,
) -> Result<(), EvalError> {
    if todo.is_empty() {
        client.close();
        return Ok(());
    }
    let mut stage = Stage::new(config)?;
    let setup = stage.spec.setup;
    let mut inference = if config.options.real_time {
        Inference::real_time(client, &config.uri, setup)
    } else {
        Inference::modelled(client, config.options.latency_steps, setup)
    };
    for &k in todo {
        let dir = staging_dir(&config.out, k);
        if dir.exists() {
            fs_err::remove_dir_all(&dir).map_err(io_err("remove", &dir))?;
        }
        let record = match run_episode(&mut stage, k, &states[k], &mut inference, &dir, metadata) {
            Ok(r) => r,
            Err(e) => {
                let _ = fs_err::remove_dir_all(&dir);
                return Err(e);
            }
        };
        commit_episode(
            &config.out,
            &dir,
            &record,
            config.options.record_pressed_digits,
        )?;
        on_done(&record)?;
    }
    Ok(())
}

/// Runs the job on worker processes, counting their episodes as they finish; the first
/// worker's error stops the others.
fn run_on_processes(
    executor: &Executor,
    job: &WorkerJob,
    on_done: &mut dyn FnMut(bool),
) -> Result<(), EvalError> {
    let Executor::Processes {
        program,
        args,
        workers,
    } = executor
    else {
        unreachable!("processes only")
    };
    let path = job.config.out.join(WORKER_CONFIG);
    let bytes = serde_json::to_vec(job).expect("serializable");
    dexjoco_formats::write_atomic(&path, &bytes)?;
    let n = (*workers).min(job.todo.len());
    let (tx, rx) = std::sync::mpsc::channel::<(usize, Option<String>)>();
    let mut children = Vec::new();
    for slot in 0..n {
        let mut cmd = Command::new(program);
        cmd.args(args)
            .arg(slot.to_string())
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit());
        dexjoco_sim::share_llvmpipe_threads(&mut cmd, n);
        let mut child = cmd.spawn().map_err(|e| {
            EvalError::Worker(format!(
                "cannot start a worker '{}': {e}",
                program.display()
            ))
        })?;
        let stdout = BufReader::new(child.stdout.take().expect("piped"));
        let tx = tx.clone();
        std::thread::spawn(move || {
            for line in stdout.lines() {
                let Ok(line) = line else { break };
                if tx.send((slot, Some(line))).is_err() {
                    return;
                }
            }
            let _ = tx.send((slot, None));
        });
        children.push(child);
    }
    drop(tx);
    let mut failure: Option<EvalError> = None;
    let mut open = n;
    while open > 0 {
        let Ok((slot, line)) = rx.recv() else { break };
        let Some(line) = line else {
            open -= 1;
            let status = children[slot].wait().map_err(io_err("wait for", program))?;
            if !status.success() && failure.is_none() {
                failure = Some(EvalError::Worker(format!(
                    "worker {slot} ended with {status} before finishing its episodes"
                )));
            }
            continue;
        };
        match serde_json::from_str::<WorkerLine>(&line) {
            Ok(WorkerLine::Done { success, .. }) => on_done(success),
            Ok(WorkerLine::Error { message }) => {
                if failure.is_none() {
                    failure = Some(EvalError::Worker(message));
                }
                for c in &mut children {
                    let _ = c.kill();
                }
            }
            Err(_) => tracing::debug!("worker {slot}: {line}"),
        }
    }
    for c in &mut children {
        let _ = c.wait();
    }
    failure.map_or(Ok(()), Err)
}

/// A worker process's side: reads the job in `out`, runs the episodes of slot `slot`
/// of `workers` (every `workers`-th of the job's list) over a connection of its own, and
/// says each on stdout as it completes.
pub fn serve_worker(out: &Path, slot: usize, workers: usize) -> Result<(), EvalError> {
    let path = out.join(WORKER_CONFIG);
    let bytes = fs_err::read(&path).map_err(io_err("read", &path))?;
    let job: WorkerJob = serde_json::from_slice(&bytes)
        .map_err(|e| EvalError::Worker(format!("'{}': {e}", path.display())))?;
    let mine: Vec<usize> = job
        .todo
        .iter()
        .copied()
        .skip(slot)
        .step_by(workers.max(1))
        .collect();
    let say = |line: &WorkerLine| {
        println!("{}", serde_json::to_string(line).expect("serializable"));
    };
    let result = connect(&job.config).and_then(|client| {
        let metadata = crate::wire::to_json(client.metadata());
        run_episodes(&job.config, &mine, &job.states, client, &metadata, |r| {
            say(&WorkerLine::Done {
                episode: r.episode,
                success: r.success,
            });
            Ok(())
        })
    });
    if let Err(e) = &result {
        say(&WorkerLine::Error {
            message: crate::error::one_line(e),
        });
    }
    result
}
