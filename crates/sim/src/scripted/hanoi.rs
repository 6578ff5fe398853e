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

use super::kin::{self, Q, V3};
use super::{Goal, Planned, Recorder, Variant, debug};
use crate::env::TaskEnv;
use crate::error::SimError;

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

/// Index and ring fingers bent down (base joints `j0`: + spreads them apart, - closes
/// them on each other), the middle finger curled away, the thumb at home.
const fn hand(j0: f64) -> [f64; HAND_DOF] {
    [
        j0, 0.8, 0.8, 0.2, 0.0, 1.6, 1.7, 1.6, -j0, 0.8, 0.8, 0.2, 0.263, 1.1, 1.6, 1.7,
    ]
}
/// Spread: the fingertips clear of the widest disk they straddle.
const SPREAD: [f64; HAND_DOF] = hand(0.25);
/// Closed on each other: the pinch (targets past contact give the squeeze).
const PINCH: [f64; HAND_DOF] = hand(-0.47);

fn disk_pos(e: &TaskEnv, disk: &str) -> Result<V3, SimError> {
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
fn grip_at(e: &TaskEnv, disk: &str) -> Result<V3, SimError> {
    let p = disk_pos(e, disk)?;
    Ok([p[0] - TIP_X, p[1], p[2] + GRIP_UP])
}

/// Grasps the medium disk with the right hand and the small one with the left (both at
/// once: they are on different posts) and lifts both clear of their posts.
fn pick_both(rec: &mut Recorder, rq: Q, lq: Q) -> Result<(), SimError> {
    let r = grip_at(rec.env(), "medium")?;
    let l = grip_at(rec.env(), "small")?;
    let up = |p: V3, dz: f64| kin::add(p, [0.0, 0.0, dz]);
    let both = |r: V3, l: V3, h: [f64; HAND_DOF]| {
        [Goal::new(RIGHT, r, rq, h), Goal::new(LEFT, l, lq, h)]
    };
    rec.go_many(&both(up(r, 0.1), up(l, 0.1), SPREAD), 90, |_| false)?;
    rec.settle(0.01, 30)?;
    show(rec, "above");
    rec.go_many(&both(r, l, SPREAD), 45, |_| false)?;
    rec.settle(0.004, 40)?;
    show(rec, "at");
    rec.snap(RIGHT, "medium_at");
    rec.go_many(&both(r, l, PINCH), 25, |_| false)?;
    rec.wait(10)?;
    show(rec, "pinched");
    rec.snap(RIGHT, "medium_pinched");
    rec.snap(LEFT, "small_pinched");
    rec.go_many(&both(up(r, LIFT), up(l, LIFT), PINCH), 100, |_| false)?;
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
) -> Result<(), SimError> {
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
pub(crate) fn plan(env: TaskEnv, id: &str, variant: Variant) -> Result<Planned, SimError> {
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
        // The medium disk on the base halfway between the middle and right posts: off
        // every post.
        let r = grip_at(rec.env(), "medium")?;
        rec.go(RIGHT, kin::add(r, [0.0, 0.0, 0.1]), rq, SPREAD, 90)?;
        rec.settle(0.01, 30)?;
        rec.go(RIGHT, r, rq, SPREAD, 45)?;
        rec.settle(0.004, 40)?;
        rec.go(RIGHT, r, rq, PINCH, 25)?;
        rec.wait(10)?;
        rec.go(RIGHT, kin::add(r, [0.0, 0.0, LIFT]), rq, PINCH, 100)?;
        let spot = kin::scale(kin::add(post_b, post_c), 0.5);
        place(&mut rec, RIGHT, rq, "medium", spot, top + H)?;
        rec.go(RIGHT, rhome, rq, SPREAD, 80)?;
        rec.wait(60)?;
        show(&rec, "end");
        return rec.finish(id);
    }
    pick_both(&mut rec, rq, lq)?;
    place(&mut rec, RIGHT, rq, "medium", post_c, top + 3.0 * H)?;
    rec.go(RIGHT, rhome, rq, SPREAD, 80)?;
    place(&mut rec, LEFT, lq, "small", post_c, top + 5.0 * H)?;
    rec.go(LEFT, lhome, lq, SPREAD, 80)?;
    rec.wait(60)?;
    show(&rec, "end");
    rec.finish(id)
}
