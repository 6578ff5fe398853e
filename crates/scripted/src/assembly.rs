//! The bimanual_assembly planner: the right hand pinches the peg's grip block across
//! the peg and lifts it while the left fingertips push the tray by its socket block
//! toward the middle of the table (within easy reach of both arms); the right hand
//! pitches fingers-down so the peg hangs vertical, the left fingertips hold the tray
//! down by its base, and the right hand brings the peg's round end over the hole, turns
//! and re-centres it on the measured tilt and offset until it is within a millimetre,
//! and lowers it slowly into the socket (the left hand lets go of the tray once the peg
//! is 5 cm in, out of the right hand's way). 7 cm in, before the pinching index finger
//! reaches the rim, the right hand opens and the peg slides down onto the hole's bottom.
//! The peg and the tray's geometry (round end, rim, base, socket block) is read from
//! their collision geoms.

use dexjoco_core::NameKind;

use super::kin::{self, Q, V3};
use super::{CLOSE, Goal, OPEN, Planned, Recorder, debug};
use crate::PlanError;
use dexjoco_sim::TaskEnv;
use dexjoco_sim::name_id;

/// Where the grip block goes, from the TCP along the thumb-to-fingers axis.
const GRIP_X: f64 = 0.06;
/// The TCP's height above the table while pinching.
const TCP_Z: f64 = 0.145;
/// Closed-loop turns that stand the peg up.
const TURNS: usize = 3;
/// The descent into the socket: metres per step, the xy gain on the peg's offset from
/// the hole's axis while its round end is above the rim, and how far the target may
/// lead the TCP downward (the push stays gentle when the peg stops).
const DESCENT_SPEED: f64 = 0.0007;
const GAIN: f64 = 0.15;
const LEAD: f64 = 0.03;
/// How deep the peg's round end is in the hole when the left hand lets go (m).
const INSIDE: f64 = 0.05;
/// How deep the peg's round end is in the hole when the right hand lets go of it (m;
/// the pinching index finger's middle link reaches the rim at 6.8 to 8.6 cm).
const DROP_DEPTH: f64 = 0.07;
/// Steps without the peg going down 0.5 mm after which the right hand lets go anyway.
const STALL: usize = 15;
/// The most steps the let-go peg is given to settle onto the hole's bottom.
const SETTLE: usize = 200;
/// The round end's height above the rim while re-centring (m), the offset accepted
/// (m) and the most re-centring rounds.
const HOVER: f64 = 0.02;
const CENTRED: f64 = 0.0008;
const ROUNDS: usize = 5;
/// The peg axis' horizontal part accepted after re-centring.
const TILT: f64 = 0.008;
/// How far the left fingertips' target goes below the tray base's top (m).
const HOLD_PRESS: f64 = 0.01;
/// The left fingertips' height above the base's top while pushing the tray (m).
const PUSH_UP: f64 = 0.008;
/// Where the tray is pushed: its hole this far toward the left arm from the middle
/// between the arms' start positions (m).
const TRAY_TO: f64 = 0.05;
/// The left hand's yaw relative to the tray's (its fingers press the base strip they
/// point at).
const LEFT_YAW: f64 = -std::f64::consts::FRAC_PI_2;
/// The left fingertips from the left TCP: ahead along the fingers, and below.
const TIP_AHEAD: f64 = 0.15;
const TIP_DOWN: f64 = 0.108;
/// Left arm.
const LEFT: usize = 1;
/// Right arm.
const RIGHT: usize = 0;
const PEG: &str = "industreal_round_peg_8mm";
const TRAY: &str = "industreal_tray_insert_round_peg_8mm";

/// Plans bimanual_assembly on an environment just restored from its initial state.
pub(crate) fn plan(env: TaskEnv, id: &str) -> Result<Planned, PlanError> {
    let s = env.state();
    let home = [s[3], s[4], s[5], s[6]];
    let left_home = [s[10], s[11], s[12], s[13]];
    let middle = (s[1] + s[8]) / 2.0;
    let mut rec = Recorder::new(env);
    let shape = Shape::measure(rec.env())?;
    let (at, q) = pinch_and_push(&mut rec, &shape, home, left_home, middle)?;
    let up = kin::add(at, [0.0, 0.0, 0.25]);
    // Turn the hand so the peg (read from the simulation) stands up, box on top, in
    // rounds (the peg may shift in the grasp while turning).
    let qd = stand_peg_up(&mut rec, up, q)?;
    rec.snap(RIGHT, "peg_turned");
    let (above, qd) = over_the_hole(&mut rec, &shape, left_home, up, qd)?;
    lower_into_socket(&mut rec, &shape, above, qd)?;
    show(&rec, "inserted");
    rec.snap(RIGHT, "peg_inserted");
    // The peg settles onto the hole's bottom (the recording ends once it has rested
    // there long enough).
    rec.wait(SETTLE)?;
    rec.phase("insert_peg");
    show(&rec, "end");
    rec.finish(id)
}

/// The peg's and the tray's geometry, read from the model's collision geoms (boxes and
/// cylinders, in their bodies' frames).
#[derive(Debug)]
struct Shape {
    /// The peg's round end along its axis.
    peg_end: f64,
    /// The top of the tray's socket walls (the hole's rim).
    rim: f64,
    /// The top of the tray's base plate.
    base_top: f64,
    /// The socket block's half width, and where the left fingertips go on the base's
    /// strip beside it (from the hole's axis).
    block_half: f64,
    strip: f64,
}

impl Shape {
    fn measure(e: &TaskEnv) -> Result<Self, PlanError> {
        let m = e.data().model();
        let geoms = |body: &str| -> Result<Vec<(V3, V3)>, PlanError> {
            let b =
                name_id(m, NameKind::Body, body).ok_or_else(|| PlanError::lacks("body", body))?;
            Ok((0..m.ffi().ngeom as usize)
                .filter(|&g| m.geom_bodyid()[g] as usize == b && m.geom_contype()[g] != 0)
                .map(|g| {
                    let [a, b, c] = m.geom_size()[g];
                    // A cylinder's size is (radius, half length, 0).
                    let half = if c > 0.0 { [a, b, c] } else { [a, a, b] };
                    (m.geom_pos()[g], half)
                })
                .collect())
        };
        let peg = geoms(PEG)?;
        let tray = geoms(TRAY)?;
        let peg_end = peg
            .iter()
            .map(|(p, h)| p[2] - h[2])
            .fold(f64::MAX, f64::min);
        let rim = tray
            .iter()
            .map(|(p, h)| p[2] + h[2])
            .fold(f64::MIN, f64::max);
        let base = tray
            .iter()
            .max_by(|a, b| (a.1[0] * a.1[1]).total_cmp(&(b.1[0] * b.1[1])))
            .ok_or_else(|| PlanError::lacks("collision geom of body", "tray"))?;
        let base_half = base.1[0].min(base.1[1]);
        let block_half = tray
            .iter()
            .filter(|(_, h)| h[0].min(h[1]) < base_half)
            .map(|(p, h)| (p[0].abs() + h[0]).max(p[1].abs() + h[1]))
            .fold(0.0, f64::max);
        Ok(Self {
            peg_end,
            rim,
            base_top: base.0[2] + base.1[2],
            block_half,
            strip: block_half + 0.6 * (base_half - block_half),
        })
    }
}

/// Both hands to their grips; the right hand pinches the peg and lifts it while the
/// left fingertips push the tray by its socket block toward `middle` (world y).
/// Returns the pinch's TCP target and orientation.
fn pinch_and_push(
    rec: &mut Recorder,
    shape: &Shape,
    home: Q,
    left_home: Q,
    middle: f64,
) -> Result<(V3, Q), PlanError> {
    let e = rec.env();
    let table = kin::site(e, "table_top")?[2];
    let (pp, pm) = kin::body(e, PEG)?;
    let axis = kin::horizontal([pm[2], pm[5], pm[8]]);
    // The fingers along the peg toward its round end: D = the fingers turned -90 deg.
    let f = [-axis[0], -axis[1], 0.0];
    let d = [f[1], -f[0], 0.0];
    let yaw = d[1].atan2(d[0]);
    let q = kin::qmul(kin::yaw(yaw), home);
    let grip = kin::add(pp, kin::mulv(&pm, [0.0, 0.0, 0.19]));
    let mut at = kin::sub(grip, kin::scale(d, GRIP_X));
    at[2] = table + TCP_Z;
    // The left fingertips come down beside the socket block on the left arm's side of
    // it (between the block and the base's edge) and push it along the fingers.
    let (start, lq, dir) = left_tips(e, shape, left_home, PUSH_UP)?;
    let (tp, _) = kin::body(e, TRAY)?;
    let dist = ((tp[1] - middle - TRAY_TO) / dir[1].abs().max(0.5)).max(0.0) + shape.strip
        - shape.block_half;
    let end = kin::add(start, kin::scale(dir, dist));
    rec.go_many(
        &[
            Goal::new(LEFT, kin::add(start, [0.0, 0.0, 0.08]), lq, OPEN),
            Goal::new(RIGHT, kin::add(at, [0.0, 0.0, 0.1]), q, OPEN),
        ],
        90,
        |_| false,
    )?;
    rec.go_many(
        &[
            Goal::new(LEFT, start, lq, OPEN),
            Goal::new(RIGHT, at, q, OPEN),
        ],
        40,
        |_| false,
    )?;
    // The left fingertips are down beside the socket block, ready to push.
    rec.phase("reach_tray");
    rec.settle(0.004, 40)?;
    rec.go(RIGHT, at, q, CLOSE, 25)?;
    rec.wait(15)?;
    show(rec, "pinched");
    rec.snap(RIGHT, "peg_pinched");
    let up = kin::add(at, [0.0, 0.0, 0.25]);
    rec.go_many(
        &[
            Goal::new(LEFT, end, lq, OPEN),
            Goal::new(RIGHT, up, q, CLOSE),
        ],
        110,
        |_| false,
    )?;
    // The peg is pinched and lifted.
    rec.phase("grasp_peg");
    let back = kin::add(kin::sub(end, kin::scale(dir, 0.02)), [0.0, 0.0, 0.03]);
    rec.go(LEFT, back, lq, OPEN, 15)?;
    show(rec, "tray pushed");
    Ok((at, q))
}

/// The left TCP target that puts its fingertips on the base's strip beside the socket
/// block on the left arm's side (along the tray's +y), `up` above the base's top,
/// fingers pointing at the hole; its orientation; the fingers' direction.
fn left_tips(e: &TaskEnv, shape: &Shape, left_home: Q, up: f64) -> Result<(V3, Q, V3), PlanError> {
    let (tp, tm) = kin::body(e, TRAY)?;
    let tyaw = tm[3].atan2(tm[0]);
    let lyaw = tyaw + LEFT_YAW;
    let lq = kin::qmul(kin::yaw(lyaw), left_home);
    let tip = kin::add(tp, kin::mulv(&tm, [0.0, shape.strip, shape.base_top]));
    let dir = [lyaw.cos(), lyaw.sin(), 0.0];
    let mut p = kin::sub(tip, kin::scale(dir, TIP_AHEAD));
    p[2] = tip[2] + TIP_DOWN + up;
    Ok((p, lq, dir))
}

/// The left fingertips hold the tray down by its base; the right hand brings the peg's
/// round end over the hole, and turns and re-centres it on the measured tilt and
/// offset. Returns the TCP target there and the hand's orientation.
fn over_the_hole(
    rec: &mut Recorder,
    shape: &Shape,
    left_home: Q,
    up: V3,
    qd: Q,
) -> Result<(V3, Q), PlanError> {
    let e = rec.env();
    let (hold, lq, _) = left_tips(e, shape, left_home, -HOLD_PRESS)?;
    let tray = hole(e, shape)?;
    let off = kin::sub(peg_bottom(e, shape)?, kin::tcp(e, RIGHT).0);
    let mut above = kin::sub(kin::add(tray, [0.0, 0.0, 0.03]), off);
    rec.go_many(
        &[
            Goal::new(LEFT, kin::add(hold, [0.0, 0.0, 0.03]), lq, OPEN),
            Goal::new(RIGHT, [above[0], above[1], up[2]], qd, CLOSE),
        ],
        80,
        |_| false,
    )?;
    rec.go_many(
        &[
            Goal::new(LEFT, hold, lq, OPEN),
            Goal::new(RIGHT, above, qd, CLOSE),
        ],
        40,
        |_| false,
    )?;
    rec.wait(30)?;
    show(rec, "above the socket");
    rec.snap(RIGHT, "peg_above");
    above[2] -= 0.03 - HOVER;
    let mut qd = qd;
    for k in 0..ROUNDS {
        let e = rec.env();
        let tray = hole(e, shape)?;
        // Turn the hand about the TCP so the peg's axis stands vertical, and shift it
        // so the round end (where the turn takes it) is over the hole's centre.
        let pm = kin::body(e, PEG)?.1;
        let a = [pm[2], pm[5], pm[8]];
        let tilt = a[0].hypot(a[1]);
        let tcp = kin::tcp(e, RIGHT).0;
        let mut b = peg_bottom(e, shape)?;
        if tilt > 1e-6 {
            let turn = kin::axis_angle(
                [a[1] / tilt, -a[0] / tilt, 0.0],
                a[2].clamp(-1.0, 1.0).acos(),
            );
            qd = kin::qmul(turn, qd);
            b = kin::add(tcp, kin::mulv(&kin::qmat(turn), kin::sub(b, tcp)));
        }
        let err = [tray[0] - b[0], tray[1] - b[1], 0.0];
        if debug() {
            eprintln!("  centring {k}: offset {err:.4?} tilt {tilt:.4}");
        }
        if k > 0 && kin::norm(err) < CENTRED && tilt < TILT {
            break;
        }
        above = kin::add(above, err);
        rec.go(RIGHT, above, qd, CLOSE, 20)?;
        rec.wait(25)?;
    }
    show(rec, "aligned");
    Ok((above, qd))
}

/// In debug mode, prints after a phase whether the peg is at the bottom, its position
/// and axis, the right TCP's distance from its target and the tray's position.
fn show(rec: &Recorder, what: &str) {
    if debug() {
        let e = rec.env();
        let peg = kin::body(e, PEG);
        let (tp, _) = kin::tcp(e, RIGHT);
        let (gp, _) = rec.target(RIGHT);
        eprintln!(
            "{what}: step {} at bottom {:?} peg {:.3?} axis {:.2?} tcp err {:.4} tray {:.3?}",
            e.steps(),
            e.checker().value("peg_at_bottom"),
            peg.as_ref().map(|b| b.0).unwrap_or_default(),
            peg.as_ref()
                .map(|b| [b.1[2], b.1[5], b.1[8]])
                .unwrap_or_default(),
            kin::norm(kin::sub(tp, gp)),
            kin::body(e, TRAY).map(|b| b.0).unwrap_or_default(),
        );
    }
}

/// Turns the right hand, closed loop, until the pinched peg stands up; returns the
/// hand's orientation.
fn stand_peg_up(rec: &mut Recorder, up: V3, q: Q) -> Result<Q, PlanError> {
    let mut qd = q;
    for k in 0..TURNS {
        let e = rec.env();
        let pm = kin::body(e, PEG)?.1;
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

/// The centre of the hole's rim.
fn hole(e: &TaskEnv, shape: &Shape) -> Result<V3, PlanError> {
    let (p, m) = kin::body(e, TRAY)?;
    Ok(kin::add(p, kin::mulv(&m, [0.0, 0.0, shape.rim])))
}

/// The peg's round end.
fn peg_bottom(e: &TaskEnv, shape: &Shape) -> Result<V3, PlanError> {
    let (p, m) = kin::body(e, PEG)?;
    Ok(kin::add(p, kin::mulv(&m, [0.0, 0.0, shape.peg_end])))
}

/// Lowers the peg from `above` into the socket whose rim's centre is `tray`, correcting
/// xy toward the hole's axis while the round end is above the rim; the target leads
/// the TCP down by at most [`LEAD`].
fn lower_into_socket(rec: &mut Recorder, shape: &Shape, above: V3, qd: Q) -> Result<(), PlanError> {
    let mut target = above;
    let floor = above[2] - HOVER - (shape.rim - shape.base_top) - 0.03;
    let mut left: Option<(V3, V3, Q, usize)> = None;
    let (mut lowest, mut since) = (f64::MAX, 0);
    while !rec.done() && target[2] > floor {
        let e = rec.env();
        let tray = hole(e, shape)?;
        let b = peg_bottom(e, shape)?;
        if b[2] > tray[2] {
            target[0] += (GAIN * (tray[0] - b[0])).clamp(-0.001, 0.001);
            target[1] += (GAIN * (tray[1] - b[1])).clamp(-0.001, 0.001);
        }
        let tcp = kin::tcp(e, RIGHT).0;
        if b[2] < lowest - 0.0005 {
            (lowest, since) = (b[2], 0);
        }
        since += 1;
        let stalled = since > STALL && b[2] < tray[2] - INSIDE;
        if b[2] < tray[2] - DROP_DEPTH || stalled {
            // Deep in the hole, before the pinching index finger reaches the rim (or
            // once the peg stops going down there): let go where the hand is; the
            // walls guide the peg down onto the bottom.
            rec.go(RIGHT, tcp, qd, OPEN, 10)?;
            show(rec, "let go");
            break;
        }
        target[2] = (target[2] - DESCENT_SPEED).max(tcp[2] - LEAD);
        // Once the peg is well inside the walls, the left hand lets go of the tray and
        // backs away (up, away from the hole) out of the right hand's way.
        if left.is_none() && b[2] < tray[2] - INSIDE {
            let (p, q) = rec.target(LEFT);
            let away = kin::horizontal(kin::sub(p, tray));
            let to = kin::add(kin::add(p, kin::scale(away, 0.06)), [0.0, 0.0, 0.08]);
            left = Some((p, to, q, 0));
        }
        let mut goals = vec![Goal::new(RIGHT, target, qd, CLOSE)];
        if let Some((from, to, q, k)) = left.as_mut() {
            *k = (*k + 1).min(40);
            let t = *k as f64 / 40.0;
            goals.push(Goal::new(
                LEFT,
                kin::add(*from, kin::scale(kin::sub(*to, *from), t)),
                *q,
                OPEN,
            ));
        }
        rec.go_many(&goals, 1, |_| false)?;
        if debug() && rec.env().steps().is_multiple_of(20) {
            show(rec, "  descending");
            eprintln!("    contacts {:?}", touching(rec.env()));
        }
    }
    Ok(())
}

/// Diagnostics: the pairs of bodies in contact that involve the right hand, the peg or
/// the tray (but not the table).
fn touching(e: &TaskEnv) -> Vec<String> {
    use mujoco_rs::prelude::MjtObjBase;
    let d = e.data();
    let m = d.model();
    let body = |g: i32| {
        let b = m.geom_bodyid()[g as usize] as usize;
        m.id_to_name(MjtObjBase::mjOBJ_BODY, b).unwrap_or("?")
    };
    d.contact()
        .iter()
        .map(|c| format!("{}-{}", body(c.geom[0]), body(c.geom[1])))
        .filter(|s| !s.contains("table") && (s.contains("industreal") || s.contains("right")))
        .collect()
}
