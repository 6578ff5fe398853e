//! The Warp batch renderer (`--renderer warp`): MuJoCo Warp's ray tracer, on a CUDA GPU
//! or Warp's CPU device, in a Python worker process of its own.
//!
//! Why a worker process: MuJoCo Warp is a Python library (its kernels are Warp Python
//! compiled at run time), so embedding it means embedding CPython in every binary and
//! worker; a child process keeps this binary free of Python, lets one Python environment
//! (setup.sh's or the wheel's `[warp]` extra) serve any number of runs, and turns a crash
//! of the GPU stack into an error naming it. The pipe carries ~50 bytes per geom and frame
//! in and 4 bytes per pixel out; the worker script is compiled into this binary
//! (`python/warp_worker.py`), so the wheel and the release bundle carry it unchanged.
//!
//! The world is MuJoCo's, simulated here: each batch carries the geoms' world poses of
//! its frames (what MuJoCo's OpenGL renderer draws from too), so the worker needs no
//! physics and no per-episode model edits; each *world* of a batch is one image (one
//! frame, one replay, one camera) with its own view, lights, headlight and table look.
//!
//! [`worker`]: the process and its protocol; [`world`]: what one image is made of, and
//! batches of them; [`renderer`]: a scene opened in a worker, rendering batches.

use serde::{Deserialize, Serialize};

mod renderer;
mod worker;
mod world;

pub use renderer::{SceneXml, WarpRenderer, WarpTimes};
pub use worker::{
    PYTHON_VARIABLE, WARP_PINS, WarpOptions, WarpWorker, WorkerInfo, python_candidates, setup_venv,
};
pub use world::{LightState, WarpBatch, WorldView, camera_pose, view_fovy, view_slots};

/// Which renderer draws the frames.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RendererKind {
    /// MuJoCo's own OpenGL renderer through EGL (the reference's look; the default).
    #[default]
    Opengl,
    /// MuJoCo Warp's batch ray tracer in a worker process.
    Warp,
}

impl RendererKind {
    /// `opengl` or `warp`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Opengl => "opengl",
            Self::Warp => "warp",
        }
    }

    /// Whether this is the default (for `skip_serializing_if`).
    pub fn is_opengl(&self) -> bool {
        *self == Self::Opengl
    }
}
