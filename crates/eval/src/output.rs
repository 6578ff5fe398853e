//! The output folder, laid out as the reference client lays it out so that
//! `stats --success-table` and `stats --language-eval` read it as it is:
//!
//! ```text
//! <out>/episode_XX_{success|failure}[_<digits>|_no_password_input]/<env image key>.mp4
//! <out>/success_rate_<n>_<episodes>.txt
//! ```
//!
//! plus, per episode folder, `episode.json` (the record) and `replay.zarr` (the rollout as
//! a DexJoCo raw episode: the executed actions and the states), and `eval_run.json` for
//! the run. An episode is written under `.staging/episode_XX/` and renamed into place when
//! complete, so a killed run leaves no half episode; the next run does only the episodes
//! missing.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{EvalError, io_err};

/// Work in progress: each episode is written here, then renamed into place.
pub const STAGING: &str = ".staging";
/// The record in each episode folder.
pub const EPISODE_RECORD: &str = dexjoco_formats::raw::EVAL_RECORD;
/// The run's record.
pub const RUN_RECORD: &str = "eval_run.json";

/// One evaluated episode, as `episode.json` holds it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EpisodeRecord {
    /// Index in the run (`episode_XX`).
    pub episode: usize,
    /// The run's seed.
    pub seed: u64,
    /// The task.
    pub task: String,
    /// Whether the task succeeded.
    pub success: bool,
    /// The step it succeeded on (after the warm-up, counted from the first observation).
    pub success_step: Option<usize>,
    /// Where each of the task's subtasks ended, counted as `success_step` is (`None`:
    /// never); absent in records made before subtasks existed.
    #[serde(default)]
    pub subtasks: Vec<dexjoco_core::SubtaskSpan>,
    /// Steps run (the last one ends the episode).
    pub steps: usize,
    /// Steps the click_mouse warm-up ran before the first observation.
    pub warmup_steps: usize,
    /// Why it ended: `success`, `failure` (the task's failure condition) or `step_cap`.
    pub ended_by: String,
    /// The step cap when `--step-cap` replaced the task's (absent otherwise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub step_cap: Option<usize>,
    /// Observations sent (chunks asked for).
    pub chunks: usize,
    /// Steps with no buffered action (the pose held).
    pub held_steps: usize,
    /// Camera frames drawn for this episode (policy images and videos): 0 when the
    /// policy takes no camera and no video is recorded.
    #[serde(default)]
    pub frames_rendered: u64,
    /// The modelled latency (steps), or `None` in real time.
    pub latency_steps: Option<usize>,
    /// The digits pressed on the iPad, per step that pressed any.
    pub pressed_digits: Vec<Vec<u8>>,
    /// The reset the episode was restored from (drawn from the seed, or given): the
    /// DexJoCo state[0] layout, robot part as drawn.
    pub reset: Vec<f64>,
    /// The full DexJoCo state the episode started from (after the restore, before any
    /// step).
    pub initial_state: Vec<f64>,
    /// The visual randomization (`--rand-full`).
    pub visuals: Option<dexjoco_render::randomize::VisualSample>,
    /// The dynamics drawn (`--randomize-dynamics`).
    pub dynamics: Option<Vec<dexjoco_sim::dynamics::DynamicsValue>>,
    /// The prompt sent.
    pub prompt: String,
    /// Seconds the server took to answer, per chunk (min, mean, max).
    pub inference_seconds: [f64; 3],
    /// The server's metadata (sent first on its connection).
    pub server_metadata: serde_json::Value,
}

impl EpisodeRecord {
    /// The folder name the reference gives the episode: `episode_XX_{success|failure}`,
    /// with `_<digits>` (each step's digits, joined by `_`) or `_no_password_input` when
    /// pressed digits are recorded.
    pub fn folder_name(&self, record_digits: bool) -> String {
        let outcome = if self.success { "success" } else { "failure" };
        let mut name = format!("episode_{:02}_{outcome}", self.episode);
        if record_digits {
            if self.pressed_digits.is_empty() {
                name.push_str("_no_password_input");
            } else {
                let parts: Vec<String> = self
                    .pressed_digits
                    .iter()
                    .map(|d| d.iter().map(u8::to_string).collect::<String>())
                    .collect();
                name.push('_');
                name.push_str(&parts.join("_"));
            }
        }
        name
    }
}

/// The episodes already complete in `out` (from their records), by index. An episode
/// folder whose record is missing or cannot be read is an error naming it: the episode
/// is never evaluated again into a folder that exists.
pub fn done_episodes(out: &Path) -> Result<BTreeMap<usize, (PathBuf, EpisodeRecord)>, EvalError> {
    let mut done = BTreeMap::new();
    let Ok(rd) = fs_err::read_dir(out) else {
        return Ok(done);
    };
    for e in rd {
        let e = e.map_err(io_err("list", out))?;
        let name = e.file_name().to_string_lossy().into_owned();
        if !name.starts_with("episode_") || !e.path().is_dir() {
            continue;
        }
        let path = e.path().join(EPISODE_RECORD);
        let r = read_record(&path)?;
        if let Some((other, _)) = done.get(&r.episode) {
            return Err(unreadable(
                &path,
                &format!(
                    "episode {} is also recorded in '{}'",
                    r.episode,
                    PathBuf::from(other).display()
                ),
            ));
        }
        done.insert(r.episode, (e.path(), r));
    }
    Ok(done)
}

/// An episode folder's record.
fn read_record(path: &Path) -> Result<EpisodeRecord, EvalError> {
    let bytes = match fs_err::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(unreadable(path, "the episode folder has no record"));
        }
        Err(e) => return Err(unreadable(path, &e.to_string())),
    };
    serde_json::from_slice(&bytes).map_err(|e| unreadable(path, &e.to_string()))
}

/// A record that cannot be used, named with what to do.
fn unreadable(path: &Path, why: &str) -> EvalError {
    let folder = path.parent().unwrap_or(path);
    EvalError::Record {
        path: path.to_path_buf(),
        message: format!(
            "{why}; to evaluate that episode again, delete its folder '{}' and rerun",
            folder.display()
        ),
    }
}

/// The staging folder of episode `k`.
pub fn staging_dir(out: &Path, k: usize) -> PathBuf {
    out.join(STAGING).join(format!("episode_{k:02}"))
}

/// Moves a complete staged episode into place under the name its record gives.
pub fn commit_episode(
    out: &Path,
    staged: &Path,
    record: &EpisodeRecord,
    record_digits: bool,
) -> Result<PathBuf, EvalError> {
    let json = serde_json::to_vec_pretty(record).expect("serializable");
    dexjoco_formats::write_atomic(&staged.join(EPISODE_RECORD), &json)?;
    dexjoco_formats::fs::sync_tree(staged)?;
    let to = out.join(record.folder_name(record_digits));
    if to.exists() {
        return Err(unreadable(
            &to.join(EPISODE_RECORD),
            &format!(
                "episode {} was evaluated again into a folder that exists",
                record.episode
            ),
        ));
    }
    fs_err::rename(staged, &to).map_err(io_err("rename", staged))?;
    dexjoco_formats::fs::sync_dir(out)?;
    Ok(to)
}

/// Writes the marker `success_rate_<n>_<episodes>.txt` (replacing an earlier run's).
pub fn write_marker(out: &Path, successes: usize, episodes: usize) -> Result<PathBuf, EvalError> {
    if let Ok(rd) = fs_err::read_dir(out) {
        for e in rd.flatten() {
            let n = e.file_name().to_string_lossy().into_owned();
            if n.starts_with("success_rate_") && n.ends_with(".txt") {
                fs_err::remove_file(e.path()).map_err(io_err("remove", &e.path()))?;
            }
        }
    }
    let path = out.join(format!("success_rate_{successes}_{episodes}.txt"));
    dexjoco_formats::write_atomic(&path, b"")?;
    Ok(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folder_names_are_the_references() {
        let mut r = EpisodeRecord {
            episode: 3,
            seed: 0,
            task: "bimanual_unlock_ipad".into(),
            success: true,
            success_step: Some(400),
            subtasks: Vec::new(),
            steps: 401,
            warmup_steps: 0,
            ended_by: "success".into(),
            step_cap: None,
            chunks: 20,
            held_steps: 0,
            frames_rendered: 0,
            latency_steps: Some(0),
            pressed_digits: vec![vec![1], vec![2, 3]],
            reset: vec![],
            initial_state: vec![],
            visuals: None,
            dynamics: None,
            prompt: String::new(),
            inference_seconds: [0.0; 3],
            server_metadata: serde_json::Value::Null,
        };
        assert_eq!(r.folder_name(false), "episode_03_success");
        assert_eq!(r.folder_name(true), "episode_03_success_1_23");
        r.pressed_digits.clear();
        r.success = false;
        r.episode = 120;
        assert_eq!(r.folder_name(true), "episode_120_failure_no_password_input");
    }
}
