//! What a generation run is given and what it writes down: its configuration, each
//! attempt's record, the report, and the names of the files of its folder. The run
//! ([`crate::run`]), its folder ([`crate::folder`]) and the figure read these; this
//! module reads none of them.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::attempt::{Attempt, AttemptFailure, AttemptOptions, Provenance};

/// The pose-spread figure of a run's folder.
pub const POSES_FIGURE: &str = "generate_poses.png";

/// The first-frames sheet of a run's folder (its pixels depend on the renderer).
pub const SHEET: &str = "generate_sheet.png";

/// The file of a run's timing: the one file whose bytes depend on the machine.
pub const TIMES_FILE: &str = "generate_times.json";

/// The file of a generated episode's record, beside its `replay.zarr`.
pub const GENERATE_RECORD: &str = "generate.json";
/// The settings file of a run's folder.
pub const SETTINGS_FILE: &str = "generate_settings.json";

/// What a run does.
#[derive(Debug, Clone)]
pub struct GenerateConfig {
    /// The task's output folder.
    pub out: PathBuf,
    /// Seed of the resets and of the segment choices.
    pub seed: u64,
    /// Successful episodes wanted.
    pub count: usize,
    /// Attempts at most (over all runs into this folder).
    pub max_attempts: usize,
    /// Attempts computed at once.
    pub workers: usize,
    /// Keep failed attempts' episodes under `.failed/`.
    pub keep_failed: bool,
    /// Empty a folder an earlier run wrote with other settings, instead of refusing it.
    pub overwrite: bool,
    /// This process's share of a run split over several (`None`: the whole run, or the
    /// finalize step after the shards).
    pub shard: Option<dexjoco_core::Shard>,
    /// How each attempt runs.
    pub options: AttemptOptions,
    /// The scene the sources and attempts run on (built-in or a scene folder): named in
    /// the settings file, and fingerprinted there by the content of every file it loads.
    pub scene: dexjoco_sim::SceneSource,
    /// Steps a source's replay may go on past its recording to reach its success
    /// (`--extend-steps`; the sources were prepared with it).
    pub extend_steps: usize,
}

/// An attempt's record (`.attempts/attempt_NNNNNN.json`, and a generated episode's
/// `generate.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AttemptRecord {
    /// What wrote it.
    pub written_by: String,
    /// The attempt's index (its reset's index in the seed's draws).
    pub attempt: usize,
    /// The run's seed.
    pub seed: u64,
    /// Whether the task succeeded.
    pub success: bool,
    /// The success step.
    pub success_step: Option<usize>,
    /// Steps recorded.
    pub steps: usize,
    /// Where and why it failed.
    pub failure: Option<AttemptFailure>,
    /// Where each subtask ran (the task spec's predicates).
    pub subtasks: Vec<dexjoco_core::SubtaskSpan>,
    /// Per subtask started: the source segment and the transform used.
    pub provenance: Vec<Provenance>,
    /// The reset (`state[0]`).
    pub reset: Vec<f64>,
}

impl AttemptRecord {
    /// The record of attempt `a` of a run with `seed`.
    pub fn of(a: &Attempt, seed: u64) -> Self {
        Self {
            written_by: "dexjoco-data generate".into(),
            attempt: a.index,
            seed,
            success: a.planned.success_at.is_some(),
            success_step: a.planned.success_at,
            steps: a.planned.episode.len(),
            failure: a.failure.clone(),
            subtasks: a.planned.subtasks.clone(),
            provenance: a.provenance.clone(),
            reset: a.reset.clone(),
        }
    }
}

/// Per subtask over a run's attempts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SubtaskOutcome {
    /// The subtask's id.
    pub subtask: String,
    /// Attempts that started it.
    pub started: usize,
    /// Attempts in which it ended.
    pub completed: usize,
    /// Attempts that failed at it.
    pub failed_at: usize,
}

/// What a run's folder holds.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct GenerateReport {
    /// The task.
    pub task: String,
    /// The seed.
    pub seed: u64,
    /// Attempts made (over every run into the folder).
    pub attempts: usize,
    /// Successful ones.
    pub successes: usize,
    /// The successful attempts' indices.
    pub episodes: Vec<usize>,
    /// Per subtask: started, completed, failed at.
    pub subtasks: Vec<SubtaskOutcome>,
    /// The sources: id and SHA-256.
    pub sources: Vec<[String; 2]>,
    /// The sources whose replay succeeded only past their recording's end, with the steps
    /// it went on (`--extend-steps`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sources_extended: Vec<(String, usize)>,
}

impl GenerateReport {
    /// Successes / attempts.
    pub fn success_rate(&self) -> f64 {
        self.successes as f64 / self.attempts.max(1) as f64
    }

    /// The report as Markdown.
    pub fn to_markdown(&self) -> String {
        use std::fmt::Write as _;
        let mut s = format!(
            "# generate: {}\n\n{} of {} attempts succeeded ({:.1} %), seed {}, from {} source episode(s).\n\n\
             | Subtask | Started | Completed | Failed at |\n|---|---:|---:|---:|\n",
            self.task,
            self.successes,
            self.attempts,
            100.0 * self.success_rate(),
            self.seed,
            self.sources.len()
        );
        for o in &self.subtasks {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} |",
                o.subtask, o.started, o.completed, o.failed_at
            );
        }
        if !self.sources_extended.is_empty() {
            s.push_str("\nSources that succeed only past their recording's end (replayed on with their last action, `--extend-steps`):\n\n");
            for (id, steps) in &self.sources_extended {
                let _ = writeln!(s, "- {id}: {steps} step(s) past its end");
            }
        }
        s
    }
}
