//! The augment run: read the inputs, check the output's settings, simulate each owned
//! episode once (success, deviation, any extension), plan what is still to render
//! (resume, shard), render the units on threads or worker processes, and (unsharded)
//! write the report and contact sheet.

use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;
use std::sync::Arc;

use dexjoco_core::{Progress, TaskSet};
use rayon::prelude::*;

use crate::assets::{TaskAssets, load_assets};
use crate::config::{AugmentConfig, STAGING};
use crate::error::{AugmentError, io_err};
use crate::fingerprint::{OutputSettings, scene_hash};
use crate::inputs::{SkippedInput, Source, read_sources};
use crate::physics::{PhysicsSummary, simulate};
use crate::plan::{
    ReplaysOnDisk, owned_replays, replays_on_disk, replays_per_unit, replays_to_render,
    source_state,
};
use crate::render::UnitJob;
use crate::report::{
    AugmentReport, AugmentRun, EpisodeOutcome, FailedUnit, contact_sheet, write_report,
};
use crate::staging::Outcome;
use crate::worker::{Executor, LocalInputs, UnitResult, WorkerPool, run_jobs, start_pool};

/// Runs the augment stage on this process's threads.
pub fn augment(
    config: &AugmentConfig,
    progress: &dyn Progress,
) -> Result<AugmentRun, AugmentError> {
    augment_with(config, &Executor::Threads, progress)
}

/// Runs the augment stage with units on `executor`, reporting the physics pass
/// (episodes) and then rendered frames to `progress`.
pub fn augment_with(
    config: &AugmentConfig,
    executor: &Executor,
    progress: &dyn Progress,
) -> Result<AugmentRun, AugmentError> {
    let (mut sources, mut skipped) = read_replayable(config)?;
    // One scene per task, shared by the workers, each `--camera` checked against it
    // before anything is written or simulated; the settings that decide the output's
    // bytes, checked below against what the folder was made with.
    let (assets, settings) = load_assets_and_settings(config, &sources)?;
    let out = &config.out;
    let created = !out.exists();
    fs_err::create_dir_all(out).map_err(io_err("create", out))?;
    let lock = crate::staging::lock_output(out, config.shard)?;
    // A resume writes into the folders it finds: none may be a link leading elsewhere.
    dexjoco_formats::fs::refuse_links_within(out)?;

    // This run's share and what of it is on disk already (resume). When anything is left
    // to render, the renderer is probed (a machine that cannot render fails now, not after
    // the physics pass) and the worker processes start: they warm their renderers up while
    // this process simulates. A finalize with nothing left starts none.
    let cameras = 1 + config.cameras.len();
    let owned = owned_replays(&sources, config, cameras);
    let on_disk = replays_on_disk(config, &sources);
    let to_render = replays_to_render(config, &sources, &owned, &on_disk);
    if to_render > 0
        && let Err(e) = executor.check_renderer()
    {
        // Nothing was written: a folder made for this run goes again (once unlocked).
        drop(lock);
        if created {
            let _ = fs_err::remove_dir(out);
        }
        return Err(e);
    }
    let pool = start_workers(executor, config, &sources, &owned, to_render)?;
    let staging = prepare_output(config, &settings)?;

    // This run's share, and the physics of every episode it touches (the unsharded run,
    // which writes the report, simulates them all). An episode the simulator rejects
    // (e.g. a state that does not fit the scene) is skipped, not the batch.
    let (physics, validation_seconds) = simulate_episodes(
        config,
        &mut sources,
        &owned,
        &assets,
        &mut skipped,
        progress,
    );

    // The units still to render, after what is on disk already (resume).
    let (mut outcomes, todo) = plan_replays(config, &sources, &owned, &physics, &assets, &on_disk)?;
    let jobs = unit_jobs(executor, config, &sources, &physics, &todo);
    let local = LocalInputs {
        sources: &sources,
        assets: &assets,
    };
    let (results, mut times) = run_jobs(executor, pool, &jobs, &local, config, cameras, progress)
        .map_err(|e| with_space_needed(e, config, &jobs, cameras))?;
    times.physics += validation_seconds;
    if config.shard.is_none() {
        let _ = fs_err::remove_dir(&staging);
    }
    let (rendered_now, failed_units) = collect_results(&jobs, results, &mut outcomes);

    let report = build_report(
        config,
        &sources,
        &physics,
        &assets,
        outcomes,
        skipped,
        failed_units,
    );
    // A shard writes no report: the unsharded run after the shards writes it (and renders
    // nothing new), the same bytes as one unsharded run.
    if config.shard.is_none() {
        write_report(out, &report)?;
        if config.contact_sheet {
            contact_sheet(out, &report)?;
        }
    }
    Ok(AugmentRun {
        report,
        rendered_now,
        times,
    })
}

/// A full disk, with the space free on the output's file system and an estimate of what
/// the replays still to render need (their frames at the bytes per frame of the replays
/// already in the output). Other errors unchanged.
fn with_space_needed(
    e: AugmentError,
    config: &AugmentConfig,
    jobs: &[(usize, UnitJob)],
    cameras: usize,
) -> AugmentError {
    let AugmentError::OutOfSpace { message, .. } = e else {
        return e;
    };
    let tasks: BTreeSet<&str> = jobs.iter().map(|(_, j)| j.task.as_str()).collect();
    let on_disk = crate::plan::existing_replays(&config.out, &tasks);
    // The replays of the run's units that are not in place.
    let frames: u64 = jobs
        .iter()
        .map(|(_, j)| {
            let done = on_disk.get(&(j.task.clone(), j.episode.clone()));
            let left = j
                .replays
                .iter()
                .filter(|r| done.is_none_or(|d| !d.contains_key(r)))
                .count();
            (j.physics.frames * cameras * left) as u64
        })
        .sum();
    let per_frame = crate::plan::bytes_per_frame(&config.out, &tasks, cameras);
    AugmentError::OutOfSpace {
        message,
        free: dexjoco_formats::fs::free_bytes(&config.out),
        needed: per_frame.map(|b| (b * frames as f64) as u64),
    }
}

/// Reads the inputs (skipping those that cannot be replayed); fails when none can be.
fn read_replayable(
    config: &AugmentConfig,
) -> Result<(Vec<Source>, Vec<SkippedInput>), AugmentError> {
    let tasks = TaskSet::with_dir(config.tasks_dir.as_deref())
        .map_err(|e| AugmentError::Input(format!("task specs: {e}")))?;
    let (sources, skipped) = read_sources(&config.inputs, &config.out, &tasks)?;
    if sources.is_empty()
        && let Some(first) = skipped.first()
    {
        return Err(AugmentError::Input(format!(
            "none of the {} input(s) can be replayed; the first: '{}': {}",
            skipped.len(),
            first.source,
            first.reason
        )));
    }
    Ok((sources, skipped))
}

/// Starts the worker processes (none on threads, none with nothing `to_render`, no more
/// than replays `to_render`), preloading the tasks this run owns replays of.
fn start_workers(
    executor: &Executor,
    config: &AugmentConfig,
    sources: &[Source],
    owned: &[Vec<usize>],
    to_render: usize,
) -> Result<WorkerPool, AugmentError> {
    let preload: BTreeSet<String> = sources
        .iter()
        .zip(owned)
        .filter(|(_, o)| !o.is_empty())
        .map(|(s, _)| s.spec.id.clone())
        .collect();
    start_pool(executor, config, preload.into_iter().collect(), to_render)
}

/// Loads each task's assets once, and the settings that decide the output's bytes.
fn load_assets_and_settings(
    config: &AugmentConfig,
    sources: &[Source],
) -> Result<(BTreeMap<String, Arc<TaskAssets>>, OutputSettings), AugmentError> {
    let mut assets: BTreeMap<String, Arc<TaskAssets>> = BTreeMap::new();
    let mut inputs = Vec::new();
    for s in sources {
        if assets.contains_key(&s.spec.id) {
            continue;
        }
        let a = load_assets(config, &s.spec)?;
        a.check_cameras(&config.cameras, &s.spec.id)?;
        inputs.push((
            s.spec.id.clone(),
            scene_hash(&config.scene, &s.spec)?,
            OutputSettings::spec_hash(&s.spec),
        ));
        assets.insert(s.spec.id.clone(), Arc::new(a));
    }
    let settings = OutputSettings::of(
        config,
        inputs
            .into_iter()
            .map(|(t, scene, spec)| (t.clone(), scene, &assets[&t].pool, spec)),
    );
    Ok((assets, settings))
}

/// Cleans the output (`--overwrite`), checks its settings against `settings` (or writes
/// them) and, unsharded, drops a killed run's leftovers; returns the staging folder.
fn prepare_output(
    config: &AugmentConfig,
    settings: &OutputSettings,
) -> Result<PathBuf, AugmentError> {
    let out = &config.out;
    if config.overwrite {
        crate::staging::clean_output(out)?;
    }
    settings.check_or_write(out)?;
    // Unsharded, this is the only writer: a killed run's staged replays are dropped.
    // Shards share the folder, and each clears only its own units' staging.
    let staging = out.join(STAGING);
    if config.shard.is_none() && staging.exists() {
        remove_staging(&staging)?;
    }
    if config.shard.is_none() {
        // And the temporaries of its atomic writes (report, settings, dropped records).
        crate::staging::remove_partial_files(out)?;
    }
    Ok(staging)
}

/// Simulates the episodes this run touches, on threads: their physics (`None` for those
/// not simulated or rejected, which join `skipped`) and the seconds spent, summed over the
/// threads.
fn simulate_episodes(
    config: &AugmentConfig,
    sources: &mut [Source],
    owned: &[Vec<usize>],
    assets: &BTreeMap<String, Arc<TaskAssets>>,
    skipped: &mut Vec<SkippedInput>,
    progress: &dyn Progress,
) -> (Vec<Option<PhysicsSummary>>, f64) {
    if config.shard.is_some() {
        // A shard needs only its own episodes' arrays (at DexJoCo scale, the others weigh
        // a gigabyte).
        for (s, o) in sources.iter_mut().zip(owned) {
            if o.is_empty() {
                s.episode.arrays.clear();
            }
        }
    }
    let simulate_it: Vec<bool> = owned
        .iter()
        .map(|o| config.shard.is_none() || !o.is_empty())
        .collect();
    progress.phase("physics", simulate_it.iter().filter(|x| **x).count() as u64);
    // Each simulation with its seconds (summed below over the threads that ran them).
    let simulated: Vec<Option<(Result<PhysicsSummary, AugmentError>, f64)>> = sources
        .par_iter()
        .zip(&simulate_it)
        .map(|(s, &go)| {
            go.then(|| {
                let mut seconds = 0.0;
                let r = crate::profile::timed(&mut seconds, || {
                    simulate(s, &assets[&s.spec.id].scene, config).map(|p| p.summary)
                });
                progress.advance(1, &s.key());
                (r, seconds)
            })
        })
        .collect();
    let validation_seconds: f64 = simulated.iter().flatten().map(|(_, s)| s).sum();
    let mut physics: Vec<Option<PhysicsSummary>> = Vec::with_capacity(sources.len());
    for (s, p) in sources
        .iter()
        .zip(simulated.into_iter().map(|p| p.map(|(r, _)| r)))
    {
        physics.push(match p {
            Some(Ok(p)) => Some(p),
            Some(Err(e)) => {
                skipped.push(crate::inputs::skipped_input(&s.path, e.to_string()));
                None
            }
            None => None,
        });
    }
    (physics, validation_seconds)
}

/// The replays already done or dropped (resume), by (source, replay), and each simulated
/// source's owned replays still to render (none for a failed replay without
/// `--keep-failed`).
type ReplayPlan = (BTreeMap<(usize, usize), Outcome>, Vec<(usize, Vec<usize>)>);

/// Plans the replays still to render from what is `on_disk` already.
fn plan_replays(
    config: &AugmentConfig,
    sources: &[Source],
    owned: &[Vec<usize>],
    physics: &[Option<PhysicsSummary>],
    assets: &BTreeMap<String, Arc<TaskAssets>>,
    on_disk: &ReplaysOnDisk,
) -> Result<ReplayPlan, AugmentError> {
    let mut outcomes: BTreeMap<(usize, usize), Outcome> = BTreeMap::new();
    let mut todo: Vec<(usize, Vec<usize>)> = Vec::new();
    for (i, s) in sources.iter().enumerate() {
        let Some(p) = &physics[i] else {
            continue;
        };
        let disk = on_disk.get(&(s.spec.id.clone(), s.episode.id.clone()));
        let state = source_state(s, &s.hash, &owned[i], disk, &assets[&s.spec.id], config)?;
        outcomes.extend(state.outcomes.into_iter().map(|(r, o)| ((i, r), o)));
        if p.first_success.is_none() && !config.keep_failed {
            if !state.todo.is_empty() {
                tracing::warn!(task = %s.spec.id, episode = %s.episode.id, "replay failed; no replays kept");
            }
            continue;
        }
        if !state.todo.is_empty() {
            todo.push((i, state.todo));
        }
    }
    Ok((outcomes, todo))
}

/// The units of work: each source's replays to render, in chunks sized for `executor`'s
/// workers.
fn unit_jobs(
    executor: &Executor,
    config: &AugmentConfig,
    sources: &[Source],
    physics: &[Option<PhysicsSummary>],
    todo: &[(usize, Vec<usize>)],
) -> Vec<(usize, UnitJob)> {
    let workers = match executor {
        Executor::Threads => rayon::current_num_threads(),
        Executor::Processes(w) => w.count,
    }
    .max(1);
    let mut jobs: Vec<(usize, UnitJob)> = Vec::new();
    for (i, replays) in todo {
        let s = &sources[*i];
        let per_unit = replays_per_unit(
            replays.len(),
            config.resimulate_per_replay || config.dynamics,
            workers,
            todo.len(),
        );
        for chunk in replays.chunks(per_unit) {
            jobs.push((
                *i,
                UnitJob {
                    path: s.path.clone(),
                    kind: s.kind,
                    task: s.spec.id.clone(),
                    episode: s.episode.id.clone(),
                    replays: chunk.to_vec(),
                    physics: physics[*i].clone().expect("simulated"),
                    source_hash: s.hash.clone(),
                    attempt: 0,
                },
            ));
        }
    }
    jobs
}

/// Adds the units' outcomes to `outcomes`; returns how many replays were rendered now and
/// the units that failed.
fn collect_results(
    jobs: &[(usize, UnitJob)],
    results: Vec<UnitResult>,
    outcomes: &mut BTreeMap<(usize, usize), Outcome>,
) -> (usize, Vec<FailedUnit>) {
    let mut rendered_now = 0;
    let mut failed_units = Vec::new();
    for ((i, job), result) in jobs.iter().zip(results) {
        match result {
            Ok(done) => {
                for o in done {
                    let r = match &o {
                        Outcome::Kept(rec) => {
                            rendered_now += 1;
                            rec.replay
                        }
                        Outcome::Dropped(rec) => rec.replay,
                    };
                    outcomes.insert((*i, r), o);
                }
            }
            Err(reason) => failed_units.push(FailedUnit {
                task: job.task.clone(),
                episode: job.episode.clone(),
                replays: job.replays.clone(),
                reason,
            }),
        }
    }
    (rendered_now, failed_units)
}

/// Removes a killed run's staging. Its worker processes stop within a frame of their
/// parent's death (their next message fails), so a removal racing one of them is retried
/// for a few seconds.
fn remove_staging(staging: &std::path::Path) -> Result<(), AugmentError> {
    let mut tries = 0;
    loop {
        match fs_err::remove_dir_all(staging) {
            Ok(()) => return Ok(()),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
            Err(_) if tries < 20 => {
                tries += 1;
                std::thread::sleep(std::time::Duration::from_millis(250));
            }
            Err(e) => return Err(io_err("remove", staging)(e)),
        }
    }
}

/// The distinct instructions of the replayed episodes per task, sorted.
fn instructions_by_task(
    sources: &[Source],
    physics: &[Option<PhysicsSummary>],
) -> BTreeMap<String, Vec<String>> {
    let mut by_task: BTreeMap<String, std::collections::BTreeSet<String>> = BTreeMap::new();
    for (s, _) in sources.iter().zip(physics).filter(|(_, p)| p.is_some()) {
        by_task
            .entry(s.spec.id.clone())
            .or_default()
            .insert(s.episode.prompt.clone());
    }
    by_task
        .into_iter()
        .map(|(task, set)| (task, set.into_iter().collect()))
        .collect()
}

/// The report: every replay of these episodes on disk, in (episode, replay) order.
#[allow(clippy::too_many_arguments)]
fn build_report(
    config: &AugmentConfig,
    sources: &[Source],
    physics: &[Option<PhysicsSummary>],
    assets: &BTreeMap<String, Arc<TaskAssets>>,
    outcomes: BTreeMap<(usize, usize), Outcome>,
    skipped: Vec<SkippedInput>,
    failed_units: Vec<FailedUnit>,
) -> AugmentReport {
    let mut replays = Vec::new();
    let mut dropped = Vec::new();
    let mut kept = vec![0; sources.len()];
    for ((i, _), o) in outcomes {
        match o {
            Outcome::Kept(rec) => {
                kept[i] += 1;
                replays.push(rec);
            }
            Outcome::Dropped(rec) => dropped.push(rec),
        }
    }
    let made_on = crate::report::take_made_on(&mut replays, &mut dropped);
    let flagged = crate::report::flagged_replays(&replays);
    let episodes = sources
        .iter()
        .zip(physics)
        .enumerate()
        .filter_map(|(i, (s, p))| {
            let p = p.as_ref()?;
            Some(EpisodeOutcome {
                task: s.spec.id.clone(),
                episode: s.episode.id.clone(),
                source: s.path.display().to_string(),
                success: p.first_success.is_some(),
                first_success: p.first_success,
                steps: p.frames,
                recorded_steps: p.recorded,
                success_shift: p.first_success.map(|k| k as i64 - (p.recorded as i64 - 1)),
                extended: p.extended(),
                max_state_deviation: p.deviation,
                replays_kept: kept[i],
                subtasks: p.subtasks.clone(),
            })
        })
        .collect();
    AugmentReport {
        seed: config.seed,
        replays_per_episode: config.replays,
        settings: config.settings,
        camera_pools: assets
            .iter()
            .map(|(t, a)| (t.clone(), a.pool.source.clone()))
            .collect(),
        table_library: assets
            .iter()
            .map(|(t, a)| {
                (
                    t.clone(),
                    a.table.entries.iter().map(|e| e.name.clone()).collect(),
                )
            })
            .collect(),
        instructions: instructions_by_task(sources, physics),
        episodes,
        replays,
        dropped,
        flagged,
        skipped,
        failed_units,
        made_on,
    }
}
