//! What the later stages read of augment's replay record (`replay.json`): the task's
//! outcome, the render checks' flags and the randomization draw. Augment writes the
//! whole record (its `ReplayRecord`); `convert` labels episodes with this part of it and
//! `stats --dataset` counts it.

use std::path::Path;

use dexjoco_core::Location;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::zarr_read::read_json;
use crate::error::{FormatError, ProblemCode, Result};

/// Augment's record of one replay, in the replay folder (its `success` field says
/// whether the task succeeded in the replay; `--keep-failed` keeps failed ones).
pub const REPLAY_RECORD: &str = "replay.json";

/// The record `dexjoco-data scripted` writes beside a plan's `replay.zarr`: its seed,
/// reset, success step and subtask spans.
pub const PLAN_RECORD: &str = "plan.json";

/// One render check a replay can fail.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RenderCheck {
    /// Frames of one colour (all black, or the clear colour only): nothing was drawn.
    BlankFrame,
    /// A camera's video stands still over many frames while the robot moves.
    FrozenVideo,
    /// NaN or infinity in a stored array (state, action, depth...).
    NonFinite,
}

impl RenderCheck {
    /// The name in records and reports (`blank_frame`, `frozen_video`, `non_finite`).
    pub fn name(self) -> &'static str {
        match self {
            Self::BlankFrame => "blank_frame",
            Self::FrozenVideo => "frozen_video",
            Self::NonFinite => "non_finite",
        }
    }
}

impl std::fmt::Display for RenderCheck {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A check a replay failed, with where: one entry per check, camera (or array) and run
/// of consecutive frames.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct RenderFlag {
    /// Which check.
    pub check: RenderCheck,
    /// The camera whose frames failed it (`None` for an array).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera: Option<String>,
    /// The array holding a non-finite value (`state`, `action`, `<camera>_depth`...).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub array: Option<String>,
    /// First frame of the run.
    pub first_frame: usize,
    /// Last frame of the run (inclusive).
    pub last_frame: usize,
    /// What was seen, in words (e.g. "every pixel (0, 0, 0)", "state moved 0.12 m").
    pub detail: String,
}

impl RenderFlag {
    /// Frames in the run.
    pub fn frames(&self) -> usize {
        self.last_frame + 1 - self.first_frame
    }

    /// One line: `blank_frame on front, frames 10-20 (every pixel (0, 0, 0))`.
    pub fn describe(&self) -> String {
        let what = match (&self.camera, &self.array) {
            (Some(c), _) => format!(" on {c}"),
            (None, Some(a)) => format!(" in {a}"),
            (None, None) => String::new(),
        };
        format!(
            "{}{what}, frames {}-{} ({})",
            self.check, self.first_frame, self.last_frame, self.detail
        )
    }
}

/// The part of a replay record (`replay.json`) the later stages use.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct ReplayLabel {
    /// Whether the task succeeded on some step.
    pub success: bool,
    /// First successful step.
    #[serde(default)]
    pub first_success: Option<usize>,
    /// Frames replayed.
    #[serde(default)]
    pub steps: usize,
    /// Recorded steps used.
    #[serde(default)]
    pub recorded_steps: usize,
    /// Whether the replay ran past the recording to reach its success.
    #[serde(default)]
    pub extended: bool,
    /// Failed render checks (empty: every check passed, or a record made before the
    /// checks existed, see `checked`).
    #[serde(default)]
    pub flags: Vec<RenderFlag>,
    /// Whether the render checks ran on this replay (records made before they existed
    /// have no `flags` field).
    #[serde(skip)]
    pub checked: bool,
    /// The visual randomization draw (`seed`, `camera_index`, `camera`, `table_index`,
    /// `table`, `headlight_*`, `lights`), as written.
    #[serde(default)]
    pub sample: Value,
    /// The dynamics draw (`--dynamics`): `[{kind, target, original, value}]`.
    #[serde(default)]
    pub dynamics: Option<Value>,
    /// Where each of the task's subtasks ended (replays made before subtasks existed
    /// have none).
    #[serde(default)]
    pub subtasks: Vec<dexjoco_core::SubtaskSpan>,
    /// Whether the label is an evaluated rollout's (`episode.json`, `eval`): its
    /// verdict is data (kept whatever it says), not a reason to leave it out.
    #[serde(skip)]
    pub evaluated: bool,
}

impl ReplayLabel {
    /// Whether a render check flagged this replay.
    pub fn flagged(&self) -> bool {
        !self.flags.is_empty()
    }

    /// Subtasks that ended.
    pub fn subtasks_done(&self) -> usize {
        self.subtasks.iter().filter(|s| s.end.is_some()).count()
    }
}

/// The part of an evaluated episode's record (`episode.json`, `eval`) that makes it
/// data: its verdict, where its subtasks ended, and how its rows and video frames line
/// up (`replay.zarr` holds the warm-up steps, then one row per step; each video holds
/// one frame per step, then the frame after the last step).
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct EvalRollout {
    /// Whether the task succeeded.
    pub success: bool,
    /// The step it succeeded on, counted from the first observation.
    #[serde(default)]
    pub success_step: Option<usize>,
    /// Steps run after the warm-up.
    pub steps: usize,
    /// Steps the click_mouse warm-up ran before the first observation.
    #[serde(default)]
    pub warmup_steps: usize,
    /// Where each subtask ended, counted as `success_step` is.
    #[serde(default)]
    pub subtasks: Vec<dexjoco_core::SubtaskSpan>,
}

/// The most steps a record (a replay's, an evaluated rollout's) may say: far beyond any
/// episode (over three days at 30 fps), far below what would exhaust memory when
/// something is made per step.
pub const MAX_RECORD_STEPS: u64 = 10_000_000;

/// Reads an evaluated episode's record: `None` when the folder has none, or an
/// `episode.json` that is not `eval`'s (neither `success` nor `steps`); an error naming
/// the file and field when it is unreadable, not JSON, or `eval`'s with a field of the
/// wrong type or out of range (a step count over [`MAX_RECORD_STEPS`], a success or
/// subtask step past the rollout's end): never read as a plain recording.
pub fn read_eval_rollout(dir: &Path) -> Result<Option<EvalRollout>> {
    let path = dir.join(super::EVAL_RECORD);
    if !path.exists() {
        return Ok(None);
    }
    let v = read_json(&path, &Location::default().path(&path))?;
    if v.get("success").is_none() && v.get("steps").is_none() {
        return Ok(None);
    }
    let at = |field: &str| Location::default().path(&path).field(field);
    let field = |name: &str, why: String| FormatError::input(ProblemCode::Corrupt, &at(name), why);
    if !v.get("success").is_some_and(Value::is_boolean) {
        return Err(field(
            "success",
            format!(
                "the evaluation record's verdict is {}, not true or false",
                shown(v.get("success"))
            ),
        ));
    }
    let steps = |name: &str, required: bool| -> Result<u64> {
        match v.get(name) {
            None if !required => Ok(0),
            Some(n) if n.as_u64().is_some_and(|n| n <= MAX_RECORD_STEPS) => {
                Ok(n.as_u64().unwrap_or(0))
            }
            other => Err(field(
                name,
                format!(
                    "{} is no step count (a whole number, 0 to {MAX_RECORD_STEPS})",
                    shown(other)
                ),
            )),
        }
    };
    let n = steps("steps", true)?;
    steps("warmup_steps", false)?;
    let rollout: EvalRollout = serde_json::from_value(v).map_err(|e| {
        FormatError::input(
            ProblemCode::Corrupt,
            &Location::default().path(&path),
            format!("the evaluation record does not parse: {e}"),
        )
    })?;
    if let Some(s) = rollout.success_step.filter(|s| *s as u64 > n) {
        return Err(field(
            "success_step",
            format!("step {s} is past the rollout's {n} steps"),
        ));
    }
    let ends = rollout
        .subtasks
        .iter()
        .flat_map(|s| [s.start, s.end])
        .flatten();
    if let Some(s) = ends.into_iter().find(|s| *s as u64 > n) {
        return Err(field(
            "subtasks",
            format!("a subtask step {s} is past the rollout's {n} steps"),
        ));
    }
    Ok(Some(rollout))
}

/// A JSON value (or its absence) for a message, shortened.
fn shown(v: Option<&Value>) -> String {
    let Some(v) = v else {
        return "missing".into();
    };
    let s = v.to_string();
    if s.len() > 40 {
        format!("{}...", &s[..s.floor_char_boundary(40)])
    } else {
        s
    }
}

impl From<EvalRollout> for ReplayLabel {
    fn from(r: EvalRollout) -> Self {
        Self {
            success: r.success,
            first_success: r.success_step,
            steps: r.steps,
            recorded_steps: r.steps,
            extended: false,
            flags: Vec::new(),
            checked: false,
            sample: Value::Null,
            dynamics: None,
            subtasks: r.subtasks,
            evaluated: true,
        }
    }
}

/// Reads the replay record (`replay.json`) of an episode folder, else its evaluation
/// record (`episode.json`) as a label: `None` when the folder has neither (a recording);
/// an error naming the file and field when it is unreadable or has no boolean `success`.
pub fn read_replay_label(dir: &Path) -> Result<Option<ReplayLabel>> {
    let path = dir.join(REPLAY_RECORD);
    if !path.exists() {
        return Ok(read_eval_rollout(dir)?.map(ReplayLabel::from));
    }
    let at = Location::default().path(&path).field("success");
    let v = read_json(&path, &at)?;
    if !v.get("success").is_some_and(Value::is_boolean) {
        return Err(FormatError::input(
            ProblemCode::Corrupt,
            &at,
            "the replay record has no boolean 'success'",
        ));
    }
    for name in ["steps", "recorded_steps"] {
        if let Some(n) = v.get(name)
            && n.as_u64().is_none_or(|n| n > MAX_RECORD_STEPS)
        {
            return Err(FormatError::input(
                ProblemCode::Corrupt,
                &Location::default().path(&path).field(name),
                format!(
                    "{} is no step count (a whole number, 0 to {MAX_RECORD_STEPS})",
                    shown(Some(n))
                ),
            ));
        }
    }
    let checked = v.get("flags").is_some();
    let mut label: ReplayLabel = serde_json::from_value(v).map_err(|e| {
        FormatError::input(
            ProblemCode::Corrupt,
            &Location::default().path(&path),
            format!("the replay record does not parse: {e}"),
        )
    })?;
    label.checked = checked;
    Ok(Some(label))
}

/// Whether the replay record (`replay.json`) of an episode folder says its task
/// succeeded: `None` when the folder has no record (a recording, not a replay).
pub fn replay_success(dir: &Path) -> Result<Option<bool>> {
    Ok(read_replay_label(dir)?.map(|l| l.success))
}

/// The subtask spans an episode folder's record gives: its replay record's
/// (`replay.json`, augment), its plan record's (`plan.json`, scripted) or its eval
/// record's (`episode.json`, eval), the first of them that has any; `None` when none
/// does (a recording, or records made before subtasks existed). A record that cannot be
/// read gives none here (the readers of each record name it).
pub fn read_subtask_spans(dir: &Path) -> Option<Vec<dexjoco_core::SubtaskSpan>> {
    #[derive(Deserialize)]
    struct Spans {
        #[serde(default)]
        subtasks: Vec<dexjoco_core::SubtaskSpan>,
    }
    [REPLAY_RECORD, PLAN_RECORD, super::EVAL_RECORD]
        .into_iter()
        .find_map(|name| {
            let bytes = fs_err::read(dir.join(name)).ok()?;
            let spans = serde_json::from_slice::<Spans>(&bytes).ok()?.subtasks;
            (!spans.is_empty()).then_some(spans)
        })
}
