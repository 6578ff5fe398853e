//! The bimanual_photograph planner: the left hand grips the camera by its lens (a pinch
//! across the lens), lifts it and turns it so the lens faces the logo, levelled in a
//! closed loop; the right index finger then presses the shutter with a guarded move.

use super::kin::{self, V3};
use super::{CLOSE, Goal, OPEN, POINT_HAND as POINT, Planned, Recorder, debug};
use crate::PlanError;
use dexjoco_sim::TaskEnv;

/// Where the lens goes, from the TCP along the thumb-to-fingers axis.
const GRIP_X: f64 = 0.075;
/// The TCP above the lens's axis while pinching.
const GRIP_UP: f64 = 0.13;
/// Where along the lens (camera frame y) the pinch closes.
const GRIP_Y: f64 = 0.08;
/// Closed-loop aiming rounds.
const AIM_ROUNDS: usize = 3;
const RIGHT: usize = 0;
const LEFT: usize = 1;
/// Extra yaw of the left hand (mirrored) for the pinch.
const LEFT_YAW: f64 = 0.0;

/// The camera's optical axis (world) and the point in front of its lens.
fn optics(e: &TaskEnv) -> Result<(V3, V3), PlanError> {
    let m = kin::geom(e, "camera_axis_z")?.1;
    Ok(([m[2], m[5], m[8]], kin::site(e, "view_direction_site")?))
}

/// Plans bimanual_photograph on an environment just restored from its initial state.
pub(crate) fn plan(env: TaskEnv, id: &str) -> Result<Planned, PlanError> {
    let s = env.state();
    let right_home = [s[3], s[4], s[5], s[6]];
    let left_home = [s[10], s[11], s[12], s[13]];
    let mut rec = Recorder::new(env);
    let e = rec.env();
    let (lens_axis, _) = optics(e)?;
    let lens = kin::geom(e, "camera_lens_collision")?;
    let along = kin::horizontal(lens_axis);
    // The pinch across the lens: D perpendicular to it, horizontal.
    let d = [along[1], -along[0], 0.0];
    let yaw = d[1].atan2(d[0]) + LEFT_YAW;
    let d = [yaw.cos(), yaw.sin(), 0.0];
    let q = kin::qmul(kin::yaw(yaw), left_home);
    let grip = kin::add(lens.0, kin::scale(along, GRIP_Y - 0.055));
    let mut at = kin::sub(grip, kin::scale(d, GRIP_X));
    at[2] = grip[2] + GRIP_UP;
    rec.go(LEFT, kin::add(at, [0.0, 0.0, 0.1]), q, OPEN, 90)?;
    rec.settle(0.005, 40)?;
    rec.go(LEFT, at, q, OPEN, 40)?;
    rec.settle(0.004, 40)?;
    rec.go(LEFT, at, q, CLOSE, 25)?;
    rec.wait(15)?;
    show(&rec, "gripped");
    rec.snap(LEFT, "camera_gripped");
    let up = kin::add(at, [0.0, 0.0, 0.2]);
    rec.go(LEFT, up, q, CLOSE, 60)?;
    rec.phase("grasp_camera");
    rec.wait(20)?;
    show(&rec, "lifted");
    rec.snap(LEFT, "camera_lifted");
    // Aim: turn the hand so the optical axis points at +x (the rotation that takes the
    // measured axis there, about the TCP), and move the point in front of the lens to the
    // middle of the target region; a few closed-loop rounds.
    aim_camera(&mut rec)?;
    rec.phase("aim_camera");
    rec.snap(LEFT, "camera_aimed");
    // The right index finger over the shutter, then a guarded press.
    let start = kin::add(rec.target(RIGHT).0, [0.0, 0.0, 0.05]);
    rec.go(RIGHT, start, right_home, POINT, 40)?;
    rec.wait(20)?;
    let tip = {
        let e = rec.env();
        let g = super::geom_of_body(e, "ff_tip_right")
            .ok_or_else(|| PlanError::lacks("collision geom of body", "ff_tip_right"))?;
        kin::sub(e.data().geom_xpos()[g], kin::tcp(e, RIGHT).0)
    };
    let cap = kin::geom(rec.env(), "camera_body_top_cap")?.0;
    let above = kin::sub(kin::add(cap, [0.0, 0.0, 0.05]), tip);
    rec.go(
        RIGHT,
        kin::add(above, [0.0, 0.0, 0.05]),
        right_home,
        POINT,
        90,
    )?;
    rec.go(RIGHT, above, right_home, POINT, 30)?;
    rec.settle(0.003, 60)?;
    show(&rec, "over the shutter");
    let pressed = |e: &TaskEnv| e.checker().value("shutter") == Some(true);
    let low = kin::add(above, [0.0, 0.0, -0.08]);
    rec.go_many(&[Goal::new(RIGHT, low, right_home, POINT)], 80, pressed)?;
    rec.phase("press_shutter");
    show(&rec, "pressed");
    rec.wait(10)?;
    rec.finish(id)
}

/// In debug mode, prints the optical axis, the view point and the success nodes after
/// a phase.
fn show(rec: &Recorder, what: &str) {
    if debug() {
        let e = rec.env();
        let (a, v) = optics(e).unwrap_or_default();
        eprintln!(
            "{what}: step {} axis {a:.2?} view {v:.3?} aimed {:?} level {:?} shutter {:?}",
            e.steps(),
            e.checker().value("aimed"),
            e.checker().value("level"),
            e.checker().value("shutter"),
        );
    }
}

/// Aims the gripped camera in closed-loop rounds: turns the left hand so the optical axis
/// points at +x and moves the view point to the middle of the target region.
fn aim_camera(rec: &mut Recorder) -> Result<(), PlanError> {
    let region = kin::geom(rec.env(), "photograph_target_region_visual")?.0;
    for k in 0..AIM_ROUNDS {
        let e = rec.env();
        let (a, v) = optics(e)?;
        let c = [0.0, a[2], -a[1]]; // a x (+x)
        let n = kin::norm(c);
        let (mut p, mut qq) = rec.target(LEFT);
        if n > 1e-6 {
            let angle = a[0].clamp(-1.0, 1.0).acos();
            let turn = kin::axis_angle(kin::scale(c, 1.0 / n), angle);
            qq = kin::qmul(turn, qq);
            // The view point turns with the hand about the TCP.
            let tcp = kin::tcp(e, LEFT).0;
            let moved = kin::add(tcp, kin::mulv(&kin::qmat(turn), kin::sub(v, tcp)));
            p = kin::add(p, kin::sub(region, moved));
        } else {
            p = kin::add(p, kin::sub(region, v));
        }
        rec.go(LEFT, p, qq, CLOSE, if k == 0 { 120 } else { 40 })?;
        rec.settle(0.003, 60)?;
        show(rec, &format!("aim {k}"));
    }
    Ok(())
}
