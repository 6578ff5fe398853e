//! Replay folders on disk: a replay is written whole under `.staging/` and renamed into
//! `<task>/<episode>__rNN/`; a replay dropped under `--dynamics` keeps only its record in
//! `.dropped/`; what an earlier run left is read back to resume.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use dexjoco_core::{CameraStream, Episode, FrameArray, TaskSpec};
use dexjoco_formats::DirLock;
use dexjoco_formats::fs::sync_tree;
use dexjoco_formats::raw;

use crate::config::{DROPPED, PREVIEWS, RECORD, STAGING, THIRD_PERSON};
use crate::error::{AugmentError, io_err, sim_err};
use crate::inputs::Source;
use crate::physics::action_row;
use crate::report::ReplayRecord;

/// What became of one replay: its folder was written, or it failed under `--dynamics`
/// and only its record was kept (`.dropped/`).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(crate) enum Outcome {
    Kept(ReplayRecord),
    Dropped(ReplayRecord),
}

/// The staging folder of a replay (renamed into place when complete).
pub(crate) fn staging_dir(out: &Path, task: &str, name: &str) -> PathBuf {
    out.join(STAGING).join(format!("{task}__{name}"))
}

/// Where the record of a replay dropped under `--dynamics` lives.
pub(crate) fn dropped_path(out: &Path, task: &str, name: &str) -> PathBuf {
    out.join(DROPPED).join(task).join(format!("{name}.json"))
}

/// The record of a replay folder, if it is complete.
pub(crate) fn read_record(dir: &Path) -> Option<ReplayRecord> {
    read_record_file(&dir.join(RECORD))
}

/// A replay record file, if it is there and readable.
pub(crate) fn read_record_file(path: &Path) -> Option<ReplayRecord> {
    let bytes = fs_err::read(path).ok()?;
    serde_json::from_slice(&bytes).ok()
}

/// Removes the temporary files that killed atomic writes left in `out` (the report and
/// settings), in `.dropped/<task>/` (dropped records); only for the folder's one writer.
pub(crate) fn remove_partial_files(out: &Path) -> Result<(), AugmentError> {
    dexjoco_formats::fs::remove_partial_files(out)?;
    let dropped = out.join(DROPPED);
    dexjoco_formats::fs::remove_partial_files(&dropped)?;
    if let Ok(rd) = fs_err::read_dir(&dropped) {
        for e in rd.flatten() {
            if e.path().is_dir() {
                dexjoco_formats::fs::remove_partial_files(&e.path())?;
            }
        }
    }
    Ok(())
}

/// Keeps only the record of a replay that failed under its dynamics draw.
pub(crate) fn write_dropped(out: &Path, record: &ReplayRecord) -> Result<(), AugmentError> {
    let path = dropped_path(out, &record.task, &record.name);
    dexjoco_formats::write_atomic(
        &path,
        &serde_json::to_vec_pretty(record).expect("serializable"),
    )?;
    Ok(())
}

/// The episode a replay folder holds: the source's actions (and timestamps) for the
/// replayed frames, the replayed states and environment states, and the cameras written.
pub(crate) fn replay_episode(
    src: &Source,
    name: &str,
    physics: &crate::physics::Physics,
    cameras: &[String],
    depth: bool,
) -> Result<Episode, AugmentError> {
    let states = &physics.states;
    let id = &src.episode.id;
    let n = states.len();
    let mut ep = Episode {
        id: format!("{}__{name}", src.spec.id),
        task: src.spec.id.clone(),
        prompt: src.episode.prompt.clone(),
        fps: src.episode.fps,
        arrays: BTreeMap::new(),
        cameras: cameras
            .iter()
            .map(|c| CameraStream {
                depth: depth.then(|| PathBuf::from(format!("{}/{c}_depth.npz", raw::VIDEOS))),
                name: c.clone(),
                video: Some(PathBuf::from(format!("{}/{c}.mp4", raw::VIDEOS))),
            })
            .collect(),
    };
    // Past the recording (an extended replay) the last action repeats and the timestamps
    // go on at the episode's rate.
    let actions = src.episode.array(Episode::ACTION).expect("checked");
    let rows: Vec<&[f64]> = (0..n).map(|k| action_row(actions, k)).collect();
    let action = FrameArray::from_rows(&rows).map_err(|e| AugmentError::Input(e.to_string()))?;
    let recorded_ts = src
        .episode
        .array(Episode::TIMESTAMP)
        .filter(|t| t.width() == 1 && !t.is_empty());
    let ts: Vec<f64> = (0..n)
        .map(|k| match recorded_ts {
            Some(t) if k < t.len() => t.row(k)[0],
            Some(t) => t.row(t.len() - 1)[0] + (k + 1 - t.len()) as f64 / src.episode.fps,
            None => k as f64 / src.episode.fps,
        })
        .collect();
    ep.arrays.insert(Episode::ACTION.into(), action);
    ep.arrays.insert(Episode::STATE.into(), states.clone());
    ep.arrays.insert(
        Episode::ENVIRONMENT_STATE.into(),
        physics.environment.clone(),
    );
    ep.arrays.insert(
        Episode::TIMESTAMP.into(),
        FrameArray::new(1, ts).map_err(|e| AugmentError::Input(e.to_string()))?,
    );
    ep.compute_action_rotvec(src.spec.setup)
        .map_err(|e| AugmentError::Input(format!("episode '{id}': {e}")))?;
    Ok(ep)
}

/// Completes a staged replay (its videos already finished in `staging/videos/`): writes
/// `replay.zarr` (with the source's own instruction, as a raw folder keeps it), the preview and the record, syncs, asks `still_wanted` (a worker whose
/// run has ended stops there), and renames the folder into `<out>/<task>/<name>`.
pub(crate) fn commit_replay(
    out: &Path,
    staging: &Path,
    ep: &Episode,
    spec: &TaskSpec,
    record: &ReplayRecord,
    preview: Option<&dexjoco_render::Frame>,
    still_wanted: &mut dyn FnMut() -> Result<(), AugmentError>,
) -> Result<(), AugmentError> {
    let (task, name) = (&record.task, &record.name);
    raw::write_raw_episode(staging, ep, spec)?;
    if let Some(frame) = preview {
        let dir = out.join(PREVIEWS);
        fs_err::create_dir_all(&dir).map_err(io_err("create", &dir))?;
        let path = dir.join(format!("{task}__{name}.png"));
        let tmp = dir.join(format!(".{task}__{name}.tmp.png"));
        frame.save_png(&tmp).map_err(sim_err(&record.episode))?;
        fs_err::rename(&tmp, &path).map_err(io_err("rename", &tmp))?;
    }
    let json = serde_json::to_vec_pretty(record).expect("serializable");
    let rec_path = staging.join(RECORD);
    fs_err::write(&rec_path, json).map_err(io_err("write", &rec_path))?;
    sync_tree(staging)?;
    let final_dir = out.join(task).join(name);
    let parent = final_dir.parent().expect("has parent");
    fs_err::create_dir_all(parent).map_err(io_err("create", parent))?;
    still_wanted()?;
    fs_err::rename(staging, &final_dir).map_err(io_err("rename", staging))?;
    dexjoco_formats::fs::sync_dir(parent)?;
    // A replay dropped by an earlier run without --keep-failed is now kept.
    let _ = fs_err::remove_file(dropped_path(out, task, name));
    tracing::debug!(replay = %final_dir.display(), "replay written");
    Ok(())
}

/// The cameras of a replay, in video order: the randomized third-person view, then the
/// fixed scene cameras.
pub(crate) fn replay_cameras(fixed: &[String]) -> Vec<String> {
    std::iter::once(THIRD_PERSON.to_owned())
        .chain(fixed.iter().cloned())
        .collect()
}

/// Removes what augment wrote into `out` (replay folders with their records, staging,
/// dropped records, previews, report, contact sheet, settings), and nothing else: the
/// `--overwrite` start from clean.
pub(crate) fn clean_output(out: &Path) -> Result<(), AugmentError> {
    use crate::config::{CONTACT_SHEET, REPORT_JSON, REPORT_MD, SETTINGS_FILE};
    let Ok(rd) = fs_err::read_dir(out) else {
        return Ok(());
    };
    for e in rd.flatten() {
        let path = e.path();
        let name = e.file_name().to_string_lossy().into_owned();
        if [STAGING, DROPPED, PREVIEWS].contains(&name.as_str()) {
            fs_err::remove_dir_all(&path).map_err(io_err("remove", &path))?;
        } else if [REPORT_JSON, REPORT_MD, CONTACT_SHEET, SETTINGS_FILE].contains(&name.as_str()) {
            fs_err::remove_file(&path).map_err(io_err("remove", &path))?;
        } else if path.is_dir() && !name.starts_with('.') {
            // A task folder: its replay folders (those holding a record) go.
            for r in fs_err::read_dir(&path)
                .map_err(io_err("list", &path))?
                .flatten()
            {
                if r.path().join(RECORD).is_file() {
                    fs_err::remove_dir_all(r.path()).map_err(io_err("remove", &r.path()))?;
                }
            }
            let _ = fs_err::remove_dir(&path);
        }
    }
    Ok(())
}

/// One writer per output folder ([`dexjoco_formats::lock::lock_output`]).
pub(crate) fn lock_output(
    out: &Path,
    shard: Option<crate::config::Shard>,
) -> Result<DirLock, AugmentError> {
    Ok(dexjoco_formats::lock::lock_output(out, shard)?)
}
