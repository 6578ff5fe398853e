//! The fold_glasses planner: with the hand pitched fingers-down, the straight index
//! fingertip folds each temple, swept around its hinge in a closed loop (the target
//! leads the temple); the folded glasses cannot stand, so the fingertip tips them over
//! backwards (away from the table's edge) when they still stand; then the hand turns
//! palm-down, pinches the front (thin side when standing, across its height when lying),
//! carries the glasses over the case and lets go inside it.

use std::f64::consts::FRAC_PI_2;

use dexjoco_core::HAND_DOF;

use super::kin::{self, Q, V3};
use super::{CLOSE, OPEN, Planned, Recorder, debug};
use crate::env::TaskEnv;
use crate::error::SimError;

/// Straight index finger, the others curled away, the thumb at home: with the hand
/// pitched fingers-down, the index fingertip is a probe well below the rest of the hand.
const POINT: [f64; HAND_DOF] = [
    0.0, 0.0, 0.0, 0.0, 0.0, 1.6, 1.7, 1.6, 0.0, 1.6, 1.7, 1.6, 0.263, 0.0, 0.0, 0.0,
];
/// Where the pinch closes on the front, from the TCP along the thumb-to-fingers axis.
const PINCH_X: f64 = 0.08;
/// The TCP's height above the table while pinching.
const PINCH_TCP_Z: f64 = 0.145;
/// As [`PINCH_X`] and [`PINCH_TCP_Z`] for glasses still standing: the thin front
/// pinched near its top.
const PINCH_X_UPRIGHT: f64 = 0.05;
const PINCH_TCP_Z_UPRIGHT: f64 = 0.2;
/// The glasses' origin above the case's when let go.
const RELEASE_Z: f64 = 0.02;
/// The index fingertip from the TCP (world axes) with the hand pitched fingers-down in
/// the [`POINT`] pose (measured on the built-in robot, which has the reference's
/// kinematics).
const TIP: V3 = [-0.0142, 0.0547, -0.1778];
/// The fingertip's distance from the hinge while folding.
const FOLD_R: f64 = 0.13;
/// How far the fingertip's target leads the temple around the hinge (rad).
const FOLD_LEAD: f64 = 0.06;
/// Where the fingertip comes down, behind the temple around the hinge (rad).
const FOLD_BEHIND: f64 = 0.3;
/// The fingertip's offset outside the temple (m).
const FOLD_OUT: f64 = 0.018;

/// Plans fold_glasses on an environment just restored from its initial state.
pub(crate) fn plan(env: TaskEnv, id: &str) -> Result<Planned, SimError> {
    let s = env.state();
    let home = [s[3], s[4], s[5], s[6]];
    let mut rec = Recorder::new(env);
    let table = kin::site(rec.env(), "table_top")?[2];
    // The hand pitched fingers-down (formed on the way to the first temple).
    let down = kin::qmul(kin::axis_angle([0.0, 1.0, 0.0], FRAC_PI_2), home);
    for (joint, temple, other) in [
        ("glass_joint_0", "glass_temple_0", "glass_joint_1"),
        ("glass_joint_1", "glass_temple_1", "glass_joint_0"),
    ] {
        fold_temple(&mut rec, down, joint, temple, other)?;
    }
    // Folded, the glasses cannot stand: tip them over backwards (away from the table's
    // edge) with the fingertip on the top of the front.
    tip_over_backwards(&mut rec, down)?;
    // Turn palm-down well above the glasses, and let the glasses settle
    // (folded, they may topple), then come over them.
    let here = rec.target(0).0;
    rec.go(0, kin::add(here, [0.0, 0.0, 0.06]), home, OPEN, 30)?;
    rec.wait(10)?;
    show(&rec, "turned");
    // Folded, the glasses no longer stand: they lie on the front. Pinch the front
    // across its width (thumb at one long edge, fingers at the other), low on the table.
    let (at, q) = front_pinch(rec.env(), table, home)?;
    rec.go(0, kin::add(at, [0.0, 0.0, 0.08]), q, OPEN, 40)?;
    rec.settle(0.01, 20)?;
    show(&rec, "above");
    rec.go(0, at, q, OPEN, 30)?;
    rec.settle(0.006, 25)?;
    show(&rec, "before the pinch");
    rec.snap(0, "glasses_before_pinch");
    rec.go(0, at, q, CLOSE, 25)?;
    rec.wait(10)?;
    show(&rec, "pinched");
    rec.snap(0, "glasses_pinched");
    let lift = kin::add(at, [0.0, 0.0, 0.16]);
    rec.go(0, lift, q, CLOSE, 45)?;
    // Over the case: the glasses' origin above the case's, then down and let go.
    let e = rec.env();
    let off = kin::sub(kin::body(e, "glass")?.0, kin::tcp(e, 0).0);
    let case = kin::body(e, "open_box")?.0;
    let over = [case[0] - off[0], case[1] - off[1], lift[2]];
    rec.go(0, over, q, CLOSE, 70)?;
    rec.settle(0.01, 20)?;
    let low = [over[0], over[1], case[2] + RELEASE_Z - off[2]];
    rec.go(0, low, q, CLOSE, 35)?;
    rec.settle(0.008, 20)?;
    show(&rec, "lowered");
    rec.go(0, low, q, OPEN, 20)?;
    rec.go(0, kin::add(low, [0.0, 0.0, 0.1]), q, OPEN, 40)?;
    show(&rec, "released");
    rec.wait(80)?;
    show(&rec, "end");
    rec.finish(id)
}

/// In debug mode, prints the temples' joints and the glasses' position after a phase.
fn show(rec: &Recorder, what: &str) {
    if debug() {
        let e = rec.env();
        eprintln!(
            "{what}: step {} joints {:.3} {:.3} glass {:.3?}",
            e.steps(),
            kin::joint(e, "glass_joint_0").unwrap_or(f64::NAN),
            kin::joint(e, "glass_joint_1").unwrap_or(f64::NAN),
            kin::body(e, "glass").map(|b| b.0).unwrap_or_default(),
        );
    }
}

/// Folds one temple (`joint`, `temple`) toward the other hinge (`other`): the index
/// fingertip comes down behind it and sweeps it around its hinge in a closed loop.
fn fold_temple(
    rec: &mut Recorder,
    down: Q,
    joint: &str,
    temple: &str,
    other: &str,
) -> Result<(), SimError> {
    let e = rec.env();
    let hinge = kin::anchor(e, joint)?;
    let dir = kin::horizontal(kin::sub(kin::geom(e, temple)?.0, hinge));
    let fold = kin::horizontal(kin::sub(kin::anchor(e, other)?, hinge));
    let a0 = dir[1].atan2(dir[0]);
    let mut a1 = fold[1].atan2(fold[0]);
    // Sweep the short way round (through the back of the glasses).
    while a1 - a0 > std::f64::consts::PI {
        a1 -= 2.0 * std::f64::consts::PI;
    }
    while a1 - a0 < -std::f64::consts::PI {
        a1 += 2.0 * std::f64::consts::PI;
    }
    let sign = (a1 - a0).signum();
    let z = hinge[2];
    // The fingertip behind the temple (against the sweep), FOLD_OUT outside it.
    let at = |a: f64| {
        let b = a - sign * FOLD_OUT / FOLD_R;
        let p = [hinge[0] + FOLD_R * b.cos(), hinge[1] + FOLD_R * b.sin(), z];
        kin::sub(p, TIP)
    };
    let first = at(a0);
    let first_time = joint == "glass_joint_0";
    let steps = if first_time { 110 } else { 45 };
    rec.go(0, kin::add(first, [0.0, 0.0, 0.08]), down, POINT, steps)?;
    rec.settle(0.01, 20)?;
    // The temple may have moved meanwhile: come down behind where it is now.
    let e = rec.env();
    let hinge = kin::anchor(e, joint)?;
    let dir = kin::horizontal(kin::sub(kin::geom(e, temple)?.0, hinge));
    let a = dir[1].atan2(dir[0]) - sign * FOLD_BEHIND;
    let p = [hinge[0] + FOLD_R * a.cos(), hinge[1] + FOLD_R * a.sin(), z];
    let first = kin::sub(p, TIP);
    rec.go(0, kin::add(first, [0.0, 0.0, 0.08]), down, POINT, 15)?;
    rec.go(0, first, down, POINT, 25)?;
    rec.settle(0.006, 25)?;
    show(rec, &format!("at {joint}"));
    rec.snap(0, &format!("glasses_at_{joint}"));
    // Closed loop: the fingertip's target leads the temple by FOLD_LEAD around the
    // hinge, both read again every step (the glasses slide a little while pushed).
    let range = {
        let m = rec.env().data().model();
        let j = crate::checker::name_id(m, dexjoco_core::NameKind::Joint, joint)
            .ok_or_else(|| SimError::Spec(format!("no joint {joint}")))?;
        m.jnt_range()[j][1]
    };
    for _ in 0..400 {
        let e = rec.env();
        if kin::joint(e, joint)? > range - 0.02 || rec.done() {
            break;
        }
        let hinge = kin::anchor(e, joint)?;
        let dir = kin::horizontal(kin::sub(kin::geom(e, temple)?.0, hinge));
        let a = dir[1].atan2(dir[0]) + sign * FOLD_LEAD;
        let p = [hinge[0] + FOLD_R * a.cos(), hinge[1] + FOLD_R * a.sin(), z];
        rec.go(0, kin::sub(p, TIP), down, POINT, 1)?;
    }
    rec.wait(20)?;
    show(rec, &format!("folded {joint}"));
    rec.snap(0, &format!("glasses_{joint}"));
    let here = rec.target(0).0;
    rec.go(0, kin::add(here, [0.0, 0.0, 0.12]), down, POINT, 30)?;
    Ok(())
}

/// Tips the folded glasses over backwards (away from the table's edge) with the
/// fingertip on the top of the front, when they still stand.
fn tip_over_backwards(rec: &mut Recorder, down: Q) -> Result<(), SimError> {
    let e = rec.env();
    let (fc, fm) = kin::geom(e, "glass_front")?;
    let up = [fm[2], fm[5], fm[8]];
    if up[2] > 0.7 {
        let mut back = kin::horizontal([fm[0], fm[3], fm[6]]);
        if back[0] < 0.0 {
            back = [-back[0], -back[1], 0.0];
        }
        let top = kin::add(fc, kin::scale(up, 0.035));
        let p0 = kin::sub(top, kin::scale(back, 0.03));
        let p1 = kin::add(top, kin::scale(back, 0.05));
        rec.go(
            0,
            kin::sub(kin::add(p0, [0.0, 0.0, 0.06]), TIP),
            down,
            POINT,
            30,
        )?;
        rec.go(0, kin::sub(p0, TIP), down, POINT, 20)?;
        rec.go(0, kin::sub(p1, TIP), down, POINT, 30)?;
        let here = rec.target(0).0;
        rec.go(0, kin::add(here, [0.0, 0.0, 0.08]), down, POINT, 20)?;
        show(rec, "tipped over");
    }
    Ok(())
}

/// The TCP target and orientation that pinch the front: across its width when the
/// glasses lie (thumb at one long edge, fingers at the other), the thin front near its
/// top when they still stand; fingers away from the robot.
fn front_pinch(e: &TaskEnv, table: f64, home: Q) -> Result<(V3, Q), SimError> {
    let (fc, fm) = kin::geom(e, "glass_front")?;
    let up = [fm[2], fm[5], fm[8]];
    let thick = [fm[0], fm[3], fm[6]];
    let upright = up[2].abs() > 0.7;
    let across = if upright { thick } else { up };
    let mut d = kin::horizontal(across);
    // Fingers away from the robot (+x), the thumb on the near side.
    if d[0] < 0.0 {
        d = [-d[0], -d[1], 0.0];
    }
    let (pinch_x, tcp_z) = if upright {
        (PINCH_X_UPRIGHT, PINCH_TCP_Z_UPRIGHT)
    } else {
        (PINCH_X, PINCH_TCP_Z)
    };
    let yaw = d[1].atan2(d[0]);
    if debug() {
        eprintln!("front {fc:.3?} up {up:.2?} thick {thick:.2?} yaw {yaw:.2}");
    }
    let q = kin::qmul(kin::yaw(yaw), home);
    let mut at = kin::sub(
        fc,
        kin::mulv(&kin::qmat(kin::yaw(yaw)), [pinch_x, 0.0, 0.0]),
    );
    at[2] = table + tcp_z;
    Ok((at, q))
}
