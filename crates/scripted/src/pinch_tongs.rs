//! The pinch_tongs planner: palm down, the hand yawed so its fingers point across both
//! arms of the tongs (from the fixed arm's side toward the swinging arm), the thumb
//! outside the fixed arm near the hinge and the fingertips outside the swinging arm
//! further out. Closing the hand pulls the arms together: two squeezes on the table,
//! each followed by opening the hand and rising a little so the spring reopens the tongs
//! (re-arming the pinch counter), then a third squeeze that keeps the arm trapped under
//! the curled fingers while the hand lifts the tongs.

use super::kin::{self, Q, V3};
use super::{CLOSE, OPEN, Planned, Recorder, debug};
use crate::PlanError;
use dexjoco_sim::TaskEnv;

/// Where the middle fingertip crosses the tongs: this far from the hinge toward the tips.
const CROSS: f64 = 0.22;
/// The TCP's offset from the tongs' axis toward the fixed arm (`link_1`'s +x side): the
/// open hand then reaches from outside the fixed arm (thumb, 0.16 m behind the
/// fingertips along the fingers) to outside the swinging arm (fingertips).
const ACROSS: f64 = 0.045;
/// The TCP's height above the table top while squeezing (the open fingertips come down
/// to about 30 mm above the table, the thumb tip to about 7 mm).
const HEIGHT: f64 = 0.125;
/// How far the open hand rises between squeezes so the spring can reopen the tongs.
const RISE: f64 = 0.04;
/// How far the closed hand lifts the tongs at the end.
const LIFT: f64 = 0.15;

/// Plans pinch_tongs on an environment just restored from its initial state.
pub(crate) fn plan(env: TaskEnv, id: &str) -> Result<Planned, PlanError> {
    let s = env.state();
    let home = [s[3], s[4], s[5], s[6]];
    let table = kin::site(&env, "table_top")?[2];
    let (mut at, mut q) = grip(&env, home, table)?;
    let mut rec = Recorder::new(env);
    rec.go(0, kin::add(at, [0.0, 0.0, 0.12]), q, OPEN, 90)?;
    rec.settle(0.004, 60)?;
    rec.go(0, at, q, OPEN, 50)?;
    rec.settle(0.002, 60)?;
    show(&rec, table, "arrived");
    for k in 0..2 {
        rec.go(0, at, q, CLOSE, 25)?;
        rec.wait(15)?;
        show(&rec, table, &format!("closed {k}"));
        rec.snap(0, &format!("tongs_closed_{k}"));
        if k == 0 {
            // The first squeeze closes the hand on the tongs.
            rec.phase("grasp_tongs");
        }
        rec.go(0, kin::add(at, [0.0, 0.0, RISE]), q, OPEN, 25)?;
        rec.wait(20)?;
        show(&rec, table, &format!("opened {k}"));
        // The squeeze may have moved the tongs: come down on them where they are now.
        (at, q) = grip(rec.env(), home, table)?;
        rec.go(0, kin::add(at, [0.0, 0.0, RISE]), q, OPEN, 15)?;
        rec.go(0, at, q, OPEN, 25)?;
        rec.settle(0.002, 40)?;
    }
    rec.go(0, at, q, CLOSE, 25)?;
    rec.wait(15)?;
    show(&rec, table, "closed 2");
    // The third squeeze: three pinches.
    rec.phase("pinch_tongs");
    rec.go(0, kin::add(at, [0.0, 0.0, LIFT]), q, CLOSE, 80)?;
    show(&rec, table, "lifted");
    rec.wait(60)?;
    show(&rec, table, "end");
    rec.phase("lift_tongs");
    rec.finish(id)
}

/// The TCP target and orientation for squeezing the tongs where they lie now: the hinge
/// and the arms' directions come from the model (joint `joint_0`'s anchor, `link_1`'s
/// frame: z along the arms toward the hinge, x from the swinging arm to the fixed one).
fn grip(env: &TaskEnv, home: Q, table: f64) -> Result<(V3, Q), PlanError> {
    let (_, m) = kin::body(env, "link_1")?;
    let hinge = kin::anchor(env, "joint_0")?;
    let along = kin::horizontal([m[2], m[5], m[8]]);
    let across = kin::horizontal([m[0], m[3], m[6]]);
    // Home orientation has the fingers along world +x: yaw them along -across.
    let q = kin::qmul(kin::yaw((-across[1]).atan2(-across[0])), home);
    let p = kin::add(
        kin::sub(hinge, kin::scale(along, CROSS)),
        kin::scale(across, ACROSS),
    );
    Ok(([p[0], p[1], table + HEIGHT], q))
}

/// With `DEXJOCO_PLAN_DEBUG`: the hinge, the tongs' height and the pinch count.
fn show(rec: &Recorder, table: f64, what: &str) {
    if debug() {
        let e = rec.env();
        eprintln!(
            "{what}: step {} joint_0 {:.3} tongs z {:.3} pinches {:?}",
            e.steps(),
            kin::joint(e, "joint_0").unwrap_or(f64::NAN),
            kin::geom(e, "tongs")
                .map(|g| g.0[2] - table)
                .unwrap_or(f64::NAN),
            e.checker().output("pinches", "count"),
        );
    }
}
