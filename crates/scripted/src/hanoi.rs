//! The bimanual_hanoi planner: the last two moves of the three-disk tower, each by a
//! lateral pinch. The hand reaches over the disk with the palm on the robot's side of
//! the post (fingers +x), the middle finger curled away; index and ring fingers pointing
//! down straddle the post and close sideways (their base joints) on the disk's two side
//! faces, a pinch through its centre. The right hand lifts the medium disk off the middle
//! post, carries it over the right post and lowers it onto the large disk; then the left
//! hand does the same with the small disk from the left post. Releases, retreats and
//! holds still until the stack has been held. The wrong plan sets the medium disk down
//! on the base between the posts (a disk on the table: illegal).

use dexjoco_core::HAND_DOF;

use super::hands::hanoi_hand;
use super::kin::{self, Q, V3};
use super::{Goal, Planned, Recorder, Variant, debug};
use crate::PlanError;
use dexjoco_sim::TaskEnv;

const RIGHT: usize = 0;
const LEFT: usize = 1;
/// Disk half-height.
const H: f64 = 0.02475;
/// The pinch line (the fingertips) ahead of the TCP along the fingers.
const TIP_X: f64 = 0.093;
/// The TCP above the disk's centre while pinching.
const GRIP_UP: f64 = 0.136;
/// How high a disk is carried (centre above its resting height on the base).
const LIFT: f64 = 0.215;

/// Spread: the fingertips clear of the widest disk they straddle.
const SPREAD: [f64; HAND_DOF] = hanoi_hand(0.25);
/// Closed on each other: the pinch (targets past contact give the squeeze).
const PINCH: [f64; HAND_DOF] = hanoi_hand(-0.47);

fn disk_pos(e: &TaskEnv, disk: &str) -> Result<V3, PlanError> {
    Ok(kin::body(e, &format!("hanoi_disk_{disk}"))?.0)
}

fn show(rec: &Recorder, what: &str) {
    if debug() {
        let e = rec.env();
        let p = |d: &str| disk_pos(e, d).unwrap_or_default();
        let err = |a: usize| kin::norm(kin::sub(kin::tcp(e, a).0, e.targets()[a].0)) * 1000.0;
        eprintln!(
            "{what}: step {} err {:.1}/{:.1} mm large {:.3?} medium {:.3?} small {:.3?} done {:?} illegal {:?}",
            e.steps(),
            err(0),
            err(1),
            p("large"),
            p("medium"),
            p("small"),
            e.checker().value("hanoi"),
            e.checker().output("hanoi", "illegal"),
        );
    }
}

/// Where `arm`'s TCP pinches `disk` now.
fn grip_at(e: &TaskEnv, disk: &str) -> Result<V3, PlanError> {
    let p = disk_pos(e, disk)?;
    Ok([p[0] - TIP_X, p[1], p[2] + GRIP_UP])
}

/// Brings each `(arm, orientation, disk)` hand around its disk, fingers spread
/// (nothing touched yet), all at once; returns where each TCP pinches.
fn reach(rec: &mut Recorder, hands: &[(usize, Q, &str)]) -> Result<Vec<V3>, PlanError> {
    let at = hands
        .iter()
        .map(|&(_, _, disk)| grip_at(rec.env(), disk))
        .collect::<Result<Vec<_>, _>>()?;
    let goals = |dz: f64| -> Vec<Goal> {
        hands
            .iter()
            .zip(&at)
            .map(|(&(arm, q, _), &p)| Goal::new(arm, kin::add(p, [0.0, 0.0, dz]), q, SPREAD))
            .collect()
    };
    rec.go_many(&goals(0.1), 90, |_| false)?;
    rec.settle(0.01, 30)?;
    show(rec, "above");
    rec.go_many(&goals(0.0), 45, |_| false)?;
    rec.settle(0.004, 40)?;
    show(rec, "around");
    rec.snap(hands[0].0, "around");
    Ok(at)
}

/// Closes `arm`'s pinch at `at` over `steps` steps (other arms as in `others`
/// meanwhile) and lifts the disk clear of its post, straight up.
fn pinch_lift(
    rec: &mut Recorder,
    arm: usize,
    q: Q,
    at: V3,
    steps: usize,
    others: &[Goal],
) -> Result<(), PlanError> {
    let mut goals = others.to_vec();
    goals.push(Goal::new(arm, at, q, PINCH));
    rec.go_many(&goals, steps, |_| false)?;
    rec.wait(10)?;
    show(rec, "pinched");
    rec.snap(arm, &format!("pinched_{arm}"));
    let up = kin::add(at, [0.0, 0.0, LIFT]);
    rec.go(arm, up, q, PINCH, 100)?;
    rec.settle(0.005, 30)?;
    show(rec, "lifted");
    Ok(())
}

/// Carries the held `disk` over `post` (a site at the post's top) and lowers it to
/// centre height `land`, then lets go and rises clear of the post.
fn place(
    rec: &mut Recorder,
    arm: usize,
    q: Q,
    disk: &str,
    post: V3,
    land: f64,
) -> Result<(), PlanError> {
    let e = rec.env();
    let off = kin::sub(disk_pos(e, disk)?, kin::tcp(e, arm).0);
    let z = rec.target(arm).0[2];
    let over = [post[0] - off[0], post[1] - off[1], z];
    rec.go(arm, over, q, PINCH, 120)?;
    rec.settle(0.004, 40)?;
    // Correct the residual offset, measured at the disk.
    let d = disk_pos(rec.env(), disk)?;
    let over = kin::add(over, [post[0] - d[0], post[1] - d[1], 0.0]);
    rec.go(arm, over, q, PINCH, 15)?;
    rec.settle(0.003, 30)?;
    show(rec, &format!("{disk} over"));
    rec.snap(arm, &format!("{disk}_over"));
    let e = rec.env();
    let off = kin::sub(disk_pos(e, disk)?, kin::tcp(e, arm).0);
    let low = [over[0], over[1], land - off[2] + 0.004];
    rec.go(arm, low, q, PINCH, 80)?;
    rec.settle(0.004, 30)?;
    show(rec, &format!("{disk} down"));
    rec.snap(arm, &format!("{disk}_down"));
    rec.go(arm, low, q, SPREAD, 20)?;
    rec.go(arm, kin::add(low, [0.0, 0.0, 0.15]), q, SPREAD, 60)?;
    show(rec, &format!("{disk} released"));
    Ok(())
}

/// Plans bimanual_hanoi on an environment just restored from its initial state.
pub(crate) fn plan(env: TaskEnv, id: &str, variant: Variant) -> Result<Planned, PlanError> {
    let s = env.state();
    let rq = [s[3], s[4], s[5], s[6]];
    let lq = [s[10], s[11], s[12], s[13]];
    let rhome = [s[0], s[1], s[2]];
    let lhome = [s[7], s[8], s[9]];
    let mut rec = Recorder::new(env);
    let e = rec.env();
    let top = kin::body(e, "hanoi_base")?.0[2] + 0.036;
    let post_b = kin::site(e, "hanoi_post_b_site")?;
    let post_c = kin::site(e, "hanoi_post_c_site")?;
    show(&rec, "start");
    if variant == Variant::Wrong {
        // The medium disk set down on the base halfway between the middle and right
        // posts: off every post, on the table.
        let r = reach(&mut rec, &[(RIGHT, rq, "medium")])?[0];
        pinch_lift(&mut rec, RIGHT, rq, r, 25, &[])?;
        let spot = kin::scale(kin::add(post_b, post_c), 0.5);
        place(&mut rec, RIGHT, rq, "medium", spot, top + H)?;
        rec.go(RIGHT, rhome, rq, SPREAD, 80)?;
        rec.wait(60)?;
        show(&rec, "end");
        return rec.finish(id);
    }
    // The right hand moves the medium disk while the left waits around the small one.
    let at = reach(&mut rec, &[(RIGHT, rq, "medium"), (LEFT, lq, "small")])?;
    pinch_lift(&mut rec, RIGHT, rq, at[0], 25, &[])?;
    place(&mut rec, RIGHT, rq, "medium", post_c, top + 3.0 * H)?;
    rec.phase("move_medium_disk");
    // Then the left hand moves the small disk; the right one goes home meanwhile.
    let home = [Goal::new(RIGHT, rhome, rq, SPREAD)];
    pinch_lift(&mut rec, LEFT, lq, at[1], 60, &home)?;
    place(&mut rec, LEFT, lq, "small", post_c, top + 5.0 * H)?;
    rec.go(LEFT, lhome, lq, SPREAD, 80)?;
    rec.wait(60)?;
    show(&rec, "end");
    rec.phase("move_small_disk");
    rec.finish(id)
}
