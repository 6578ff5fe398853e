//! The pick_bucket planner: pinch the food box across its width, carry it over the
//! basket and let go, then lift the basket by its handle. An upright handle (held up by
//! its spring, as in the built-in scene) is gripped by its bar from above; a handle lying
//! folded on the rim toward the robot (no spring: the reference basket) is first raised
//! about its pivot by fingertips pushing the bar's underside along its arc, hooked by the
//! curling fingers, carried on toward upright and then lifted.

use dexjoco_core::HAND_DOF;

use super::hands::pick_bucket::{DOWN, HOOK, HOOK_DOWN};
use super::kin::{self, Q, V3};
use super::{CLOSE, OPEN, Planned, Recorder, debug};
use crate::PlanError;
use dexjoco_sim::TaskEnv;

/// The food's centre from the TCP along the thumb-to-fingers axis, and below it.
const FOOD_X: f64 = 0.07;
const FOOD_DOWN: f64 = 0.13;
/// The bar from the TCP along the thumb-to-fingers axis, and below it.
const BAR_X: f64 = 0.05;
const BAR_DOWN: f64 = 0.10;
const BAR_SIDE: f64 = 0.045;

/// A handle whose hinge is below this angle at reset lies folded on the rim (rad).
const FOLDED: f64 = 0.5;
/// Where the food is let go, from the basket's centre along its x axis (away from the
/// robot): the near half, clear of an upright handle, or the far half, clear of the
/// fingers that come down inside the near wall to raise a folded handle.
const FOOD_SPOT_UPRIGHT: f64 = -0.09;
const FOOD_SPOT_FOLDED: f64 = 0.02;

/// The middle fingertip of [`DOWN`] from the TCP (palm down): along the fingers, below.
const DOWN_TIP: (f64, f64) = (0.075, 0.14);
/// The fingertips' distance inside the bar (toward the pivot) while raising it (m).
const TIP_INSIDE: f64 = 0.008;
/// The fingertips' angle behind the bar about the pivot (below it at the start; rad).
const TIP_LAG: f64 = 0.22;
/// The bar's angle at which the fingers curl round it, and where the arc ends (rad).
const HOOK_AT: f64 = 0.6;
const ARC_END: f64 = 1.35;
/// Arc steps: this angle (rad) over this many control steps.
const ARC_STEP: (f64, usize) = (0.1, 10);
/// How far the hand lifts the basket at the end (m).
const LIFT: f64 = 0.22;

/// The basket's inside box: centre and its x and y axes (world), from its sites.
fn basket(e: &TaskEnv) -> Result<(V3, V3, V3), PlanError> {
    let mut c = [0.0; 3];
    let mut p = Vec::new();
    for i in 0..8 {
        let s = kin::site(e, &format!("bucket_ref_{i}"))?;
        c = kin::add(c, kin::scale(s, 1.0 / 8.0));
        p.push(s);
    }
    let x = kin::sub(p[0], p[4]);
    let y = kin::sub(p[1], p[0]);
    Ok((
        c,
        kin::scale(x, 1.0 / kin::norm(x)),
        kin::scale(y, 1.0 / kin::norm(y)),
    ))
}

/// Plans pick_bucket on an environment just restored from its initial state.
pub(crate) fn plan(env: TaskEnv, id: &str) -> Result<Planned, PlanError> {
    let s = env.state();
    let home = [s[3], s[4], s[5], s[6]];
    let folded = kin::joint(&env, "bucket_joint_0")? < FOLDED;
    let mut rec = Recorder::new(env);
    let spot = if folded {
        FOOD_SPOT_FOLDED
    } else {
        FOOD_SPOT_UPRIGHT
    };
    put_food(&mut rec, home, spot)?;
    if folded {
        raise_folded(&mut rec, home)?;
    } else {
        grip_upright(&mut rec, home)?;
    }
    rec.phase("lift_bucket");
    rec.finish(id)
}

/// Pinches the food, carries it over the basket (`spot` from its centre along its x
/// axis), lowers it and lets go.
fn put_food(rec: &mut Recorder, home: Q, spot: f64) -> Result<(), PlanError> {
    let e = rec.env();
    let table = kin::site(e, "table_top")?[2];
    let (fp, fm) = kin::body(e, "boxed_food_0")?;
    let mut d = [fm[0], fm[3], 0.0];
    if d[0] < 0.0 {
        d = [-d[0], -d[1], 0.0];
    }
    let d = kin::scale(d, 1.0 / kin::norm(d));
    let yaw = d[1].atan2(d[0]);
    let q = kin::qmul(kin::yaw(yaw), home);
    let mut at = kin::sub(fp, kin::scale(d, FOOD_X));
    at[2] = fp[2] + FOOD_DOWN;
    rec.go(0, kin::add(at, [0.0, 0.0, 0.1]), q, OPEN, 90)?;
    rec.settle(0.005, 40)?;
    rec.go(0, at, q, OPEN, 40)?;
    rec.settle(0.004, 40)?;
    rec.go(0, at, q, CLOSE, 25)?;
    rec.wait(15)?;
    let up = [at[0], at[1], table + 0.42];
    rec.go(0, up, q, CLOSE, 70)?;
    show(rec, "food lifted");
    rec.phase("grasp_food");
    // Over the basket, down, let go.
    let e = rec.env();
    let off = kin::sub(kin::body(e, "boxed_food_0")?.0, kin::tcp(e, 0).0);
    let (c, bx, _) = basket(e)?;
    let spot = kin::add(c, kin::scale(bx, spot));
    let over = [spot[0] - off[0], spot[1] - off[1], up[2]];
    rec.go(0, over, q, CLOSE, 100)?;
    rec.settle(0.006, 30)?;
    let low = [over[0], over[1], c[2] - 0.031 + 0.01 - off[2]];
    rec.go(0, low, q, CLOSE, 50)?;
    rec.settle(0.005, 30)?;
    rec.go(0, low, q, OPEN, 20)?;
    // Let go: the food is in.
    rec.phase("place_food");
    rec.go(0, kin::add(low, [0.0, 0.0, 0.25]), q, OPEN, 50)?;
    show(rec, "food in");
    rec.snap(0, "bucket_food_in");
    Ok(())
}

/// Grips an upright handle's bar from above (fingers on its far side) and lifts.
fn grip_upright(rec: &mut Recorder, home: Q) -> Result<(), PlanError> {
    let e = rec.env();
    let bar = kin::geom(e, "handle1")?.0;
    let (_, bx, _) = basket(e)?;
    let d = kin::horizontal(bx);
    let yaw = d[1].atan2(d[0]);
    let q = kin::qmul(kin::yaw(yaw), home);
    // The hand spans from its ring finger to its thumb (the +y side at home yaw): centre
    // that span on the bar, clear of the handle's arms.
    let side = [-d[1], d[0], 0.0];
    let grip_at = |bar: V3| {
        let mut at = kin::sub(
            kin::sub(bar, kin::scale(d, BAR_X)),
            kin::scale(side, BAR_SIDE),
        );
        at[2] = bar[2] + BAR_DOWN;
        at
    };
    let at = grip_at(bar);
    rec.go(0, kin::add(at, [0.0, 0.0, 0.08]), q, OPEN, 60)?;
    rec.settle(0.005, 40)?;
    // Where the bar is now (the handle sways a little).
    let at = grip_at(kin::geom(rec.env(), "handle1")?.0);
    rec.go(0, at, q, OPEN, 30)?;
    rec.settle(0.004, 40)?;
    show(rec, "at the bar");
    rec.snap(0, "bucket_at_bar");
    // Fingers first (they hook the bar from its far side), then the thumb.
    rec.go(0, at, q, HOOK, 25)?;
    rec.go(0, at, q, CLOSE, 20)?;
    rec.wait(10)?;
    show(rec, "bar gripped");
    rec.snap(0, "bucket_bar");
    rec.go(0, kin::add(at, [0.0, 0.0, 0.25]), q, CLOSE, 100)?;
    show(rec, "lifted");
    rec.wait(30)?;
    show(rec, "end");
    Ok(())
}

/// Raises a handle lying folded toward the robot: palm down, fingers pointing away from
/// the robot and bent straight down, the fingertips come down just inside the bar and
/// below it, push its underside up along its arc about the pivot (the hand moves on that
/// arc, orientation fixed), curl round it, carry it on toward upright, close and lift.
/// The pivot, its axis and the bar's radius come from the model (the hinge's anchor,
/// the handle body's frame, the bar geom `handle1`).
fn raise_folded(rec: &mut Recorder, home: Q) -> Result<(), PlanError> {
    let e = rec.env();
    let pivot = kin::anchor(e, "bucket_joint_0")?;
    let (_, lm) = kin::body(e, "bucket_link_0")?;
    let axis = [lm[2], lm[5], lm[8]];
    let d = kin::sub(kin::geom(e, "handle1")?.0, pivot);
    let along: f64 = (0..3).map(|i| d[i] * axis[i]).sum();
    let radial = kin::sub(d, kin::scale(axis, along));
    // u0: from the pivot toward the folded bar; turning it about w by +t raises it.
    let u0 = kin::horizontal(radial);
    let w = [u0[1], -u0[0], 0.0];
    let mid = kin::add(pivot, kin::scale(axis, along));
    let rho = kin::norm(radial) - TIP_INSIDE;
    let q = kin::qmul(kin::yaw((-u0[1]).atan2(-u0[0])), home);
    // The TCP with the middle fingertip on the arc at angle t about the pivot.
    let tcp_at = |t: f64| {
        let rot = kin::qmat(kin::axis_angle(w, t));
        let tip = kin::add(mid, kin::mulv(&rot, kin::scale(u0, rho)));
        kin::add(tip, [DOWN_TIP.0 * u0[0], DOWN_TIP.0 * u0[1], DOWN_TIP.1])
    };
    // Carries the fingertips along the arc, a step at a time, until the bar is at `to`.
    let sweep = |rec: &mut Recorder, t: &mut f64, to: f64, hand: &[f64; HAND_DOF]| {
        while *t < to - TIP_LAG {
            *t += ARC_STEP.0;
            rec.go(0, tcp_at(*t), q, *hand, ARC_STEP.1)?;
        }
        Ok::<(), PlanError>(())
    };
    let mut t = -TIP_LAG;
    rec.go(0, kin::add(tcp_at(t), [0.0, 0.0, 0.1]), q, DOWN, 60)?;
    rec.settle(0.005, 40)?;
    rec.go(0, tcp_at(t), q, DOWN, 30)?;
    rec.settle(0.003, 40)?;
    show(rec, "below the bar");
    rec.snap(0, "bucket_below_bar");
    sweep(rec, &mut t, HOOK_AT, &DOWN)?;
    rec.wait(10)?;
    show(rec, "bar raised");
    rec.go(0, tcp_at(t), q, HOOK_DOWN, 25)?;
    show(rec, "bar hooked");
    rec.snap(0, "bucket_bar_hooked");
    sweep(rec, &mut t, ARC_END, &HOOK_DOWN)?;
    rec.wait(10)?;
    show(rec, "bar up");
    rec.go(0, tcp_at(t), q, CLOSE, 20)?;
    rec.go(0, kin::add(tcp_at(t), [0.0, 0.0, LIFT]), q, CLOSE, 100)?;
    show(rec, "lifted");
    rec.wait(60)?;
    show(rec, "end");
    Ok(())
}

/// With `DEXJOCO_PLAN_DEBUG`: the food, the handle's angle and the task's conditions.
fn show(rec: &Recorder, what: &str) {
    if debug() {
        let e = rec.env();
        eprintln!(
            "{what}: step {} food {:.3?} handle {:.2} in {:?} lifted {:?}",
            e.steps(),
            kin::body(e, "boxed_food_0")
                .map(|b| b.0)
                .unwrap_or_default(),
            kin::joint(e, "bucket_joint_0").unwrap_or(f64::NAN),
            e.checker().value("food_in_bucket"),
            e.checker().value("bucket_lifted"),
        );
    }
}
