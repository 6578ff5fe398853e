//! The augment run: read the inputs, simulate each episode once (success, deviation),
//! plan what is still to render (resume), render the units in parallel, and write the
//! report and contact sheet.

use std::collections::BTreeMap;
use std::sync::Arc;

use dexjoco_core::{Progress, TaskSet, TaskSpec};
use dexjoco_sim::{Scene, SceneSource, load_task_scene};
use rayon::prelude::*;

use crate::config::{AugmentConfig, STAGING, TABLE_GEOM, replay_name};
use crate::dynamics::{dynamics_seed, sample_dynamics};
use crate::error::{AugmentError, io_err, sim_err};
use crate::inputs::{SkippedInput, Source, read_sources};
use crate::physics::{Physics, frames, simulate};
use crate::randomize::{CameraPool, TableLibrary, builtin_pool};
use crate::render::{Unit, close_renderer, render_unit};
use crate::report::{AugmentReport, EpisodeOutcome, contact_sheet, write_report};
use crate::staging::{Outcome, dropped_path, read_record, read_record_file};

/// A task's scene and what randomization needs of it, shared by every worker.
pub(crate) struct TaskAssets {
    pub(crate) scene: Scene,
    pub(crate) pool: CameraPool,
    pub(crate) table: TableLibrary,
    pub(crate) nlight: usize,
    pub(crate) key: String,
}

fn pool_for(config: &AugmentConfig, spec: &TaskSpec) -> Result<CameraPool, AugmentError> {
    if let Some(p) = &config.camera_pool {
        return CameraPool::load(p);
    }
    if let SceneSource::Dir(dir) = &config.scene {
        let file = match spec.setup {
            dexjoco_core::ArmSetup::SingleArm => "replay_cameras.json",
            dexjoco_core::ArmSetup::Bimanual => "replay_cameras_2.json",
        };
        // The reference pools sit beside its `xmls/` folder.
        for cand in [dir.join(file), dir.join("..").join(file)] {
            if cand.is_file() {
                return CameraPool::load(&cand);
            }
        }
    }
    Ok(builtin_pool(spec.setup))
}

/// Runs the augment stage, reporting rendered units to `progress`.
pub fn augment(
    config: &AugmentConfig,
    progress: &dyn Progress,
) -> Result<AugmentReport, AugmentError> {
    let tasks = TaskSet::with_dir(config.tasks_dir.as_deref())
        .map_err(|e| AugmentError::Input(format!("task specs: {e}")))?;
    let (sources, mut skipped) = read_sources(&config.inputs, &tasks)?;
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
    let out = &config.out;
    fs_err::create_dir_all(out).map_err(io_err("create", out))?;
    // A killed run leaves at most staged (never renamed) replays: drop them.
    let staging = out.join(STAGING);
    if staging.exists() {
        fs_err::remove_dir_all(&staging).map_err(io_err("remove", &staging))?;
    }

    // One scene per task, shared by the workers.
    let mut assets: BTreeMap<String, Arc<TaskAssets>> = BTreeMap::new();
    for s in &sources {
        if assets.contains_key(&s.spec.id) {
            continue;
        }
        let scene = load_task_scene(&config.scene, &s.spec).map_err(sim_err(&s.episode.id))?;
        let table = TableLibrary::of_model(&scene.model, TABLE_GEOM)?;
        let pool = pool_for(config, &s.spec)?;
        let nlight = scene.model.ffi().nlight as usize;
        let key = format!("{}:{}", s.spec.id, scene.path.display());
        assets.insert(
            s.spec.id.clone(),
            Arc::new(TaskAssets {
                scene,
                pool,
                table,
                nlight,
                key,
            }),
        );
    }

    // Physics once per episode: success and deviation from the recording.
    // An episode the simulator rejects (e.g. a state that does not fit the scene) is
    // skipped, not the batch.
    let simulated: Vec<Result<Physics, AugmentError>> = sources
        .par_iter()
        .map(|s| simulate(s, &assets[&s.spec.id], frames(s, config)))
        .collect();
    let (sources, physics): (Vec<Source>, Vec<Physics>) = sources
        .into_iter()
        .zip(simulated)
        .filter_map(|(s, p)| match p {
            Ok(p) => Some((s, p)),
            Err(e) => {
                skipped.push(SkippedInput::new(&s.path, e.to_string()));
                None
            }
        })
        .unzip();

    // What is on disk already (resume), read once, and which replays are still to do.
    let mut outcomes: BTreeMap<(usize, usize), Outcome> = BTreeMap::new();
    let mut units = Vec::new();
    let jobs = rayon::current_num_threads().max(1);
    for (i, s) in sources.iter().enumerate() {
        // Done: the replay's folder is there (made with this seed), or, without
        // --keep-failed (which would now keep it), it was dropped under --dynamics with the
        // same seed and the same draw (a changed spec draws again).
        let key = s.key();
        let mut todo = Vec::new();
        for r in 0..config.replays {
            let name = replay_name(&s.episode.id, r);
            let seed = crate::randomize::replay_seed(config.seed, &key, r);
            let folder = out.join(&s.spec.id).join(&name);
            if let Some(rec) = read_record(&folder) {
                if rec.sample.seed != seed {
                    return Err(AugmentError::Input(format!(
                        "'{}' was made with another --seed (replay seed {}, now {seed}): augment into another --out, or remove it",
                        folder.display(),
                        rec.sample.seed
                    )));
                }
                outcomes.insert((i, r), Outcome::Kept(rec));
                continue;
            }
            if config.dynamics
                && !config.keep_failed
                && let Some(rec) = read_record_file(&dropped_path(out, &s.spec.id, &name))
            {
                let model = &assets[&s.spec.id].scene.model;
                let draw = sample_dynamics(&s.spec, model, dynamics_seed(seed))?;
                if rec.sample.seed == seed && rec.dynamics.as_ref() == Some(&draw) {
                    outcomes.insert((i, r), Outcome::Dropped(rec));
                    continue;
                }
            }
            todo.push(r);
        }
        if physics[i].first_success.is_none() && !config.keep_failed {
            tracing::warn!(task = %s.spec.id, episode = %s.episode.id, "replay failed; no replays kept");
            continue;
        }
        if todo.is_empty() {
            continue;
        }
        let per_unit = if config.resimulate_per_replay || config.dynamics {
            1
        } else {
            // Enough units to keep every worker busy; the output never depends on it.
            let units_per_episode = (2 * jobs).div_ceil(sources.len()).max(1);
            todo.len().div_ceil(units_per_episode).max(1)
        };
        for chunk in todo.chunks(per_unit) {
            units.push(Unit {
                source: i,
                replays: chunk.to_vec(),
            });
        }
    }
    progress.start(units.len() as u64);
    let rendered: Vec<Vec<Outcome>> = units
        .par_iter()
        .map(|u| {
            let s = &sources[u.source];
            let r = render_unit(u, s, &assets[&s.spec.id], &physics[u.source], config, out);
            progress.advance(1, &s.key());
            r
        })
        .collect::<Result<_, _>>()?;
    // Close every worker's renderer (and its EGL context) now, in order, rather than at
    // process exit while other threads are still alive.
    rayon::broadcast(|_| close_renderer());
    let _ = fs_err::remove_dir(&staging);
    let mut rendered_now = 0;
    for (u, done) in units.iter().zip(rendered) {
        for o in done {
            let r = match &o {
                Outcome::Kept(rec) => {
                    rendered_now += 1;
                    rec.replay
                }
                Outcome::Dropped(rec) => rec.replay,
            };
            outcomes.insert((u.source, r), o);
        }
    }

    // The report covers every replay of these episodes on disk, in (episode, replay)
    // order.
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
    let mut episodes = Vec::new();
    for (i, s) in sources.iter().enumerate() {
        episodes.push(EpisodeOutcome {
            task: s.spec.id.clone(),
            episode: s.episode.id.clone(),
            source: s.path.display().to_string(),
            success: physics[i].first_success.is_some(),
            first_success: physics[i].first_success,
            steps: frames(s, config),
            max_state_deviation: physics[i].deviation,
            replays_kept: kept[i],
        });
    }
    let report = AugmentReport {
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
        episodes,
        replays,
        dropped,
        skipped,
        rendered_now,
    };
    write_report(out, &report)?;
    if config.contact_sheet {
        contact_sheet(out, &report)?;
    }
    Ok(report)
}
