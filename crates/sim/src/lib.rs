//! MuJoCo for dexjoco-data: loading scenes, headless rendering through EGL (Mesa's
//! llvmpipe on CPU machines, the NVIDIA driver on GPU machines) with quality presets,
//! RGB and metric depth.
//!
//! The simulation core of the DexJoCo tasks: [`TaskEnv`] builds a task's reference
//! scene from a recorded initial state, steps recorded actions with the DexJoCo
//! controller ([`Robot`]: operational-space arm control, hand position targets) and
//! evaluates the task spec's conditions ([`SuccessChecker`] in `checker/`: `compile.rs`
//! turns a spec into nodes, `eval.rs` evaluates them; built from the reusable
//! [`primitives`]) after every step.
//!
//! `MjModel` is shared across threads; each worker owns its `MjData` and its
//! [`Renderer`], which holds a GL context bound to the thread that created it.

pub mod builtin;
mod checker;
mod control;
pub mod dynamics;
mod egl;
mod env;
mod error;
mod feedback;
pub mod fidelity;
mod geometry;
pub mod primitives;
pub mod randomize;
mod render;
mod scene;
pub mod scene_files;
pub mod scripted;
mod sheet;
mod subtasks;
pub mod warp;

pub use checker::{SuccessChecker, Verdict, name_id, unresolved_names};
pub use control::{
    ARM_DOF, ARM_HOME, Arm, HOLD_EPS, OscGains, Robot, SUBSTEPS, mat_to_quat, orientation_error,
};
pub use dexjoco_core::SubtaskSpan;
pub use egl::{
    EGL_DEVICE_ENV, EglDevice, EglProbe, gpu_devices, list_egl_devices, probe_egl, probe_renderer,
    requested_egl_device, share_llvmpipe_threads,
};
pub use env::{EnvOptions, Rollout, SceneSource, TaskEnv, load_task_scene};
pub use error::SimError;
pub use feedback::Feedback;
pub use geometry::Geometry;
pub use render::{
    CameraView, Frame, MAX_IMAGE_SIDE, RenderQuality, RenderSettings, RenderTimes, Renderer,
};
pub use scene::{Scene, mujoco_library_path, mujoco_version, route_mujoco_warnings};
pub use sheet::{SheetLayout, contact_sheet};
pub use subtasks::SubtaskTracker;
pub use warp::RendererKind;

/// Re-exported so callers can step and inspect the simulation without naming the crate.
pub use mujoco_rs;
