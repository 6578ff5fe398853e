//! MuJoCo for dexjoco-data: loading scenes, headless rendering through EGL (Mesa's
//! llvmpipe on CPU machines, the NVIDIA driver on GPU machines) with quality presets,
//! RGB and metric depth.
//!
//! `MjModel` is shared across threads; each worker owns its `MjData` and its
//! [`Renderer`], which holds a GL context bound to the thread that created it.

mod egl;
mod error;
mod render;
mod scene;

pub use egl::{EglDevice, EglProbe, probe_egl};
pub use error::SimError;
pub use render::{CameraView, Frame, RenderQuality, RenderSettings, Renderer};
pub use scene::{Scene, mujoco_library_path, mujoco_version};

/// Re-exported so callers can step and inspect the simulation without naming the crate.
pub use mujoco_rs;
