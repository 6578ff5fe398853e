//! A task environment: a scene, its robot, the success checker, and the DexJoCo state
//! vector; built from a recorded initial state (`state[0]`) as the reference replay does.

use std::path::PathBuf;
use std::sync::Arc;

use dexjoco_core::{
    ArmTargetInit, ArrayLayout, DerivedPose, FrameArray, HAND_DOF, HandSource, LegStyle, NameKind,
    PoseSource, TaskSpec, ZRule,
};
use mujoco_rs::prelude::{MjData, MjModel, MjtDisableBit};

use crate::checker::{Resolver, SuccessChecker, Verdict, name_id};
use crate::control::{ARM_HOME, Robot, THUMB_HOME};
use crate::error::SimError;
use crate::scene::Scene;
use crate::subtasks::SubtaskTracker;
use dexjoco_core::SubtaskSpan;

mod poses;

/// Options of a task environment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EnvOptions {
    /// Disable multi-point convex collision (MuJoCo 3.17 enables it by default; the
    /// reference's 3.4 did not): brings replays of reference recordings closest.
    pub disable_multiccd: bool,
}

impl Default for EnvOptions {
    fn default() -> Self {
        Self {
            disable_multiccd: true,
        }
    }
}

/// The simulation of one task episode.
#[derive(Debug)]
pub struct TaskEnv {
    spec: TaskSpec,
    data: MjData<Arc<MjModel>>,
    robot: Robot,
    checker: SuccessChecker,
    subtasks: SubtaskTracker,
    privileged: Vec<f64>,
    steps: usize,
}

/// The result of applying a sequence of actions.
#[derive(Debug, Clone, PartialEq)]
pub struct Rollout {
    /// The state before each step (frame k = observation before action k).
    pub states: FrameArray,
    /// The verdict after each step.
    pub verdicts: Vec<Verdict>,
}

impl Rollout {
    /// The first step whose verdict is a success.
    pub fn first_success(&self) -> Option<usize> {
        self.verdicts.iter().position(|v| v.success)
    }

    /// The first step whose verdict is a failure.
    pub fn first_failure(&self) -> Option<usize> {
        self.verdicts.iter().position(|v| v.failure)
    }

    /// The reference's replay criterion: success on any step.
    pub fn succeeded(&self) -> bool {
        self.first_success().is_some()
    }
}

/// Where a task's scene comes from.
#[derive(Debug, Clone, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum SceneSource {
    /// The scenes authored by this project and embedded in the binary (the default).
    #[default]
    BuiltIn,
    /// A scene pack folder (`--scene-dir`), e.g. the DexJoCo reference `xmls/`: the
    /// task spec's `scene` file in it.
    Dir(PathBuf),
}

impl SceneSource {
    /// `--scene-dir` if given, else the built-in scenes.
    pub fn from_option(dir: Option<PathBuf>) -> Self {
        dir.map_or(Self::BuiltIn, Self::Dir)
    }
}

/// Loads a task's scene: built-in, or from a scene pack folder (`--scene-dir`, e.g. the
/// DexJoCo `xmls/`). A missing asset is reported with its file name.
pub fn load_task_scene(source: &SceneSource, spec: &TaskSpec) -> Result<Scene, SimError> {
    match source {
        SceneSource::Dir(dir) => Scene::load(dir.join(&spec.scene)),
        SceneSource::BuiltIn => crate::builtin::load_builtin(spec),
    }
}

/// Reads the reset-time pose of a state object.
fn read_pose(
    model: &MjModel,
    data: &MjData<Arc<MjModel>>,
    source: &PoseSource,
    out: &mut Vec<f64>,
) {
    match source {
        PoseSource::FreeJoint(n) => {
            let j = name_id(model, NameKind::Joint, n).expect("resolved");
            let a = model.jnt_qposadr()[j] as usize;
            out.extend_from_slice(&data.qpos()[a..a + 7]);
        }
        PoseSource::Body(n) => {
            let b = name_id(model, NameKind::Body, n).expect("resolved");
            out.extend_from_slice(&model.body_pos()[b]);
            out.extend_from_slice(&model.body_quat()[b]);
        }
        PoseSource::BodyPosition(n) => {
            let b = name_id(model, NameKind::Body, n).expect("resolved");
            out.extend_from_slice(&model.body_pos()[b]);
        }
        PoseSource::Mocap(n) => {
            let b = name_id(model, NameKind::Body, n).expect("resolved");
            let m = model.body_mocapid()[b] as usize;
            out.extend_from_slice(&data.mocap_pos()[m]);
            out.extend_from_slice(&data.mocap_quat()[m]);
        }
        PoseSource::GeomLocal(n) => {
            let g = name_id(model, NameKind::Geom, n).expect("resolved");
            out.extend_from_slice(&model.geom_pos()[g]);
            out.extend_from_slice(&model.geom_quat()[g]);
        }
    }
}

/// Where a pose is written: the model (static) or the data (free joint, mocap).
fn is_model_pose(s: &PoseSource) -> bool {
    matches!(
        s,
        PoseSource::Body(_) | PoseSource::BodyPosition(_) | PoseSource::GeomLocal(_)
    )
}

fn write_model_pose(
    model: &mut MjModel,
    source: &PoseSource,
    pos: [Option<f64>; 3],
    quat: Option<[f64; 4]>,
) {
    let set = |dst: &mut [f64; 3]| {
        for i in 0..3 {
            if let Some(v) = pos[i] {
                dst[i] = v;
            }
        }
    };
    match source {
        PoseSource::Body(n) | PoseSource::BodyPosition(n) => {
            let b = name_id(model, NameKind::Body, n).expect("resolved");
            set(&mut model.body_pos_mut()[b]);
            if let Some(q) = quat {
                model.body_quat_mut()[b] = q;
            }
        }
        PoseSource::GeomLocal(n) => {
            let g = name_id(model, NameKind::Geom, n).expect("resolved");
            set(&mut model.geom_pos_mut()[g]);
            if let Some(q) = quat {
                model.geom_quat_mut()[g] = q;
            }
        }
        _ => unreachable!("not a model pose"),
    }
}

fn write_data_pose(
    data: &mut MjData<Arc<MjModel>>,
    source: &PoseSource,
    pos: [Option<f64>; 3],
    quat: Option<[f64; 4]>,
) {
    let model = data.model_clone();
    match source {
        PoseSource::FreeJoint(n) => {
            let j = name_id(&model, NameKind::Joint, n).expect("resolved");
            let a = model.jnt_qposadr()[j] as usize;
            let d = model.jnt_dofadr()[j] as usize;
            let qpos = data.qpos_mut();
            for i in 0..3 {
                if let Some(v) = pos[i] {
                    qpos[a + i] = v;
                }
            }
            if let Some(q) = quat {
                qpos[a + 3..a + 7].copy_from_slice(&q);
            }
            data.qvel_mut()[d..d + 6].iter_mut().for_each(|v| *v = 0.0);
        }
        PoseSource::Mocap(n) => {
            let b = name_id(&model, NameKind::Body, n).expect("resolved");
            let m = model.body_mocapid()[b] as usize;
            for (dst, v) in data.mocap_pos_mut()[m].iter_mut().zip(pos) {
                if let Some(v) = v {
                    *dst = v;
                }
            }
            if let Some(q) = quat {
                data.mocap_quat_mut()[m] = q;
            }
        }
        _ => unreachable!("not a data pose"),
    }
}

impl TaskEnv {
    /// An environment at the scene's own object poses and dh = 0 (derived poses applied).
    pub fn new(scene: &Scene, spec: &TaskSpec, options: EnvOptions) -> Result<Self, SimError> {
        let state0 = Self::default_initial_state(scene, spec)?;
        Self::from_initial_state(scene, spec, &state0, options)
    }

    /// A state row holding the scene's own object poses and dh = 0 (the proprioceptive
    /// part is zeros: a restore does not read it).
    pub fn default_initial_state(scene: &Scene, spec: &TaskSpec) -> Result<Vec<f64>, SimError> {
        let model = &*scene.model;
        Self::check_names(spec, model)?;
        let data = MjData::new(scene.model.clone());
        let mut state = vec![0.0; spec.setup.proprio_dim()];
        for o in &spec.state.objects {
            read_pose(model, &data, &o.source, &mut state);
        }
        state.push(0.0);
        Ok(state)
    }

    /// A randomized initial state as the reference reset draws it: dh = U(0, 0.05)
    /// first, then each placement in spec order (two coordinates as
    /// `low + (high - low) * u`, then the yaw as `qz(U(-a, a)) * quat`, or the yaw first
    /// where the spec says so). `uniform` returns U(0, 1) draws.
    pub fn sample_initial_state(
        scene: &Scene,
        spec: &TaskSpec,
        uniform: &mut dyn FnMut() -> f64,
    ) -> Result<Vec<f64>, SimError> {
        let mut s = Self::default_initial_state(scene, spec)?;
        let layout = spec.state_layout();
        let model = &*scene.model;
        let dh = 0.05 * uniform();
        let top_site = name_id(model, NameKind::Site, &spec.table.top_site).expect("resolved");
        let table = name_id(model, NameKind::Body, &spec.table.body).expect("resolved");
        let table_top_z = model.body_pos()[table][2] + model.site_pos()[top_site][2] + dh;
        for p in &spec.placement {
            let f = layout
                .get(&format!("{}.pose", p.object))
                .expect("validated");
            let pose = &mut s[f.start..f.start + f.len];
            let yaw = |u: &mut dyn FnMut() -> f64| {
                (p.yaw_deg > 0.0).then(|| -p.yaw_deg + 2.0 * p.yaw_deg * u())
            };
            let mut angle = if p.yaw_first { yaw(uniform) } else { None };
            for (k, axis) in p.axes.iter().enumerate() {
                pose[axis.index()] = p.low[k] + (p.high[k] - p.low[k]) * uniform();
            }
            if !p.yaw_first {
                angle = yaw(uniform);
            }
            match p.z {
                ZRule::DhPlus(v) => pose[2] = v + dh,
                ZRule::TableTopPlus(v) => pose[2] = table_top_z + v,
                ZRule::Keep | ZRule::FromSource => {}
            }
            if pose.len() == 7 {
                let (sz, cz) = (angle.unwrap_or(0.0).to_radians() / 2.0).sin_cos();
                let q = p.quat;
                // qz * q, then normalized.
                let r = [
                    cz * q[0] - sz * q[3],
                    cz * q[1] - sz * q[2],
                    cz * q[2] + sz * q[1],
                    cz * q[3] + sz * q[0],
                ];
                let n = r.iter().map(|v| v * v).sum::<f64>().sqrt();
                for i in 0..4 {
                    pose[3 + i] = r[i] / n;
                }
            }
        }
        // Objects that follow another one (the iPad on its stand).
        for d in &spec.state.derived {
            let Some(o) = spec.state.objects.iter().find(|o| o.source == d.target) else {
                continue;
            };
            let f = layout.get(&format!("{}.pose", o.name)).expect("validated");
            let src = d.from.as_deref().map(|n| {
                let g = layout.get(&format!("{n}.pose")).expect("validated");
                [s[g.start], s[g.start + 1], s[g.start + 2]]
            });
            if let Some(src) = src {
                s[f.start] = src[0] + d.offset[0];
                s[f.start + 1] = src[1] + d.offset[1];
            }
            match d.z {
                ZRule::DhPlus(v) => s[f.start + 2] = v + dh,
                ZRule::TableTopPlus(v) => s[f.start + 2] = table_top_z + v,
                ZRule::FromSource => {
                    if let Some(src) = src {
                        s[f.start + 2] = src[2] + d.offset[2];
                    }
                }
                ZRule::Keep => {}
            }
            if let (Some(q), 7) = (d.quat, f.len) {
                s[f.start + 3..f.start + 7].copy_from_slice(&q);
            }
        }
        let last = s.len() - 1;
        s[last] = dh;
        Ok(s)
    }

    fn check_names(spec: &TaskSpec, model: &MjModel) -> Result<(), SimError> {
        let mut r = Resolver::new(model);
        for (k, n) in spec.scene_names() {
            r.id(k, &n);
        }
        r.finish(&format!("task '{}'", spec.id))
    }

    /// Builds the environment and restores a recorded initial state (`state[0]`): the
    /// table height offset dh (table, legs, the objects' recorded poses), the poses
    /// derived from them, the reset of the robot (home pose, target = TCP), then
    /// `mj_forward`, as the reference replay does.
    pub fn from_initial_state(
        scene: &Scene,
        spec: &TaskSpec,
        state0: &[f64],
        options: EnvOptions,
    ) -> Result<Self, SimError> {
        let layout = spec.state_layout();
        if state0.len() != layout.width() {
            return Err(SimError::Width {
                what: "state[0]",
                expected: layout.width(),
                found: state0.len(),
            });
        }
        Self::check_names(spec, &scene.model)?;
        let robot = Robot::new(&scene.model, spec.setup)?;
        let dh = state0[layout.width() - 1];

        // Model edits: physics options, table, static objects.
        let mut model = (*scene.model).clone();
        if options.disable_multiccd {
            model.opt_mut().disableflags |= MjtDisableBit::mjDSBL_MULTICCD as i32;
        }
        let table_top_z = raise_table(&mut model, spec, dh);
        let recorded = RecordedState {
            layout,
            state0,
            dh,
            table_top_z,
        };
        let derived: Vec<&DerivedPose> = spec
            .state
            .derived
            .iter()
            .filter(|d| !spec.state.objects.iter().any(|o| o.source == d.target))
            .collect();
        recorded.write_model_poses(&mut model, spec, &derived);

        // The robot's reset.
        let mut data = reset_robot(model, spec, &robot);
        let model = data.model_clone();

        // The recorded objects and the poses derived from them.
        recorded.write_data_poses(&mut data, spec, &derived);
        data.forward();

        let mut privileged = Vec::new();
        for o in &spec.state.objects {
            read_pose(&model, &data, &o.source, &mut privileged);
        }
        privileged.push(dh);
        let mut checker = SuccessChecker::new(spec, &model)?;
        checker.reset(&data);
        Ok(Self {
            spec: spec.clone(),
            data,
            robot,
            checker,
            subtasks: SubtaskTracker::new(spec),
            privileged,
            steps: 0,
        })
    }

    /// The DexJoCo state vector now: TCP poses (frame sensors on `attachment_site`),
    /// hand joints (sensors, or qpos where the task says so; float32 as recorded; the
    /// left hand in rf, mf, ff, th order), then the reset-time object poses and dh.
    pub fn state(&self) -> Vec<f64> {
        let sd = self.data.sensordata();
        let qpos = self.data.qpos();
        let mut s = Vec::with_capacity(self.spec.state.width);
        for arm in &self.robot.arms {
            s.extend_from_slice(&sd[arm.tcp_pos_sensor..arm.tcp_pos_sensor + 3]);
            s.extend_from_slice(&sd[arm.tcp_quat_sensor..arm.tcp_quat_sensor + 4]);
        }
        for arm in &self.robot.arms {
            for i in 0..HAND_DOF {
                let v = match self.spec.state.hand_source {
                    HandSource::Sensor => sd[arm.hand_sensors[i]],
                    HandSource::Qpos => qpos[arm.hand_qpos[i]],
                };
                s.push(f64::from(v as f32));
            }
        }
        s.extend_from_slice(&self.privileged);
        s
    }

    /// The environment state now ([`dexjoco_core::Episode::ENVIRONMENT_STATE`]): each of
    /// the task's [`TaskSpec::environment_poses`] (its state objects, then the poses its
    /// reset derives from them) read from the simulation as the reset reads them, then dh.
    /// At the reset its state objects' part equals the privileged part of [`Self::state`];
    /// it is what datasets record per frame and what `eval` sends a policy, from this one
    /// function.
    pub fn environment_state(&self) -> Vec<f64> {
        let model = self.data.model();
        let mut out = Vec::with_capacity(self.privileged.len() + 14);
        for (_, source) in self.spec.environment_poses() {
            read_pose(model, &self.data, source, &mut out);
        }
        out.push(*self.privileged.last().expect("dh"));
        out
    }

    /// Applies one recorded action (23 or 46 values): targets, 10 substeps, then the
    /// task's mechanics and conditions.
    pub fn step(&mut self, action: &[f64]) -> Result<Verdict, SimError> {
        let expected = self.spec.setup.action_dim();
        if action.len() != expected {
            return Err(SimError::Width {
                what: "action",
                expected,
                found: action.len(),
            });
        }
        let checker = &mut self.checker;
        self.robot
            .step(&mut self.data, action, |d| checker.after_substep(d));
        self.steps += 1;
        let verdict = self.checker.after_step(&mut self.data);
        self.subtasks.observe(&self.checker);
        Ok(verdict)
    }

    /// Where each of the task's subtasks ended so far (`None`: not yet).
    pub fn subtask_spans(&self) -> Vec<SubtaskSpan> {
        self.subtasks.spans()
    }

    /// Applies every action (the reference replay does not stop at success or failure)
    /// and records the state before each step.
    pub fn rollout(&mut self, actions: &FrameArray) -> Result<Rollout, SimError> {
        let mut states = Vec::with_capacity(actions.len());
        let mut verdicts = Vec::with_capacity(actions.len());
        for a in actions.rows() {
            states.push(self.state());
            verdicts.push(self.step(a)?);
        }
        let states = if states.is_empty() {
            FrameArray::zeros(0, self.spec.state.width)
        } else {
            FrameArray::from_rows(&states).map_err(|e| SimError::Rows(Box::new(e)))?
        };
        Ok(Rollout { states, verdicts })
    }

    /// Control steps taken.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// The task.
    pub fn spec(&self) -> &TaskSpec {
        &self.spec
    }

    /// The simulation data.
    pub fn data(&self) -> &MjData<Arc<MjModel>> {
        &self.data
    }

    /// The simulation data, mutable (for tests and planners).
    pub fn data_mut(&mut self) -> &mut MjData<Arc<MjModel>> {
        &mut self.data
    }

    /// The robot.
    pub fn robot(&self) -> &Robot {
        &self.robot
    }

    /// The success checker.
    pub fn checker(&self) -> &SuccessChecker {
        &self.checker
    }
}

/// The table edits of a height offset `dh` (the table body, its legs); returns the z of
/// the table top.
fn raise_table(model: &mut MjModel, spec: &TaskSpec, dh: f64) -> f64 {
    let table = name_id(model, NameKind::Body, &spec.table.body).expect("resolved");
    model.body_pos_mut()[table][2] = dh;
    for g in table_legs(model, spec, table) {
        match spec.table.leg_style {
            LegStyle::Extend => model.geom_size_mut()[g][1] += dh,
            LegStyle::Half => {
                model.geom_pos_mut()[g][2] -= dh / 2.0;
                model.geom_size_mut()[g][1] += dh / 2.0;
            }
        }
    }
    let top_site = name_id(model, NameKind::Site, &spec.table.top_site).expect("resolved");
    model.body_pos()[table][2] + model.site_pos()[top_site][2]
}

/// The table's leg geoms: the spec's named legs, and with `cylinder_legs` every visual
/// cylinder of the table body (each once).
fn table_legs(model: &MjModel, spec: &TaskSpec, table: usize) -> Vec<usize> {
    let mut legs: Vec<usize> = spec
        .table
        .legs
        .iter()
        .map(|leg| name_id(model, NameKind::Geom, leg).expect("resolved"))
        .collect();
    if spec.table.cylinder_legs {
        for g in 0..model.ffi().ngeom as usize {
            let visual = model.geom_contype()[g] == 0 && model.geom_conaffinity()[g] == 0;
            if model.geom_bodyid()[g] as usize == table
                && model.geom_type()[g] == mujoco_rs::mujoco_c::_mjtGeomBase::mjGEOM_CYLINDER
                && visual
                && !legs.contains(&g)
            {
                legs.push(g);
            }
        }
    }
    legs
}

/// The reset of the robot on the edited model: home pose, the task's joint values, arm
/// targets at the TCPs, and the task's hand pose when it has one.
fn reset_robot(model: MjModel, spec: &TaskSpec, robot: &Robot) -> MjData<Arc<MjModel>> {
    let mut data = MjData::new(Arc::new(model));
    data.reset();
    let thumb = if spec.reset.exact_thumb {
        THUMB_HOME
    } else {
        f64::from(THUMB_HOME as f32)
    };
    for arm in &robot.arms {
        let qpos = data.qpos_mut();
        for i in 0..ARM_HOME.len() {
            qpos[arm.qpos[i]] = ARM_HOME[i];
        }
        for &a in &arm.hand_qpos {
            qpos[a] = 0.0;
        }
        qpos[arm.thumb_base_qpos] = thumb;
    }
    let model = data.model_clone();
    for (joint, value) in &spec.reset.joint_qpos {
        let j = name_id(&model, NameKind::Joint, joint).expect("resolved");
        data.qpos_mut()[model.jnt_qposadr()[j] as usize] = *value;
    }
    data.forward();
    for arm in &robot.arms {
        let sd = data.sensordata();
        let pos: [f64; 3] = sd[arm.tcp_pos_sensor..arm.tcp_pos_sensor + 3]
            .try_into()
            .expect("3");
        let quat: [f64; 4] = sd[arm.tcp_quat_sensor..arm.tcp_quat_sensor + 4]
            .try_into()
            .expect("4");
        data.mocap_pos_mut()[arm.mocap] = pos;
        if spec.reset.arm_target == ArmTargetInit::Pose {
            data.mocap_quat_mut()[arm.mocap] = quat;
        }
    }
    if let Some(hand) = &spec.reset.hand_qpos {
        for arm in &robot.arms {
            for (&act, &v) in arm.hand_actuators.iter().zip(hand) {
                // The reset pose is given in the action order; write it by actuator.
                let joint = model.actuator_trnid()[act][0] as usize;
                let a = model.jnt_qposadr()[joint] as usize;
                data.qpos_mut()[a] = v;
            }
        }
        data.forward();
        for arm in &robot.arms {
            for (&act, &v) in arm.hand_actuators.iter().zip(hand) {
                data.ctrl_mut()[act] = v;
            }
        }
    }
    data
}

/// A recorded initial state (`state[0]`) read by its task's layout, with the table top
/// its objects are placed on.
struct RecordedState<'a> {
    layout: ArrayLayout,
    state0: &'a [f64],
    dh: f64,
    table_top_z: f64,
}

impl RecordedState<'_> {
    /// The recorded pose (or position) of a state object.
    fn object(&self, name: &str) -> &[f64] {
        let f = self.layout.get(&format!("{name}.pose")).expect("validated");
        &self.state0[f.start..f.start + f.len]
    }

    /// The recorded position and, for a full pose, orientation of a state object, as
    /// written to the scene.
    fn object_pose(&self, name: &str) -> ([Option<f64>; 3], Option<[f64; 4]>) {
        let v = self.object(name);
        let pos = [Some(v[0]), Some(v[1]), Some(v[2])];
        let quat = (v.len() == 7).then(|| [v[3], v[4], v[5], v[6]]);
        (pos, quat)
    }

    /// The position of a derived pose: offsets from its source object, z by its rule.
    fn derived_position(&self, d: &DerivedPose) -> [Option<f64>; 3] {
        let src = d.from.as_deref().map(|name| self.object(name));
        let xy = |i: usize| src.map(|s| s[i] + d.offset[i]);
        let z = match d.z {
            ZRule::Keep => None,
            ZRule::DhPlus(v) => Some(v + self.dh),
            ZRule::TableTopPlus(v) => Some(self.table_top_z + v),
            ZRule::FromSource => src.map(|s| s[2] + d.offset[2]),
        };
        [xy(0), xy(1), z]
    }

    /// Writes the recorded and derived poses kept in the model (static objects).
    fn write_model_poses(&self, model: &mut MjModel, spec: &TaskSpec, derived: &[&DerivedPose]) {
        for o in &spec.state.objects {
            if is_model_pose(&o.source) {
                let (pos, quat) = self.object_pose(&o.name);
                write_model_pose(
                    model,
                    &o.source,
                    pos,
                    if o.restore_position_only { None } else { quat },
                );
            }
        }
        for d in derived {
            if is_model_pose(&d.target) {
                write_model_pose(model, &d.target, self.derived_position(d), d.quat);
            }
        }
    }

    /// Writes the recorded and derived poses kept in the data (free joints, mocap).
    fn write_data_poses(
        &self,
        data: &mut MjData<Arc<MjModel>>,
        spec: &TaskSpec,
        derived: &[&DerivedPose],
    ) {
        for o in &spec.state.objects {
            if !is_model_pose(&o.source) {
                let (pos, quat) = self.object_pose(&o.name);
                write_data_pose(
                    data,
                    &o.source,
                    pos,
                    if o.restore_position_only { None } else { quat },
                );
            }
        }
        for d in derived {
            if !is_model_pose(&d.target) {
                write_data_pose(data, &d.target, self.derived_position(d), d.quat);
            }
        }
    }
}
