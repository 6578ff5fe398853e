//! The hammer_nail planner: pinch the handle near the head between the thumb and the
//! fingers, lift the hammer face-down over the nail, and strike with the arm (a fast
//! straight-down target step) until the nail is driven in.

use super::kin::{self, V3};
use super::{CLOSE, OPEN, Planned, Recorder, debug};
use crate::env::TaskEnv;
use crate::error::SimError;

/// Where the pinch closes, from the TCP (home orientation, world axes).
const GRIP: V3 = [0.045, 0.011, -0.126];
const GRIP_ALONG: f64 = 0.045;

/// Plans hammer_nail on an environment just restored from its initial state.
pub(crate) fn plan(env: TaskEnv, id: &str) -> Result<Planned, SimError> {
    let s = env.state();
    let home = [s[3], s[4], s[5], s[6]];
    let mut rec = Recorder::new(env);
    // Let the hammer settle before reading its pose.
    rec.wait(30)?;
    let e = rec.env();
    let (hp, m) = kin::body(e, "hammer_body")?;
    let down = [m[0], m[3], m[6]];
    let along = [m[2], m[5], m[8]];
    let handle = kin::geom(e, "handle")?.0;
    let face = kin::geom(e, "face")?.0;
    if debug() {
        eprintln!(
            "hammer at {hp:.3?} down {down:.3?} along {along:.3?} handle {handle:.3?} face {face:.3?}"
        );
    }
    // The pinch axis of the hand at home yaw is world (-1, 1): turn it across the handle.
    let a = along[1].atan2(along[0]);
    let mut yaw = a - std::f64::consts::FRAC_PI_4;
    while yaw > std::f64::consts::FRAC_PI_2 {
        yaw -= std::f64::consts::PI;
    }
    while yaw < -std::f64::consts::FRAC_PI_2 {
        yaw += std::f64::consts::PI;
    }
    let q = kin::qmul(kin::yaw(yaw), home);
    let grip_off = kin::mulv(&kin::qmat(kin::yaw(yaw)), GRIP);
    let g = kin::add(handle, kin::scale(along, GRIP_ALONG));
    let at = kin::sub(g, grip_off);
    rec.go(0, kin::add(at, [0.0, 0.0, 0.12]), q, OPEN, 90)?;
    rec.settle(0.004, 60)?;
    rec.go(0, at, q, OPEN, 50)?;
    rec.settle(0.002, 60)?;
    rec.go(0, at, q, CLOSE, 30)?;
    rec.wait(20)?;
    // Lift well above the board before carrying the hammer over it.
    rec.go(0, kin::add(at, [0.0, 0.0, 0.20]), q, CLOSE, 90)?;
    rec.settle(0.004, 60)?;
    let e = rec.env();
    let face = kin::geom(e, "face")?.0;
    let nail = kin::site(e, "nail_top_site")?;
    let tcp = kin::tcp(e, 0).0;
    let off = kin::sub(face, tcp);
    rec.snap(0, "hammer_lifted");
    if debug() {
        eprintln!("lifted: face {face:.3?} nail top {nail:.3?} tcp {tcp:.3?}");
    }
    let above = kin::sub(kin::add(nail, [0.0, 0.0, 0.06 + 0.024]), off);
    for k in 0..4 {
        rec.go(0, above, q, CLOSE, if k == 0 { 90 } else { 30 })?;
        rec.settle(0.003, 80)?;
        let strike = kin::add(above, [0.0, 0.0, -0.20]);
        rec.go(0, strike, q, CLOSE, 1)?;
        rec.wait(25)?;
        if debug() {
            let e = rec.env();
            eprintln!(
                "strike {k}: step {} depth {:?} face {:.3?}",
                e.steps(),
                e.checker().output("nail", "depth"),
                kin::geom(e, "face")?.0
            );
        }
        if rec.done() {
            break;
        }
    }
    rec.finish(id)
}
