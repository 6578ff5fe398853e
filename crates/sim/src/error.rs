//! The simulation errors, each naming the scene, file or name concerned.

use std::path::PathBuf;

/// Errors of the simulator.
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
