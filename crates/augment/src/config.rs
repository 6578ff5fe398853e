//! What an augment run is asked to do ([`AugmentConfig`]) and the names of the files it
//! writes.

use std::path::PathBuf;

use dexjoco_sim::{RenderSettings, SceneSource};

/// Name of the randomized third-person camera's video (`videos/third_person.mp4`).
pub const THIRD_PERSON: &str = "third_person";
/// The report, JSON.
pub const REPORT_JSON: &str = "augment_report.json";
/// The report, readable.
pub const REPORT_MD: &str = "augment_report.md";
/// The per-replay record inside each replay folder (written last, before the rename).
pub(crate) const RECORD: &str = "replay.json";
/// The table-top geom randomized by texture, in every DexJoCo scene.
pub(crate) const TABLE_GEOM: &str = "table_visual";
pub(crate) const STAGING: &str = ".staging";
pub(crate) const PREVIEWS: &str = ".previews";
/// Records of replays that failed under `--dynamics` and were not kept
/// (`.dropped/<task>/<replay>.json`), so a resumed run does not simulate them again and
/// the report can list them.
pub(crate) const DROPPED: &str = ".dropped";

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

/// The folder name of replay `r` of `episode`.
pub fn replay_name(episode: &str, r: usize) -> String {
    format!("{episode}__r{r:02}")
}
