//! The data model shared by every dexjoco-data stage: episodes as named per-frame
//! arrays, the arm setups and array layouts of the DexJoCo tasks, rotations in the
//! DexJoCo convention, task specifications as data, and the error type that names file, episode, field and frame.
//!
//! This crate stays light: no MuJoCo, Arrow or Zarr. Formats convert into these types
//! once, in their own crates.

mod episode;
mod error;
mod layout;
mod progress;
mod rotation;
pub mod synth;
mod task_set;
mod task_spec;

pub use episode::{CameraStream, Episode, FrameArray};
pub use error::{CoreError, Location};
pub use layout::{
    ArmSetup, ArrayLayout, DEXJOCO_FPS, FieldSlice, HAND_CTRL_RANGES, HAND_DOF, POSE_DIM,
    ROTVEC_POSE_DIM, TABLE_OFFSET_RANGE,
};
pub use progress::{NoProgress, Progress};
pub use rotation::{ZERO_QUAT_EPS, action_to_rotvec, quat_wxyz_to_rotvec, rotvec_to_quat_wxyz};
pub use task_set::{BUILTIN_SPEC_FILES, PrivilegedField, PrivilegedKind, TaskSet};
pub use task_spec::{
    ArmTargetInit, Axis, BoxAxes, CameraSpec, Cmp, ConstraintKind, DerivedPose,
    DynamicsRandomization, FrameRef, GeomSet, HandSource, HanoiDisk, JointRef, KeypadButton,
    LegStyle, NameKind, Node, Placement, PointRef, PoseSource, ResetSpec, StateObject, StateSpec,
    TableSpec, TaskSpec, TaskSpecError, Threshold, ZRule,
};
