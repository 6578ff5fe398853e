//! The pinch_tongs planner: the hand comes down over the tongs' grip pads with the
//! thumb outside one arm and the fingers outside the other, squeezes them shut three
//! times on the table (opening the hand between squeezes so the spring reopens them),
//! then keeps them squeezed and lifts them.

use super::kin::{self, V3};
use super::{CLOSE, OPEN, Planned, Recorder, debug};
use crate::env::TaskEnv;
use crate::error::SimError;

/// Where the squeeze closes, from the TCP (home orientation, world axes): between the
/// thumb tip and the middle fingertip of [`CLOSE`].
const GRIP: V3 = [0.045, 0.011, -0.126];

/// Plans pinch_tongs on an environment just restored from its initial state.
pub(crate) fn plan(env: TaskEnv, id: &str) -> Result<Planned, SimError> {
    let s = env.state();
    let q = [s[3], s[4], s[5], s[6]];
    let table = kin::site(&env, "table_top")?[2];
    // The grip pads: 0.22 m from the hinge toward the tips (link_1's -z axis).
    let (_, m) = kin::body(&env, "link_1")?;
    let hinge = kin::anchor(&env, "joint_0")?;
    let c = kin::sub(hinge, kin::scale([m[2], m[5], m[8]], 0.22));
    let grip = [c[0], c[1], table + 0.015];
    let at = kin::sub(grip, GRIP);
    let mut rec = Recorder::new(env);
    let show = |rec: &Recorder, what: &str| {
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
    };
    rec.go(0, kin::add(at, [0.0, 0.0, 0.12]), q, OPEN, 90)?;
    rec.settle(0.004, 60)?;
    rec.go(0, at, q, OPEN, 50)?;
    rec.settle(0.002, 60)?;
    show(&rec, "arrived");
    for k in 0..3 {
        rec.go(0, at, q, CLOSE, 25)?;
        rec.wait(15)?;
        show(&rec, &format!("closed {k}"));
        rec.snap(0, &format!("tongs_closed_{k}"));
        rec.go(0, at, q, OPEN, 20)?;
        rec.wait(15)?;
        show(&rec, &format!("opened {k}"));
    }
    rec.go(0, at, q, CLOSE, 25)?;
    rec.wait(15)?;
    rec.go(0, kin::add(at, [0.0, 0.0, 0.15]), q, CLOSE, 80)?;
    show(&rec, "lifted");
    rec.wait(60)?;
    show(&rec, "end");
    rec.finish(id)
}
