//! The bimanual_assembly planner: the right hand pinches the peg's grip block across
//! the peg, lifts it, pitches the hand fingers-down so the peg hangs vertical, and
//! lowers it into the tray's socket; the left hand holds the tray down by its base.

use super::kin::{self, Q, V3};
use super::{CLOSE, Goal, OPEN, Planned, Recorder, debug};
use crate::env::TaskEnv;
use crate::error::SimError;

/// Where the grip block goes, from the TCP along the thumb-to-fingers axis.
const GRIP_X: f64 = 0.06;
/// The TCP's height above the table while pinching.
const TCP_Z: f64 = 0.145;
/// Closed-loop turns that stand the peg up.
const TURNS: usize = 3;
/// The closed-loop descent into the socket: steps, metres per step, xy gain.
const DESCENT_STEPS: usize = 220;
const DESCENT_SPEED: f64 = 0.001;
const GAIN: f64 = 0.3;
/// How far the left fingertips' target goes below the tray base's top (m).
const HOLD_PRESS: f64 = 0.01;
/// The left hand's yaw relative to the tray's (its fingers press the base strip they
/// point at).
const LEFT_YAW: f64 = -std::f64::consts::FRAC_PI_2;
/// Left arm.
const LEFT: usize = 1;
/// Right arm.
const RIGHT: usize = 0;

/// Plans bimanual_assembly on an environment just restored from its initial state.
pub(crate) fn plan(env: TaskEnv, id: &str) -> Result<Planned, SimError> {
    let s = env.state();
    let home = [s[3], s[4], s[5], s[6]];
    let mut rec = Recorder::new(env);
    let e = rec.env();
    let table = kin::site(e, "table_top")?[2];
    let (pp, pm) = kin::body(e, "industreal_round_peg_8mm")?;
    let axis = kin::horizontal([pm[2], pm[5], pm[8]]);
    // The fingers along the peg toward its round end: D = the fingers turned -90 deg.
    let f = [-axis[0], -axis[1], 0.0];
    let d = [f[1], -f[0], 0.0];
    let yaw = d[1].atan2(d[0]);
    let q = kin::qmul(kin::yaw(yaw), home);
    let grip = kin::add(pp, kin::mulv(&pm, [0.0, 0.0, 0.19]));
    let mut at = kin::sub(grip, kin::scale(d, GRIP_X));
    at[2] = table + TCP_Z;
    // The left hand holds the tray down: fingertips pressing the strip of its base on
    // the left robot's side of the socket, fingers pointing at the socket.
    let (hold, lq) = tray_hold(e, [s[10], s[11], s[12], s[13]])?;
    rec.go_many(
        &[
            Goal::new(LEFT, kin::add(hold, [0.0, 0.0, 0.08]), lq, OPEN),
            Goal::new(RIGHT, kin::add(at, [0.0, 0.0, 0.1]), q, OPEN),
        ],
        90,
        |_| false,
    )?;
    rec.go(LEFT, hold, lq, OPEN, 30)?;
    rec.settle(0.005, 40)?;
    rec.go(RIGHT, at, q, OPEN, 40)?;
    rec.settle(0.004, 40)?;
    rec.go(RIGHT, at, q, CLOSE, 25)?;
    rec.wait(15)?;
    show(&rec, "pinched");
    rec.snap(RIGHT, "peg_pinched");
    let up = kin::add(at, [0.0, 0.0, 0.25]);
    rec.go(RIGHT, up, q, CLOSE, 70)?;
    // Turn the hand so the peg (read from the simulation) stands up, box on top, twice
    // (the peg may shift in the grasp while turning).
    let qd = stand_peg_up(&mut rec, up, q)?;
    rec.snap(RIGHT, "peg_turned");
    // Over the socket: the peg's round end above the hole, then down into it.
    let e = rec.env();
    let tray = kin::body(e, "industreal_tray_insert_round_peg_8mm")?.0;
    let off = kin::sub(peg_bottom(e)?, kin::tcp(e, RIGHT).0);
    let above = kin::sub([tray[0], tray[1], tray[2] + 0.126 + 0.03], off);
    rec.go(RIGHT, [above[0], above[1], up[2]], qd, CLOSE, 80)?;
    rec.go(RIGHT, above, qd, CLOSE, 40)?;
    rec.settle(0.002, 60)?;
    show(&rec, "above the socket");
    // Correct the residual offset once, measured at the peg.
    let e = rec.env();
    let b = peg_bottom(e)?;
    let err = [tray[0] - b[0], tray[1] - b[1], 0.0];
    let above = kin::add(above, err);
    rec.go(RIGHT, above, qd, CLOSE, 20)?;
    rec.settle(0.0015, 60)?;
    show(&rec, "aligned");
    // Down in a closed loop: every step the target steps down and its xy corrects the
    // peg's round end toward the socket's axis (the peg tilts a little in the grasp).
    lower_into_socket(&mut rec, above, tray, qd)?;
    show(&rec, "inserted");
    rec.snap(RIGHT, "peg_inserted");
    if debug() {
        let e = rec.env();
        let t = kin::body(e, "industreal_tray_insert_round_peg_8mm")?;
        eprintln!(
            "  tray {:.3?} tray z axis {:.2?} peg bottom {:.3?}",
            t.0,
            [t.1[2], t.1[5], t.1[8]],
            peg_bottom(e)?
        );
    }
    rec.wait(60)?;
    show(&rec, "end");
    rec.finish(id)
}

/// In debug mode, prints the peg's position and axis after a phase.
fn show(rec: &Recorder, what: &str) {
    if debug() {
        let e = rec.env();
        let peg = kin::body(e, "industreal_round_peg_8mm");
        eprintln!(
            "{what}: step {} peg {:.3?} axis {:.2?}",
            e.steps(),
            peg.as_ref().map(|b| b.0).unwrap_or_default(),
            peg.map(|b| [b.1[2], b.1[5], b.1[8]]).unwrap_or_default(),
        );
    }
}

/// The left hand's target holding the tray down (fingertips on the strip of its base
/// on the left robot's side of the socket, fingers pointing at the socket), and its
/// orientation from the left hand's home orientation.
fn tray_hold(e: &TaskEnv, left_home: Q) -> Result<(V3, Q), SimError> {
    let (tp, tm) = kin::body(e, "industreal_tray_insert_round_peg_8mm")?;
    let tyaw = tm[3].atan2(tm[0]);
    let lyaw = tyaw + LEFT_YAW;
    let lq = kin::qmul(kin::yaw(lyaw), left_home);
    let strip = kin::add(
        tp,
        kin::mulv(
            &tm,
            [-0.075 * LEFT_YAW.cos(), -0.075 * LEFT_YAW.sin(), 0.0134],
        ),
    );
    let mut hold = kin::sub(
        strip,
        kin::mulv(&kin::qmat(kin::yaw(lyaw)), [0.15, 0.0, 0.0]),
    );
    hold[2] = strip[2] + 0.096 + 0.012 - HOLD_PRESS;
    Ok((hold, lq))
}

/// Turns the right hand, closed loop, until the pinched peg stands up; returns the
/// hand's orientation.
fn stand_peg_up(rec: &mut Recorder, up: V3, q: Q) -> Result<Q, SimError> {
    let mut qd = q;
    for k in 0..TURNS {
        let e = rec.env();
        let pm = kin::body(e, "industreal_round_peg_8mm")?.1;
        let a = [pm[2], pm[5], pm[8]];
        let c = [a[1], -a[0], 0.0]; // a x z
        let n = kin::norm(c);
        if n > 1e-6 {
            let angle = a[2].clamp(-1.0, 1.0).acos();
            let turn = kin::axis_angle(kin::scale(c, 1.0 / n), angle);
            qd = kin::qmul(turn, rec.target(RIGHT).1);
        }
        rec.go(RIGHT, up, qd, CLOSE, if k == 0 { 80 } else { 30 })?;
        rec.wait(40)?;
        show(rec, &format!("turned {k}"));
    }
    Ok(qd)
}

/// The peg's round end.
fn peg_bottom(e: &TaskEnv) -> Result<V3, SimError> {
    let (p, m) = kin::body(e, "industreal_round_peg_8mm")?;
    Ok(kin::add(p, kin::mulv(&m, [0.0, 0.0, 0.0135])))
}

/// Lowers the peg from `above` into the socket at `tray`, correcting xy every step.
fn lower_into_socket(rec: &mut Recorder, above: V3, tray: V3, qd: Q) -> Result<(), SimError> {
    let mut target = above;
    for _ in 0..DESCENT_STEPS {
        if rec.done() {
            break;
        }
        let b = peg_bottom(rec.env())?;
        target[0] += (GAIN * (tray[0] - b[0])).clamp(-0.002, 0.002);
        target[1] += (GAIN * (tray[1] - b[1])).clamp(-0.002, 0.002);
        target[2] = (target[2] - DESCENT_SPEED).max(above[2] - 0.17);
        rec.go(RIGHT, target, qd, CLOSE, 1)?;
    }
    Ok(())
}
