//! The simulator of dexjoco-data: MuJoCo scenes and the DexJoCo tasks' physics.
//!
//! [`TaskEnv`] builds a task's scene (the reference scene from a folder, or a built-in
//! one from [`builtin`]) from a recorded initial state, steps recorded actions with the
//! DexJoCo controller ([`Robot`]: operational-space arm control, hand position targets)
//! and evaluates the task spec's conditions ([`SuccessChecker`] in `checker/`:
//! `compile.rs` turns a spec into nodes, `eval.rs` evaluates them; built from the
//! reusable [`primitives`]) after every step; [`SubtaskTracker`] marks subtask spans and
//! [`dynamics`] randomizes physical parameters. Rendering lives in `dexjoco-render`, the
//! scripted planners in `dexjoco-scripted`.
//!
//! `MjModel` is shared across threads; each worker owns its `MjData`.

pub mod builtin;
mod checker;
mod control;
pub mod dynamics;
mod env;
mod error;
mod feedback;
pub mod primitives;
mod scene;
pub mod scene_files;
mod subtasks;

pub use checker::{SuccessChecker, Verdict, name_id, unresolved_names};
pub use control::{
    ARM_DOF, ARM_HOME, Arm, HOLD_EPS, OscGains, Robot, SUBSTEPS, THUMB_HOME, mat_to_quat,
    orientation_error,
};
pub use dexjoco_core::SubtaskSpan;
pub use env::{EnvOptions, Rollout, SceneSource, TaskEnv, load_task_scene};
pub use error::SimError;
pub use feedback::Feedback;
pub use scene::{Scene, mujoco_library_path, mujoco_version, route_mujoco_warnings};
pub use subtasks::SubtaskTracker;

/// Re-exported so callers can step and inspect the simulation without naming the crate.
pub use mujoco_rs;
