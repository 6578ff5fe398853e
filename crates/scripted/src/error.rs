//! Why a planner could not plan: the simulator failed, the scene lacks what the planner
//! holds on to, or the task is not one it plans.

use dexjoco_sim::SimError;

/// Errors of the scripted planners.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlanError {
    /// The simulator failed (restoring the state, stepping, a name the spec needs).
    #[error(transparent)]
    Sim(#[from] SimError),
    /// The scene lacks an element the planner reads a pose from.
    #[error("the scene has no {kind} '{name}'")]
    SceneLacks {
        /// What kind of element (`geom`, `body`, `joint`, `site`, `collision geom of body`).
        kind: &'static str,
        /// Its name.
        name: String,
    },
    /// The task spec lacks what the planner follows (the keypad's password).
    #[error("task '{task}' has no {what}")]
    SpecLacks {
        /// The task.
        task: String,
        /// What it lacks.
        what: &'static str,
    },
    /// No planner plans this task.
    #[error("no scripted planner for '{task}' (planned: {})", crate::PLANNED_TASKS.join(", "))]
    NoPlanner {
        /// The task.
        task: String,
    },
    /// A failing plan was asked of a task without a failure condition.
    #[error("'{task}' has no failure condition to plan for")]
    NoFailure {
        /// The task.
        task: String,
    },
    /// A task-specific demo function was given another task.
    #[error("{planner} cannot plan '{task}'")]
    WrongTask {
        /// The function.
        planner: &'static str,
        /// The task it was given.
        task: String,
    },
    /// The recorded frames could not be made into an episode.
    #[error("recording the episode: {0}")]
    Episode(#[source] dexjoco_core::CoreError),
}

impl PlanError {
    /// The scene lacks `name` of `kind`.
    pub(crate) fn lacks(kind: &'static str, name: impl Into<String>) -> Self {
        Self::SceneLacks {
            kind,
            name: name.into(),
        }
    }
}
