//! Scripted demonstrations: plans that use privileged state (object poses read from the
//! simulation) to move the OSC target and the hand, recorded in the DexJoCo raw layout.
//!
//! A [`Recorder`] steps a [`TaskEnv`], keeping each frame's state and action; the
//! per-task planners are built from its motions (straight target moves with a fixed
//! orientation and hand pose, holds, guarded moves that stop on a condition).

use dexjoco_core::{Episode, HAND_DOF, NameKind, TaskSpec};

use dexjoco_sim::Scene;
use dexjoco_sim::name_id;
use dexjoco_sim::{EnvOptions, TaskEnv};
pub use error::PlanError;

mod assembly;
mod click_mouse;
mod error;
mod fold_glasses;
mod hammer_nail;
mod hands;
mod hanoi;
pub(crate) mod kin;
mod microwave_cook;
mod photograph;
mod pick_bucket;
mod pinch_tongs;
mod unlock_ipad;
mod water_plant;

pub use click_mouse::click_mouse_demo;
pub use unlock_ipad::unlock_ipad_demo;

pub(crate) use hands::{CLOSE, FLAT_HAND, OPEN, POINT_HAND};
use kin::{Q, V3};

/// Steps an environment and records frames (state before the step, action applied).
#[derive(Debug)]
pub struct Recorder {
    env: TaskEnv,
    states: Vec<Vec<f64>>,
    /// The environment state before each step.
    environment: Vec<Vec<f64>>,
    actions: Vec<Vec<f64>>,
    success_at: Option<usize>,
    failed: bool,
    hands: Vec<[f64; HAND_DOF]>,
    phases: Vec<(String, usize)>,
}

impl Recorder {
    /// Marks the end of the planner's own phase for subtask `id`: the last step it
    /// recorded (to compare the planner's idea of where a subtask ends with the task
    /// spec's predicate). A phase marked before any step is at step 0.
    pub fn phase(&mut self, id: &str) {
        let step = self.actions.len().saturating_sub(1);
        self.phases.push((id.to_owned(), step));
    }

    /// Records on an environment.
    pub fn new(env: TaskEnv) -> Self {
        let hands = env
            .robot()
            .arms
            .iter()
            .map(|a| {
                let mut h = [0.0; HAND_DOF];
                for (v, &act) in h.iter_mut().zip(&a.hand_actuators) {
                    *v = env.data().ctrl()[act];
                }
                h
            })
            .collect();
        Self {
            hands,
            env,
            states: Vec::new(),
            environment: Vec::new(),
            actions: Vec::new(),
            success_at: None,
            failed: false,
            phases: Vec::new(),
        }
    }

    /// The environment.
    pub fn env(&self) -> &TaskEnv {
        &self.env
    }

    /// Steps one action; stops recording (returns false) once the task succeeded or
    /// failed, or the step cap is reached.
    pub fn step(&mut self, action: Vec<f64>) -> Result<bool, PlanError> {
        if self.done() {
            return Ok(false);
        }
        // Motions blend from the hand targets as commanded; the recorded (and applied)
        // targets are clamped to the actuators' ranges, which is what MuJoCo applies
        // anyway, so every recorded action is within range and the physics is the same.
        for (arm, hand) in self.hands.iter_mut().enumerate() {
            let o = arm * 23;
            hand.copy_from_slice(&action[o + 7..o + 23]);
        }
        let mut action = action;
        {
            let m = self.env.data().model();
            for (arm, a) in self.env.robot().arms.iter().enumerate() {
                for (i, &act) in a.hand_actuators.iter().enumerate() {
                    let [lo, hi] = m.actuator_ctrlrange()[act];
                    let v = &mut action[arm * 23 + 7 + i];
                    *v = v.clamp(lo, hi);
                }
            }
        }
        self.states.push(self.env.state());
        self.environment.push(self.env.environment_state());
        let v = self.env.step(&action)?;
        self.actions.push(action);
        if v.success {
            self.success_at = Some(self.actions.len() - 1);
        }
        self.failed |= v.failure;
        Ok(!self.done())
    }

    /// The task succeeded or failed, or the cap is reached.
    pub fn done(&self) -> bool {
        self.success_at.is_some() || self.failed || self.actions.len() >= self.env.spec().step_cap
    }

    /// The step on which the task succeeded.
    pub fn success_at(&self) -> Option<usize> {
        self.success_at
    }

    /// Moves arm `arm`'s target in a straight line from its current target to `to` over
    /// `steps` steps, with orientation `quat` and hand targets `hand` (16, this arm's
    /// action order); other arms hold their targets. Stops early when `stop` says so.
    pub fn move_to(
        &mut self,
        arm: usize,
        to: [f64; 3],
        quat: [f64; 4],
        hand: [f64; HAND_DOF],
        steps: usize,
        mut stop: impl FnMut(&TaskEnv) -> bool,
    ) -> Result<bool, PlanError> {
        let from = self.env.targets()[arm].0;
        for k in 1..=steps.max(1) {
            let t = k as f64 / steps.max(1) as f64;
            let p = [
                from[0] + (to[0] - from[0]) * t,
                from[1] + (to[1] - from[1]) * t,
                from[2] + (to[2] - from[2]) * t,
            ];
            let mut a = self.others_held(arm);
            let o = arm * 23;
            a[o..o + 3].copy_from_slice(&p);
            a[o + 3..o + 7].copy_from_slice(&quat);
            a[o + 7..o + 23].copy_from_slice(&hand);
            if !self.step(a)? {
                return Ok(false);
            }
            if stop(&self.env) {
                return Ok(true);
            }
        }
        Ok(false)
    }

    /// Keeps the current targets for `steps` steps with hand targets `hand`.
    pub fn hold(
        &mut self,
        arm: usize,
        quat: [f64; 4],
        hand: [f64; HAND_DOF],
        steps: usize,
    ) -> Result<(), PlanError> {
        let at = self.env.targets()[arm].0;
        for _ in 0..steps {
            let mut a = self.others_held(arm);
            let o = arm * 23;
            a[o..o + 3].copy_from_slice(&at);
            a[o + 3..o + 7].copy_from_slice(&quat);
            a[o + 7..o + 23].copy_from_slice(&hand);
            if !self.step(a)? {
                break;
            }
        }
        Ok(())
    }

    /// An action in which every arm but `arm` holds its current targets (pose and hand),
    /// written out rather than left as the raw format's all-zero "hold": so that every
    /// recorded action, and the `action_rotvec` a policy learns from, is a real target.
    fn others_held(&self, arm: usize) -> Vec<f64> {
        let mut a = vec![0.0; self.env.spec().setup.action_dim()];
        for (b, (p, q)) in self.env.targets().into_iter().enumerate() {
            if b != arm {
                let o = b * 23;
                a[o..o + 3].copy_from_slice(&p);
                a[o + 3..o + 7].copy_from_slice(&q);
                a[o + 7..o + 23].copy_from_slice(&self.hands[b]);
            }
        }
        a
    }

    /// Arm `arm`'s current target (mocap) position and orientation.
    pub(crate) fn target(&self, arm: usize) -> (V3, Q) {
        self.env.targets()[arm]
    }

    /// Moves the targets of the arms in `goals` together along straight lines (position),
    /// normalized interpolation (orientation) and linear hand blends, from where they are
    /// to the goals over `steps` steps; arms not named hold. Stops early when `stop`
    /// says so (returns true then), or when the recording is done.
    pub(crate) fn go_many(
        &mut self,
        goals: &[Goal],
        steps: usize,
        mut stop: impl FnMut(&TaskEnv) -> bool,
    ) -> Result<bool, PlanError> {
        let n = self.hands.len();
        let from: Vec<(V3, Q, [f64; HAND_DOF])> = (0..n)
            .map(|a| {
                let (p, q) = self.target(a);
                (p, q, self.hands[a])
            })
            .collect();
        let steps = steps.max(1);
        for k in 1..=steps {
            let t = k as f64 / steps as f64;
            let mut a = vec![0.0; self.env.spec().setup.action_dim()];
            for (arm, (p0, q0, h0)) in from.iter().enumerate() {
                let (p, q, h) = match goals.iter().find(|g| g.arm == arm) {
                    Some(g) => {
                        let p1 = g.pos.unwrap_or(*p0);
                        let q1 = g.quat.unwrap_or(*q0);
                        let h1 = g.hand.unwrap_or(*h0);
                        let mut h = [0.0; HAND_DOF];
                        for i in 0..HAND_DOF {
                            h[i] = h0[i] + (h1[i] - h0[i]) * t;
                        }
                        let p = kin::add(*p0, kin::scale(kin::sub(p1, *p0), t));
                        let q = if g.quat.is_some() {
                            kin::nlerp(*q0, q1, t)
                        } else {
                            *q0
                        };
                        (p, q, h)
                    }
                    None => (*p0, *q0, *h0),
                };
                let o = arm * 23;
                a[o..o + 3].copy_from_slice(&p);
                a[o + 3..o + 7].copy_from_slice(&q);
                a[o + 7..o + 23].copy_from_slice(&h);
            }
            if !self.step(a)? {
                return Ok(false);
            }
            if stop(&self.env) {
                return Ok(true);
            }
        }
        Ok(false)
    }

    /// Moves one arm (position, orientation, hand) over `steps` steps; see [`Self::go_many`].
    pub(crate) fn go(
        &mut self,
        arm: usize,
        pos: V3,
        quat: Q,
        hand: [f64; HAND_DOF],
        steps: usize,
    ) -> Result<(), PlanError> {
        self.go_many(&[Goal::new(arm, pos, quat, hand)], steps, |_| false)?;
        Ok(())
    }

    /// Holds every target for `steps` steps.
    pub(crate) fn wait(&mut self, steps: usize) -> Result<(), PlanError> {
        self.go_many(&[], steps, |_| false)?;
        Ok(())
    }

    /// Holds every target until each arm's TCP is within `tol` (m) of its target
    /// position, at most `max_steps` steps: contact phases start only after this.
    pub(crate) fn settle(&mut self, tol: f64, max_steps: usize) -> Result<(), PlanError> {
        let n = self.hands.len();
        let arrived = move |e: &TaskEnv| {
            (0..n).all(|a| kin::norm(kin::sub(kin::tcp(e, a).0, e.targets()[a].0)) < tol)
        };
        if !arrived(&self.env) {
            self.go_many(&[], max_steps, arrived)?;
        }
        Ok(())
    }

    /// With `DEXJOCO_PLAN_SNAP` set to a folder: a picture of the scene around arm
    /// `arm`'s TCP (planner diagnostics; rendering does not change the state).
    pub(crate) fn snap(&mut self, arm: usize, name: &str) {
        let lookat = kin::tcp(&self.env, arm).0;
        let views = [90.0, 180.0].map(|azimuth| dexjoco_render::CameraView::Orbit {
            lookat: [lookat[0], lookat[1], lookat[2] - 0.1],
            distance: 0.6,
            azimuth,
            elevation: -30.0,
        });
        self.snap_views(name, (480, 480), &views);
    }

    /// With `DEXJOCO_PLAN_SNAP` set to a folder: `views` of the scene as it is, drawn at
    /// `size` into `<name>_<k>.png` there (planner diagnostics; rendering does not change
    /// the state; a failure is printed, never stops the plan).
    pub(crate) fn snap_views(
        &mut self,
        name: &str,
        (width, height): (u32, u32),
        views: &[dexjoco_render::CameraView],
    ) {
        let Some(dir) = std::env::var_os("DEXJOCO_PLAN_SNAP") else {
            return;
        };
        let model = self.env.data().model_clone();
        let settings = dexjoco_render::RenderSettings {
            width,
            height,
            ..Default::default()
        };
        let result = dexjoco_render::Renderer::new(&model, settings).and_then(|mut r| {
            for (k, view) in views.iter().enumerate() {
                let f = r.render(self.env.data_mut(), *view)?;
                f.save_png(&std::path::Path::new(&dir).join(format!("{name}_{k}.png")))?;
            }
            Ok(())
        });
        if let Err(e) = result {
            eprintln!("snapshot {name}: {e}");
        }
    }

    /// The recorded episode and how it ended.
    pub fn finish(mut self, id: &str) -> Result<Planned, PlanError> {
        let success_at = self.success_at;
        let failed = self.failed;
        let subtasks = self.env.subtask_spans();
        let phases = std::mem::take(&mut self.phases);
        Ok(Planned {
            episode: self.into_episode(id)?,
            success_at,
            failed,
            subtasks,
            phases,
        })
    }

    /// The recorded episode (frames up to and including the success step).
    pub fn into_episode(self, id: &str) -> Result<Episode, PlanError> {
        let mut ep =
            Episode::from_rollout(id.to_owned(), self.env.spec(), &self.actions, &self.states)
                .map_err(PlanError::Episode)?;
        ep.insert_rows(Episode::ENVIRONMENT_STATE, &self.environment)
            .map_err(PlanError::Episode)?;
        Ok(ep)
    }
}

pub(crate) fn geom_of_body(env: &TaskEnv, body: &str) -> Option<usize> {
    let m = env.data().model();
    let b = name_id(m, NameKind::Body, body)?;
    (0..m.ffi().ngeom as usize)
        .find(|&g| m.geom_bodyid()[g] as usize == b && m.geom_contype()[g] != 0)
}

/// One arm's goal in a [`Recorder::go_many`] motion; `None` keeps the current value.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Goal {
    arm: usize,
    pos: Option<V3>,
    quat: Option<Q>,
    hand: Option<[f64; HAND_DOF]>,
}

impl Goal {
    /// A full goal: position, orientation and hand.
    pub(crate) fn new(arm: usize, pos: V3, quat: Q, hand: [f64; HAND_DOF]) -> Self {
        Self {
            arm,
            pos: Some(pos),
            quat: Some(quat),
            hand: Some(hand),
        }
    }
}

/// Planner diagnostics on stderr when `DEXJOCO_PLAN_DEBUG` is set.
pub(crate) fn debug() -> bool {
    std::env::var_os("DEXJOCO_PLAN_DEBUG").is_some()
}

/// How far a planner's own phase end may lie from the predicate's end of the same
/// subtask, in control steps: the predicate ends at most `PHASE_AGREEMENT.0` steps after
/// the phase (a grasp closing after the approach phase is over) and at most
/// `PHASE_AGREEMENT.1` steps before it (a predicate holds as soon as its condition does;
/// the planner marks its phase after the motion completes). Measured over scripted's 20
/// resets of seed 0 on both scene sets (`examples/subtask_agreement.rs`,
/// docs/tasks-and-scenes.md).
pub const PHASE_AGREEMENT: (usize, usize) = (60, 130);

/// A planned demonstration: the recorded frames (up to and including the success step,
/// or all of them when the plan did not succeed) and how the recording ended.
#[derive(Debug, Clone)]
pub struct Planned {
    /// The recorded episode.
    pub episode: Episode,
    /// The step on which the task succeeded, if it did.
    pub success_at: Option<usize>,
    /// The task's failure condition was reached.
    pub failed: bool,
    /// Where each of the task's subtasks ran in the recording (by the task spec's
    /// predicates).
    pub subtasks: Vec<dexjoco_core::SubtaskSpan>,
    /// Where the planner's own phases ended, by subtask id ([`Recorder::phase`]).
    pub phases: Vec<(String, usize)>,
}

impl Planned {
    /// The subtasks whose predicate end is not within [`PHASE_AGREEMENT`] of the
    /// planner's own phase end, each described (also those that never ended or have no
    /// phase). Empty for a plan whose segmentation agrees with its planner.
    pub fn phase_disagreements(&self) -> Vec<String> {
        let (after, before) = PHASE_AGREEMENT;
        let mut out = Vec::new();
        for s in &self.subtasks {
            let phase = self.phases.iter().find(|(id, _)| *id == s.id).map(|p| p.1);
            match (s.end, phase) {
                (None, _) => out.push(format!("'{}' never ended", s.id)),
                (_, None) => out.push(format!("the planner marks no phase '{}'", s.id)),
                (Some(end), Some(phase)) if end > phase + after || end + before < phase => {
                    out.push(format!(
                        "'{}' ended on step {end}, the planner's phase on {phase}",
                        s.id
                    ));
                }
                _ => {}
            }
        }
        out
    }
}

/// Which plan to make: the task's demonstration, or a deliberately wrong one that
/// reaches the task's failure condition (for tasks that have one).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Variant {
    /// A demonstration that should succeed.
    #[default]
    Demo,
    /// A plan meant to reach the task's failure condition.
    Wrong,
}

/// A planner: from the task's environment at its initial state, the episode id and the
/// variant, the recorded plan.
type PlanFn = fn(TaskEnv, &str, Variant) -> Result<Planned, PlanError>;

/// A planner that only plans demonstrations (its task has no failure condition).
macro_rules! demo_only {
    ($plan:path) => {
        |env: TaskEnv, id: &str, variant: Variant| match variant {
            Variant::Demo => $plan(env, id),
            Variant::Wrong => Err(PlanError::NoFailure {
                task: env.spec().id.clone(),
            }),
        }
    };
}

/// The planners by task id: the one list of what `scripted` can plan.
const PLANNERS: [(&str, PlanFn); 11] = [
    ("bimanual_assembly", demo_only!(assembly::plan)),
    ("bimanual_hanoi", hanoi::plan),
    ("bimanual_microwave_cook", demo_only!(microwave_cook::plan)),
    ("bimanual_photograph", demo_only!(photograph::plan)),
    ("bimanual_unlock_ipad", unlock_ipad::plan),
    ("click_mouse", demo_only!(click_mouse::plan)),
    ("fold_glasses", demo_only!(fold_glasses::plan)),
    ("hammer_nail", demo_only!(hammer_nail::plan)),
    ("pick_bucket", demo_only!(pick_bucket::plan)),
    ("pinch_tongs", demo_only!(pinch_tongs::plan)),
    ("water_plant", water_plant::plan),
];

/// The tasks that have a scripted planner (the ids of [`PLANNERS`], in its order).
pub const PLANNED_TASKS: &[&str] = &{
    let mut ids = [""; PLANNERS.len()];
    let mut i = 0;
    while i < PLANNERS.len() {
        ids[i] = PLANNERS[i].0;
        i += 1;
    }
    ids
};

/// Plans and records a demonstration of `spec`'s task from the initial state `state0`
/// (a `state[0]` row, e.g. from [`TaskEnv::sample_initial_state`]).
pub fn plan(
    scene: &Scene,
    spec: &TaskSpec,
    state0: &[f64],
    id: &str,
    variant: Variant,
) -> Result<Planned, PlanError> {
    let Some((_, planner)) = PLANNERS.iter().find(|(task, _)| *task == spec.id) else {
        return Err(match variant {
            Variant::Demo => PlanError::NoPlanner {
                task: spec.id.clone(),
            },
            Variant::Wrong => PlanError::NoFailure {
                task: spec.id.clone(),
            },
        });
    };
    planner(
        TaskEnv::from_initial_state(scene, spec, state0, EnvOptions::default())?,
        id,
        variant,
    )
}
