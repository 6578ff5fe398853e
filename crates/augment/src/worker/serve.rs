//! The worker process's side: read the `hello`, preload the run's scenes and open the
//! renderer (saying on which EGL device, then that the first frame is drawn), then render
//! each `job` and answer with its outcomes.

use std::collections::BTreeMap;
use std::io::{BufRead, Write};
use std::path::PathBuf;
use std::sync::Arc;

use dexjoco_core::TaskSet;
use dexjoco_formats::Source as FoundSource;

use super::protocol::{FromWorker, SLOT_ENV, ToWorker, send};
use super::{FAULT_ENV, STALL_ENV};
use crate::config::AugmentConfig;
use crate::error::AugmentError;
use crate::inputs::{Source, check_fields};
use crate::render::{UnitInputs, UnitJob, close_renderer, preload_renderer, render_unit};
use crate::run::{TaskAssets, load_assets};

/// What a worker process holds between jobs.
struct WorkerState {
    config: AugmentConfig,
    tasks: TaskSet,
    sources: BTreeMap<PathBuf, Source>,
    assets: BTreeMap<String, Arc<TaskAssets>>,
    /// Whether the renderer has drawn its first frame (and the parent was told).
    ready: bool,
    /// This worker stalls before its first frame (the stall test hook).
    stall: bool,
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
    let mut state = WorkerState {
        config,
        tasks,
        sources: BTreeMap::new(),
        assets: BTreeMap::new(),
        ready: false,
        stall: stalls_here(),
    };
    // The scenes this run will need, and this worker's renderer, before the first job.
    // A failure here is not fatal: the job that needs the scene reports it.
    for task in &preload {
        let Some(spec) = state.tasks.get(task).cloned() else {
            continue;
        };
        match load_assets(&state.config, &spec) {
            Ok(a) => {
                let a = Arc::new(a);
                if let Err(e) = state.warm_up(&a, &mut output) {
                    tracing::debug!(task, "renderer not preloaded: {e}");
                }
                state.assets.insert(task.clone(), a);
            }
            Err(e) => tracing::debug!(task, "scene not preloaded: {e}"),
        }
    }
    for line in lines {
        let job = match serde_json::from_str::<ToWorker>(&line.map_err(io)?) {
            Ok(ToWorker::Job(j)) => *j,
            _ => return Err(AugmentError::Input("worker: expected a job".into())),
        };
        let msg = match state.run(&job, &mut output) {
            Ok((outcomes, times)) => FromWorker::Done { outcomes, times },
            Err(e) => FromWorker::Error(e.to_string()),
        };
        send(&mut output, &msg).map_err(io)?;
    }
    close_renderer();
    Ok(())
}

/// Whether the stall hook names this worker's slot.
fn stalls_here() -> bool {
    let (Ok(list), Ok(slot)) = (std::env::var(STALL_ENV), std::env::var(SLOT_ENV)) else {
        return false;
    };
    list.split(',')
        .any(|s| s.trim() == "all" || s.trim() == slot)
}

/// Sends a message; a failed write means the parent has ended (killed): stop at once,
/// before anything more is written or renamed into place.
fn tell(output: &mut dyn Write, msg: &FromWorker) {
    if send(output, msg).is_err() {
        tracing::debug!("the augment run that started this worker has ended");
        std::process::exit(1);
    }
}

impl WorkerState {
    /// Opens the renderer on `assets`' scene and draws its warm-up frames; the first time,
    /// tells the parent the device, then that a frame was drawn.
    fn warm_up(&mut self, assets: &TaskAssets, output: &mut dyn Write) -> Result<(), AugmentError> {
        let (first, stall) = (!self.ready, self.stall);
        preload_renderer(assets, &self.config, &mut |device| {
            if first {
                tell(
                    output,
                    &FromWorker::Device(format!("{} ({})", device.index, device.label())),
                );
                if stall {
                    tracing::warn!(
                        "{STALL_ENV}: stalling before the first frame, as a hung driver would"
                    );
                    loop {
                        std::thread::sleep(std::time::Duration::from_secs(3600));
                    }
                }
            }
        })?;
        if first {
            tell(output, &FromWorker::Ready);
            self.ready = true;
        }
        Ok(())
    }

    /// Renders one job.
    fn run(
        &mut self,
        job: &UnitJob,
        output: &mut dyn Write,
    ) -> Result<(Vec<crate::staging::Outcome>, crate::profile::StageTimes), AugmentError> {
        load_source(&mut self.sources, job, &self.tasks)?;
        if !self.assets.contains_key(&job.task) {
            let spec = self.sources[&job.path].spec.clone();
            let a = Arc::new(load_assets(&self.config, &spec)?);
            self.assets.insert(job.task.clone(), a);
        }
        let assets = Arc::clone(&self.assets[&job.task]);
        if !self.ready {
            self.warm_up(&assets, output)?;
        }
        let inputs = UnitInputs {
            src: &self.sources[&job.path],
            assets: &assets,
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
            tell(output, &FromWorker::Frames(n));
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
