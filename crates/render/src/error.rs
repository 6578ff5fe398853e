//! The rendering errors, each naming the device, worker, file or scene concerned.

use std::path::PathBuf;

use dexjoco_sim::SimError;

/// Errors of the renderers, visual randomization and image files.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RenderError {
    /// The scene itself failed (loading it, a name it lacks).
    #[error(transparent)]
    Sim(#[from] SimError),
    /// No EGL device could open an offscreen OpenGL context.
    #[error("offscreen rendering is not available: {0}")]
    Egl(#[from] EglError),
    /// An image size the renderer cannot draw (empty, or larger than it or the device
    /// allows).
    #[error("rendering failed: image size {width}x{height}{}", limit_words(*max, device.as_deref()))]
    ImageSize {
        /// Width asked for.
        width: u32,
        /// Height asked for.
        height: u32,
        /// The largest side allowed (0: the size is empty).
        max: u32,
        /// The EGL device whose limit it is (`None`: the renderer's own limit).
        device: Option<String>,
    },
    /// Reading the pixels back failed.
    #[error("rendering failed: {0}")]
    ReadPixels(String),
    /// The Warp renderer's worker could not start or failed.
    #[error("warp renderer: {0}")]
    Warp(String),
    /// Writing an image failed.
    #[error("cannot write image '{path}': {message}")]
    Image {
        /// The image file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// A camera pool file is malformed or cannot be read.
    #[error("camera pool '{}': {message}", path.display())]
    Pool {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The scene lacks something visual randomization needs (the table-top geom).
    #[error("the scene has no {kind} '{name}'")]
    SceneLacks {
        /// Object kind.
        kind: &'static str,
        /// The name.
        name: String,
    },
}

/// The end of an [`RenderError::ImageSize`] message: why the size cannot be drawn.
fn limit_words(max: u32, device: Option<&str>) -> String {
    match (max, device) {
        (0, _) => " is empty".into(),
        (max, None) => format!(": the renderer draws at most {max} pixels a side"),
        (max, Some(d)) => {
            format!(": EGL device {d} draws at most {max} pixels a side (GL_MAX_RENDERBUFFER_SIZE)")
        }
    }
}

/// Why no offscreen OpenGL context opened through EGL.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EglError {
    /// EGL could not list its devices (no libEGL, or no vendor library).
    #[error(
        "cannot list EGL devices ({source}); is libEGL installed (Debian: libegl1 libegl-mesa0 libgl1-mesa-dri)?"
    )]
    List {
        /// EGL's error.
        source: glutin::error::Error,
    },
    /// `DEXJOCO_EGL_DEVICE` is not a device index.
    #[error(
        "{}='{value}' is not an EGL device index: give a number from the list of `dexjoco-data doctor`",
        crate::EGL_DEVICE_ENV
    )]
    NotAnIndex {
        /// The variable's value.
        value: String,
    },
    /// EGL lists no device at all.
    #[error("EGL lists no device")]
    NoDevice,
    /// The device asked for is not in EGL's list.
    #[error("EGL device {index} does not exist: EGL lists {count} device(s) ({listed})")]
    NoSuchDevice {
        /// The index asked for.
        index: usize,
        /// Devices EGL lists.
        count: usize,
        /// Those devices, `0 (software), 1 (/dev/dri/renderD128)`.
        listed: String,
    },
    /// Every device tried failed to open a context.
    #[error("{}", attempts.iter().map(|a| format!("device {} ({}): {}", a.index, a.device, a.source)).collect::<Vec<_>>().join("; "))]
    NoContext {
        /// Each device tried, in order, and why it failed.
        attempts: Vec<DeviceAttempt>,
    },
    /// The context could not be made current on this thread.
    #[error("{source}")]
    MakeCurrent {
        /// EGL's error.
        source: glutin::error::Error,
    },
}

/// One device on which no context opened, and why.
#[derive(Debug)]
pub struct DeviceAttempt {
    /// The device's index in EGL's list.
    pub index: usize,
    /// The device, in words.
    pub device: String,
    /// EGL's error.
    pub source: glutin::error::Error,
}
