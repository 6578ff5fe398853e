//! The fold_glasses planner: with the hand pitched fingers-down, the straight index
//! fingertip folds each temple, swept around its hinge in a closed loop (the target
//! leads the temple); then the hand turns palm-down, pinches the front (thin side when
//! standing, across its height when lying), carries the glasses over the case and lets
//! go inside it. Temples that stay put (the built-in hinges) are both folded standing and
//! the glasses tipped over backwards; temples that gravity unfolds (see [`temple_sags`])
//! end face down, on top of the front: one folded standing, the glasses tipped over
//! forwards, the other folded down onto the front.

use std::f64::consts::FRAC_PI_2;

mod face_down;
mod model;

use self::face_down::{fold_face_down, temple_sags};
use self::model::{body_box, box_centre, front, hinge_damped, joint_body, table_near_edge, temple};
use super::hands::INDEX_HAND as POINT;
use super::kin::{self, Q, V3};
use super::{CLOSE, OPEN, Planned, Recorder, debug};
use crate::PlanError;
use dexjoco_sim::TaskEnv;

/// Where the pinch closes on the front, from the TCP along the thumb-to-fingers axis.
const PINCH_X: f64 = 0.08;
/// The TCP's height above the table while pinching.
const PINCH_TCP_Z: f64 = 0.145;
/// As [`PINCH_X`] and [`PINCH_TCP_Z`] for glasses still standing: the thin front
/// pinched near its top.
const PINCH_X_UPRIGHT: f64 = 0.05;
const PINCH_TCP_Z_UPRIGHT: f64 = 0.2;
/// The index fingertip from the TCP (world axes) with the hand pitched fingers-down in
/// the [`POINT`] pose (measured on the built-in robot, which has the reference's
/// kinematics).
const TIP: V3 = [-0.0142, 0.0547, -0.1778];
/// How far the front should stand from the table's near edge after a push back.
const EDGE_CLEAR: f64 = 0.2;
/// A fold stops (for a push back) when the front comes this close to the table's edge.
const EDGE_MIN: f64 = 0.05;
/// The fingertip's distance from a light hinge (damping under [`DAMPED`]) while folding.
const FOLD_R: f64 = 0.13;
/// Hinge damping (N m s) from which a temple is pushed near its tip ([`FOLD_AT`]): a
/// damped hinge needs the longer lever, or the push drags the whole glasses.
const DAMPED: f64 = 0.05;
/// Where the fingertip pushes a temple on a damped hinge, as a fraction of its reach
/// from the hinge.
const FOLD_AT: f64 = 0.85;
/// As [`FOLD_AT`] for the second temple (clear of the first one's tip, folded by then).
const FOLD_AT_2: f64 = 0.8;
/// A damped temple's fold has stalled when the hinge gains less than `STALL_DQ` (rad)
/// in `STALL_STEPS` steps, within `STALL_NEAR` (rad) of its stop.
const STALL_DQ: f64 = 0.003;
const STALL_STEPS: usize = 20;
const STALL_NEAR: f64 = 0.12;
/// How far the fingertip's target leads the temple around the hinge (rad).
const FOLD_LEAD: f64 = 0.06;
/// Where the fingertip comes down, behind the temple around the hinge (rad).
const FOLD_BEHIND: f64 = 0.3;
/// The fingertip's offset outside the temple (m).
const FOLD_OUT: f64 = 0.018;
/// The fingertip's height above the temple's estimated lowest point while folding.
const FOLD_DZ: f64 = 0.005;

/// Step counts (and the last press) where the two plans differ: the face-down plan
/// for temples that sag (see [`temple_sags`]) must fit a longer sequence in the same
/// step cap, so it moves on sooner after each contact phase.
struct Pace {
    /// After a standing fold: the hold before lifting off the temple, and the lift.
    fold_hold: usize,
    fold_lift: usize,
    /// The lift off the front after a push back.
    push_lift: usize,
    /// Turning palm-down, the hold after it, and the move above the pinch.
    turn: usize,
    turn_hold: usize,
    above: usize,
    /// The glasses' origin above the case's when let go (m): the face-down glasses
    /// hang tilted from the pinch, and let go lower they land flat.
    release_z: f64,
    /// How far (m) the open hand presses the let-go glasses down into the case: a
    /// temple the pinch has half unfolded lies on top, face down, and is pressed back
    /// onto the front.
    press: Option<f64>,
}

/// The plan for temples that stay where they are put (the built-in scene).
const STANDING: Pace = Pace {
    fold_hold: 20,
    fold_lift: 30,
    push_lift: 15,
    turn: 30,
    turn_hold: 10,
    above: 40,
    release_z: 0.02,
    press: None,
};

/// The plan for temples that sag (the reference scene).
const FACE_DOWN: Pace = Pace {
    fold_hold: 5,
    fold_lift: 20,
    push_lift: 10,
    turn: 20,
    turn_hold: 1,
    above: 30,
    release_z: 0.0,
    press: Some(0.07),
};

/// Plans fold_glasses on an environment just restored from its initial state.
pub(crate) fn plan(env: TaskEnv, id: &str) -> Result<Planned, PlanError> {
    let s = env.state();
    let home = [s[3], s[4], s[5], s[6]];
    let mut rec = Recorder::new(env);
    let table = kin::site(rec.env(), "table_top")?[2];
    // The hand pitched fingers-down (formed on the way to the first temple).
    let down = kin::qmul(kin::axis_angle([0.0, 1.0, 0.0], FRAC_PI_2), home);
    let sags = temple_sags(rec.env(), "glass_joint_0")? || temple_sags(rec.env(), "glass_joint_1")?;
    let pace = if sags { &FACE_DOWN } else { &STANDING };
    if sags {
        fold_face_down(&mut rec, down, pace)?;
    } else {
        fold_standing(&mut rec, down, "glass_joint_0", "glass_joint_1", 110, pace)?;
        rec.phase("fold_first_temple");
        fold_standing(&mut rec, down, "glass_joint_1", "glass_joint_0", 45, pace)?;
        rec.phase("fold_second_temple");
        // Folded, the glasses cannot stand: tip them over backwards (away from the
        // table's edge) with the fingertip on the top of the front.
        tip_over_backwards(&mut rec, down)?;
    }
    stow(&mut rec, table, home, pace)?;
    rec.phase("place_glasses");
    rec.finish(id)
}

/// Turns the hand palm-down, pinches the folded glasses lying on the table, carries
/// them over the case and lets go inside it.
fn stow(rec: &mut Recorder, table: f64, home: Q, pace: &Pace) -> Result<(), PlanError> {
    // Turn palm-down well above the glasses, and let the glasses settle
    // (folded, they may topple), then come over them.
    let here = rec.target(0).0;
    rec.go(0, kin::add(here, [0.0, 0.0, 0.06]), home, OPEN, pace.turn)?;
    rec.wait(pace.turn_hold)?;
    show(rec, "turned");
    // Folded, the glasses no longer stand: they lie on the front. Pinch the front
    // across its width (thumb at one long edge, fingers at the other), low on the table.
    let (at, q) = front_pinch(rec.env(), table, home)?;
    rec.go(0, kin::add(at, [0.0, 0.0, 0.08]), q, OPEN, pace.above)?;
    rec.settle(0.01, 20)?;
    show(rec, "above");
    rec.go(0, at, q, OPEN, 30)?;
    rec.settle(0.006, 25)?;
    show(rec, "before the pinch");
    rec.snap(0, "glasses_before_pinch");
    rec.go(0, at, q, CLOSE, 25)?;
    rec.wait(10)?;
    show(rec, "pinched");
    rec.snap(0, "glasses_pinched");
    let lift = kin::add(at, [0.0, 0.0, 0.16]);
    rec.go(0, lift, q, CLOSE, 45)?;
    rec.phase("pick_glasses");
    // Over the case: the glasses' origin above the case's, then down and let go.
    let e = rec.env();
    let off = kin::sub(kin::body(e, "glass")?.0, kin::tcp(e, 0).0);
    let case = kin::body(e, "open_box")?.0;
    let over = [case[0] - off[0], case[1] - off[1], lift[2]];
    rec.go(0, over, q, CLOSE, 70)?;
    rec.settle(0.01, 20)?;
    let low = [over[0], over[1], case[2] + pace.release_z - off[2]];
    rec.go(0, low, q, CLOSE, 35)?;
    rec.settle(0.008, 20)?;
    show(rec, "lowered");
    rec.go(0, low, q, OPEN, 20)?;
    if let Some(press) = pace.press {
        rec.go(0, kin::add(low, [0.0, 0.0, -press]), q, OPEN, 15)?;
        show(rec, "pressed");
        rec.go(0, kin::add(low, [0.0, 0.0, 0.03]), q, OPEN, 10)?;
    }
    rec.go(0, kin::add(low, [0.0, 0.0, 0.1]), q, OPEN, 40)?;
    show(rec, "released");
    rec.wait(80)?;
    show(rec, "end");
    Ok(())
}

/// Folds the temple on hinge `joint` with the glasses standing; when the folding slides
/// them near the table's edge, pushes them back and goes on folding.
fn fold_standing(
    rec: &mut Recorder,
    down: Q,
    joint: &str,
    other: &str,
    mut approach: usize,
    pace: &Pace,
) -> Result<(), PlanError> {
    for _ in 0..3 {
        if fold_temple(rec, down, joint, other, approach, pace)? {
            break;
        }
        push_back(rec, down, 45, EDGE_CLEAR, pace)?;
        approach = 45;
    }
    Ok(())
}

/// Pushes the standing glasses away from the table's near edge (the folds push them
/// toward it): the fingertip comes down in front of the lower front and moves it back
/// until the front is [`EDGE_CLEAR`] from the edge.
fn push_back(
    rec: &mut Recorder,
    down: Q,
    approach: usize,
    clear: f64,
    pace: &Pace,
) -> Result<bool, PlanError> {
    let e = rec.env();
    let (fc, fm, half) = front(e)?;
    let edge = table_near_edge(e)?;
    let need = (edge + clear - fc[0]).min(0.15);
    if debug() {
        eprintln!("table edge {edge:.3} front {:.3} push {need:.3}", fc[0]);
    }
    if need < 0.01 {
        return Ok(false);
    }
    let mut back = kin::horizontal([fm[0], fm[3], fm[6]]);
    if back[0] < 0.0 {
        back = [-back[0], -back[1], 0.0];
    }
    let mut p0 = kin::sub(fc, kin::scale(back, half[0] + 0.03));
    p0[2] = fc[2] - 0.4 * half[2];
    let p1 = kin::add(p0, kin::scale(back, (need + 0.03) / back[0]));
    rec.go(
        0,
        kin::sub(kin::add(p0, [0.0, 0.0, 0.1]), TIP),
        down,
        POINT,
        approach,
    )?;
    rec.settle(0.01, 10)?;
    rec.go(0, kin::sub(p0, TIP), down, POINT, 20)?;
    rec.settle(0.008, 10)?;
    rec.go(0, kin::sub(p1, TIP), down, POINT, 40)?;
    let here = rec.target(0).0;
    rec.go(
        0,
        kin::add(kin::sub(here, kin::scale(back, 0.02)), [0.0, 0.0, 0.08]),
        down,
        POINT,
        pace.push_lift,
    )?;
    show(rec, "pushed back");
    Ok(true)
}

/// In debug mode, prints the temples' joints and the glasses' position after a phase.
fn show(rec: &Recorder, what: &str) {
    if debug() {
        let e = rec.env();
        eprintln!(
            "{what}: step {} joints {:.3} {:.3} glass {:.3?} up {:.2?} front {:.3?}",
            e.steps(),
            kin::joint(e, "glass_joint_0").unwrap_or(f64::NAN),
            kin::joint(e, "glass_joint_1").unwrap_or(f64::NAN),
            kin::body(e, "glass").map(|b| b.0).unwrap_or_default(),
            front(e)
                .map(|f| [f.1[2], f.1[5], f.1[8]])
                .unwrap_or_default(),
            front(e).ok(),
        );
    }
}

/// Folds the temple on hinge `joint` toward the other hinge (`other`): the index
/// fingertip comes down behind it and sweeps it around its hinge in a closed loop.
fn fold_temple(
    rec: &mut Recorder,
    down: Q,
    joint: &str,
    other: &str,
    approach: usize,
    pace: &Pace,
) -> Result<bool, PlanError> {
    let e = rec.env();
    let hinge = kin::anchor(e, joint)?;
    let dir = kin::horizontal(kin::sub(temple(e, joint)?, hinge));
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
    let first_time = joint == "glass_joint_0";
    // The fold stops just short of the hinge's limit.
    let stop = e.data().model().jnt_range()[joint_body(e, joint)?.0][1] - 0.02;
    if kin::joint(e, joint)? > stop {
        // Folded already (pushing the glasses back may fold a temple).
        return Ok(true);
    }
    let (fold_r, z) = fold_at(e, joint, if first_time { FOLD_AT } else { FOLD_AT_2 })?;
    // The fingertip behind the temple (against the sweep), FOLD_OUT outside it.
    let at = |a: f64| {
        let b = a - sign * FOLD_OUT / fold_r;
        let p = [hinge[0] + fold_r * b.cos(), hinge[1] + fold_r * b.sin(), z];
        kin::sub(p, TIP)
    };
    let first = at(a0);
    rec.go(0, kin::add(first, [0.0, 0.0, 0.08]), down, POINT, approach)?;
    rec.settle(0.01, 20)?;
    // The temple may have moved meanwhile: come down behind where it is now.
    let e = rec.env();
    let hinge = kin::anchor(e, joint)?;
    let dir = kin::horizontal(kin::sub(temple(e, joint)?, hinge));
    let a = dir[1].atan2(dir[0]) - sign * FOLD_BEHIND;
    let p = [hinge[0] + fold_r * a.cos(), hinge[1] + fold_r * a.sin(), z];
    let first = kin::sub(p, TIP);
    rec.go(0, kin::add(first, [0.0, 0.0, 0.08]), down, POINT, 15)?;
    rec.go(0, first, down, POINT, 25)?;
    rec.settle(0.006, 25)?;
    show(rec, &format!("at {joint}"));
    if debug() {
        eprintln!(
            "  tcp {:.3?} target {:.3?}",
            kin::tcp(rec.env(), 0).0,
            rec.target(0).0
        );
    }
    rec.snap(0, &format!("glasses_at_{joint}"));
    // Closed loop: the fingertip's target leads the temple by FOLD_LEAD around the
    // hinge, both read again every step (the glasses slide a little while pushed).
    let edge = table_near_edge(rec.env())?;
    let mut clear = true;
    // A damped temple may stall short of its limit while the push drags the glasses:
    // near the limit, a stall ends the fold.
    let stalls = hinge_damped(rec.env(), joint)?;
    let (mut best, mut best_at) = (f64::NEG_INFINITY, 0);
    for k in 0..400_usize {
        let e = rec.env();
        if debug() && k.is_multiple_of(25) {
            show(rec, &format!("  {k}"));
            eprintln!(
                "  tcp {:.3?} target {:.3?}",
                kin::tcp(rec.env(), 0).0,
                rec.target(0).0
            );
        }
        if front(e)?.0[0] < edge + EDGE_MIN {
            clear = false;
            break;
        }
        let q = kin::joint(e, joint)?;
        if q > stop || rec.done() {
            break;
        }
        if q > best + STALL_DQ {
            (best, best_at) = (q, k);
        } else if stalls && q > stop - STALL_NEAR && k - best_at > STALL_STEPS {
            break;
        }
        let hinge = kin::anchor(e, joint)?;
        let dir = kin::horizontal(kin::sub(temple(e, joint)?, hinge));
        let a = dir[1].atan2(dir[0]) + sign * FOLD_LEAD;
        let p = [hinge[0] + fold_r * a.cos(), hinge[1] + fold_r * a.sin(), z];
        rec.go(0, kin::sub(p, TIP), down, POINT, 1)?;
    }
    rec.wait(pace.fold_hold)?;
    show(rec, &format!("folded {joint}"));
    rec.snap(0, &format!("glasses_{joint}"));
    let here = rec.target(0).0;
    rec.go(
        0,
        kin::add(here, [0.0, 0.0, 0.12]),
        down,
        POINT,
        pace.fold_lift,
    )?;
    Ok(clear)
}

/// Tips the folded glasses over backwards (away from the table's edge) with the
/// fingertip on the top of the front, when they still stand.
fn tip_over_backwards(rec: &mut Recorder, down: Q) -> Result<(), PlanError> {
    let e = rec.env();
    let (fc, fm, half) = front(e)?;
    let up = [fm[2], fm[5], fm[8]];
    if up[2] > 0.7 {
        let mut back = kin::horizontal([fm[0], fm[3], fm[6]]);
        if back[0] < 0.0 {
            back = [-back[0], -back[1], 0.0];
        }
        let top = kin::add(fc, kin::scale(up, half[2] - 0.009));
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
fn front_pinch(e: &TaskEnv, table: f64, home: Q) -> Result<(V3, Q), PlanError> {
    let (fc, fm, _) = front(e)?;
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

/// Where the fingertip pushes the temple on hinge `joint` (damped: see [`DAMPED`]): its
/// distance from the hinge,
/// [`FOLD_AT`] of the temple's reach (near its tip, so the push beats the tip's friction
/// on the table directly, not through the hinge), and its height, just above the
/// temple's lowest point there. The temple (its bounding box) is taken to run from the
/// hinge down to the box's bottom over twice the horizontal distance to the box's centre
/// (the straight finger, pointing down, spans the temple's height).
fn fold_at(e: &TaskEnv, joint: &str, t: f64) -> Result<(f64, f64), PlanError> {
    let (j, b) = joint_body(e, joint)?;
    let m = e.data().model();
    let (_, h) = body_box(e, b);
    let xm = e.data().xmat()[b];
    let centre = box_centre(e, b);
    let bottom = centre[2] - (0..3).map(|i| xm[6 + i].abs() * h[i]).sum::<f64>();
    let hinge = kin::anchor(e, joint)?;
    if m.dof_damping()[m.jnt_dofadr()[j] as usize] < DAMPED {
        // A light hinge: push the temple mid-way, level with the hinge.
        return Ok((FOLD_R, hinge[2]));
    }
    let reach = 2.0 * (centre[0] - hinge[0]).hypot(centre[1] - hinge[1]);
    if debug() {
        eprintln!(
            "{joint}: hinge z {:.3} bottom {bottom:.3} reach {reach:.3}",
            hinge[2]
        );
    }
    Ok((reach * t, hinge[2] - (hinge[2] - bottom) * t + FOLD_DZ))
}
