//! One generation attempt: a new reset, then the task's subtasks in the spec's order,
//! each arm on its own lane (in parallel where the spec lets the arms run so, together
//! for a `both` subtask, waiting where `after` says): a source segment of the subtask is
//! chosen, its arm targets carried from the source's reference-object pose to the new
//! one, bridged from where the arm is, executed through the DexJoCo controller, and the
//! subtask's end condition checked. Kept only when the task succeeds.

use dexjoco_core::{HAND_DOF, Pose, TaskSpec};
use dexjoco_scripted::{Planned, Recorder};
use dexjoco_sim::{EnvOptions, Scene, TaskEnv};
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

use crate::error::GenerateError;
use crate::source::{ArmTarget, Segment, SourceDemo, current_targets};

/// How a source segment is chosen for each subtask.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SegmentChoice {
    /// Uniformly among the sources (drawn from the attempt's seed).
    #[default]
    Random,
    /// The source whose reference object was closest to where it is now (position, plus
    /// 0.1 m per radian of rotation), as MimicGen's nearest-neighbour selection.
    Nearest,
}

/// Settings of an attempt.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AttemptOptions {
    /// How a segment is chosen.
    pub choice: SegmentChoice,
    /// Choose a source anew for every subtask; otherwise (MimicGen's default) each arm
    /// keeps the source chosen for its first subtask, so that its consecutive segments
    /// come from one demonstration (a `both` subtask whose arms kept different sources
    /// chooses again, for both).
    pub per_subtask: bool,
    /// Steps a lane waits, holding its last target, for its subtask's end after its
    /// segment is done, before the attempt fails at that subtask.
    pub grace_steps: usize,
    /// Bridge speed: metres per step of the target (and `bridge_rad_per_step` radians).
    pub bridge_m_per_step: f64,
    /// Bridge turning speed (radians per step).
    pub bridge_rad_per_step: f64,
    /// Fewest bridge steps (except where a segment continues the arm's last one in its
    /// source).
    pub bridge_min_steps: usize,
}

impl Default for AttemptOptions {
    fn default() -> Self {
        Self {
            choice: SegmentChoice::Random,
            per_subtask: false,
            grace_steps: 60,
            bridge_m_per_step: 0.005,
            bridge_rad_per_step: 0.03,
            bridge_min_steps: 10,
        }
    }
}

/// What was used for one subtask of a generated episode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    /// The subtask's id.
    pub subtask: String,
    /// The source episode the segment came from.
    pub source: String,
    /// The segment's steps in the source (inclusive).
    pub source_steps: [usize; 2],
    /// The reference object's pose in the source when the segment began, and in the new
    /// episode when it was carried over (`[x, y, z, qw, qx, qy, qz]`).
    pub source_object: [f64; 7],
    /// The same object's pose in the new episode.
    pub new_object: [f64; 7],
    /// The step of the new episode on which the bridge to the segment began, and the
    /// bridge's length.
    pub started_at: usize,
    /// Bridge steps.
    pub bridge_steps: usize,
}

/// Where and why an attempt failed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AttemptFailure {
    /// The first subtask that did not end (its id), or `None` when all ended and the task
    /// still did not succeed.
    pub subtask: Option<String>,
    /// The step the attempt stopped on.
    pub step: usize,
    /// Why.
    pub reason: String,
}

/// One attempt's outcome.
#[derive(Debug)]
pub struct Attempt {
    /// The attempt's index (also its reset's index in the seed's draws).
    pub index: usize,
    /// The reset it started from (`state[0]`).
    pub reset: Vec<f64>,
    /// The recording (the episode up to success, or where it stopped) and its subtasks.
    pub planned: Planned,
    /// Per subtask started, what it used.
    pub provenance: Vec<Provenance>,
    /// Why it failed, when it did.
    pub failure: Option<AttemptFailure>,
}

/// A started subtask's work: its bridged, carried-over targets, for its arms.
struct Run {
    /// Per step, per arm of `arms`.
    targets: Vec<Vec<ArmTarget>>,
    arms: Vec<usize>,
    /// The next step of `targets`.
    cursor: usize,
    /// Steps waited for its end after the last target.
    waited: usize,
}

/// The lanes and runs of an attempt in progress.
struct Lanes {
    /// Which subtask each arm's lane works on (a `both` subtask holds both).
    held: Vec<Option<usize>>,
    /// Each started subtask's run, until its lanes are free again.
    runs: Vec<Option<Run>>,
    started: Vec<bool>,
    /// Each arm's last target (held when it has nothing new).
    last: Vec<ArmTarget>,
    /// Each arm's source (its index) and the last source step of its last segment, once
    /// chosen.
    source: Vec<Option<(usize, usize)>>,
}

impl Lanes {
    /// A run whose segment is done frees its lanes once its subtask ended; the attempt
    /// fails when that end does not come within the grace steps.
    fn retire(
        &mut self,
        spec: &TaskSpec,
        env: &TaskEnv,
        options: &AttemptOptions,
    ) -> Option<AttemptFailure> {
        let spans = env.subtask_spans();
        for (i, slot) in self.runs.iter_mut().enumerate() {
            let Some(run) = slot else { continue };
            if run.cursor < run.targets.len() {
                continue;
            }
            if spans[i].end.is_some() {
                *slot = None;
                self.held
                    .iter_mut()
                    .filter(|l| **l == Some(i))
                    .for_each(|l| *l = None);
            } else if run.waited >= options.grace_steps {
                return Some(AttemptFailure {
                    subtask: Some(spec.subtasks[i].id.clone()),
                    step: env.steps(),
                    reason: format!(
                        "its end condition '{}' did not hold within {} steps after the segment",
                        spec.subtasks[i].end, options.grace_steps
                    ),
                });
            } else {
                run.waited += 1;
            }
        }
        None
    }

    /// Starts every subtask whose lanes are free and whose predecessors ended.
    fn start_ready(
        &mut self,
        spec: &TaskSpec,
        env: &TaskEnv,
        sources: &[SourceDemo],
        rng: &mut rand_chacha::ChaCha8Rng,
        options: &AttemptOptions,
        provenance: &mut Vec<Provenance>,
    ) -> Result<(), GenerateError> {
        let spans = env.subtask_spans();
        let before = spec.subtask_predecessors();
        for (i, sub) in spec.subtasks.iter().enumerate() {
            let free = sub.arm.lanes().iter().all(|&l| self.held[l].is_none());
            let ready = before[i].iter().all(|&b| spans[b].end.is_some());
            if self.started[i] || !free || !ready {
                continue;
            }
            let lanes = sub.arm.lanes();
            let kept = self.source[lanes[0]].filter(|s| {
                !options.per_subtask && lanes.iter().all(|&l| self.source[l] == Some(*s))
            });
            let (run, prov, chosen) = start(env, spec, sources, i, &self.last, kept, rng, options)?;
            for &l in lanes {
                self.source[l] = Some((chosen, prov.source_steps[1]));
            }
            provenance.push(Provenance {
                started_at: env.steps(),
                ..prov
            });
            for &l in &run.arms {
                self.held[l] = Some(i);
            }
            self.runs[i] = Some(run);
            self.started[i] = true;
        }
        Ok(())
    }

    /// The next action: each arm's next target of its run, else the last one it had.
    fn next_action(&mut self, spec: &TaskSpec) -> Vec<f64> {
        for run in self.runs.iter_mut().flatten() {
            if run.cursor < run.targets.len() {
                for (k, &a) in run.arms.iter().enumerate() {
                    self.last[a] = run.targets[run.cursor][k];
                }
                run.cursor += 1;
            }
        }
        let mut action = vec![0.0; spec.setup.action_dim()];
        let per_arm = action.len() / self.last.len();
        for (a, t) in self.last.iter().enumerate() {
            let o = a * per_arm;
            t.pose.write(&mut action[o..o + 7]);
            action[o + 7..o + 7 + HAND_DOF].copy_from_slice(&t.hand);
        }
        action
    }
}

/// Runs attempt `index` from the reset `reset` with the given sources.
pub fn attempt(
    scene: &Scene,
    spec: &TaskSpec,
    sources: &[SourceDemo],
    reset: Vec<f64>,
    index: usize,
    seed: u64,
    options: &AttemptOptions,
) -> Result<Attempt, GenerateError> {
    let env = TaskEnv::from_initial_state(scene, spec, &reset, EnvOptions::default())?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(index as u64 + 1);
    let n = spec.subtasks.len();
    let mut lanes = Lanes {
        held: vec![None; spec.setup.arms()],
        runs: (0..n).map(|_| None).collect(),
        started: vec![false; n],
        last: current_targets(&env),
        source: vec![None; spec.setup.arms()],
    };
    let mut rec = Recorder::new(env);
    let mut provenance = Vec::new();
    let mut failure = None;
    while !rec.done() {
        failure = lanes.retire(spec, rec.env(), options);
        if failure.is_some() {
            break;
        }
        lanes.start_ready(spec, rec.env(), sources, &mut rng, options, &mut provenance)?;
        let action = lanes.next_action(spec);
        rec.step(action)?;
    }
    let steps = rec.env().steps();
    let first_open = rec
        .env()
        .subtask_spans()
        .iter()
        .find(|s| s.end.is_none())
        .map(|s| s.id.clone());
    let planned = rec.finish(&format!("{}_generated_{index:06}", spec.id))?;
    if planned.success_at.is_none() && failure.is_none() {
        failure = Some(AttemptFailure {
            subtask: first_open,
            step: steps,
            reason: if planned.failed {
                "the task's failure condition was reached".into()
            } else {
                format!("no success within the task's {} steps", spec.step_cap)
            },
        });
    }
    Ok(Attempt {
        index,
        reset,
        planned,
        provenance,
        failure,
    })
}

/// Chooses a segment of subtask `i` (of source `kept.0` when given), carries it to the
/// reference object's pose now and bridges each of its arms from its last target to the
/// segment's first; returns the run, its provenance and the source's index. A segment
/// that continues the arms' last one in their source (it starts on the step after
/// `kept.1`) is bridged only as far as the two transforms differ, without the minimum:
/// a pause mid-motion (a finger held on a button) is not in any source.
#[allow(clippy::too_many_arguments)]
fn start(
    env: &TaskEnv,
    spec: &TaskSpec,
    sources: &[SourceDemo],
    i: usize,
    last: &[ArmTarget],
    kept: Option<(usize, usize)>,
    rng: &mut rand_chacha::ChaCha8Rng,
    options: &AttemptOptions,
) -> Result<(Run, Provenance, usize), GenerateError> {
    let sub = &spec.subtasks[i];
    let now = env
        .object_pose(&sub.object)
        .ok_or_else(|| GenerateError::Spec(format!("no state object '{}'", sub.object)))?;
    let chosen = kept.map_or_else(|| choose(sources, i, &now, rng, options.choice), |k| k.0);
    let segment = &sources[chosen].segments[i];
    let min_steps = match kept {
        Some((_, last)) if segment.start == last + 1 => 0,
        _ => options.bridge_min_steps,
    };
    let carried = carry(segment, &now);
    let first = &carried[0];
    let bridge = segment
        .arms
        .iter()
        .enumerate()
        .map(|(k, &a)| bridge_steps(&last[a].pose, &first[k].pose, min_steps, options))
        .max()
        .unwrap_or(min_steps);
    let mut targets: Vec<Vec<ArmTarget>> = (1..=bridge)
        .map(|s| {
            let t = s as f64 / (bridge + 1) as f64;
            segment
                .arms
                .iter()
                .enumerate()
                .map(|(k, &a)| blend(&last[a], &first[k], t))
                .collect()
        })
        .collect();
    targets.extend(carried);
    let pose7 = |p: &Pose| {
        let mut v = [0.0; 7];
        p.write(&mut v);
        v
    };
    let prov = Provenance {
        subtask: sub.id.clone(),
        source: segment.source.clone(),
        source_steps: [segment.start, segment.last],
        source_object: pose7(&segment.object_pose),
        new_object: pose7(&now),
        started_at: 0,
        bridge_steps: bridge,
    };
    Ok((
        Run {
            targets,
            arms: segment.arms.clone(),
            cursor: 0,
            waited: 0,
        },
        prov,
        chosen,
    ))
}

/// The source (its index) whose segment of subtask `i` to use.
fn choose(
    sources: &[SourceDemo],
    i: usize,
    now: &Pose,
    rng: &mut rand_chacha::ChaCha8Rng,
    choice: SegmentChoice,
) -> usize {
    match choice {
        SegmentChoice::Random => rng.random_range(0..sources.len()),
        SegmentChoice::Nearest => {
            let cost =
                |s: &Segment| s.object_pose.distance(now) + 0.1 * s.object_pose.angle_to(now);
            (0..sources.len())
                .min_by(|&a, &b| {
                    cost(&sources[a].segments[i]).total_cmp(&cost(&sources[b].segments[i]))
                })
                .expect("at least one source")
        }
    }
}

/// The segment's targets carried from its reference object's pose in the source to
/// `now`: `now * source^-1 * target`; the hands as recorded.
pub fn carry(segment: &Segment, now: &Pose) -> Vec<Vec<ArmTarget>> {
    let delta = now.compose(&segment.object_pose.inverse());
    segment
        .targets
        .iter()
        .map(|step| {
            step.iter()
                .map(|t| ArmTarget {
                    pose: delta.compose(&t.pose),
                    hand: t.hand,
                })
                .collect()
        })
        .collect()
}

/// Bridge length from `from` to `to` at the bridge speeds.
fn bridge_steps(from: &Pose, to: &Pose, min_steps: usize, options: &AttemptOptions) -> usize {
    let by_distance = from.distance(to) / options.bridge_m_per_step;
    let by_angle = from.angle_to(to) / options.bridge_rad_per_step;
    (by_distance.max(by_angle).ceil() as usize).max(min_steps)
}

/// The target `t` of the way from `a` to `b` (hands linearly).
fn blend(a: &ArmTarget, b: &ArmTarget, t: f64) -> ArmTarget {
    ArmTarget {
        pose: a.pose.interpolate(&b.pose, t),
        hand: std::array::from_fn(|j| a.hand[j] + (b.hand[j] - a.hand[j]) * t),
    }
}
