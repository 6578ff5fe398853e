//! The worker process's side: read the `hello`, preload the run's scenes and open the
//! renderer (saying on which EGL device, then that the first frame is drawn), then render
//! each `job` and answer with its outcomes.

use std::collections::BTreeMap;
use std::io::{BufRead, Write};
use std::path::PathBuf;
use std::sync::Arc;

use dexjoco_core::TaskSet;
use dexjoco_formats::Source as FoundSource;
use dexjoco_workers::serve::{FromParent, tell};
use dexjoco_workers::{Failure, SLOT_ENV};

use super::protocol::{FromWorker, Hello, UnitDone};
use crate::assets::{TaskAssets, load_assets};
use crate::config::AugmentConfig;
use crate::error::AugmentError;
use crate::inputs::{Source, check_fields};
use crate::render::{
    UnitInputs, UnitJob, close_renderer, preload_renderer, render_unit, renderer_ready,
};

/// Environment variable of a test hook: `<task>/<episode>@<k>` makes a worker process die
/// (exit status 134, as a crash would end it, without a core file) after the first rendered
/// frames of that episode's units, on their first `k` attempts.
pub const FAULT_ENV: &str = "DEXJOCO_TEST_WORKER_ABORT";

/// Environment variable of a test hook: worker slots (`0,2`, or `all`) whose worker
/// processes open their renderer and then stall before their first frame, as a hung EGL
/// driver does.
pub const STALL_ENV: &str = "DEXJOCO_TEST_WORKER_STALL";

/// What a worker process holds between jobs.
struct WorkerState {
    config: AugmentConfig,
    tasks: TaskSet,
    sources: BTreeMap<PathBuf, Source>,
    assets: BTreeMap<String, Arc<TaskAssets>>,
    /// This worker stalls before its first frame (the stall test hook).
    stall: bool,
}

/// Why a job could not start.
enum NotStarted {
    /// The renderer did not open or draw: this worker cannot render.
    CannotRender(String),
    /// The job's episode or scene failed.
    Unit(AugmentError),
}

/// The worker side: reads the `hello` and `job` lines from `input`, renders each unit,
/// answers on `output`. Returns when `input` ends.
pub fn serve_worker(input: impl BufRead, mut output: impl Write) -> Result<(), AugmentError> {
    let mut parent = FromParent::new(input);
    let Some(Hello { config, preload }) = parent.hello().map_err(AugmentError::Input)? else {
        return Ok(());
    };
    let tasks = TaskSet::with_dir(config.tasks_dir.as_deref())
        .map_err(|e| AugmentError::Input(format!("task specs: {e}")))?;
    let mut state = WorkerState {
        config,
        tasks,
        sources: BTreeMap::new(),
        assets: BTreeMap::new(),
        stall: stalls_here(),
    };
    state.preload(&preload, &mut output);
    while let Some((attempt, job)) = parent.job::<UnitJob>().map_err(AugmentError::Input)? {
        let job = UnitJob { attempt, ..job };
        let msg = match state.prepare(&job, &mut output) {
            Err(NotStarted::CannotRender(why)) => FromWorker::CannotRender(why),
            Err(NotStarted::Unit(e)) => FromWorker::Failed(failure(&e)),
            Ok(assets) => match state.render(&job, &assets, &mut output) {
                Ok((outcomes, times)) => FromWorker::Done(UnitDone { outcomes, times }),
                Err(e) => FromWorker::Failed(failure(&e)),
            },
        };
        tell(&mut output, &msg);
    }
    close_renderer();
    Ok(())
}

/// A unit's failure: run-wide when the disk is full.
fn failure(e: &AugmentError) -> Failure {
    if dexjoco_formats::fs::out_of_space(e) {
        Failure::run_wide(e.to_string())
    } else {
        Failure::job(e.to_string())
    }
}

/// Whether the stall hook names this worker's slot.
fn stalls_here() -> bool {
    let (Ok(list), Ok(slot)) = (std::env::var(STALL_ENV), std::env::var(SLOT_ENV)) else {
        return false;
    };
    list.split(',')
        .any(|s| s.trim() == "all" || s.trim() == slot)
}

impl WorkerState {
    /// Loads the scenes this run will need, each with the renderer warmed up, before the
    /// first job. A scene that fails to load is not fatal here (the job that needs it
    /// reports it); a renderer that fails is: the parent hears that this worker cannot
    /// render.
    fn preload(&mut self, tasks: &[String], output: &mut dyn Write) {
        for task in tasks {
            let Some(spec) = self.tasks.get(task).cloned() else {
                continue;
            };
            match load_assets(&self.config, &spec) {
                Ok(a) => {
                    let a = Arc::new(a);
                    self.assets.insert(task.clone(), Arc::clone(&a));
                    if let Err(e) = self.warm_up(&a, output) {
                        tell(output, &FromWorker::CannotRender(e.to_string()));
                        return;
                    }
                }
                Err(e) => tracing::debug!(task, "scene not preloaded: {e}"),
            }
        }
    }

    /// Opens the renderer on `assets`' scene and draws its warm-up frames, telling the
    /// parent as it goes: opening, the device it opened on, the first frame drawn.
    fn warm_up(&self, assets: &TaskAssets, output: &mut dyn Write) -> Result<(), AugmentError> {
        tell(output, &FromWorker::Opening);
        let stall = self.stall;
        preload_renderer(assets, &self.config, &mut |device| {
            tell(output, &FromWorker::Device(device.to_owned()));
            if stall {
                tracing::warn!(
                    "{STALL_ENV}: stalling before the first frame, as a hung driver would"
                );
                loop {
                    std::thread::sleep(std::time::Duration::from_secs(3600));
                }
            }
        })?;
        tell(output, &FromWorker::Ready);
        Ok(())
    }

    /// The job's episode and scene, with the renderer open on it.
    fn prepare(
        &mut self,
        job: &UnitJob,
        output: &mut dyn Write,
    ) -> Result<Arc<TaskAssets>, NotStarted> {
        load_source(&mut self.sources, job, &self.tasks).map_err(NotStarted::Unit)?;
        if !self.assets.contains_key(&job.task) {
            let spec = self.sources[&job.path].spec.clone();
            let a = load_assets(&self.config, &spec).map_err(NotStarted::Unit)?;
            self.assets.insert(job.task.clone(), Arc::new(a));
        }
        let assets = Arc::clone(&self.assets[&job.task]);
        if !renderer_ready(&assets, &self.config) {
            self.warm_up(&assets, output)
                .map_err(|e| NotStarted::CannotRender(e.to_string()))?;
        }
        Ok(assets)
    }

    /// Renders one prepared job.
    fn render(
        &self,
        job: &UnitJob,
        assets: &TaskAssets,
        output: &mut dyn Write,
    ) -> Result<(Vec<crate::staging::Outcome>, crate::profile::StageTimes), AugmentError> {
        let inputs = UnitInputs {
            src: &self.sources[&job.path],
            assets,
            config: &self.config,
            out: &self.config.out,
        };
        let abort = std::env::var(FAULT_ENV)
            .ok()
            .as_deref()
            .and_then(|f| f.rsplit_once('@'))
            .filter(|(key, k)| *key == job.key() && k.parse::<u32>().is_ok_and(|k| job.attempt < k))
            .is_some();
        render_unit(job, &inputs, &mut |n| {
            tell(output, &FromWorker::Progress(n));
            if abort && n > 0 {
                tracing::warn!("{FAULT_ENV}: dying mid-unit, as a crash would");
                std::process::exit(134);
            }
            Ok(())
        })
    }
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
                hash: crate::fingerprint::episode_hash(&episode, &spec),
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
