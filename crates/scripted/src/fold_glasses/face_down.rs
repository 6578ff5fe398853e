//! fold_glasses with temples that gravity unfolds (the reference's): the glasses end face
//! down, temples on top, where gravity keeps them folded. One temple is folded with the
//! glasses standing, the glasses are tipped over forwards, and the other temple is swept
//! around its now-level hinge axis down onto the front.

use super::model::{box_centre, front, joint_body};
use super::{POINT, Pace, STALL_DQ, STALL_NEAR, STALL_STEPS, TIP, fold_standing, push_back, show};
use crate::PlanError;
use crate::kin::{self, Q, V3};
use crate::{Recorder, debug};
use dexjoco_sim::TaskEnv;

/// How far behind the front's top the fingertip comes down to tip the glasses forward
/// (behind the folded temples), along the arc about the front's lower edge (m).
const TIP_BEHIND: f64 = 0.05;

/// Where the forward tip's sweep ends: the angle (rad, back from upright) about the
/// front's lower edge.
const TIP_TO: f64 = -0.7;

/// The fingertip's distance from the hinge's axis when folding a temple of glasses
/// lying face down (m), how far its target leads the temple (rad), where it comes down
/// behind the temple (rad) and its offset outside the temple (m).
const LYING_FOLD_R: f64 = 0.14;
const LYING_FOLD_LEAD: f64 = 0.2;
const LYING_FOLD_BEHIND: f64 = 0.35;
const LYING_FOLD_OUT: f64 = 0.015;

/// As [`EDGE_CLEAR`](super::EDGE_CLEAR) before the first fold of a face-down plan (the fold and the tip
/// over move the glasses 0.1-0.15 m toward the edge).
const EDGE_CLEAR_FIRST: f64 = 0.25;

/// Folds sagging temples so that the glasses end face down, temples on top (gravity
/// unfolds a temple hanging under the front, and keeps one lying on it folded): pushes
/// the standing glasses away from the table's edge (the fold and the tip-over move them
/// toward it), folds the first temple standing, tips the glasses over forwards and
/// folds the second temple down onto the front (the push then presses them onto the
/// table, where a standing fold drags them).
pub(super) fn fold_face_down(rec: &mut Recorder, down: Q, pace: &Pace) -> Result<(), PlanError> {
    let mut approach = 110;
    if push_back(rec, down, 60, EDGE_CLEAR_FIRST, pace)? {
        let here = rec.target(0).0;
        rec.go(0, kin::add(here, [0.0, 0.0, 0.06]), down, POINT, 5)?;
        approach = 40;
    }
    fold_standing(rec, down, "glass_joint_0", "glass_joint_1", approach, pace)?;
    rec.phase("fold_first_temple");
    tip_over_forwards(rec, down)?;
    fold_lying(rec, down, "glass_joint_1", "glass_joint_0")?;
    rec.phase("fold_second_temple");
    Ok(())
}

/// Folds the temple on hinge `joint` with the glasses lying face down (the hinge's axis
/// level, the temple pointing up): the fingertip sweeps it around the axis toward the
/// other hinge (`other`) and down onto the front, in a closed loop as [`fold_temple`](super::fold_temple).
fn fold_lying(rec: &mut Recorder, down: Q, joint: &str, other: &str) -> Result<(), PlanError> {
    let e = rec.env();
    // Where the index fingertip (its collision capsule's centre) is from the TCP now:
    // the temple is a thin wire, so the sweep needs the fingertip itself.
    let tip = crate::geom_of_body(e, "ff_tip")
        .map(|g| kin::sub(e.data().geom_xpos()[g], kin::tcp(e, 0).0))
        .unwrap_or(TIP);
    let (j, b) = joint_body(e, joint)?;
    let stop = e.data().model().jnt_range()[j][1] - 0.02;
    let r = LYING_FOLD_R;
    let at = |centre: V3, e1: V3, e2: V3, a: f64| {
        let b = a - LYING_FOLD_OUT / r;
        let p = kin::add(
            centre,
            kin::add(kin::scale(e1, r * b.cos()), kin::scale(e2, r * b.sin())),
        );
        kin::sub(p, tip)
    };
    // The temple swings as the glasses land: aim from above, let it come to rest,
    // then aim again from where it is.
    let (centre, e1, e2) = sweep_plane(e, j, b, other)?;
    let start = at(centre, e1, e2, -LYING_FOLD_BEHIND);
    rec.go(0, kin::add(start, [0.0, 0.0, 0.08]), down, POINT, 30)?;
    rec.wait(5)?;
    let (centre, e1, e2) = sweep_plane(rec.env(), j, b, other)?;
    let start = at(centre, e1, e2, -LYING_FOLD_BEHIND);
    rec.go(0, kin::add(start, [0.0, 0.0, 0.08]), down, POINT, 10)?;
    rec.go(0, start, down, POINT, 20)?;
    rec.settle(0.006, 20)?;
    show(rec, &format!("at lying {joint}"));
    rec.snap(0, &format!("glasses_at_lying_{joint}"));
    let (mut best, mut best_at) = (f64::NEG_INFINITY, 0);
    for k in 0..300_usize {
        let e = rec.env();
        if debug() && k.is_multiple_of(25) {
            show(rec, &format!("  {k}"));
        }
        let q = kin::joint(e, joint)?;
        if q > stop || rec.done() {
            break;
        }
        if q > best + STALL_DQ {
            (best, best_at) = (q, k);
        } else if q > stop - STALL_NEAR && k - best_at > STALL_STEPS {
            break;
        }
        // The plane as it is now (the glasses may still be settling).
        let (centre, u, v) = sweep_plane(e, j, b, other)?;
        rec.go(0, at(centre, u, v, LYING_FOLD_LEAD), down, POINT, 1)?;
    }
    show(rec, &format!("folded lying {joint}"));
    rec.snap(0, &format!("glasses_lying_{joint}"));
    let here = rec.target(0).0;
    rec.go(0, kin::add(here, [0.0, 0.0, 0.06]), down, POINT, 15)?;
    Ok(())
}

/// The plane of a lying fold's sweep about hinge `j` (moving body `b`): its centre, the
/// temple's direction from the axis now, and the direction toward hinge `other`
/// square to it (both square to the axis).
fn sweep_plane(e: &TaskEnv, j: usize, b: usize, other: &str) -> Result<(V3, V3, V3), PlanError> {
    let d = e.data();
    let h = d.xanchor()[j];
    let n = d.xaxis()[j];
    let off = kin::sub(box_centre(e, b), h);
    let u = kin::unit(kin::sub(off, kin::scale(n, kin::dot(off, n))));
    let to = kin::sub(kin::anchor(e, other)?, h);
    let w = kin::unit(kin::sub(to, kin::scale(n, kin::dot(to, n))));
    Ok((h, u, kin::unit(kin::sub(w, kin::scale(u, kin::dot(w, u))))))
}

/// Lays the folded glasses face down (temples on top): the fingertip comes down behind
/// the top of the front (behind the folded temples) and sweeps forward on an arc about
/// the front's lower edge until they fall over toward the robot.
fn tip_over_forwards(rec: &mut Recorder, down: Q) -> Result<(), PlanError> {
    let e = rec.env();
    let (fc, fm, half) = front(e)?;
    let up = [fm[2], fm[5], fm[8]];
    if up[2] < 0.5 {
        show(rec, "lying already");
        return Ok(());
    }
    let mut back = kin::horizontal([fm[0], fm[3], fm[6]]);
    if back[0] < 0.0 {
        back = [-back[0], -back[1], 0.0];
    }
    // The pivot: the front's lower edge; the lean: the front's angle back from upright.
    let pivot = kin::sub(fc, kin::scale(up, half[2]));
    let lean = (up[0] * back[0] + up[1] * back[1]).atan2(up[2]);
    let r = 2.0 * half[2] - 0.01;
    let at = |a: f64| {
        let p = kin::add(
            pivot,
            kin::add(kin::scale(back, r * a.sin()), [0.0, 0.0, r * a.cos()]),
        );
        kin::sub(p, TIP)
    };
    let a0 = lean + TIP_BEHIND / r;
    rec.go(0, kin::add(at(a0), [0.0, 0.0, 0.06]), down, POINT, 30)?;
    rec.go(0, at(a0), down, POINT, 15)?;
    const SWEEP: usize = 40;
    for k in 1..=SWEEP {
        let a = a0 + (TIP_TO - a0) * k as f64 / SWEEP as f64;
        rec.go(0, at(a), down, POINT, 1)?;
    }
    let here = rec.target(0).0;
    rec.go(0, kin::add(here, [0.0, 0.0, 0.06]), down, POINT, 15)?;
    show(rec, "tipped forwards");
    rec.wait(5)?;
    rec.snap(0, "glasses_tipped");
    Ok(())
}

/// Whether gravity can turn the temple on hinge `joint` against the hinge's friction
/// loss when the hinge's axis lies level (the glasses lying down): its weight times
/// its centre of mass's distance from the axis exceeds the friction loss.
pub(super) fn temple_sags(e: &TaskEnv, joint: &str) -> Result<bool, PlanError> {
    let (j, b) = joint_body(e, joint)?;
    let m = e.data().model();
    let d = e.data();
    let axis = d.xaxis()[j];
    let r = kin::sub(d.xipos()[b], d.xanchor()[j]);
    let along = kin::dot(r, axis);
    let lever = kin::norm(kin::sub(r, kin::scale(axis, along)));
    let g = kin::norm(m.ffi().opt.gravity);
    let torque = m.body_mass()[b] * g * lever;
    let friction = m.dof_frictionloss()[m.jnt_dofadr()[j] as usize];
    if debug() {
        eprintln!("{joint}: gravity torque {torque:.4} friction loss {friction:.4}");
    }
    Ok(torque > friction)
}
