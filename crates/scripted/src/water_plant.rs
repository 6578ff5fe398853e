//! The water_plant planner: hold the spray bottle from above, middle and ring fingers on
//! the front of the body and the thumb on its back (a pinch near the centre of mass),
//! the index finger straight along the bottle over the trigger lever on the spray head;
//! carry the nozzle beside the plant, then curl the index finger to press the lever
//! down and keep it pressed.
//!
//! A sprayer whose trigger hangs in front of the body below the spray head (the
//! reference bottle: measured from the trigger hinge's place in the bottle's frame) has
//! its trigger face 12.8 cm from the back of the body, beyond what the hand spans from a
//! thumb on the back: the same grasp carries it beside the plant and sets it down there,
//! then the hand rests palm-down on the body with the index and middle fingers hooked in
//! front of the trigger (the middle one near its free end) and curls them to pull it.

use super::hands::water_plant::{AIM, HOLD, OPEN, PRESS, PULL};
use super::kin::{self, V3};
use super::{Goal, Planned, Recorder, Variant, debug};
use crate::PlanError;
use dexjoco_sim::TaskEnv;

/// Where the bottle's axis goes, from the TCP (home orientation, world axes): the
/// thumb closes on its back at x ~ 0.04, the fingers on its front.
const GRIP: V3 = [GRIP_X, 0.0, 0.0];
const GRIP_X: f64 = 0.075;
/// The TCP's height above the table while holding.
const TCP_Z: f64 = 0.16;
/// The pinch in the bottle's frame: along it (y, toward the head) and across it (z).
const GRIP_Y: f64 = -0.05;

/// Plans water_plant on an environment just restored from its initial state; the wrong
/// plan pulls the trigger right after lifting the bottle (a front trigger: after setting
/// it down again), far from the plant.
pub(crate) fn plan(env: TaskEnv, id: &str, variant: Variant) -> Result<Planned, PlanError> {
    let s = env.state();
    let home = [s[3], s[4], s[5], s[6]];
    let mut rec = Recorder::new(env);
    rec.wait(20)?;
    let e = rec.env();
    let (bp, m) = kin::body(e, "link_2")?;
    let front = [m[2], m[5], m[8]];
    // With the hand yawed to the bottle's front (+z) the grasp (measured) has the middle
    // and ring fingers on the front, the thumb on the back and the straight index finger
    // along the bottle toward its head, over the trigger lever.
    let yaw = front[1].atan2(front[0]);
    let q = kin::qmul(kin::yaw(yaw), home);
    let table = kin::site(e, "table_top")?[2];
    let front_kind = front_trigger(e)?;
    let rest_z = bp[2];
    let grip = kin::add(bp, kin::mulv(&m, [0.0, GRIP_Y, -0.01]));
    let mut at = kin::sub(grip, kin::mulv(&kin::qmat(kin::yaw(yaw)), GRIP));
    at[2] = table + TCP_Z;
    let show = |rec: &Recorder, what: &str| {
        if debug() {
            let e = rec.env();
            eprintln!(
                "{what}: step {} trigger {:.3} ref {:.3?} bottle {:.3?}",
                e.steps(),
                kin::joint(e, "joint_0").unwrap_or(f64::NAN),
                kin::site(e, "ref_point").unwrap_or_default(),
                kin::body(e, "link_2").map(|b| b.0).unwrap_or_default(),
            );
        }
    };
    rec.go(0, kin::add(at, [0.0, 0.0, 0.12]), q, OPEN, 90)?;
    rec.settle(0.004, 60)?;
    rec.go(0, at, q, OPEN, 50)?;
    rec.settle(0.002, 60)?;
    rec.snap(0, "water_open");
    rec.go(0, at, q, HOLD, 30)?;
    rec.wait(20)?;
    show(&rec, "held");
    frame_debug(&rec);
    rec.snap(0, "water_held");
    let up = kin::add(at, [0.0, 0.0, 0.15]);
    rec.go(0, up, q, HOLD, 80)?;
    rec.settle(0.004, 60)?;
    show(&rec, "lifted");
    rec.phase("grasp_spray");
    let latched = |e: &TaskEnv| e.checker().value("trigger") == Some(true);
    if variant == Variant::Wrong && front_kind {
        // Set down where it was lifted, far from the plant, and pull there.
        return place_and_press(rec, home, rest_z, [up[0], up[1]], id, variant);
    }
    if variant == Variant::Wrong {
        rec.go_many(&[Goal::new(0, up, q, PULL)], 60, latched)?;
        rec.wait(30)?;
        return rec.finish(id);
    }
    // Nozzle 0.15 m from the plant's axis on the robot's side, at the plant's height.
    let e = rec.env();
    let nozzle = kin::sub(kin::site(e, "ref_point")?, kin::tcp(e, 0).0);
    let plant = kin::body(e, "plant")?.0;
    let target = [plant[0] - 0.15, plant[1], plant[2] + 0.02];
    if front_kind {
        let to = kin::sub(target, nozzle);
        return place_and_press(rec, home, rest_z, [to[0], to[1]], id, variant);
    }
    let mid = kin::scale(kin::add(kin::add(up, kin::sub(target, nozzle)), up), 0.5);
    rec.go(0, [mid[0], mid[1], up[2] + 0.05], q, HOLD, 90)?;
    rec.go(0, kin::sub(target, nozzle), q, HOLD, 90)?;
    rec.settle(0.004, 80)?;
    show(&rec, "over the plant");
    rec.phase("aim_spray");
    frame_debug(&rec);
    // Guarded press: curl the index finger until the trigger latches, then keep it there.
    let goal = Goal::new(0, kin::sub(target, nozzle), q, PULL);
    rec.go_many(&[goal], 60, latched)?;
    show(&rec, "pulled");
    frame_debug(&rec);
    rec.snap(0, "water_pulled");
    rec.wait(80)?;
    show(&rec, "end");
    rec.phase("water");
    rec.finish(id)
}

/// Diagnostics: the hand joints and the fingertips in the bottle's frame.
fn frame_debug(rec: &Recorder) {
    if let Err(e) = frame_debug_inner(rec) {
        eprintln!("  ({e})");
    }
}

fn frame_debug_inner(rec: &Recorder) -> Result<(), PlanError> {
    if debug() {
        let e = rec.env();
        let (bp, m) = kin::body(e, "link_2")?;
        let local = |w: V3| {
            let d = kin::sub(w, bp);
            [
                m[0] * d[0] + m[3] * d[1] + m[6] * d[2],
                m[1] * d[0] + m[4] * d[1] + m[7] * d[2],
                m[2] * d[0] + m[5] * d[1] + m[8] * d[2],
            ]
        };
        let st = e.state();
        eprintln!(
            "  hand ff {:.2?} mf {:.2?} th {:.2?}",
            &st[7..11],
            &st[11..15],
            &st[19..23]
        );
        eprintln!(
            "  trigger (bottle frame) {:.3?}",
            local(kin::geom(e, "spray_trigger")?.0)
        );
        for b in ["ff_tip", "mf_tip", "rf_tip", "th_tip"] {
            if let Some(g) = super::geom_of_body(e, b) {
                eprintln!(
                    "  {b} (bottle frame) {:.3?}",
                    local(e.data().geom_xpos()[g])
                );
            }
        }
    }
    Ok(())
}

/// Whether the trigger hangs in front of the body (its hinge ahead of the body's front
/// face along the spray direction), as on a hand-held sprayer, rather than lying on top
/// of the spray head.
fn front_trigger(e: &TaskEnv) -> Result<bool, PlanError> {
    let (bp, m) = kin::body(e, "link_2")?;
    let d = kin::sub(kin::anchor(e, "joint_0")?, bp);
    Ok(m[2] * d[0] + m[5] * d[1] + m[8] * d[2] > 0.03)
}

/// Diagnostics: the TCP in the bottle's frame and the fingertips relative to it.
fn tips_debug(rec: &Recorder, what: &str) {
    if !debug() {
        return;
    }
    let e = rec.env();
    let Ok((bp, m)) = kin::body(e, "link_2") else {
        return;
    };
    let local = |d: V3| {
        [
            m[0] * d[0] + m[3] * d[1] + m[6] * d[2],
            m[1] * d[0] + m[4] * d[1] + m[7] * d[2],
            m[2] * d[0] + m[5] * d[1] + m[8] * d[2],
        ]
    };
    let t = kin::tcp(e, 0).0;
    eprintln!(
        "{what}: tcp (bottle frame) {:.3?} trigger {:.3}",
        local(kin::sub(t, bp)),
        kin::joint(e, "joint_0").unwrap_or(f64::NAN)
    );
    for b in ["ff_tip", "mf_tip", "rf_tip", "th_tip"] {
        if let Some(g) = super::geom_of_body(e, b) {
            let tip = local(kin::sub(e.data().geom_xpos()[g], t));
            eprintln!("{what} {b} - tcp (bottle frame) {tip:.3?}");
        }
    }
}

/// The TCP in the bottle's frame for the press (x down, y toward the head, z along the
/// spray): the hand rests on the body's upper face (x; it stops ~1 cm above this and
/// presses, so the bottle does not slide), the index tip at y ~0.04 and the middle one
/// at ~-0.01 near the trigger's free end (y), both ~1 cm ahead of the trigger (z).
const PRESS_TCP: V3 = [-0.062, -0.035, -0.035];

/// A sprayer whose trigger hangs in front of the body: carry the held bottle to TCP
/// position `xy` and set it down (its centre `rest_z` high, as it lay), let go, then
/// rest the hand on the body, yawed to its new spray direction, and pull the trigger
/// with the index and middle fingers. The demonstration ([`Variant::Demo`], set down
/// beside the plant) marks its phases.
fn place_and_press(
    mut rec: Recorder,
    home: kin::Q,
    rest_z: f64,
    xy: [f64; 2],
    id: &str,
    variant: Variant,
) -> Result<Planned, PlanError> {
    let demo = variant == Variant::Demo;
    let (tp, tq) = rec.target(0);
    let bz = kin::body(rec.env(), "link_2")?.0[2];
    let down = [xy[0], xy[1], tp[2] - (bz - rest_z) + 0.005];
    if (down[0] - tp[0]).hypot(down[1] - tp[1]) > 0.05 {
        let mid = kin::scale(kin::add(tp, down), 0.5);
        rec.go(0, [mid[0], mid[1], tp[2] + 0.03], tq, HOLD, 70)?;
    }
    rec.go(0, down, tq, HOLD, 70)?;
    rec.settle(0.004, 40)?;
    rec.go(0, down, tq, OPEN, 20)?;
    rec.go(0, kin::add(down, [0.0, 0.0, 0.08]), tq, OPEN, 40)?;
    if demo {
        rec.phase("aim_spray");
    }
    let e = rec.env();
    let (bp, m) = kin::body(e, "link_2")?;
    let yaw = m[5].atan2(m[2]);
    let q = kin::qmul(kin::yaw(yaw), home);
    let at = kin::add(bp, kin::mulv(&m, PRESS_TCP));
    rec.go(0, kin::add(at, [0.0, 0.0, 0.08]), q, AIM, 60)?;
    rec.go(0, at, q, AIM, 40)?;
    rec.settle(0.003, 30)?;
    tips_debug(&rec, "aim");
    rec.snap(0, "water_aim");
    let latched = |e: &TaskEnv| e.checker().value("trigger") == Some(true);
    rec.go_many(&[Goal::new(0, at, q, PRESS)], 60, latched)?;
    if debug() {
        let st = rec.env().state();
        eprintln!(
            "pressed: trigger {:.3} ff {:.2?}",
            kin::joint(rec.env(), "joint_0")?,
            &st[7..11]
        );
    }
    tips_debug(&rec, "press");
    rec.snap(0, "water_press");
    rec.wait(60)?;
    if demo {
        rec.phase("water");
    }
    rec.finish(id)
}
