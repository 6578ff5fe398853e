//! Source demonstrations cut into subtask segments: each source episode is replayed in
//! its task environment (bit for bit what it recorded), which gives where each subtask
//! ran (the task spec's predicates), the pose of each subtask's reference object when
//! the subtask began (states hold object poses only at reset), and the arm targets the
//! controller was given on every step (a zero action, the raw format's "hold", resolved
//! to the target it held).

use dexjoco_core::{Episode, HAND_DOF, Pose, TaskSpec};
use dexjoco_sim::{EnvOptions, Scene, TaskEnv};
use sha2::{Digest, Sha256};

use crate::error::GenerateError;

/// One arm's target on one step: the OSC target pose and the hand's 16 joint targets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmTarget {
    /// The arm target (world frame).
    pub pose: Pose,
    /// Hand joint targets, in the action's order.
    pub hand: [f64; HAND_DOF],
}

/// The steps of one subtask in one source episode, for the arms it belongs to.
#[derive(Debug, Clone, PartialEq)]
pub struct Segment {
    /// The subtask's index in the task spec.
    pub subtask: usize,
    /// The source episode's id.
    pub source: String,
    /// The segment's first step in the source.
    pub start: usize,
    /// The step its end node first held.
    pub end: usize,
    /// The segment's last step: the arms go on as the source did after the subtask
    /// ended (a hand withdrawn from the microwave, a tray held still) until their next
    /// subtask starts, or to the source's end after an arm's last subtask.
    pub last: usize,
    /// The arms (lanes: 0 right or single, 1 left) whose targets it holds.
    pub arms: Vec<usize>,
    /// The subtask's reference object's world pose before the segment's first step.
    pub object_pose: Pose,
    /// Per step, per arm of `arms` (in that order), the target the controller was given.
    pub targets: Vec<Vec<ArmTarget>>,
}

/// A source episode cut into one segment per subtask.
#[derive(Debug, Clone)]
pub struct SourceDemo {
    /// The episode's id.
    pub id: String,
    /// SHA-256 of its action and state arrays (what a generated episode's provenance names).
    pub sha256: String,
    /// One segment per subtask of the task spec, in its order.
    pub segments: Vec<Segment>,
    /// Each subtask's reference object's pose at reset.
    pub reset_poses: Vec<Pose>,
    /// Its reset (`state[0]`), for the pose-spread figure.
    pub reset: Vec<f64>,
    /// Steps its replay went on past the recording (its last action repeated) before it
    /// succeeded: 0 for a source that succeeds within its recording.
    pub extended: usize,
}

/// Hex SHA-256 of an episode's action and state values (little-endian f64 bits).
pub fn episode_sha256(episode: &Episode) -> String {
    let mut h = Sha256::new();
    for name in [Episode::ACTION, Episode::STATE] {
        if let Some(a) = episode.array(name) {
            h.update(name.as_bytes());
            h.update((a.width() as u64).to_le_bytes());
            for row in a.rows() {
                for v in row {
                    h.update(v.to_le_bytes());
                }
            }
        }
    }
    format!("{:x}", h.finalize())
}

/// The targets every arm was given on the last step (mocap pose, hand controls).
pub fn current_targets(env: &TaskEnv) -> Vec<ArmTarget> {
    let ctrl = env.data().ctrl();
    env.robot()
        .arms
        .iter()
        .zip(env.targets())
        .map(|(arm, (pos, quat))| {
            let mut hand = [0.0; HAND_DOF];
            for (h, &act) in hand.iter_mut().zip(&arm.hand_actuators) {
                *h = ctrl[act];
            }
            ArmTarget {
                pose: Pose::new(pos, quat),
                hand,
            }
        })
        .collect()
}

/// What a source's replay gives step by step: the subtasks' objects' poses before each
/// step, the targets given by it.
#[derive(Default)]
struct Trace {
    poses: Vec<Vec<Pose>>,
    given: Vec<Vec<ArmTarget>>,
}

impl Trace {
    /// Replays `actions` on `env` up to the task's success; without one, goes on with the
    /// last action for up to `extend_steps` steps, kept only if they reach it. Returns the
    /// trace, the subtask spans and the steps added past the recording.
    fn replay(
        env: &mut TaskEnv,
        actions: &dexjoco_core::FrameArray,
        objects: &[&str],
        extend_steps: usize,
    ) -> Result<(Self, Vec<dexjoco_core::SubtaskSpan>, usize), String> {
        let mut trace = Self::default();
        for row in actions.rows() {
            if trace.step(env, row, objects)? {
                return Ok((trace, env.subtask_spans(), 0));
            }
        }
        let spans = env.subtask_spans();
        let recorded = trace.given.len();
        let last = actions.row(actions.len() - 1);
        for _ in 0..extend_steps {
            if trace.step(env, last, objects)? {
                let extended = trace.given.len() - recorded;
                return Ok((trace, env.subtask_spans(), extended));
            }
        }
        trace.poses.truncate(recorded);
        trace.given.truncate(recorded);
        Ok((trace, spans, 0))
    }

    /// One step of `row`; whether the task succeeded on it.
    fn step(&mut self, env: &mut TaskEnv, row: &[f64], objects: &[&str]) -> Result<bool, String> {
        let poses = objects
            .iter()
            .map(|o| {
                env.object_pose(o)
                    .ok_or_else(|| format!("no state object '{o}' in the scene"))
            })
            .collect::<Result<_, _>>()?;
        self.poses.push(poses);
        let verdict = env.step(row).map_err(|e| e.to_string())?;
        self.given.push(current_targets(env));
        Ok(verdict.success)
    }
}

impl SourceDemo {
    /// Replays `episode` of `spec` on `scene` up to the task's success and cuts it into
    /// its subtasks' segments; a recording that ends before its success goes on for up
    /// to `extend_steps` steps with its last action repeated (as augment's
    /// `--extend-steps`: a recording made with another MuJoCo may succeed a few steps
    /// late). Fails, naming the episode and the subtask, when a subtask never ends in the
    /// replay (a source must show every subtask).
    pub fn prepare(
        scene: &Scene,
        spec: &TaskSpec,
        episode: &Episode,
        extend_steps: usize,
    ) -> Result<Self, GenerateError> {
        let bad = |message: String| GenerateError::Source {
            episode: episode.id.clone(),
            message,
        };
        if spec.subtasks.is_empty() {
            return Err(bad(format!(
                "task '{}' has no subtasks in its spec: generate cuts sources at them",
                spec.id
            )));
        }
        let (actions, states) = match (
            episode.array(Episode::ACTION),
            episode.array(Episode::STATE),
        ) {
            (Some(a), Some(s)) if !s.is_empty() => (a, s),
            _ => return Err(bad("no action or state array".into())),
        };
        let mut env =
            TaskEnv::from_initial_state(scene, spec, states.row(0), EnvOptions::default())
                .map_err(|e| bad(e.to_string()))?;
        let objects: Vec<&str> = spec.subtasks.iter().map(|s| s.object.as_str()).collect();
        let pose_of = |env: &TaskEnv, o: &str| {
            env.object_pose(o)
                .ok_or_else(|| bad(format!("no state object '{o}' in the scene")))
        };
        let reset_poses = objects
            .iter()
            .map(|o| pose_of(&env, o))
            .collect::<Result<Vec<_>, _>>()?;
        // Before each step: the subtasks' objects' poses; after it: the targets given.
        let (Trace { poses, given }, spans, extended) =
            Trace::replay(&mut env, actions, &objects, extend_steps).map_err(&bad)?;
        let mut segments = Vec::with_capacity(spans.len());
        // Where each arm's next subtask starts after subtask i (the arm's motion until
        // then belongs to subtask i's segment).
        let next_start = |i: usize, lane: usize| {
            spec.subtasks[i + 1..]
                .iter()
                .zip(&spans[i + 1..])
                .find(|(s, _)| s.arm.lanes().contains(&lane))
                .map_or(Some(given.len()), |(_, sp)| sp.start)
        };
        for (i, (span, sub)) in spans.iter().zip(&spec.subtasks).enumerate() {
            let (Some(start), Some(end)) = (span.start, span.end) else {
                return Err(bad(format!(
                    "its subtask '{}' never ends when it is replayed ({} steps): a source must \
                     complete every subtask",
                    sub.id,
                    given.len()
                )));
            };
            let arms = sub.arm.lanes().to_vec();
            let last = arms
                .iter()
                .filter_map(|&l| next_start(i, l))
                .min()
                .map_or(end, |n| n.saturating_sub(1).max(end));
            let targets = given[start..=last]
                .iter()
                .map(|t| arms.iter().map(|&a| t[a]).collect())
                .collect();
            segments.push(Segment {
                subtask: i,
                source: episode.id.clone(),
                start,
                end,
                last,
                arms,
                object_pose: poses[start][i],
                targets,
            });
        }
        Ok(Self {
            id: episode.id.clone(),
            sha256: episode_sha256(episode),
            segments,
            reset_poses,
            reset: states.row(0).to_vec(),
            extended,
        })
    }
}
