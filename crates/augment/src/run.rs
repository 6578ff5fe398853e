//! The augment run: read episodes, validate their replay, render randomized replays,
//! write them in the DexJoCo raw layout with a report; resumable and deterministic.

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use dexjoco_core::{CameraStream, Episode, FrameArray, TaskSpec};
use dexjoco_ingest::depth::DepthWriter;
use dexjoco_ingest::raw;
use dexjoco_sim::mujoco_rs::prelude::MjModel;
use dexjoco_sim::{
    CameraView, EnvOptions, RenderSettings, Renderer, Scene, SceneSource, TaskEnv, load_task_scene,
};
use dexjoco_video::{Codec, VideoSpec, VideoWriter};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::dynamics::{DynamicsValue, apply_dynamics, dynamics_seed, sample_dynamics};
use crate::error::{AugmentError, io_err};
use crate::randomize::{CameraPool, TableLibrary, VisualSample, apply_visuals, builtin_pool};

/// Name of the randomized third-person camera's video (`videos/third_person.mp4`).
pub const THIRD_PERSON: &str = "third_person";
/// The report, JSON.
pub const REPORT_JSON: &str = "augment_report.json";
/// The report, readable.
pub const REPORT_MD: &str = "augment_report.md";
/// The per-replay record inside each replay folder (written last, before the rename).
const RECORD: &str = "replay.json";
/// The table-top geom randomized by texture, in every DexJoCo scene.
const TABLE_GEOM: &str = "table_visual";
const STAGING: &str = ".staging";
const PREVIEWS: &str = ".previews";
/// Records of replays that failed under `--dynamics` and were not kept
/// (`.dropped/<task>/<replay>.json`), so a resumed run does not simulate them again and
/// the report can list them.
const DROPPED: &str = ".dropped";

/// What to do.
#[derive(Debug, Clone)]
pub struct AugmentConfig {
    /// Raw episode folders, episode stores or MCAP files.
    pub inputs: Vec<PathBuf>,
    /// Output folder (one folder per replay: `<task>/<episode>__rNN/`).
    pub out: PathBuf,
    /// Replays per episode.
    pub replays: usize,
    /// Global seed.
    pub seed: u64,
    /// A folder of task specs replacing the built-in ones of the same id.
    pub tasks_dir: Option<PathBuf>,
    /// Where the task scenes come from.
    pub scene: SceneSource,
    /// Camera pool file; default: the reference pool beside `--scene-dir`, else built-in.
    pub camera_pool: Option<PathBuf>,
    /// Fixed scene cameras rendered besides the randomized third-person view.
    pub cameras: Vec<String>,
    /// Image size and quality.
    pub settings: RenderSettings,
    /// Keep replays whose task failed (flagged in the report).
    pub keep_failed: bool,
    /// Only the first N frames of each episode (quick looks and tests).
    pub max_frames: Option<usize>,
    /// The reference approach: simulate every replay on its own (for comparisons).
    pub resimulate_per_replay: bool,
    /// Write a contact sheet of the sampled views.
    pub contact_sheet: bool,
    /// Also write each camera's depth (`videos/<camera>_depth.npz`, float32 metres).
    pub depth: bool,
    /// Dynamics randomization per replay (the task spec's `[[dynamics]]`): every replay is
    /// simulated on its own model copy and kept only if the task still succeeds.
    pub dynamics: bool,
}

/// One replay in the report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReplayRecord {
    /// Folder name, `<episode>__rNN`.
    pub name: String,
    /// Task id.
    pub task: String,
    /// Source episode id.
    pub episode: String,
    /// Replay index.
    pub replay: usize,
    /// The sampled randomization (incl. the seed).
    pub sample: VisualSample,
    /// Whether the task succeeded on some step.
    pub success: bool,
    /// First successful step.
    pub first_success: Option<usize>,
    /// Steps replayed (= frames).
    pub steps: usize,
    /// Largest |replayed state - recorded state| over frames and columns.
    pub max_state_deviation: f64,
    /// Where that largest deviation is: (frame, column).
    pub deviation_at: Option<(usize, usize)>,
    /// Videos written, relative to the replay folder.
    pub videos: Vec<String>,
    /// Depth files written (`videos/<camera>_depth.npz`), relative to the replay folder.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub depth: Vec<String>,
    /// The dynamics drawn for this replay (`--dynamics`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dynamics: Option<Vec<DynamicsValue>>,
}

/// The result of replaying one source episode (physics only).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EpisodeOutcome {
    /// Task id.
    pub task: String,
    /// Episode id.
    pub episode: String,
    /// Source folder or file.
    pub source: String,
    /// Success on some step.
    pub success: bool,
    /// First successful step.
    pub first_success: Option<usize>,
    /// Steps replayed.
    pub steps: usize,
    /// Largest deviation of the replayed state from the recording.
    pub max_state_deviation: f64,
    /// Replays kept for this episode (done now or earlier).
    pub replays_kept: usize,
}

/// The augment report (`augment_report.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AugmentReport {
    /// Global seed.
    pub seed: u64,
    /// Replays asked per episode.
    pub replays_per_episode: usize,
    /// Render settings.
    pub settings: RenderSettings,
    /// Camera pool per setup used.
    pub camera_pools: BTreeMap<String, String>,
    /// Table looks per task (names).
    pub table_library: BTreeMap<String, Vec<String>>,
    /// Per source episode.
    pub episodes: Vec<EpisodeOutcome>,
    /// Per replay, sorted by folder.
    pub replays: Vec<ReplayRecord>,
    /// Replays that failed under `--dynamics` and were not kept (no folder), in the same
    /// order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub dropped: Vec<ReplayRecord>,
    /// Inputs that could not be replayed: those unreadable, of an unknown task or missing
    /// a field, in input order, then those the simulator rejected, by task and episode.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub skipped: Vec<SkippedInput>,
    /// Replays rendered by this run (the rest were already there).
    pub rendered_now: usize,
}

impl AugmentReport {
    /// Episodes whose replay did not succeed.
    pub fn failed_episodes(&self) -> usize {
        self.episodes.iter().filter(|e| !e.success).count()
    }
}

/// The folder name of replay `r` of `episode`.
pub fn replay_name(episode: &str, r: usize) -> String {
    format!("{episode}__r{r:02}")
}

struct Source {
    episode: Episode,
    spec: TaskSpec,
    path: PathBuf,
}

impl Source {
    /// `<task>/<episode>`: what a replay's seed is derived from.
    fn key(&self) -> String {
        format!("{}/{}", self.spec.id, self.episode.id)
    }
}

/// An input that could not be replayed, and why; the rest of the batch goes on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SkippedInput {
    /// The file or folder.
    pub source: String,
    /// What is wrong with it (episode, field and frame where known).
    pub reason: String,
}

impl SkippedInput {
    fn new(path: &Path, reason: String) -> Self {
        tracing::warn!(input = %path.display(), "skipped: {reason}");
        Self {
            source: path.display().to_string(),
            reason,
        }
    }
}

/// What became of one replay: its folder was written, or it failed under `--dynamics`
/// and only its record was kept (`.dropped/`).
enum Outcome {
    Kept(ReplayRecord),
    Dropped(ReplayRecord),
}

/// Reads every input episode and its task spec. A folder or MCAP file that cannot be
/// read, an unknown task or a missing field skips that episode only.
fn read_sources(
    inputs: &[PathBuf],
    specs: &[TaskSpec],
) -> Result<(Vec<Source>, Vec<SkippedInput>), AugmentError> {
    let mut out = Vec::new();
    let mut skipped = Vec::new();
    let mut skip = |path: &Path, reason: String| skipped.push(SkippedInput::new(path, reason));
    for input in inputs {
        let mut eps = Vec::new();
        if input.is_file() {
            let read = fs_err::read(input)
                .map_err(io_err("read", input))
                .and_then(|bytes| Ok(dexjoco_ingest::teleop::read_episode_mcap(input, &bytes)?));
            match read {
                Ok(t) => {
                    let mut t = t.episode;
                    if t.id.is_empty() {
                        t.id = input
                            .file_stem()
                            .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
                    }
                    eps.push((t, input.clone()));
                }
                Err(e) => skip(input, e.to_string()),
            }
        } else {
            let dirs = match dexjoco_ingest::episode_dirs(input) {
                Ok(dirs) => dirs,
                Err(e) => {
                    skip(input, e.to_string());
                    continue;
                }
            };
            for dir in dirs {
                match dexjoco_ingest::read_stored_episode(&dir) {
                    Ok(ep) => eps.push((ep, dir)),
                    Err(e) => skip(&dir, e.to_string()),
                }
            }
        }
        'episodes: for (episode, path) in eps {
            let Some(spec) = specs.iter().find(|s| s.id == episode.task).cloned() else {
                skip(
                    &path,
                    format!("episode '{}': unknown task '{}'", episode.id, episode.task),
                );
                continue;
            };
            for field in [Episode::ACTION, Episode::STATE] {
                if episode.array(field).is_none_or(FrameArray::is_empty) {
                    skip(
                        &path,
                        format!(
                            "episode '{}': field '{field}' is missing or empty (frame 0)",
                            episode.id
                        ),
                    );
                    continue 'episodes;
                }
            }
            out.push(Source {
                episode,
                spec,
                path,
            });
        }
    }
    out.sort_by(|a, b| (&a.episode.task, &a.episode.id).cmp(&(&b.episode.task, &b.episode.id)));
    for w in out.windows(2) {
        if w[0].episode.task == w[1].episode.task && w[0].episode.id == w[1].episode.id {
            return Err(AugmentError::Input(format!(
                "episode '{}/{}' is given twice ('{}' and '{}')",
                w[0].episode.task,
                w[0].episode.id,
                w[0].path.display(),
                w[1].path.display()
            )));
        }
    }
    Ok((out, skipped))
}

/// A task's scene and what randomization needs of it, shared by every worker.
struct TaskAssets {
    scene: Scene,
    pool: CameraPool,
    table: TableLibrary,
    nlight: usize,
    key: String,
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

/// The physics-only replay of one episode.
struct Physics {
    states: FrameArray,
    first_success: Option<usize>,
    deviation: f64,
    deviation_at: Option<(usize, usize)>,
}

pub(crate) fn sim_err(episode: &str) -> impl FnOnce(dexjoco_sim::SimError) -> AugmentError + '_ {
    move |source| AugmentError::Sim {
        episode: episode.into(),
        source,
    }
}

fn frames(src: &Source, config: &AugmentConfig) -> usize {
    let n = src.episode.len();
    config.max_frames.map_or(n, |m| m.min(n))
}

fn new_env(src: &Source, assets: &TaskAssets) -> Result<TaskEnv, AugmentError> {
    let state0 = src
        .episode
        .array(Episode::STATE)
        .expect("checked")
        .row(0)
        .to_vec();
    TaskEnv::from_initial_state(&assets.scene, &src.spec, &state0, EnvOptions::default())
        .map_err(sim_err(&src.episode.id))
}

fn simulate(src: &Source, assets: &TaskAssets, n: usize) -> Result<Physics, AugmentError> {
    let mut env = new_env(src, assets)?;
    let actions = src.episode.array(Episode::ACTION).expect("checked");
    let recorded = src.episode.array(Episode::STATE).expect("checked");
    let mut rows = Vec::with_capacity(n);
    let mut first_success = None;
    for k in 0..n {
        rows.push(env.state());
        let v = env.step(actions.row(k)).map_err(sim_err(&src.episode.id))?;
        if v.success && first_success.is_none() {
            first_success = Some(k);
        }
    }
    let states = FrameArray::from_rows(&rows).map_err(|e| AugmentError::Input(e.to_string()))?;
    let (deviation, deviation_at) = deviation(&states, recorded);
    Ok(Physics {
        states,
        first_success,
        deviation,
        deviation_at,
    })
}

/// Largest absolute difference and where; a width mismatch or a NaN counts as infinite.
fn deviation(replayed: &FrameArray, recorded: &FrameArray) -> (f64, Option<(usize, usize)>) {
    if replayed.width() != recorded.width() {
        return (f64::INFINITY, None);
    }
    let mut best = (0.0, None);
    for k in 0..replayed.len().min(recorded.len()) {
        for (c, (a, b)) in replayed.row(k).iter().zip(recorded.row(k)).enumerate() {
            let d = (a - b).abs();
            let d = if d.is_nan() { f64::INFINITY } else { d };
            if d > best.0 {
                best = (d, Some((k, c)));
            }
        }
    }
    best
}

thread_local! {
    /// One renderer per worker thread, for the scene it last drew.
    static RENDERER: RefCell<Option<(String, Renderer)>> = const { RefCell::new(None) };
}

fn with_renderer<T>(
    key: &str,
    model: &MjModel,
    settings: RenderSettings,
    f: impl FnOnce(&mut Renderer) -> Result<T, AugmentError>,
) -> Result<T, AugmentError> {
    RENDERER.with(|cell| {
        let mut slot = cell.borrow_mut();
        let fresh = !matches!(&*slot, Some((k, r)) if k == key && r.settings() == settings);
        if fresh {
            *slot = None;
            let r = Renderer::new(model, settings).map_err(sim_err(key))?;
            *slot = Some((key.to_owned(), r));
        }
        let (_, r) = slot.as_mut().expect("set");
        f(r)
    })
}

/// One unit of rendering work: replays `replays` of one episode, from one simulation.
struct Unit {
    source: usize,
    replays: Vec<usize>,
}

/// A replay being written.
struct Pending {
    index: usize,
    staging: PathBuf,
    sample: VisualSample,
    writers: Vec<(String, VideoWriter)>,
    /// One per camera, in the order of `writers`, with `--depth`.
    depth: Vec<DepthWriter>,
    /// The drawn dynamics, with `--dynamics`.
    dynamics: Option<Vec<DynamicsValue>>,
    preview: Option<dexjoco_sim::Frame>,
}

fn video_err(episode: &str) -> impl FnOnce(dexjoco_video::VideoError) -> AugmentError + '_ {
    move |source| AugmentError::Video {
        episode: episode.into(),
        source,
    }
}

#[allow(clippy::too_many_arguments)]
fn render_unit(
    unit: &Unit,
    src: &Source,
    assets: &TaskAssets,
    physics: &Physics,
    config: &AugmentConfig,
    ep_key: &str,
    out: &Path,
) -> Result<Vec<Outcome>, AugmentError> {
    let n = frames(src, config);
    let id = &src.episode.id;
    let fixed: Vec<(String, usize)> = config
        .cameras
        .iter()
        .map(|c| {
            assets
                .scene
                .camera_id(c)
                .map(|i| (c.clone(), i))
                .map_err(sim_err(id))
        })
        .collect::<Result<_, _>>()?;
    let spec = VideoSpec {
        width: config.settings.width,
        height: config.settings.height,
        fps: src.episode.fps.round().max(1.0) as u32,
        codec: Codec::DEXJOCO,
    };
    let staging_root = out.join(STAGING);
    let mut pending = Vec::new();
    for &r in &unit.replays {
        let name = replay_name(id, r);
        let staging = staging_root.join(format!("{}__{name}", src.spec.id));
        if staging.exists() {
            fs_err::remove_dir_all(&staging).map_err(io_err("remove", &staging))?;
        }
        let videos = staging.join(raw::VIDEOS);
        fs_err::create_dir_all(&videos).map_err(io_err("create", &videos))?;
        let seed = crate::randomize::replay_seed(config.seed, ep_key, r);
        let sample = VisualSample::sample(seed, &assets.pool, &assets.table, assets.nlight);
        let dynamics = if config.dynamics {
            Some(sample_dynamics(
                &src.spec,
                &assets.scene.model,
                dynamics_seed(seed),
            )?)
        } else {
            None
        };
        let mut writers = Vec::new();
        let mut depth = Vec::new();
        for cam in std::iter::once(THIRD_PERSON).chain(fixed.iter().map(|(c, _)| c.as_str())) {
            let w = VideoWriter::create(videos.join(format!("{cam}.mp4")), spec)
                .map_err(video_err(id))?;
            writers.push((cam.to_owned(), w));
            if config.depth {
                depth.push(DepthWriter::create(
                    videos.join(format!("{cam}_depth.npz")),
                    n,
                    spec.width,
                    spec.height,
                )?);
            }
        }
        pending.push(Pending {
            index: r,
            staging,
            sample,
            writers,
            depth,
            dynamics,
            preview: None,
        });
    }

    // With --dynamics a unit holds one replay, simulated on its own model copy.
    let mut env = match pending.first().and_then(|p| p.dynamics.as_ref()) {
        Some(values) => {
            debug_assert_eq!(pending.len(), 1);
            let model = apply_dynamics(&src.spec, &assets.scene.model, values)?;
            let scene = Scene {
                model: Arc::new(model),
                path: assets.scene.path.clone(),
            };
            let state0 = src.episode.array(Episode::STATE).expect("checked").row(0);
            TaskEnv::from_initial_state(&scene, &src.spec, state0, EnvOptions::default())
                .map_err(sim_err(id))?
        }
        None => new_env(src, assets)?,
    };
    let actions = src.episode.array(Episode::ACTION).expect("checked");
    let mut rows = Vec::with_capacity(n);
    let mut first_success = None;
    with_renderer(
        &assets.key,
        &assets.scene.model,
        RenderSettings {
            depth: config.depth,
            ..config.settings
        },
        |renderer| {
            for k in 0..n {
                rows.push(env.state());
                for p in &mut pending {
                    let views = std::iter::once(p.sample.camera.view())
                        .chain(fixed.iter().map(|(_, i)| CameraView::Fixed(*i)));
                    for (c, (view, (_, writer))) in views.zip(p.writers.iter_mut()).enumerate() {
                        renderer.update_scene(env.data_mut(), view);
                        apply_visuals(renderer, &p.sample, &assets.table);
                        let frame = renderer.draw().map_err(sim_err(id))?;
                        writer.write_frame(&frame.rgb).map_err(video_err(id))?;
                        if let (Some(d), Some(depth)) = (p.depth.get_mut(c), &frame.depth) {
                            d.write_frame(depth)?;
                        }
                        if k == 0 && p.preview.is_none() {
                            p.preview = Some(frame);
                        }
                    }
                }
                let v = env.step(actions.row(k)).map_err(sim_err(id))?;
                if v.success && first_success.is_none() {
                    first_success = Some(k);
                }
            }
            Ok(())
        },
    )?;
    let replayed = FrameArray::from_rows(&rows).map_err(|e| AugmentError::Input(e.to_string()))?;
    // Without --dynamics this simulation must be the validated one, bit for bit; with
    // it, this simulation is the replay's own, and says whether it succeeded.
    let (states, first_success, max_dev, dev_at) = if config.dynamics {
        let recorded = src.episode.array(Episode::STATE).expect("checked");
        let (d, at) = deviation(&replayed, recorded);
        (replayed, first_success, d, at)
    } else {
        if replayed
            .as_slice()
            .iter()
            .zip(physics.states.as_slice())
            .any(|(a, b)| a.to_bits() != b.to_bits())
        {
            return Err(AugmentError::Input(format!(
                "episode '{id}': the rendering simulation diverged from the validation one"
            )));
        }
        (
            physics.states.clone(),
            physics.first_success,
            physics.deviation,
            physics.deviation_at,
        )
    };
    let record_of = |index: usize,
                     sample: VisualSample,
                     dynamics: Option<Vec<DynamicsValue>>,
                     videos: Vec<String>,
                     depth: Vec<String>| ReplayRecord {
        name: replay_name(id, index),
        task: src.spec.id.clone(),
        episode: id.clone(),
        replay: index,
        sample,
        success: first_success.is_some(),
        first_success,
        steps: n,
        max_state_deviation: max_dev,
        deviation_at: dev_at,
        videos,
        depth,
        dynamics,
    };
    if config.dynamics && first_success.is_none() && !config.keep_failed {
        // The task failed under these dynamics: only the record of the draw is kept.
        let mut dropped = Vec::new();
        for p in pending {
            for (_, w) in p.writers {
                let _ = w.finish();
            }
            let _ = fs_err::remove_dir_all(&p.staging);
            let record = record_of(p.index, p.sample, p.dynamics, Vec::new(), Vec::new());
            let path = dropped_path(out, &record.task, &record.name);
            let dir = path.parent().expect("has parent");
            fs_err::create_dir_all(dir).map_err(io_err("create", dir))?;
            write_atomic(
                &path,
                &serde_json::to_vec_pretty(&record).expect("serializable"),
            )?;
            tracing::debug!(episode = %id, replay = p.index, "failed under randomized dynamics; dropped");
            dropped.push(Outcome::Dropped(record));
        }
        return Ok(dropped);
    }

    let mut records = Vec::new();
    for p in pending {
        let mut videos = Vec::new();
        let mut depth = Vec::new();
        let cams: Vec<String> = p.writers.iter().map(|(c, _)| c.clone()).collect();
        for (cam, w) in p.writers {
            w.finish().map_err(video_err(id))?;
            videos.push(format!("{}/{cam}.mp4", raw::VIDEOS));
        }
        for (d, cam) in p.depth.into_iter().zip(&cams) {
            d.finish()?;
            depth.push(format!("{}/{cam}_depth.npz", raw::VIDEOS));
        }
        let name = replay_name(id, p.index);
        let mut ep = Episode {
            id: format!("{}__{name}", src.spec.id),
            task: src.spec.id.clone(),
            prompt: src.episode.prompt.clone(),
            fps: src.episode.fps,
            arrays: BTreeMap::new(),
            cameras: videos
                .iter()
                .zip(
                    std::iter::once(THIRD_PERSON.to_owned())
                        .chain(fixed.iter().map(|(c, _)| c.clone())),
                )
                .map(|(v, c)| CameraStream {
                    depth: config
                        .depth
                        .then(|| PathBuf::from(format!("{}/{c}_depth.npz", raw::VIDEOS))),
                    name: c,
                    video: Some(PathBuf::from(v)),
                })
                .collect(),
        };
        let take = |name: &str| -> Option<FrameArray> {
            let a = src.episode.array(name)?;
            let rows: Vec<&[f64]> = (0..n).map(|k| a.row(k)).collect();
            FrameArray::from_rows(&rows).ok()
        };
        ep.arrays.insert(
            Episode::ACTION.into(),
            take(Episode::ACTION).expect("checked"),
        );
        ep.arrays.insert(Episode::STATE.into(), states.clone());
        let ts = take(Episode::TIMESTAMP)
            .unwrap_or_else(|| Episode::regular_timestamps(n, src.episode.fps));
        ep.arrays.insert(Episode::TIMESTAMP.into(), ts);
        ep.compute_action_rotvec(src.spec.setup)
            .map_err(|e| AugmentError::Input(format!("episode '{id}': {e}")))?;
        raw::write_replay_zarr(&p.staging, &ep)?;
        let record = record_of(p.index, p.sample, p.dynamics, videos, depth);
        if let Some(frame) = &p.preview {
            let dir = out.join(PREVIEWS);
            fs_err::create_dir_all(&dir).map_err(io_err("create", &dir))?;
            let path = dir.join(format!("{}__{name}.png", src.spec.id));
            let tmp = dir.join(format!(".{}__{name}.tmp.png", src.spec.id));
            frame.save_png(&tmp).map_err(sim_err(id))?;
            fs_err::rename(&tmp, &path).map_err(io_err("rename", &tmp))?;
        }
        let json = serde_json::to_vec_pretty(&record).expect("serializable");
        let rec_path = p.staging.join(RECORD);
        fs_err::write(&rec_path, json).map_err(io_err("write", &rec_path))?;
        sync_dir(&p.staging);
        let final_dir = out.join(&src.spec.id).join(&name);
        let parent = final_dir.parent().expect("has parent");
        fs_err::create_dir_all(parent).map_err(io_err("create", parent))?;
        fs_err::rename(&p.staging, &final_dir).map_err(io_err("rename", &p.staging))?;
        // A replay dropped by an earlier run without --keep-failed is now kept.
        let _ = std::fs::remove_file(dropped_path(out, &src.spec.id, &name));
        tracing::debug!(replay = %final_dir.display(), "replay written");
        records.push(Outcome::Kept(record));
    }
    Ok(records)
}

/// Flushes a staged replay's files before its rename (best effort).
fn sync_dir(dir: &Path) {
    fn walk(p: &Path) {
        if p.is_dir() {
            if let Ok(rd) = std::fs::read_dir(p) {
                for e in rd.flatten() {
                    walk(&e.path());
                }
            }
        } else if let Ok(f) = std::fs::File::open(p) {
            let _ = f.sync_all();
        }
    }
    walk(dir);
}

fn read_record(dir: &Path) -> Option<ReplayRecord> {
    read_record_file(&dir.join(RECORD))
}

fn read_record_file(path: &Path) -> Option<ReplayRecord> {
    let bytes = std::fs::read(path).ok()?;
    serde_json::from_slice(&bytes).ok()
}

/// Where the record of a replay dropped under `--dynamics` lives.
fn dropped_path(out: &Path, task: &str, name: &str) -> PathBuf {
    out.join(DROPPED).join(task).join(format!("{name}.json"))
}

/// Runs the augment stage; `progress` is called after each unit with (done, total).
pub fn augment(
    config: &AugmentConfig,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<AugmentReport, AugmentError> {
    let specs = TaskSpec::builtin_and(config.tasks_dir.as_deref())
        .map_err(|e| AugmentError::Input(format!("task specs: {e}")))?;
    let (sources, mut skipped) = read_sources(&config.inputs, &specs)?;
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
    let total = units.len();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let rendered: Vec<Vec<Outcome>> = units
        .par_iter()
        .map(|u| {
            let s = &sources[u.source];
            let key = s.key();
            let r = render_unit(
                u,
                s,
                &assets[&s.spec.id],
                &physics[u.source],
                config,
                &key,
                out,
            );
            let d = done.fetch_add(1, std::sync::atomic::Ordering::SeqCst) + 1;
            progress(d, total);
            r
        })
        .collect::<Result<_, _>>()?;
    // Close every worker's renderer (and its EGL context) now, in order, rather than at
    // process exit while other threads are still alive.
    rayon::broadcast(|_| {
        RENDERER.with(|cell| cell.borrow_mut().take());
    });
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

fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), AugmentError> {
    dexjoco_ingest::write_atomic(path, bytes)?;
    Ok(())
}

/// The success cell of a replay that has its folder.
fn kept_label(r: &ReplayRecord) -> &'static str {
    if r.success { "yes" } else { "FAILED (kept)" }
}

fn write_report(out: &Path, report: &AugmentReport) -> Result<(), AugmentError> {
    let json = serde_json::to_vec_pretty(report).expect("serializable");
    write_atomic(&out.join(REPORT_JSON), &json)?;
    let mut md = String::new();
    md.push_str("# Augment report\n\n");
    md.push_str(&format!(
        "Seed {}, {} replays per episode, {}x{}, {} render samples. Rendered by this run: {}.\n\n",
        report.seed,
        report.replays_per_episode,
        report.settings.width,
        report.settings.height,
        report.settings.quality.samples,
        report.rendered_now
    ));
    md.push_str("| task | episode | replay success | first success | steps | max state deviation | replays kept |\n|---|---|---|---|---|---|---|\n");
    for e in &report.episodes {
        md.push_str(&format!(
            "| {} | {} | {} | {} | {} | {:e} | {} |\n",
            e.task,
            e.episode,
            if e.success { "yes" } else { "NO" },
            e.first_success.map_or("-".into(), |k| k.to_string()),
            e.steps,
            e.max_state_deviation,
            e.replays_kept
        ));
    }
    if !report.skipped.is_empty() {
        md.push_str(&format!(
            "\n**Skipped inputs ({}):**\n\n",
            report.skipped.len()
        ));
        for k in &report.skipped {
            md.push_str(&format!("- `{}`: {}\n", k.source, k.reason));
        }
    }
    md.push_str("\n| replay | seed | camera (az, el, d) | table | headlight ambient | success |\n|---|---|---|---|---|---|\n");
    for r in &report.replays {
        let c = &r.sample.camera;
        let a = r.sample.headlight_ambient;
        md.push_str(&format!(
            "| {}/{} | {} | #{} ({:.1}, {:.2}, {:.2}) | {} | ({:.2}, {:.2}, {:.2}) | {} |\n",
            r.task,
            r.name,
            r.sample.seed,
            r.sample.camera_index,
            c.azimuth,
            c.elevation,
            c.distance,
            r.sample.table,
            a[0],
            a[1],
            a[2],
            kept_label(r)
        ));
    }
    if report
        .replays
        .iter()
        .chain(&report.dropped)
        .any(|r| r.dynamics.is_some())
    {
        md.push_str(&format!(
            "\n## Dynamics (`--dynamics`)\n\n{} replay(s) kept, {} failed under their draw and dropped (rerun with `--keep-failed` to keep them).\n\n",
            report.replays.len(),
            report.dropped.len()
        ));
        md.push_str("| replay | success | max state deviation | drawn values (original -> used) |\n|---|---|---:|---|\n");
        let mut rows: Vec<(&ReplayRecord, &str)> = report
            .replays
            .iter()
            .map(|r| (r, kept_label(r)))
            .chain(report.dropped.iter().map(|r| (r, "FAILED (dropped)")))
            .collect();
        rows.sort_by(|(a, _), (b, _)| (&a.task, &a.name).cmp(&(&b.task, &b.name)));
        for (r, label) in rows {
            let values = r.dynamics.as_deref().unwrap_or_default();
            let cells: Vec<String> = values
                .iter()
                .map(|v| {
                    format!(
                        "{} {}: {:.4} -> {:.4}",
                        v.kind, v.target, v.original, v.value
                    )
                })
                .collect();
            md.push_str(&format!(
                "| {}/{} | {} | {:.3e} | {} |\n",
                r.task,
                r.name,
                label,
                r.max_state_deviation,
                cells.join("; ")
            ));
        }
    }
    write_atomic(&out.join(REPORT_MD), md.as_bytes())
}

/// A grid of the first frame of every replay's third-person view (`contact_sheet.png`).
fn contact_sheet(out: &Path, report: &AugmentReport) -> Result<(), AugmentError> {
    let dir = out.join(PREVIEWS);
    let mut tiles = Vec::new();
    for r in &report.replays {
        let p = dir.join(format!("{}__{}.png", r.task, r.name));
        if let Ok(img) = image::open(&p) {
            tiles.push(img.to_rgb8());
        }
    }
    if tiles.is_empty() {
        return Ok(());
    }
    let tile = 160u32;
    let cols = report.replays_per_episode.clamp(1, 10) as u32;
    let rows = (tiles.len() as u32).div_ceil(cols);
    let mut sheet = image::RgbImage::new(cols * tile, rows * tile);
    for (i, t) in tiles.iter().enumerate() {
        let small = image::imageops::resize(t, tile, tile, image::imageops::FilterType::Triangle);
        let (x, y) = ((i as u32 % cols) * tile, (i as u32 / cols) * tile);
        image::imageops::replace(&mut sheet, &small, i64::from(x), i64::from(y));
    }
    let path = out.join("contact_sheet.png");
    let tmp = out.join(".contact_sheet.tmp.png");
    sheet
        .save_with_format(&tmp, image::ImageFormat::Png)
        .map_err(|e| AugmentError::Input(format!("cannot write '{}': {e}", tmp.display())))?;
    fs_err::rename(&tmp, &path).map_err(io_err("rename", &tmp))?;
    Ok(())
}
