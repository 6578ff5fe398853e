//! Scripted demonstrations: plans that use privileged state (object poses read from the
//! simulation) to move the OSC target and the hand, recorded in the DexJoCo raw layout.
//!
//! A [`Recorder`] steps a [`TaskEnv`], keeping each frame's state and action; the
//! per-task planners are built from its motions (straight target moves with a fixed
//! orientation and hand pose, holds, guarded moves that stop on a condition).

use std::collections::BTreeMap;

use dexjoco_core::{Episode, FrameArray, HAND_DOF, NameKind, TaskSpec};

use crate::checker::name_id;
use crate::env::{EnvOptions, TaskEnv};
use crate::error::SimError;
use crate::scene::Scene;

/// Steps an environment and records frames (state before the step, action applied).
#[derive(Debug)]
pub struct Recorder {
    env: TaskEnv,
    states: Vec<Vec<f64>>,
    actions: Vec<Vec<f64>>,
    success_at: Option<usize>,
    failed: bool,
}

impl Recorder {
    /// Records on an environment.
    pub fn new(env: TaskEnv) -> Self {
        Self {
            env,
            states: Vec::new(),
            actions: Vec::new(),
            success_at: None,
            failed: false,
        }
    }

    /// The environment.
    pub fn env(&self) -> &TaskEnv {
        &self.env
    }

    /// Steps one action; stops recording (returns false) once the task succeeded or
    /// failed, or the step cap is reached.
    pub fn step(&mut self, action: Vec<f64>) -> Result<bool, SimError> {
        if self.done() {
            return Ok(false);
        }
        self.states.push(self.env.state());
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
    /// action order); other arms hold. Stops early when `stop` says so.
    pub fn move_to(
        &mut self,
        arm: usize,
        to: [f64; 3],
        quat: [f64; 4],
        hand: [f64; HAND_DOF],
        steps: usize,
        mut stop: impl FnMut(&TaskEnv) -> bool,
    ) -> Result<bool, SimError> {
        let from = self.env.targets()[arm].0;
        for k in 1..=steps.max(1) {
            let t = k as f64 / steps.max(1) as f64;
            let p = [
                from[0] + (to[0] - from[0]) * t,
                from[1] + (to[1] - from[1]) * t,
                from[2] + (to[2] - from[2]) * t,
            ];
            let mut a = vec![0.0; self.env.spec().setup.action_dim()];
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
    ) -> Result<(), SimError> {
        let at = self.env.targets()[arm].0;
        for _ in 0..steps {
            let mut a = vec![0.0; self.env.spec().setup.action_dim()];
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

    /// The recorded episode (frames up to and including the success step).
    pub fn into_episode(self, id: &str) -> Result<Episode, SimError> {
        let spec = self.env.spec().clone();
        let bad = |e: dexjoco_core::CoreError| SimError::Spec(e.to_string());
        let n = self.actions.len();
        let mut arrays = BTreeMap::new();
        arrays.insert(
            Episode::ACTION.to_owned(),
            FrameArray::from_rows(&self.actions).map_err(bad)?,
        );
        arrays.insert(
            Episode::STATE.to_owned(),
            FrameArray::from_rows(&self.states).map_err(bad)?,
        );
        arrays.insert(
            Episode::TIMESTAMP.to_owned(),
            Episode::regular_timestamps(n, 30.0),
        );
        let mut ep = Episode {
            id: id.to_owned(),
            task: spec.id.clone(),
            prompt: spec.prompt.clone(),
            fps: 30.0,
            arrays,
            cameras: Vec::new(),
        };
        ep.compute_action_rotvec(spec.setup).map_err(bad)?;
        Ok(ep)
    }
}

fn geom_of_body(env: &TaskEnv, body: &str) -> Option<usize> {
    let m = env.data().model();
    let b = name_id(m, NameKind::Body, body)?;
    (0..m.ffi().ngeom as usize)
        .find(|&g| m.geom_bodyid()[g] as usize == b && m.geom_contype()[g] != 0)
}

/// Hand targets (ff, mf, rf, th) with straight fingers and the thumb at home.
const FLAT_HAND: [f64; HAND_DOF] = [
    0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.263, 0.0, 0.0, 0.0,
];
/// Index finger curled to point down, the others tucked away, the thumb at home.
const POINT_HAND: [f64; HAND_DOF] = [
    0.0, 1.3, 0.9, 0.3, 0.0, 1.6, 1.7, 1.6, 0.0, 1.6, 1.7, 1.6, 0.263, 0.0, 0.0, 0.0,
];

/// A scripted click_mouse demonstration from an initial state: push the mouse's side
/// with the ring-finger edge of the flat hand toward -y onto the pad, lift, point the
/// index finger down above the left button and lower it until the click registers,
/// then hold still until the task succeeds.
pub fn click_mouse_demo(
    scene: &Scene,
    spec: &TaskSpec,
    state0: &[f64],
    id: &str,
) -> Result<Episode, SimError> {
    if spec.id != "click_mouse" {
        return Err(SimError::Spec(format!(
            "click_mouse_demo cannot plan '{}'",
            spec.id
        )));
    }
    let env = TaskEnv::from_initial_state(scene, spec, state0, EnvOptions::default())?;
    let layout = spec.state_layout();
    let mouse = layout
        .get("mouse.pose")
        .expect("click_mouse has a mouse")
        .start;
    let (mx, my) = (state0[mouse], state0[mouse + 1]);
    let dh = state0[layout.width() - 1];
    let table = 0.92 + dh;
    let s = env.state();
    let quat = [s[3], s[4], s[5], s[6]];
    let mut rec = Recorder::new(env);
    let never = |_: &TaskEnv| false;

    // Push: ring-finger edge (about 0.067 m toward -y from the TCP) just beside the
    // mouse's +y side, fingers over its length, 5 cm above the table.
    let x = mx - 0.10;
    let y0 = my + 0.16;
    let y1 = my - 0.25 + 0.12;
    rec.move_to(0, [x, y0, table + 0.20], quat, FLAT_HAND, 70, never)?;
    rec.move_to(0, [x, y0, table + 0.05], quat, FLAT_HAND, 50, never)?;
    rec.hold(0, quat, FLAT_HAND, 20)?;
    rec.move_to(0, [x, y1, table + 0.05], quat, FLAT_HAND, 140, never)?;
    rec.hold(0, quat, FLAT_HAND, 20)?;
    rec.move_to(0, [x, y1 + 0.04, table + 0.20], quat, FLAT_HAND, 45, never)?;

    // Curl the index finger down in the air and measure where its tip is.
    rec.hold(0, quat, POINT_HAND, 30)?;
    let tip =
        geom_of_body(rec.env(), "ff_tip").ok_or_else(|| SimError::Spec("no ff_tip geom".into()))?;
    let button =
        geom_of_body(rec.env(), "link_0").ok_or_else(|| SimError::Spec("no button geom".into()))?;
    let d = rec.env().data();
    let tcp = rec.env().robot().tcp_pose(d, &rec.env().robot().arms[0]).0;
    let t = d.geom_xpos()[tip];
    let off = [t[0] - tcp[0], t[1] - tcp[1], t[2] - tcp[2]];
    let b = d.geom_xpos()[button];
    let above = [b[0] - off[0], b[1] - off[1], table + 0.12 - off[2]];
    rec.move_to(0, above, quat, POINT_HAND, 60, never)?;
    rec.hold(0, quat, POINT_HAND, 20)?;
    // Guarded press: lower until the display turns blue.
    let blue = |e: &TaskEnv| e.checker().value("display_blue") == Some(true);
    let low = [above[0], above[1], above[2] - 0.10];
    rec.move_to(0, low, quat, POINT_HAND, 70, blue)?;
    let at = rec.env().state();
    let up = [at[0], at[1], at[2] + 0.02];
    rec.move_to(0, up, quat, POINT_HAND, 10, never)?;
    rec.hold(0, quat, POINT_HAND, 40)?;
    rec.into_episode(id)
}

/// Hamilton product a * b of wxyz quaternions.
fn qmul(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ]
}

/// Straight index finger, middle and ring curled away, thumb at home.
const INDEX_HAND: [f64; HAND_DOF] = [
    0.0, 0.0, 0.0, 0.0, 0.0, 1.6, 1.7, 1.6, 0.0, 1.6, 1.7, 1.6, 0.263, 0.0, 0.0, 0.0,
];

/// A scripted bimanual_unlock_ipad demonstration with the right hand alone: the hand
/// pitched 30 degrees down so the straight index finger is perpendicular to the screen;
/// each digit of the password is pressed by a guarded move along the screen normal
/// that stops as soon as the digit registers, then backs off.
pub fn unlock_ipad_demo(
    scene: &Scene,
    spec: &TaskSpec,
    state0: &[f64],
    id: &str,
) -> Result<Episode, SimError> {
    if spec.id != "bimanual_unlock_ipad" {
        return Err(SimError::Spec(format!(
            "unlock_ipad_demo cannot plan '{}'",
            spec.id
        )));
    }
    let password = spec
        .nodes
        .values()
        .find_map(|n| match n {
            dexjoco_core::Node::Keypad { password, .. } => Some(password.clone()),
            _ => None,
        })
        .ok_or_else(|| SimError::Spec("no keypad".into()))?;
    let env = TaskEnv::from_initial_state(scene, spec, state0, EnvOptions::default())?;
    let s = env.state();
    let (h, c) = (15f64.to_radians().sin(), 15f64.to_radians().cos());
    let quat = qmul([c, 0.0, h, 0.0], [s[3], s[4], s[5], s[6]]);
    let mut rec = Recorder::new(env);
    let never = |_: &TaskEnv| false;

    // Screen normal (out of the screen) = the iPad body's z axis.
    let (normal, ipad_pos) = {
        let d = rec.env().data();
        let b = name_id(d.model(), NameKind::Body, "ipad_body")
            .ok_or_else(|| SimError::Spec("no ipad_body".into()))?;
        let m = d.xmat()[b];
        ([m[2], m[5], m[8]], d.xpos()[b])
    };
    // Turn the hand and measure the index fingertip relative to the TCP.
    let start = [ipad_pos[0] - 0.25, ipad_pos[1] - 0.05, ipad_pos[2] + 0.25];
    rec.move_to(0, start, quat, INDEX_HAND, 80, never)?;
    rec.hold(0, quat, INDEX_HAND, 40)?;
    let offset = {
        let e = rec.env();
        let d = e.data();
        let tip = name_id(d.model(), NameKind::Geom, "fingertip_ff_right")
            .ok_or_else(|| SimError::Spec("no fingertip".into()))?;
        let tcp = e.robot().tcp_pose(d, &e.robot().arms[0]).0;
        let t = d.geom_xpos()[tip];
        [t[0] - tcp[0], t[1] - tcp[1], t[2] - tcp[2]]
    };
    let along = |p: [f64; 3], k: f64| {
        [
            p[0] + normal[0] * k,
            p[1] + normal[1] * k,
            p[2] + normal[2] * k,
        ]
    };
    for (i, digit) in password.iter().enumerate() {
        let button = {
            let d = rec.env().data();
            let g = name_id(d.model(), NameKind::Geom, &format!("btn{digit}_cyl"))
                .ok_or_else(|| SimError::Spec(format!("no button {digit}")))?;
            d.geom_xpos()[g]
        };
        let tcp_at = |k: f64| {
            let p = along(button, k);
            [p[0] - offset[0], p[1] - offset[1], p[2] - offset[2]]
        };
        rec.move_to(0, tcp_at(0.04), quat, INDEX_HAND, 60, never)?;
        rec.hold(0, quat, INDEX_HAND, 25)?;
        let entered = move |e: &TaskEnv| {
            e.checker().output("keypad", "index").unwrap_or(0.0) as usize > i
                || e.checker().value("keypad") == Some(true)
        };
        if !rec.move_to(0, tcp_at(-0.005), quat, INDEX_HAND, 23, entered)? {
            let here = rec.env().targets()[0].0;
            rec.move_to(0, here, quat, INDEX_HAND, 60, entered)?;
        }
        rec.move_to(0, tcp_at(0.04), quat, INDEX_HAND, 15, never)?;
    }
    rec.hold(0, quat, INDEX_HAND, 30)?;
    rec.into_episode(id)
}
