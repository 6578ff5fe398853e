//! Rendering for dexjoco-data: pictures of MuJoCo scenes and what varies them.
//!
//! [`Renderer`] draws RGB and metric depth offscreen through EGL (Mesa's llvmpipe on CPU
//! machines, the NVIDIA driver on GPU machines) with quality presets and a chosen
//! [`Geometry`]; [`warp`] drives the MuJoCo Warp batch renderer in a Python worker;
//! [`randomize`] samples and applies the visual randomization (cameras, lights,
//! textures, table looks); [`contact_sheet`] tiles frames; [`compare`] measures how alike
//! two images are (the one SSIM of the project).
//!
//! Each worker owns its [`Renderer`], which holds a GL context bound to the thread that
//! created it.

pub mod compare;
mod egl;
mod error;
mod geometry;
pub mod randomize;
mod render;
mod sheet;
pub mod warp;

pub use egl::{
    EGL_DEVICE_ENV, EglDevice, EglProbe, gpu_devices, list_egl_devices, probe_egl, probe_renderer,
    requested_egl_device, share_llvmpipe_threads,
};
pub use error::{DeviceAttempt, EglError, RenderError, WarpError};
pub use geometry::Geometry;
pub use render::{
    CameraView, Frame, MAX_IMAGE_SIDE, RenderQuality, RenderSettings, RenderTimes, Renderer,
};
pub use sheet::{SheetLayout, contact_sheet};
pub use warp::RendererKind;
