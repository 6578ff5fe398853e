//! The bimanual_unlock_ipad planner: the right index finger presses the password's
//! digits on the screen with guarded moves along the screen normal.

use dexjoco_core::{Episode, NameKind, TaskSpec};

use super::hands::INDEX_HAND;
use super::kin::qmul;
use super::{Planned, Recorder, Variant};
use crate::PlanError;
use dexjoco_sim::Scene;
use dexjoco_sim::name_id;
use dexjoco_sim::{EnvOptions, TaskEnv};

/// A scripted bimanual_unlock_ipad demonstration with the right hand alone: the hand
/// pitched 30 degrees down so the straight index finger is perpendicular to the screen;
/// each digit of the password is pressed by a guarded move along the screen normal
/// that stops as soon as the digit registers, then backs off.
pub fn unlock_ipad_demo(
    scene: &Scene,
    spec: &TaskSpec,
    state0: &[f64],
    id: &str,
) -> Result<Episode, PlanError> {
    if spec.id != "bimanual_unlock_ipad" {
        return Err(PlanError::WrongTask {
            planner: "unlock_ipad_demo",
            task: spec.id.clone(),
        });
    }
    let env = TaskEnv::from_initial_state(scene, spec, state0, EnvOptions::default())?;
    Ok(plan(env, id, Variant::Demo)?.episode)
}

/// Plans bimanual_unlock_ipad on an environment just restored from its initial state;
/// the wrong plan enters the password's first digit, then a wrong one.
pub(crate) fn plan(env: TaskEnv, id: &str, variant: Variant) -> Result<Planned, PlanError> {
    let mut password = env
        .spec()
        .nodes
        .values()
        .find_map(|n| match n {
            dexjoco_core::Node::Keypad { password, .. } => Some(password.clone()),
            _ => None,
        })
        .ok_or_else(|| PlanError::SpecLacks {
            task: env.spec().id.clone(),
            what: "keypad node",
        })?;
    if variant == Variant::Wrong {
        let wrong = (password[1] + 1) % 10;
        password.truncate(1);
        password.push(wrong);
    }
    let s = env.state();
    let (h, c) = (15f64.to_radians().sin(), 15f64.to_radians().cos());
    let quat = qmul([c, 0.0, h, 0.0], [s[3], s[4], s[5], s[6]]);
    let mut rec = Recorder::new(env);
    let never = |_: &TaskEnv| false;

    // Screen normal (out of the screen) = the iPad body's z axis.
    let (normal, ipad_pos) = {
        let d = rec.env().data();
        let b = name_id(d.model(), NameKind::Body, "ipad_body")
            .ok_or_else(|| PlanError::lacks("body", "ipad_body"))?;
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
            .ok_or_else(|| PlanError::lacks("geom", "fingertip_ff_right"))?;
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
                .ok_or_else(|| PlanError::lacks("geom of keypad button", digit.to_string()))?;
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
        if i == 0 {
            rec.phase("press_first_digit");
        }
    }
    rec.hold(0, quat, INDEX_HAND, 30)?;
    if variant == Variant::Demo {
        rec.phase("enter_password");
    }
    rec.finish(id)
}
