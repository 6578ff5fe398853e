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
    Egl(String),
    /// Drawing or reading back an image failed.
    #[error("rendering failed: {0}")]
    Render(String),
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
