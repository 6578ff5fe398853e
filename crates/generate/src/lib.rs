//! `dexjoco-data generate`: new demonstrations at new object poses from a few, object
//! centric as MimicGen and DexMimicGen make them, in MuJoCo, on every DexJoCo task.
//!
//! - [`source`]: a source episode replayed and cut at its task's subtasks (the spec's
//!   predicates), each segment with its reference object's pose when it began;
//! - [`attempt`]: one new episode from a new reset: per subtask a source segment carried
//!   to the object's new pose (`new * source^-1 * target`), bridged, executed through the
//!   DexJoCo controller, its end checked; both arms on their own lanes;
//! - [`record`]: the run's configuration, each attempt's record, the report;
//! - [`run`]: attempts in index order, in parallel, committed in order; resumable;
//!   a report and a figure of the object poses the attempts started from.

pub mod attempt;
mod error;
mod figure;
mod folder;
pub mod record;
pub mod run;
mod sheet;
pub mod source;

pub use attempt::{
    Attempt, AttemptFailure, AttemptOptions, Provenance, SegmentChoice, attempt, carry,
};
pub use error::GenerateError;
pub use figure::write_pose_figure;
pub use record::{
    AttemptRecord, GENERATE_RECORD, GenerateConfig, GenerateReport, POSES_FIGURE, SETTINGS_FILE,
    SHEET, SubtaskOutcome, TIMES_FILE,
};
pub use run::{GenerateOutcome, generate, pilot};
pub use sheet::{SHEET_TILES, write_first_frames};
pub use source::{ArmTarget, Segment, SourceDemo, current_targets, episode_sha256};
