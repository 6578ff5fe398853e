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
    /// A task spec's success graph cannot be ordered (a cycle, a missing node).
    #[error("task spec: {0}")]
    Spec(Box<dexjoco_core::TaskSpecError>),
    /// A condition refers to a node the spec does not define.
    #[error("task spec: unknown node '{0}'")]
    UnknownNode(String),
    /// A condition refers to an output its node does not have (`node.output`).
    #[error("task spec: no output '{0}'")]
    UnknownOutput(String),
    /// A body the spec or the robot moves as a mocap body is not one.
    #[error("task spec: body '{0}' is not a mocap body")]
    NotMocap(String),
    /// A feedback rule of the task spec cannot be read.
    #[error("task spec: feedback rule '{name}' (\"{text}\"): {problem}")]
    FeedbackRule {
        /// The rule's name.
        name: String,
        /// The rule as written.
        text: String,
        /// What is wrong with it.
        problem: String,
    },
    /// A dynamics entry of the task spec names something the scene lacks.
    #[error(
        "task spec: task '{task}': the dynamics entry names {kind} '{name}', which the scene lacks"
    )]
    DynamicsName {
        /// The task.
        task: String,
        /// What kind of element (`joint`, `body`, `geom`...).
        kind: String,
        /// The name.
        name: String,
    },
    /// The task has no built-in scene.
    #[error(
        "task spec: task '{task}' has no built-in scene (no assets/builtin/objects/{task}.xml; built-in: {}); pass --scene-dir with the DexJoCo reference scenes",
        builtin.join(", ")
    )]
    NoBuiltinScene {
        /// The task.
        task: String,
        /// The tasks that have one.
        builtin: Vec<String>,
    },
    /// Recorded rows could not be made into an array.
    #[error("task spec: {0}")]
    Rows(#[source] Box<dexjoco_core::CoreError>),
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
