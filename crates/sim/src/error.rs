//! The simulation and rendering errors, each naming the scene, name or device concerned.

use std::path::PathBuf;

/// Errors of the simulation and rendering layer.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// MuJoCo could not compile a scene (the message names the missing or bad file).
    #[error("cannot load scene '{path}': {message}")]
    Load {
        /// The scene file.
        path: PathBuf,
        /// MuJoCo's message.
        message: String,
    },
    /// A scene file does not exist.
    #[error("scene file '{0}' does not exist")]
    Missing(PathBuf),
    /// No EGL device could open an offscreen OpenGL context.
    #[error("offscreen rendering is not available: {0}")]
    Egl(String),
    /// A name (camera, body, geom...) is not in the scene.
    #[error("scene has no {kind} named '{name}' (it has: {available})")]
    UnknownName {
        /// Object kind.
        kind: &'static str,
        /// The name asked for.
        name: String,
        /// The names the scene has.
        available: String,
    },
    /// Rendering failed.
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
    /// Names a task spec or the robot refers to are not in the scene.
    #[error("{what}: the scene lacks {}", names.join(", "))]
    MissingNames {
        /// What needed the names (a task, the robot).
        what: String,
        /// Each missing name as `kind 'name'`.
        names: Vec<String>,
    },
    /// A task spec cannot be used.
    #[error("task spec: {0}")]
    Spec(String),
    /// A camera pool file is malformed or cannot be read.
    #[error("camera pool '{}': {message}", path.display())]
    Pool {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A file of a scene could not be read.
    #[error("cannot {action} '{}': {source}", path.display())]
    Io {
        /// What was being done.
        action: &'static str,
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A state or action row has the wrong width.
    #[error("{what} has {found} values, the task needs {expected}")]
    Width {
        /// `state[0]` or `action`.
        what: &'static str,
        /// Values needed.
        expected: usize,
        /// Values given.
        found: usize,
    },
}
