//! The data model shared by every dexjoco-data stage:
//!
//! - [`Episode`]: named per-frame arrays plus camera streams;
//! - [`ArmSetup`] and [`ArrayLayout`]: the robot's array layouts, Allegro ranges, 30 fps;
//! - [`TaskSpec`] (`schemas/tasks/<id>.toml`, the only source of task facts) and
//!   [`TaskSet`], the known tasks, parsed once;
//! - rotations in the DexJoCo convention and rigid [`Pose`]s; [`synth`]: valid synthetic
//!   episodes;
//! - [`Progress`]: how every stage reports long work; [`available_cores`]: the default
//!   worker count;
//! - [`CoreError`] and [`Location`]: errors that name file, episode, field and frame;
//! - [`safe_name`]: what a name from input data may be as a file name.
//!
//! This crate stays light: no MuJoCo, Arrow or Zarr. Formats convert into these types
//! once, in `dexjoco-formats`.

mod episode;
mod error;
mod layout;
mod names;
mod parallelism;
pub mod pose;
mod progress;
mod rotation;
pub mod shard;
pub mod synth;
mod task_set;
mod task_spec;

pub use episode::{CameraStream, Episode, FrameArray, first_moving_frame, possible_cuts};
pub use error::{CoreError, Location};
pub use layout::{
    ArmSetup, ArrayLayout, DEFAULT_EXTEND_STEPS, DEXJOCO_FPS, FieldSlice, HAND_CTRL_RANGES,
    HAND_DOF, POSE_DIM, ROTVEC_POSE_DIM, TABLE_OFFSET_RANGE,
};
pub use names::{MAX_NAME_BYTES, UnsafeName, safe_name};
pub use parallelism::available_cores;
pub use pose::{Pose, Quat, Vec3};
pub use progress::{NoProgress, Progress};
pub use rotation::{
    ZERO_QUAT_EPS, action_to_rotvec, quat_wxyz_to_rotvec, rotvec_geodesic, rotvec_to_quat_wxyz,
};
pub use shard::{Shard, ShardError};
pub use task_set::TaskSet;
pub use task_spec::{
    ArmTargetInit, Axis, BUILTIN_SPEC_FILES, BoxAxes, CameraSpec, Cmp, ConstraintKind, DerivedPose,
    DynamicsRandomization, FrameRef, GeomSet, Hand, HandSource, HanoiDisk, JointRef, KeypadButton,
    LegStyle, NameKind, Node, Placement, PointRef, PoseSource, PrivilegedField, PrivilegedKind,
    ResetSpec, StateObject, StateSpec, Subtask, SubtaskArm, SubtaskSpan, TableSpec, TaskSpec,
    TaskSpecError, Threshold, ZRule,
};
