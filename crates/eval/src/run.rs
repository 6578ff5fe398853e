//! A whole evaluation run: the episodes' initial states (drawn from `--seed` as
//! `scripted` draws its resets, or given), the episodes a previous run left to do, the
//! episodes run here or on worker processes (`dexjoco-workers`' pool: each worker with
//! its own renderer, EGL device and connection to the policy server, an episode whose
//! worker died retried once on a fresh one, every worker killed when the run fails), the
//! marker and the run's record. One writer per output folder (its `.lock`).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use dexjoco_core::{Progress, TaskSpec};
use dexjoco_formats::DirLock;
use dexjoco_sim::{SceneSource, TaskEnv, load_task_scene};
use dexjoco_workers::{JobSet, WorkerPool, WorkerProcesses};
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

use crate::config::EvalConfig;
use crate::episode::run_episode;
use crate::error::{EvalError, io_err, sim_err};
use crate::inference::Inference;
use crate::output::{
    EpisodeRecord, RUN_RECORD, STAGING, commit_episode, done_episodes, staging_dir, write_marker,
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
    /// On worker processes (`dexjoco-data eval-worker`), each taking the next episode.
    Processes(WorkerProcesses),
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

/// What a worker process is told first: the run.
#[derive(Debug, Serialize, Deserialize)]
pub(crate) struct WorkerHello {
    pub(crate) config: EvalConfig,
}

/// An episode a worker process is given: its index and initial state.
#[derive(Debug, Serialize, Deserialize)]
pub(crate) struct EpisodeJob {
    pub(crate) episode: usize,
    pub(crate) state: Vec<f64>,
}

/// What a worker says of an episode it finished (and committed).
#[derive(Debug, Serialize, Deserialize)]
pub(crate) struct EpisodeDone {
    pub(crate) episode: usize,
    pub(crate) success: bool,
}

/// Episodes finished and successful, on the progress bar.
struct Tally<'a> {
    finished: AtomicUsize,
    successes: AtomicUsize,
    progress: &'a dyn Progress,
}

impl Tally<'_> {
    fn add(&self, n: usize, successes: usize) {
        let f = self.finished.fetch_add(n, Ordering::SeqCst) + n;
        let s = self.successes.fetch_add(successes, Ordering::SeqCst) + successes;
        self.progress
            .advance(n as u64, &format!("{s} of {f} successful"));
    }
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
    let client = connect(config, &spec)?;
    let metadata = client.metadata().clone();
    fs_err::create_dir_all(out).map_err(io_err("create", out))?;
    let _lock = DirLock::acquire(out)?;
    // A resume writes into the folders it finds: none may be a link leading elsewhere.
    dexjoco_formats::fs::refuse_links_within(out)?;
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
    let tally = Tally {
        finished: AtomicUsize::new(0),
        successes: AtomicUsize::new(0),
        progress,
    };
    tally.add(done.len(), done.values().filter(|(_, r)| r.success).count());
    let result = match executor {
        Executor::Processes(w) if w.count > 1 && todo.len() > 1 => {
            client.close();
            run_on_processes(w, config, &states, &todo, &tally)
        }
        _ => run_episodes(config, &todo, &states, client, &metadata, &mut |r| {
            tally.add(1, usize::from(r.success));
            Ok(())
        }),
    };
    let _ = fs_err::remove_dir_all(&staging);
    result?;
    finish(config, out, &metadata, todo.len())
}

/// A connection to the run's server, its answers checked against the task's action width.
pub(crate) fn connect(config: &EvalConfig, spec: &TaskSpec) -> Result<PolicyClient, EvalError> {
    PolicyClient::connect(
        &config.uri,
        std::time::Duration::from_secs_f64(config.options.server_wait_secs),
        std::time::Duration::from_secs_f64(config.options.deadline_secs),
        crate::decode::Limits::for_width(spec.setup.action_rotvec_dim()),
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
    on_done: &mut dyn FnMut(&EpisodeRecord) -> Result<(), EvalError>,
) -> Result<(), EvalError> {
    if todo.is_empty() {
        client.close();
        return Ok(());
    }
    let mut stage = Stage::new(config)?;
    let mut inference = inference_over(config, client);
    for &k in todo {
        let record = run_one(
            &mut stage,
            &mut inference,
            k,
            &states[k],
            metadata,
            &mut || {},
        )?;
        on_done(&record)?;
    }
    Ok(())
}

/// Answers over `client`, modelled or in real time as the run says.
pub(crate) fn inference_over(config: &EvalConfig, client: PolicyClient) -> Inference {
    if config.options.real_time {
        Inference::real_time(client, &config.uri)
    } else {
        Inference::modelled(client, config.options.latency_steps)
    }
}

/// Runs episode `k` into its staging folder and commits it into place; `tick` is called
/// every step and once before the commit. A failed episode leaves nothing.
pub(crate) fn run_one(
    stage: &mut Stage,
    inference: &mut Inference,
    k: usize,
    state0: &[f64],
    metadata: &serde_json::Value,
    tick: &mut dyn FnMut(),
) -> Result<EpisodeRecord, EvalError> {
    let out = stage.config.out.clone();
    let dir = staging_dir(&out, k);
    if dir.exists() {
        fs_err::remove_dir_all(&dir).map_err(io_err("remove", &dir))?;
    }
    let record = match run_episode(stage, k, state0, inference, &dir, metadata, tick) {
        Ok(r) => r,
        Err(e) => {
            let _ = fs_err::remove_dir_all(&dir);
            return Err(e);
        }
    };
    tick();
    let digits = stage.config.options.record_pressed_digits;
    commit_episode(&out, &dir, &record, digits)?;
    Ok(record)
}

/// The episodes of a run as the worker schedule sees them: in index order, each a job;
/// a failed attempt's staging folder removed.
struct Episodes<'a> {
    hello: WorkerHello,
    todo: Vec<EpisodeJob>,
    tally: &'a Tally<'a>,
}

impl JobSet for Episodes<'_> {
    type Hello = WorkerHello;
    type Job = EpisodeJob;
    type Done = EpisodeDone;

    fn hello(&self) -> &WorkerHello {
        &self.hello
    }

    fn len(&self) -> usize {
        self.todo.len()
    }

    fn job(&self, k: usize) -> &EpisodeJob {
        &self.todo[k]
    }

    fn key(&self, k: usize) -> String {
        format!("episode {}", self.todo[k].episode)
    }

    fn clear(&self, k: usize) {
        let dir = staging_dir(&self.hello.config.out, self.todo[k].episode);
        let _ = fs_err::remove_dir_all(dir);
    }

    fn retrying(&self, k: usize, reason: &str, _redone: u64) {
        self.tally
            .progress
            .note(&format!("retrying {}: {reason}", self.key(k)));
    }

    fn done(&self, _k: usize, done: &EpisodeDone) {
        self.tally.add(1, usize::from(done.success));
    }

    fn note(&self, message: &str) {
        self.tally.progress.note(message);
    }
}

/// Runs episodes `todo` on worker processes; the first failure (a server that answers
/// badly, an episode whose worker died twice) stops the run, and every worker is ended.
fn run_on_processes(
    w: &WorkerProcesses,
    config: &EvalConfig,
    states: &[Vec<f64>],
    todo: &[usize],
    tally: &Tally<'_>,
) -> Result<(), EvalError> {
    let episodes = Episodes {
        hello: WorkerHello {
            config: config.clone(),
        },
        todo: todo
            .iter()
            .map(|&episode| EpisodeJob {
                episode,
                state: states[episode].clone(),
            })
            .collect(),
        tally,
    };
    let pool = WorkerPool::start(w, &episodes.hello, todo.len())?;
    let results = dexjoco_workers::run_jobs(w, pool, &episodes)?;
    let failures: Vec<(usize, String)> = todo
        .iter()
        .zip(results)
        .filter_map(|(&k, r)| r.err().map(|why| (k, why.to_string())))
        .collect();
    if failures.is_empty() {
        Ok(())
    } else {
        Err(EvalError::EpisodesFailed { failures })
    }
}
