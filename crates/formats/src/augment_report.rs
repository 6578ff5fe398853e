//! The augment report (`augment_report.json`) and the replay record (`replay.json` in
//! each replay folder): the one definition of both files, which augment writes and reads
//! back (resume) and `stats` reads. The parts that belong to the renderer and the
//! simulator (the randomization draw, the render settings, a dynamics value) are type
//! parameters: augment fills them with its own types, a reader that does not look at them
//! with [`serde::de::IgnoredAny`] ([`ReportSummary`]).

use std::collections::BTreeMap;
use std::path::Path;

use dexjoco_core::{Location, SubtaskSpan};
use serde::de::IgnoredAny;
use serde::{Deserialize, Serialize};

use crate::error::{FormatError, ProblemCode, Result};
use crate::raw::RenderFlag;

/// The report's file name, in the augment output folder.
pub const AUGMENT_REPORT: &str = "augment_report.json";

/// What a version reads when it was not recorded (an output folder made before it was).
const NOT_RECORDED: &str = "not recorded";

/// The largest report read (a report of a million replays is about 2 GB; 4 GB bounds a
/// hostile file).
const MAX_REPORT_BYTES: u64 = 4 << 30;

/// A report read without the renderer's and simulator's parts.
pub type ReportSummary = AugmentReport<IgnoredAny, IgnoredAny, IgnoredAny>;

/// Reads a report (`augment_report.json`), its size checked first.
pub fn read_report<S, R, D>(path: &Path) -> Result<AugmentReport<S, R, D>>
where
    AugmentReport<S, R, D>: serde::de::DeserializeOwned,
{
    let at = Location::default().path(path);
    let io = |source| FormatError::Io {
        op: "read",
        path: path.to_path_buf(),
        source,
    };
    let len = fs_err::metadata(path).map_err(io)?.len();
    if len > MAX_REPORT_BYTES {
        let why = format!("{len} bytes, more than an augment report holds ({MAX_REPORT_BYTES})");
        return Err(FormatError::input(ProblemCode::Corrupt, &at, why));
    }
    let file = fs_err::File::open(path).map_err(io)?;
    serde_json::from_reader(std::io::BufReader::new(file))
        .map_err(|e| FormatError::input(ProblemCode::Corrupt, &at, e))
}

/// One replay: its record (`replay.json` in its folder) and its entry in the report.
/// `Sample` is the randomization draw and `Dynamics` one dynamics value (augment's
/// `VisualSample` and `DynamicsValue`; a reader that does not look at them can use
/// [`serde::de::IgnoredAny`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(bound(deserialize = "Sample: Deserialize<'de>, Dynamics: Deserialize<'de>"))]
pub struct ReplayRecord<Sample, Dynamics> {
    /// Folder name, `<episode>__rNN`.
    pub name: String,
    /// Task id.
    pub task: String,
    /// Source episode id.
    pub episode: String,
    /// Replay index.
    pub replay: usize,
    /// The sampled randomization (incl. the seed).
    pub sample: Sample,
    /// Whether the task succeeded on some step.
    pub success: bool,
    /// First successful step.
    pub first_success: Option<usize>,
    /// Steps replayed (= frames): the recorded steps used, plus any extension.
    pub steps: usize,
    /// Recorded steps used (the recording's length, or `--max-frames`).
    #[serde(default)]
    pub recorded_steps: usize,
    /// The replay ran past the recording (`--extend-steps`) to reach its success.
    #[serde(default)]
    pub extended: bool,
    /// Largest |replayed state - recorded state| over frames and columns.
    pub max_state_deviation: f64,
    /// Where that largest deviation is: (frame, column).
    pub deviation_at: Option<(usize, usize)>,
    /// Where each of the task's subtasks ended (the step, `None` when it never did),
    /// the task spec's subtasks in order. Absent in replays made before subtasks existed.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub subtasks: Vec<SubtaskSpan>,
    /// The render checks this replay failed (empty: it passed them all). Absent in
    /// replays made before the checks existed.
    #[serde(default)]
    pub flags: Vec<RenderFlag>,
    /// Videos written, relative to the replay folder.
    pub videos: Vec<String>,
    /// Depth files written (`videos/<camera>_depth.npz`), relative to the replay folder.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub depth: Vec<String>,
    /// The dynamics drawn for this replay (`--dynamics`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dynamics: Option<Vec<Dynamics>>,
    /// Content hash of the source episode it was made from.
    #[serde(default)]
    pub source_hash: String,
    /// The renderer that drew its frames: `opengl`, or the Warp worker's version and
    /// device (`warp 3.17.0 on cpu`). Absent in replays made before it was recorded (all
    /// OpenGL) and in records of replays dropped before rendering.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub renderer: String,
    /// Where it was made: the CPU and the programs' versions (absent in replays made
    /// before it was recorded, and in the report, which lists each once in `made_on`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub made_on: Option<Provenance>,
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
    /// Steps replayed (with any extension).
    pub steps: usize,
    /// Recorded steps used.
    pub recorded_steps: usize,
    /// First success minus the recording's last step: 0 when the replay succeeds where
    /// the recording ends (the DexJoCo recorder stops on the first success), +k when k
    /// steps later (after an extension), -k when earlier.
    pub success_shift: Option<i64>,
    /// The replay ran past the recording to reach its success.
    pub extended: bool,
    /// Largest deviation of the replayed state from the recording.
    pub max_state_deviation: f64,
    /// Replays kept for this episode (done now or earlier).
    pub replays_kept: usize,
    /// Where each of the task's subtasks ended in the replay.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub subtasks: Vec<SubtaskSpan>,
}

impl EpisodeOutcome {
    /// The success shift in words: `on time`, `+1 step, extended`, `-3 steps`.
    pub fn shift_label(&self) -> String {
        match self.success_shift {
            None => "-".into(),
            Some(0) => "on time".into(),
            Some(s) => format!(
                "{s:+} step{}{}",
                if s.abs() == 1 { "" } else { "s" },
                if self.extended { ", extended" } else { "" }
            ),
        }
    }
}

/// The augment report (`augment_report.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(bound(
    deserialize = "Sample: Deserialize<'de>, Settings: Deserialize<'de>, Dynamics: Deserialize<'de>"
))]
pub struct AugmentReport<Sample, Settings, Dynamics> {
    /// Global seed.
    pub seed: u64,
    /// Replays asked per episode.
    pub replays_per_episode: usize,
    /// Render settings.
    pub settings: Settings,
    /// Camera pool per setup used.
    pub camera_pools: BTreeMap<String, String>,
    /// Table looks per task (names).
    pub table_library: BTreeMap<String, Vec<String>>,
    /// The language instructions of the replayed episodes per task, sorted: each
    /// episode's own, else its task's prompt; the replays keep them, and `convert` writes
    /// them unless its config names another.
    #[serde(default)]
    pub instructions: BTreeMap<String, Vec<String>>,
    /// Per source episode.
    pub episodes: Vec<EpisodeOutcome>,
    /// Per replay, sorted by folder.
    pub replays: Vec<ReplayRecord<Sample, Dynamics>>,
    /// Replays that failed under `--dynamics` and were not kept (no folder), in the same
    /// order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub dropped: Vec<ReplayRecord<Sample, Dynamics>>,
    /// The replays a render check flagged (kept on disk, with their `flags` in their
    /// record; `convert` leaves them out unless `--include-flagged`), in the order of `replays`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub flagged: Vec<FlaggedReplay>,
    /// Inputs that could not be replayed: those unreadable, of an unknown task or missing
    /// a field, in input order, then those the simulator rejected, by task and episode.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub skipped: Vec<SkippedInput>,
    /// Units of work that failed twice (a crashed worker, an error), with the reason;
    /// their replays are not there and a later run redoes them.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub failed_units: Vec<FailedUnit>,
    /// Where the replays (kept and dropped) were made: each distinct CPU and set of
    /// versions, with its count. More than one: the dataset mixes machines or builds,
    /// whose bytes differ for the same inputs.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub made_on: Vec<MadeOn>,
}

impl<Sample, Settings, Dynamics> AugmentReport<Sample, Settings, Dynamics> {
    /// Episodes whose replay did not succeed.
    pub fn failed_episodes(&self) -> usize {
        self.episodes.iter().filter(|e| !e.success).count()
    }
}

/// A replay a render check flagged, and why.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FlaggedReplay {
    /// Task id.
    pub task: String,
    /// Replay folder name, `<episode>__rNN`.
    pub replay: String,
    /// The checks it failed, where (as in its record).
    pub flags: Vec<RenderFlag>,
}

/// One place replays were made, and how many.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MadeOn {
    /// The CPU and versions.
    #[serde(flatten)]
    pub provenance: Provenance,
    /// Replays made there.
    pub replays: usize,
}

/// A unit of work that failed on its retry too.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FailedUnit {
    /// Task id.
    pub task: String,
    /// Episode id.
    pub episode: String,
    /// Replay indices of the unit.
    pub replays: Vec<usize>,
    /// Why (the second attempt's reason).
    pub reason: String,
}

/// An input that could not be replayed, and why; the rest of the batch goes on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SkippedInput {
    /// The file or folder.
    pub source: String,
    /// What is wrong with it (episode, field and frame where known).
    pub reason: String,
}

/// The programs that decide an augment output's bytes, as they name themselves.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub struct ToolVersions {
    /// This program: its version and the git commit it was built from
    /// (`0.1.0 (git 3f1ab45…)`; the version alone when built outside a git checkout).
    pub dexjoco_data: String,
    /// The MuJoCo library loaded (`3.17.0`).
    pub mujoco: String,
    /// ffmpeg as `ffmpeg -version` names itself (`5.1.9-0+deb12u1`), or why it could not
    /// be asked.
    pub ffmpeg: String,
    /// x264 as it names itself in the streams it writes (`x264 - core 164 r3095 baee400`).
    pub x264: String,
}

impl Default for ToolVersions {
    /// Every version "not recorded".
    fn default() -> Self {
        Self {
            dexjoco_data: NOT_RECORDED.into(),
            mujoco: NOT_RECORDED.into(),
            ffmpeg: NOT_RECORDED.into(),
            x264: NOT_RECORDED.into(),
        }
    }
}

/// Where a replay was made.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Provenance {
    /// The CPU model (`/proc/cpuinfo`'s `model name`, or its ARM equivalents).
    pub cpu_model: String,
    /// The CPU's feature flags (`/proc/cpuinfo`'s `flags` or `Features`), as listed there.
    pub cpu_flags: String,
    /// The programs' versions.
    pub versions: ToolVersions,
}

impl Default for Provenance {
    /// Every field "not recorded" (a replay made before provenance was recorded).
    fn default() -> Self {
        Self {
            cpu_model: NOT_RECORDED.into(),
            cpu_flags: NOT_RECORDED.into(),
            versions: ToolVersions::default(),
        }
    }
}
