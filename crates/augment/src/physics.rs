//! The physics of a replay: the episode restored from its recorded `state[0]`, every
//! recorded action stepped with the DexJoCo controller; success and the deviation from
//! the recorded states.
//!
//! After the recording ends without success, the last recorded action is repeated for up
//! to `--extend-steps` more steps, stopping at the first success (the DexJoCo recorder
//! stops on the step that first succeeds, so a replay that drifts by a step or two would
//! otherwise never succeed within the recorded actions).

use dexjoco_core::{Episode, FrameArray, TaskSpec};
use dexjoco_sim::{EnvOptions, Scene, TaskEnv};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::config::AugmentConfig;
use crate::error::{AugmentError, sim_err};
use crate::inputs::Source;

/// A replay's simulated trajectory.
pub(crate) struct Physics {
    /// The state before every replayed step.
    pub(crate) states: FrameArray,
    /// The environment state (objects now, dh) before every replayed step.
    pub(crate) environment: FrameArray,
    /// What the rest of the run needs to know of it.
    pub(crate) summary: PhysicsSummary,
}

/// The facts of a replay's simulation that planning, rendering and the report use; a
/// worker's rendering simulation must reproduce them exactly.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct PhysicsSummary {
    /// Steps replayed (= frames written): the recorded ones used, plus any extension.
    pub(crate) frames: usize,
    /// Recorded steps used (the whole recording, or `--max-frames` of it).
    pub(crate) recorded: usize,
    /// First successful step.
    pub(crate) first_success: Option<usize>,
    /// Largest |replayed - recorded state| over the recorded frames.
    pub(crate) deviation: f64,
    /// Where that deviation is: (frame, column).
    pub(crate) deviation_at: Option<(usize, usize)>,
    /// SHA-256 of the replayed states' bits.
    pub(crate) states_hash: String,
    /// Where each of the task's subtasks ended in the replay.
    pub(crate) subtasks: Vec<dexjoco_core::SubtaskSpan>,
}

impl PhysicsSummary {
    /// The replay reached its first success only past the recording's end (in the
    /// `--extend-steps` extension). A replay that never succeeds is not extended, even
    /// though it ran the whole extension.
    pub(crate) fn extended(&self) -> bool {
        self.first_success.is_some_and(|k| k >= self.recorded)
    }
}

/// Recorded steps a run replays of `src`: all, or the first `--max-frames`.
pub(crate) fn recorded_frames(src: &Source, config: &AugmentConfig) -> usize {
    let n = src.episode.len();
    config.max_frames.map_or(n, |m| m.min(n))
}

/// Steps the replay may add after the recording: `--extend-steps`, unless the recording
/// is cut by `--max-frames`.
pub(crate) fn extension(src: &Source, config: &AugmentConfig) -> usize {
    if recorded_frames(src, config) == src.episode.len() {
        config.extend_steps
    } else {
        0
    }
}

/// The action of replayed step `k`: the recorded one, or past the recording its last.
pub(crate) fn action_row(actions: &FrameArray, k: usize) -> &[f64] {
    actions.row(k.min(actions.len() - 1))
}

/// A fresh environment restored from the episode's `state[0]` on `scene`.
pub(crate) fn new_env(
    src: &Source,
    scene: &Scene,
    spec: &TaskSpec,
) -> Result<TaskEnv, AugmentError> {
    let state0 = src.episode.array(Episode::STATE).expect("checked").row(0);
    TaskEnv::from_initial_state(scene, spec, state0, EnvOptions::default())
        .map_err(sim_err(&src.episode.id))
}

/// Steps a replay through `before_step` (called with the environment and the step index
/// before each step) and returns its trajectory.
pub(crate) fn replay(
    src: &Source,
    env: &mut TaskEnv,
    config: &AugmentConfig,
    mut before_step: impl FnMut(&mut TaskEnv, usize) -> Result<(), AugmentError>,
) -> Result<Physics, AugmentError> {
    let id = &src.episode.id;
    let actions = src.episode.array(Episode::ACTION).expect("checked");
    let recorded = recorded_frames(src, config);
    let limit = recorded + extension(src, config);
    let mut rows = Vec::with_capacity(recorded);
    let mut environment = Vec::with_capacity(recorded);
    let mut first_success = None;
    for k in 0..limit {
        if k >= recorded && first_success.is_some() {
            break;
        }
        rows.push(env.state());
        environment.push(env.environment_state());
        before_step(env, k)?;
        let v = env.step(action_row(actions, k)).map_err(sim_err(id))?;
        if v.success && first_success.is_none() {
            first_success = Some(k);
        }
    }
    let states = FrameArray::from_rows(&rows).map_err(|e| AugmentError::Input(e.to_string()))?;
    let environment =
        FrameArray::from_rows(&environment).map_err(|e| AugmentError::Input(e.to_string()))?;
    let recorded_states = src.episode.array(Episode::STATE).expect("checked");
    let (deviation, deviation_at) = deviation(&states, recorded_states, recorded);
    let summary = PhysicsSummary {
        frames: states.len(),
        recorded,
        first_success,
        deviation,
        deviation_at,
        states_hash: states_hash(&states),
        subtasks: env.subtask_spans(),
    };
    Ok(Physics {
        states,
        environment,
        summary,
    })
}

/// The physics-only replay of an episode on its task's scene.
pub(crate) fn simulate(
    src: &Source,
    scene: &Scene,
    config: &AugmentConfig,
) -> Result<Physics, AugmentError> {
    let mut env = new_env(src, scene, &src.spec)?;
    replay(src, &mut env, config, |_, _| Ok(()))
}

/// SHA-256 (hex) of an array's values, bit for bit.
pub(crate) fn states_hash(states: &FrameArray) -> String {
    let mut h = Sha256::new();
    h.update((states.width() as u64).to_le_bytes());
    for v in states.as_slice() {
        h.update(v.to_bits().to_le_bytes());
    }
    format!("{:x}", h.finalize())
}

/// Largest absolute difference over the first `frames` frames, and where; a width
/// mismatch or a NaN counts as infinite.
pub(crate) fn deviation(
    replayed: &FrameArray,
    recorded: &FrameArray,
    frames: usize,
) -> (f64, Option<(usize, usize)>) {
    if replayed.width() != recorded.width() {
        return (f64::INFINITY, None);
    }
    let mut best = (0.0, None);
    for k in 0..replayed.len().min(recorded.len()).min(frames) {
        for (c, (a, b)) in replayed.row(k).iter().zip(recorded.row(k)).enumerate() {
            let d = (a - b).abs();
            let d = if d.is_nan() { f64::INFINITY } else { d };
            if d > best.0 {
                best = (d, Some((k, c)));
            }
        }
    }
    best
}
