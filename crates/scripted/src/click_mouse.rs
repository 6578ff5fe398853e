//! The click_mouse planner: push the mouse onto its pad with the ring-finger edge of the
//! flat hand, then press the left button with a curled index finger.

use dexjoco_core::{Episode, TaskSpec};

use super::{FLAT_HAND, POINT_HAND, Planned, Recorder, geom_of_body};
use crate::PlanError;
use dexjoco_sim::Scene;
use dexjoco_sim::{EnvOptions, TaskEnv};

/// A scripted click_mouse demonstration from an initial state: push the mouse's side
/// with the ring-finger edge of the flat hand toward -y onto the pad, lift, point the
/// index finger down above the left button and lower it until the click registers,
/// then hold still until the task succeeds.
pub fn click_mouse_demo(
    scene: &Scene,
    spec: &TaskSpec,
    state0: &[f64],
    id: &str,
) -> Result<Episode, PlanError> {
    if spec.id != "click_mouse" {
        return Err(PlanError::WrongTask {
            planner: "click_mouse_demo",
            task: spec.id.clone(),
        });
    }
    let env = TaskEnv::from_initial_state(scene, spec, state0, EnvOptions::default())?;
    Ok(plan(env, id)?.episode)
}

/// Plans click_mouse on an environment just restored from its initial state.
pub(crate) fn plan(env: TaskEnv, id: &str) -> Result<Planned, PlanError> {
    let state0 = env.state();
    let layout = env.spec().state_layout();
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
    rec.phase("push_mouse");
    rec.hold(0, quat, FLAT_HAND, 20)?;
    rec.move_to(0, [x, y1 + 0.04, table + 0.20], quat, FLAT_HAND, 45, never)?;

    // Curl the index finger down in the air and measure where its tip is.
    rec.hold(0, quat, POINT_HAND, 30)?;
    let tip = geom_of_body(rec.env(), "ff_tip")
        .ok_or_else(|| PlanError::lacks("collision geom of body", "ff_tip"))?;
    let button = geom_of_body(rec.env(), "link_0")
        .ok_or_else(|| PlanError::lacks("collision geom of body", "link_0"))?;
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
    rec.phase("click");
    rec.finish(id)
}
