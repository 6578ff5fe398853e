//! The DexJoCo raw layout: `replay.zarr` (Zarr v2, one episode) + `videos/`, read and
//! written with `zarrs` exactly as the reference recorder (zarr-python 2) lays it out.
//! [`RawFolder`] is its [`EpisodeContainer`]. `zarr_read.rs` reads and checks the store's
//! arrays; `write.rs` writes an episode the recorder's way.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use dexjoco_core::{CameraStream, Episode, FrameArray, Location, TaskSet, TaskSpec};
use serde_json::Value;
use zarrs::array::{Array, ArrayMetadataOptions, CodecOptions};
use zarrs::filesystem::FilesystemStore;
use zarrs::group::{Group, GroupMetadata};
use zarrs::metadata::v2::GroupMetadataV2;

use crate::container::{EpisodeContainer, EpisodeMeta, ReadEpisode, ReadOptions, unknown_task};
use crate::error::{FormatError, ProblemCode, Result, io_err};
use crate::manifest::{ManifestEntry, SourceKind};
use crate::zarr_v2::{self, Blosc};

mod record;
mod write;
mod zarr_read;

pub use record::{
    EvalRollout, MAX_RECORD_STEPS, PLAN_RECORD, REPLAY_RECORD, RenderCheck, RenderFlag,
    ReplayLabel, read_eval_rollout, read_replay_label, read_subtask_spans, replay_success,
};
use write::ATTRIBUTES_FILE;
pub use write::{own_instruction, write_raw_episode, write_replay_zarr};
use zarr_read::*;

/// Name of the Zarr store inside an episode folder.
pub const REPLAY_ZARR: &str = "replay.zarr";
/// Name of the video folder inside an episode folder.
pub const VIDEOS: &str = "videos";
/// The attribute of `replay.zarr/.zattrs` (the root group's attributes, which the
/// DexJoCo tools and zarr-python 2 read past) holding the episode's own language
/// instruction. Absent when the episode has none of its own: its task's prompt applies.
pub const INSTRUCTION_ATTRIBUTE: &str = "instruction";
/// Largest chunk the recorder makes, in bytes (`2e6 // bytes_per_step` frames).
pub const CHUNK_BYTES: usize = 2_000_000;
/// Most values one array of an episode may hold (2^25, 256 MiB of float64: a hundred
/// times the longest DexJoCo episode); a larger `.zarray` shape is refused before
/// anything is allocated.
pub const MAX_ELEMENTS: u64 = 1 << 25;
/// Most chunks one array may have.
const MAX_CHUNKS: u64 = 1 << 20;

/// An episode read from a raw folder, with what reading it changed or left out.
#[derive(Debug, Clone)]
pub struct RawEpisode {
    /// The episode (`id` is empty until the store gives it one).
    pub episode: Episode,
    /// Files under `videos/`, relative to the episode folder.
    pub videos: Vec<PathBuf>,
    /// Normalisations applied (float32 widened, object order fixed, rotvec computed) and
    /// things not carried over.
    pub notes: Vec<String>,
}

/// The dtype of a stored array, from its `.zarray`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Dtype {
    F64,
    F32,
    I64,
}

/// The task of a raw folder from its path: `<task>/episode_NNNNNN/` or
/// `<task>_demo_<k>_<date>/` (replays: `_replay_`), or any folder under a `<task>/` folder
/// where `<task>` is one of `tasks`.
pub fn task_from_path(dir: &Path, tasks: &TaskSet) -> Option<String> {
    let name = dir.file_name()?.to_str()?;
    for marker in ["_demo_", "_replay_"] {
        if let Some(i) = name.find(marker) {
            return Some(name[..i].to_owned());
        }
    }
    // `<root>/<task_id>/episode_000000` (released datasets) or any folder under a folder
    // named after a task (e.g. augment's `<task_id>/<episode>__r03`).
    let parent = dir.parent()?.file_name()?.to_str()?;
    if name.starts_with("episode_") || tasks.contains(parent) {
        return Some(parent.to_owned());
    }
    None
}

/// The record `dexjoco-data eval` writes in each evaluated episode's folder, beside the
/// rollout's `replay.zarr` (its `task` key names the task).
pub const EVAL_RECORD: &str = "episode.json";

/// The task an evaluated episode's record names, when the folder holds one.
pub fn task_from_eval_record(dir: &Path) -> Result<Option<String>> {
    let path = dir.join(EVAL_RECORD);
    if !path.exists() {
        return Ok(None);
    }
    let v = read_json(&path, &Location::default().path(&path).field("task"))?;
    Ok(v.get("task").and_then(|t| t.as_str()).map(str::to_owned))
}

/// Reads a raw episode folder (holding `replay.zarr`, optionally `videos/`) of `task`.
/// Its prompt is its own instruction ([`INSTRUCTION_ATTRIBUTE`]), else the task's.
///
/// Applies the documented normalisations: float32 `state` is widened to float64; the
/// older pick_bucket object order (food before bucket) is put in the current order;
/// `action_rotvec` is computed when absent. Each is recorded in [`RawEpisode::notes`].
pub fn read_raw_episode(dir: &Path, task: &TaskSpec) -> Result<RawEpisode> {
    let zarr = dir.join(REPLAY_ZARR);
    let base = Location::default().path(dir);
    if !zarr.is_dir() {
        return Err(FormatError::input(
            ProblemCode::MissingArray,
            &base.clone().field(REPLAY_ZARR),
            "no replay.zarr folder",
        ));
    }
    read_json(&zarr.join(".zgroup"), &base.clone().field(".zgroup"))?;
    let store = open_store(&zarr, &base.clone().field(REPLAY_ZARR))?;
    let mut notes = Vec::new();
    let mut arrays = BTreeMap::new();
    for name in &data_array_names(&zarr) {
        let at = base.clone().field(name.as_str());
        let key = format!("data/{name}");
        if name == Episode::ACTION_ROTVEC && !zarr.join(&key).join(".zarray").exists() {
            continue;
        }
        let fa = read_data_array(&store, &zarr, name, &at, &mut notes)?;
        arrays.insert(name.clone(), fa);
    }
    check_episode_ends(&store, &zarr, &arrays, &base)?;
    let instruction = read_instruction(&zarr, &base)?;

    let mut episode = Episode {
        id: String::new(),
        task: task.id.clone(),
        prompt: instruction.unwrap_or_else(|| task.prompt.clone()),
        fps: dexjoco_core::DEXJOCO_FPS,
        arrays,
        cameras: Vec::new(),
    };
    normalise(&mut episode, task, &mut notes)?;

    let mut videos = list_files(&dir.join(VIDEOS), Path::new(VIDEOS))?;
    if let Some(rollout) = read_eval_rollout(dir)? {
        videos = eval_rollout(&mut episode, &rollout, dir, &mut notes)?;
    }
    episode.cameras = cameras_of(&videos);
    Ok(RawEpisode {
        episode,
        videos,
        notes,
    })
}

/// An evaluated episode (`eval`'s folder: [`EVAL_RECORD`] beside `replay.zarr`, the
/// camera videos `<key>.mp4` in the folder itself) as data: the warm-up rows before the
/// first observation left out, so row k is step k and video frame k; its videos (each
/// holds one frame more, after the last step, which `convert` leaves out).
fn eval_rollout(
    episode: &mut Episode,
    rollout: &EvalRollout,
    dir: &Path,
    notes: &mut Vec<String>,
) -> Result<Vec<PathBuf>> {
    let rows = rollout.warmup_steps + rollout.steps;
    if episode.len() != rows {
        return Err(FormatError::input(
            ProblemCode::WrongLength,
            &Location::default().path(dir.join(REPLAY_ZARR)),
            format!(
                "{} rows, but its record ({EVAL_RECORD}) says {} warm-up steps and {} steps",
                episode.len(),
                rollout.warmup_steps,
                rollout.steps
            ),
        ));
    }
    let skip = rollout.warmup_steps;
    if skip > 0 {
        for a in episode.arrays.values_mut() {
            let w = a.width();
            *a = FrameArray::new(w, a.as_slice()[skip * w..].to_vec()).expect("whole rows");
        }
        notes.push(format!(
            "evaluated rollout: the {skip} warm-up step(s) before the first observation left out"
        ));
    }
    let mut videos: Vec<PathBuf> = fs_err::read_dir(dir)
        .map_err(io_err("list", dir))?
        .flatten()
        .filter(|e| e.path().is_file())
        .map(|e| PathBuf::from(e.file_name()))
        .filter(|p| p.extension().is_some_and(|e| e == "mp4"))
        .collect();
    videos.sort();
    Ok(videos)
}

/// The episode's own instruction: the [`INSTRUCTION_ATTRIBUTE`] of `replay.zarr/.zattrs`
/// (`None` when the file, the attribute or its text is absent); an error naming the file
/// and attribute when it is unreadable or not a string.
fn read_instruction(zarr: &Path, base: &Location) -> Result<Option<String>> {
    let path = zarr.join(ATTRIBUTES_FILE);
    if !path.exists() {
        return Ok(None);
    }
    let at = base.clone().path(&path).field(INSTRUCTION_ATTRIBUTE);
    match read_json(&path, &at)?.get(INSTRUCTION_ATTRIBUTE) {
        None | Some(Value::Null) => Ok(None),
        Some(Value::String(s)) if s.trim().is_empty() => Ok(None),
        Some(Value::String(s)) => Ok(Some(s.clone())),
        Some(other) => Err(FormatError::input(
            ProblemCode::WrongDtype,
            &at,
            format!("the instruction is {other}, not a text"),
        )),
    }
}

/// The arrays of `data/` to read: the standard ones, then any other array (carried
/// unchanged) in name order.
fn data_array_names(zarr: &Path) -> Vec<String> {
    let mut names: Vec<String> = [
        Episode::ACTION,
        Episode::STATE,
        Episode::TIMESTAMP,
        Episode::ACTION_ROTVEC,
    ]
    .map(str::to_owned)
    .to_vec();
    if let Ok(rd) = fs_err::read_dir(zarr.join("data")) {
        let mut extra: Vec<String> = rd
            .flatten()
            .filter(|e| e.path().join(".zarray").is_file())
            .filter_map(|e| e.file_name().to_str().map(str::to_owned))
            .filter(|n| !names.contains(n))
            .collect();
        extra.sort();
        names.extend(extra);
    }
    names
}

/// Reads `data/<name>`: (T,) or (T, width) float64 (float32 only for the older `state`,
/// widened and noted).
fn read_data_array(
    store: &Arc<FilesystemStore>,
    zarr: &Path,
    name: &str,
    at: &Location,
    notes: &mut Vec<String>,
) -> Result<FrameArray> {
    let key = format!("data/{name}");
    let info = array_info(zarr, &key, at)?;
    let width = match info.shape.as_slice() {
        [_] => 1,
        [_, w] if name != Episode::TIMESTAMP || *w == 1 => *w as usize,
        other => {
            return Err(FormatError::input(
                ProblemCode::WrongDimensions,
                at,
                format!("shape {other:?} is not (T,) or (T, width)"),
            ));
        }
    };
    if width == 0 {
        return Err(FormatError::input(
            ProblemCode::WrongDimensions,
            at,
            "zero values per frame",
        ));
    }
    if info.dtype == Dtype::F32 {
        if name == Episode::STATE {
            notes.push("state was float32 (older release): widened to float64".into());
        } else {
            return Err(FormatError::input(
                ProblemCode::WrongDtype,
                at,
                "dtype float32 where float64 is expected (only the older `state` is float32)",
            ));
        }
    }
    let values = read_array(store, zarr, &key, &info, at)?;
    FrameArray::new(width, values).map_err(FormatError::Core)
}

/// A problem unless every array holds the same frames and `meta/episode_ends` says
/// they are one episode of them.
fn check_episode_ends(
    store: &Arc<FilesystemStore>,
    zarr: &Path,
    arrays: &BTreeMap<String, FrameArray>,
    base: &Location,
) -> Result<()> {
    let frames = check_lengths(arrays, base)?;
    let at = base.clone().field("meta/episode_ends");
    let ends = read_episode_ends(store, zarr, &at)?;
    if ends != [frames as i64] {
        let at = match ends.first() {
            Some(&end) if ends.len() == 1 && end >= 0 && (end as usize) < frames => {
                at.frame(end as usize)
            }
            _ => at,
        };
        return Err(FormatError::input(
            ProblemCode::EpisodeEndsMismatch,
            &at,
            format!(
                "episode_ends {ends:?} where every array ({}) holds one episode of {frames} frames",
                arrays.keys().cloned().collect::<Vec<_>>().join(", ")
            ),
        ));
    }
    Ok(())
}

/// The normalisations of older releases, each noted: pick_bucket's object order, and
/// `action_rotvec` computed when absent.
fn normalise(episode: &mut Episode, task: &TaskSpec, notes: &mut Vec<String>) -> Result<()> {
    if task.id == "pick_bucket" && fix_pick_bucket_order(episode) {
        notes.push(
            "pick_bucket state had the older object order (food, bucket): reordered to bucket, food"
                .into(),
        );
    }
    if episode.array(Episode::ACTION_ROTVEC).is_none()
        && episode
            .array(Episode::ACTION)
            .is_some_and(|a| a.width() == task.setup.action_dim())
    {
        episode.compute_action_rotvec(task.setup)?;
        notes.push("action_rotvec was absent: computed from action".into());
    }
    Ok(())
}

/// The number of frames every array holds: that of `action` (else of the first array);
/// an array of another length is an error naming it and the first frame it lacks (or
/// has beyond the others).
fn check_lengths(arrays: &BTreeMap<String, FrameArray>, base: &Location) -> Result<usize> {
    let Some((lead, frames)) = arrays
        .get_key_value(Episode::ACTION)
        .or_else(|| arrays.iter().next())
        .map(|(name, a)| (name.clone(), a.len()))
    else {
        return Ok(0);
    };
    for (name, a) in arrays {
        if a.len() != frames {
            return Err(FormatError::input(
                ProblemCode::WrongLength,
                &base.clone().field(name.as_str()).frame(a.len().min(frames)),
                format!("{} frames where '{lead}' has {frames}", a.len()),
            ));
        }
    }
    Ok(frames)
}

/// In the older pick_bucket releases state[23:30] is the food and [30:37] the bucket.
/// The bucket is reset at y in [-0.25, -0.20] and the food at y in [0.15, 0.20], so the
/// sign of the first object's y tells the order. Returns whether it swapped.
fn fix_pick_bucket_order(ep: &mut Episode) -> bool {
    let Some(state) = ep.arrays.get_mut(Episode::STATE) else {
        return false;
    };
    if state.width() != 38 || state.is_empty() || state.row(0)[24] <= 0.0 {
        return false;
    }
    for i in 0..state.len() {
        let row = state.row_mut(i);
        let mut first = [0.0; 7];
        first.copy_from_slice(&row[23..30]);
        row.copy_within(30..37, 23);
        row[30..37].copy_from_slice(&first);
    }
    true
}

/// Files under `dir`, recursively, relative paths prefixed with `prefix`, sorted (none
/// when `dir` is not a folder).
pub fn list_files(dir: &Path, prefix: &Path) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    if !dir.is_dir() {
        return Ok(out);
    }
    let mut entries: Vec<_> = fs_err::read_dir(dir)
        .map_err(|e| FormatError::Io {
            op: "list",
            path: dir.to_owned(),
            source: e,
        })?
        .flatten()
        .collect();
    entries.sort_by_key(|e| e.file_name());
    for e in entries {
        let p = e.path();
        let rel = prefix.join(e.file_name());
        if p.is_dir() {
            out.extend(list_files(&p, &rel)?);
        } else {
            out.push(rel);
        }
    }
    Ok(out)
}

fn cameras_of(videos: &[PathBuf]) -> Vec<CameraStream> {
    let mut cams = Vec::new();
    for v in videos {
        let Some(name) = v.file_name().and_then(|n| n.to_str()) else {
            continue;
        };
        if let Some(cam) = name.strip_suffix(".mp4") {
            if cam.ends_with("_depth") {
                continue;
            }
            let depth = Path::new(VIDEOS).join(format!("{cam}_depth.npz"));
            cams.push(CameraStream {
                name: cam.to_owned(),
                video: Some(v.clone()),
                depth: videos.contains(&depth).then_some(depth),
            });
        }
    }
    cams
}

/// DexJoCo raw episode folders as an [`EpisodeContainer`]: a folder holding
/// `replay.zarr` (and optionally `videos/`).
#[derive(Debug, Clone, Copy, Default)]
pub struct RawFolder;

impl EpisodeContainer for RawFolder {
    fn name(&self) -> &'static str {
        "raw"
    }

    fn kind(&self) -> SourceKind {
        SourceKind::Raw
    }

    fn extension(&self) -> Option<&'static str> {
        None
    }

    fn probe(&self, path: &Path) -> bool {
        path.join(REPLAY_ZARR).is_dir()
    }

    /// Reads the folder. Its task is, in order: `options.task`, the folder's store entry
    /// (`.dexjoco-ingest.json`), an evaluated episode's record ([`EVAL_RECORD`]), its path
    /// ([`task_from_path`]); its id is the store entry's, else the folder name.
    fn read(&self, dir: &Path, tasks: &TaskSet, options: ReadOptions<'_>) -> Result<ReadEpisode> {
        let entry = ManifestEntry::of_episode_dir(dir);
        // An evaluation record that cannot be read is named as such, whatever names the task.
        let from_record = task_from_eval_record(dir)?;
        let name = options
            .task
            .map(str::to_owned)
            .or_else(|| entry.as_ref().and_then(|e| e.task.clone()))
            .or(from_record)
            .or_else(|| task_from_path(dir, tasks));
        let at = Location::default().path(dir);
        let task = match name.as_deref() {
            Some(n) => tasks.get(n).ok_or_else(|| unknown_task(&at, n, tasks))?,
            None => {
                return Err(FormatError::input(
                    ProblemCode::UnknownTask,
                    &at,
                    format!(
                        "cannot tell the task of '{}': its path names no known task \
                         (<task>/episode_N, <task>_demo_..., or any folder under a folder \
                         named after a known task); for a task of your own, pass the \
                         folder holding its spec with --tasks-dir; a folder laid out \
                         otherwise can be stored with `dexjoco-data ingest --task <task>`",
                        dir.display()
                    ),
                ));
            }
        };
        let r = read_raw_episode(dir, task)?;
        let mut episode = r.episode;
        episode.id = entry.map_or_else(
            || {
                dir.file_name()
                    .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
            },
            |e| e.id,
        );
        Ok(ReadEpisode {
            episode,
            videos: r.videos,
            notes: r.notes,
        })
    }

    /// Writes `replay.zarr` under `dir` with the episode's own instruction
    /// ([`write_raw_episode`]); the raw layout has no place for `meta`.
    fn write(
        &self,
        dir: &Path,
        episode: &Episode,
        task: &TaskSpec,
        _meta: &EpisodeMeta,
    ) -> Result<()> {
        write_raw_episode(dir, episode, task)
    }
}
