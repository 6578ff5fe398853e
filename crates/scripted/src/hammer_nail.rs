//! The hammer_nail planner: grasp the handle near the head, lift the hammer face-down over
//! the nail, and strike with the arm (a fast straight-down target step) until the nail is
//! driven in.
//!
//! A thick handle (the reference hammer's 51 mm box) is held in an overhand wrap: palm on
//! its top face, fingers over the far side and under it, the thumb on the near side. A
//! slim handle (the built-in one) is pinched between the thumb and the fingers.

use dexjoco_core::{HAND_DOF, NameKind};

use super::hands::hammer_nail::{WRAP, WRAP_OPEN};
use super::kin::{self, Q, V3};
use super::{CLOSE, OPEN, Planned, Recorder, debug};
use crate::PlanError;
use dexjoco_sim::TaskEnv;
use dexjoco_sim::mat_to_quat;
use dexjoco_sim::name_id;

/// Where the pinch closes, from the TCP (home orientation, world axes).
const GRIP: V3 = [0.045, 0.011, -0.126];
const GRIP_ALONG: f64 = 0.045;

/// A handle whose half sizes across and in height are both at least this (m) is wrapped,
/// not pinched.
const WRAP_MIN_HALF: f64 = 0.02;

/// The handle geom: world centre, rotation (row-major) and half sizes.
struct Handle {
    c: V3,
    m: [f64; 9],
    half: V3,
}

impl Handle {
    fn read(e: &TaskEnv) -> Result<Self, PlanError> {
        let (c, m) = kin::geom(e, "handle")?;
        let g = name_id(e.data().model(), NameKind::Geom, "handle")
            .ok_or_else(|| PlanError::lacks("geom", "handle"))?;
        let half = e.data().model().geom_size()[g];
        Ok(Self { c, m, half })
    }

    /// Column `k` of the rotation: the geom's x (toward the face), y (across), z (along,
    /// toward the head).
    fn axis(&self, k: usize) -> V3 {
        [self.m[k], self.m[3 + k], self.m[6 + k]]
    }
}

/// The wxyz quaternion of the TCP frame with x axis `f` (fingers) and z axis `n` (out of
/// the palm).
fn frame(f: V3, n: V3) -> Q {
    let y = cross(n, f);
    mat_to_quat(&[f[0], y[0], n[0], f[1], y[1], n[1], f[2], y[2], n[2]])
}

fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Plans hammer_nail on an environment just restored from its initial state.
pub(crate) fn plan(env: TaskEnv, id: &str) -> Result<Planned, PlanError> {
    let s = env.state();
    let home = [s[3], s[4], s[5], s[6]];
    let mut rec = Recorder::new(env);
    // Let the hammer settle before reading its pose.
    rec.wait(30)?;
    let h = Handle::read(rec.env())?;
    if h.half[1].min(h.half[0]) >= WRAP_MIN_HALF {
        plan_wrap(rec, &h, id)
    } else {
        plan_pinch(rec, home, id)
    }
}

/// Where the handle's far face sits in the TCP frame when wrapped (m): just in from the
/// finger roots (its centre line lies a half width nearer, below the palm face by a half
/// height).
const FAR_X: f64 = 0.056;
const PALM_Z: f64 = 0.041;
/// The wrap's centre from the handle's centre toward the head (m).
const WRAP_ALONG: f64 = 0.04;

fn plan_wrap(mut rec: Recorder, h: &Handle, id: &str) -> Result<Planned, PlanError> {
    let (d, a) = (h.axis(0), h.axis(2));
    // Palm on the top face (normal = toward the face), thumb toward the head.
    let f = cross(kin::scale(a, -1.0), d);
    let q = frame(f, d);
    let rm = kin::qmat(q);
    let g = kin::add(h.c, kin::scale(a, WRAP_ALONG));
    let at = kin::sub(
        g,
        kin::mulv(&rm, [FAR_X - h.half[1], 0.0, PALM_Z + h.half[0]]),
    );
    if debug() {
        eprintln!(
            "wrap: handle {:.3?} half {:.4?} f {f:.3?} n {d:.3?}",
            h.c, h.half
        );
    }
    let up = kin::sub(at, kin::scale(d, 0.08));
    rec.go(0, kin::add(up, [0.0, 0.0, 0.05]), q, WRAP_OPEN, 100)?;
    rec.settle(0.004, 60)?;
    rec.go(0, at, q, WRAP_OPEN, 60)?;
    rec.settle(0.002, 60)?;
    rec.snap(0, "wrap_open");
    tips(rec.env(), "open");
    rec.go(0, at, q, WRAP, 30)?;
    rec.wait(20)?;
    rec.snap(0, "wrap_closed");
    tips(rec.env(), "closed");
    let level = frame(kin::horizontal(f), [0.0, 0.0, -1.0]);
    rec.go(0, kin::add(at, [0.0, 0.0, 0.20]), level, WRAP, 90)?;
    rec.phase("grasp_hammer");
    rec.settle(0.004, 60)?;
    strikes(rec, level, WRAP, id)
}

/// Debug: the digit tips and the hammer's handle, head and face in the TCP frame.
fn tips(e: &TaskEnv, what: &str) {
    if !debug() {
        return;
    }
    let (p, q) = kin::tcp(e, 0);
    let m = kin::qmat(q);
    let loc = |w: V3| {
        let d = kin::sub(w, p);
        [
            m[0] * d[0] + m[3] * d[1] + m[6] * d[2],
            m[1] * d[0] + m[4] * d[1] + m[7] * d[2],
            m[2] * d[0] + m[5] * d[1] + m[8] * d[2],
        ]
    };
    let mut line = format!("{what}:");
    for b in ["ff_tip", "mf_tip", "rf_tip", "th_tip"] {
        if let Ok((w, _)) = kin::body(e, b) {
            line += &format!(" {b} {:.3?}", loc(w));
        }
    }
    for g in ["handle", "head", "face"] {
        if let Ok((w, _)) = kin::geom(e, g) {
            line += &format!(" {g} {:.3?}", loc(w));
        }
    }
    eprintln!("{line}");
}

/// Carries the held hammer's face over the nail and strikes until the nail is in.
fn strikes(mut rec: Recorder, q: Q, hand: [f64; HAND_DOF], id: &str) -> Result<Planned, PlanError> {
    rec.snap(0, "hammer_lifted");
    let mut above = face_above_nail(rec.env())?;
    for k in 0..4 {
        if k > 0 {
            // The hammer may have turned in the hand: measure again from above.
            rec.go(0, above, q, hand, 30)?;
            rec.settle(0.003, 80)?;
            above = face_above_nail(rec.env())?;
        }
        rec.go(0, above, q, hand, if k == 0 { 90 } else { 20 })?;
        rec.settle(0.003, 80)?;
        let strike = kin::add(above, [0.0, 0.0, -0.20]);
        rec.go(0, strike, q, hand, 1)?;
        rec.wait(25)?;
        if k == 0 {
            // The first strike hits the nail.
            rec.phase("hit_nail");
        }
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
    rec.phase("drive_nail");
    rec.finish(id)
}

/// The TCP target that puts the held hammer's face over the nail, ready to strike.
fn face_above_nail(e: &TaskEnv) -> Result<V3, PlanError> {
    let face = kin::geom(e, "face")?.0;
    let nail = kin::site(e, "nail_top_site")?;
    let tcp = kin::tcp(e, 0).0;
    if debug() {
        eprintln!("above: face {face:.3?} nail top {nail:.3?} tcp {tcp:.3?}");
    }
    Ok(kin::sub(
        kin::add(nail, [0.0, 0.0, 0.06 + 0.024]),
        kin::sub(face, tcp),
    ))
}

/// The pinch for a slim handle.
fn plan_pinch(mut rec: Recorder, home: Q, id: &str) -> Result<Planned, PlanError> {
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
    rec.phase("grasp_hammer");
    rec.settle(0.004, 60)?;
    strikes(rec, q, CLOSE, id)
}
