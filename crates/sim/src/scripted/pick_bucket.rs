//! The pick_bucket planner: pinch the food box across its width, carry it over the
//! basket and let go in the half nearer the robot (clear of the upright handle), then
//! grip the handle's bar from above and lift the basket.

use dexjoco_core::HAND_DOF;

use super::kin::{self, V3};
use super::{CLOSE, OPEN, Planned, Recorder, debug};
use crate::env::TaskEnv;
use crate::error::SimError;

/// The fingers closed, the thumb still open.
const HOOK: [f64; HAND_DOF] = [
    0.0, 1.2, 1.2, 1.0, 0.0, 1.2, 1.2, 1.0, 0.0, 1.2, 1.2, 1.0, 0.8, 0.0, 0.2, 0.2,
];
/// The food's centre from the TCP along the thumb-to-fingers axis, and below it.
const FOOD_X: f64 = 0.07;
const FOOD_DOWN: f64 = 0.13;
/// The bar from the TCP along the thumb-to-fingers axis, and below it.
const BAR_X: f64 = 0.05;
const BAR_DOWN: f64 = 0.10;
const BAR_SIDE: f64 = 0.045;

/// The basket's inside box: centre and its x and y axes (world), from its sites.
fn basket(e: &TaskEnv) -> Result<(V3, V3, V3), SimError> {
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
pub(crate) fn plan(env: TaskEnv, id: &str) -> Result<Planned, SimError> {
    let s = env.state();
    let home = [s[3], s[4], s[5], s[6]];
    let mut rec = Recorder::new(env);
    let show = |rec: &Recorder, what: &str| {
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
    };
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
    show(&rec, "food lifted");
    // Over the basket's near half, down, let go.
    let e = rec.env();
    let off = kin::sub(kin::body(e, "boxed_food_0")?.0, kin::tcp(e, 0).0);
    let (c, bx, _) = basket(e)?;
    let spot = kin::add(c, kin::scale(bx, -0.09));
    let over = [spot[0] - off[0], spot[1] - off[1], up[2]];
    rec.go(0, over, q, CLOSE, 100)?;
    rec.settle(0.006, 30)?;
    let low = [over[0], over[1], c[2] - 0.031 + 0.01 - off[2]];
    rec.go(0, low, q, CLOSE, 50)?;
    rec.settle(0.005, 30)?;
    rec.go(0, low, q, OPEN, 20)?;
    rec.go(0, kin::add(low, [0.0, 0.0, 0.25]), q, OPEN, 50)?;
    show(&rec, "food in");
    rec.snap(0, "bucket_food_in");
    // The handle's bar, from above: fingers on its far side.
    let e = rec.env();
    let bar = kin::geom(e, "handle1")?.0;
    let (_, bx, _) = basket(e)?;
    let d = kin::scale(kin::horizontal(bx), 1.0);
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
    show(&rec, "at the bar");
    rec.snap(0, "bucket_at_bar");
    // Fingers first (they hook the bar from its far side), then the thumb.
    rec.go(0, at, q, HOOK, 25)?;
    rec.go(0, at, q, CLOSE, 20)?;
    rec.wait(10)?;
    show(&rec, "bar gripped");
    rec.snap(0, "bucket_bar");
    rec.go(0, kin::add(at, [0.0, 0.0, 0.25]), q, CLOSE, 100)?;
    show(&rec, "lifted");
    rec.wait(30)?;
    show(&rec, "end");
    rec.finish(id)
}
