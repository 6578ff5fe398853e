//! The bimanual_microwave_cook planner. The left hand hooks the door handle (fingers
//! slid through the gap between the bar and the door, palm toward the door) and pulls
//! the door open along its arc in a closed loop on the hinge angle, while the right hand
//! clamps the hot dog (thumb under the palm, fingers curled over its far side) and lifts
//! it. The right hand carries the hot dog in over the oven's floor, lets go and pushes
//! it deeper with straight fingers; the left hand then pushes the door shut with its
//! finger pads and holds it, while the right index finger presses the start button
//! with a guarded move.

use dexjoco_core::HAND_DOF;

use super::kin::{self, Q, V3};
use super::{CLOSE, Goal, Planned, Recorder, debug};
use crate::env::TaskEnv;
use crate::error::SimError;

const RIGHT: usize = 0;
const LEFT: usize = 1;

/// The left hand while hooking the handle: fingers almost straight, the thumb tucked.
const HOOK: [f64; HAND_DOF] = [
    0.0, 0.1, 0.1, 0.1, 0.0, 0.1, 0.1, 0.1, 0.0, 0.1, 0.1, 0.1, 1.4, -0.1, 1.6, 1.6,
];
/// The left hand pushing the door shut: fingertips curled a little toward the door so
/// that they, not the palm, touch it.
const SHUT_HAND: [f64; HAND_DOF] = [
    0.0, 0.5, 0.2, 0.1, 0.0, 0.5, 0.2, 0.1, 0.0, 0.5, 0.2, 0.1, 1.4, -0.1, 1.6, 1.6,
];
/// The clamp's approach: fingers half curled, the thumb already turned under the palm.
const CLAMP_OPEN: [f64; HAND_DOF] = [
    0.0, 0.4, 0.4, 0.3, 0.0, 0.4, 0.4, 0.3, 0.0, 0.4, 0.4, 0.3, 1.4, 0.5, 0.8, 0.8,
];
/// Straight fingers, the thumb folded up under the palm (its tip 5 cm below the TCP).
const PUSH: [f64; HAND_DOF] = [
    0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.4, 0.5, 1.6, 1.6,
];
/// Straight index finger, middle and ring curled, the thumb folded up under the palm.
const PRESS: [f64; HAND_DOF] = [
    0.0, 0.0, 0.0, 0.0, 0.0, 1.6, 1.7, 1.6, 0.0, 1.6, 1.7, 1.6, 1.4, 0.5, 1.6, 1.6,
];

/// The bar's half depth (door normal) and half width (along the door), from the model.
const BAR_DEPTH: f64 = 0.0096;
const BAR_WIDTH: f64 = 0.018;
/// The finger plane's offset from the TCP along the palm normal.
const FINGERS_OUT: f64 = 0.03;
/// The left TCP from the bar's edge along the door (toward the hinge) when hooked.
const HOOK_IN: f64 = 0.09;
/// The hook turned about the vertical through the gap, fingertips toward the door (rad):
/// the wrist stays farther from the left arm's base as the door opens.
const HOOK_YAW: f64 = 0.2;
/// The left TCP above the bar's middle when hooked (the lowest fingertip stays above
/// the start button).
const HOOK_UP: f64 = 0.015;
/// How far the left target leads the hook out from the door while pulling (m), and
/// into the door while pushing it shut.
const PULL: f64 = 0.08;
const SHUT: f64 = 0.06;
/// As [`SHUT`] once shut (blended in over the last 0.05 rad).
const SHUT_HOLD: f64 = 0.015;
/// The right TCP's distance from the hinge beyond which the door may swing shut.
const CLEAR: f64 = 0.56;
/// How far the door opens (rad), and the most control steps the pull may take.
const OPEN_TO: f64 = -0.75;
const PULL_STEPS: usize = 220;
/// The hot dog's centre from the TCP along the fingers, and below it, when clamped.
const FOOD_X: f64 = 0.1;
const FOOD_DOWN: f64 = 0.09;
/// Where the hot dog goes (microwave frame): across the opening (x) and in (y); how
/// far above the floor it is let go.
const PLACE_X: f64 = 0.05;
const DROP_Y: f64 = -0.09;
const DROP_UP: f64 = 0.02;
/// The right hand's yaw from straight into the oven (toward its right arm's side) and
/// pitch (fingers up) while placing (rad).
const PLACE_YAW: f64 = 0.1;
const PITCH: f64 = 0.45;

/// The wxyz quaternion of the TCP frame whose x axis (fingers) is `f` and z axis (palm
/// normal, out of the palm) is `n` (unit, perpendicular).
fn frame(f: V3, n: V3) -> Q {
    let y = [
        n[1] * f[2] - n[2] * f[1],
        n[2] * f[0] - n[0] * f[2],
        n[0] * f[1] - n[1] * f[0],
    ];
    let m = [f[0], y[0], n[0], f[1], y[1], n[1], f[2], y[2], n[2]];
    let tr = m[0] + m[4] + m[8];
    let q = if tr > 0.0 {
        let s = (tr + 1.0).sqrt() * 2.0;
        [0.25 * s, (m[7] - m[5]) / s, (m[2] - m[6]) / s, (m[3] - m[1]) / s]
    } else if m[0] > m[4] && m[0] > m[8] {
        let s = (1.0 + m[0] - m[4] - m[8]).sqrt() * 2.0;
        [(m[7] - m[5]) / s, 0.25 * s, (m[1] + m[3]) / s, (m[2] + m[6]) / s]
    } else if m[4] > m[8] {
        let s = (1.0 + m[4] - m[0] - m[8]).sqrt() * 2.0;
        [(m[2] - m[6]) / s, (m[1] + m[3]) / s, 0.25 * s, (m[5] + m[7]) / s]
    } else {
        let s = (1.0 + m[8] - m[0] - m[4]).sqrt() * 2.0;
        [(m[3] - m[1]) / s, (m[2] + m[6]) / s, (m[5] + m[7]) / s, 0.25 * s]
    };
    kin::qnorm(q)
}

/// `v` turned by `a` about world z.
fn rz(v: V3, a: f64) -> V3 {
    let (s, c) = a.sin_cos();
    [c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]]
}

/// One arm's commanded target: position, orientation, hand.
#[derive(Debug, Clone, Copy)]
struct Pose {
    p: V3,
    q: Q,
    h: [f64; HAND_DOF],
}

impl Pose {
    fn goal(&self, arm: usize) -> Goal {
        Goal::new(arm, self.p, self.q, self.h)
    }
}

/// A queue of straight moves for one arm, stepped alongside another arm's closed loop.
#[derive(Debug, Default)]
struct Track {
    moves: Vec<(Pose, usize)>,
    from: Option<Pose>,
    k: usize,
}

impl Track {
    fn then(mut self, to: Pose, steps: usize) -> Self {
        self.moves.push((to, steps.max(1)));
        self
    }

    /// The next step's target from `now` (the current target), or `None` when done.
    fn next(&mut self, now: Pose) -> Option<Pose> {
        let (to, steps) = *self.moves.first()?;
        let from = *self.from.get_or_insert(now);
        self.k += 1;
        let t = self.k as f64 / steps as f64;
        let mut h = [0.0; HAND_DOF];
        for (i, v) in h.iter_mut().enumerate() {
            *v = from.h[i] + (to.h[i] - from.h[i]) * t;
        }
        let pose = Pose {
            p: kin::add(from.p, kin::scale(kin::sub(to.p, from.p), t)),
            q: kin::nlerp(from.q, to.q, t),
            h,
        };
        if self.k >= steps {
            self.moves.remove(0);
            self.from = None;
            self.k = 0;
        }
        Some(pose)
    }
}

/// The current target of `arm` as a [`Pose`].
fn now(rec: &Recorder, arm: usize) -> Pose {
    let (p, q) = rec.target(arm);
    Pose { p, q, h: rec.hands[arm] }
}

/// With `DEXJOCO_PLAN_SNAP` set: pictures of the scene around `lookat` (from behind
/// and above, from the right, from the front right, from above).
fn snap_at(rec: &mut Recorder, name: &str, lookat: V3, scale: f64) {
    let Some(dir) = std::env::var_os("DEXJOCO_PLAN_SNAP") else {
        return;
    };
    let model = rec.env.data().model_clone();
    let settings = crate::render::RenderSettings {
        width: 640,
        height: 480,
        ..Default::default()
    };
    let result = crate::render::Renderer::new(&model, settings).and_then(|mut r| {
        for (k, az, el, dist) in [
            (0, 0.0, -45.0, 1.3),
            (1, 90.0, -10.0, 0.9),
            (2, 30.0, -35.0, 0.8),
            (3, 0.0, -88.0, 1.3),
        ] {
            let view = crate::render::CameraView::Orbit {
                lookat,
                distance: dist * scale,
                azimuth: az,
                elevation: el,
            };
            let f = r.render(rec.env.data_mut(), view)?;
            f.save_png(&std::path::Path::new(&dir).join(format!("{name}_{k}.png")))?;
        }
        Ok(())
    });
    if let Err(e) = result {
        eprintln!("snapshot {name}: {e}");
    }
}

fn snap(rec: &mut Recorder, name: &str) {
    snap_at(rec, name, [-0.3, 0.0, 1.1], 1.0);
}

/// Debug: the bodies touching geom `g` now.
fn touching(e: &TaskEnv, g: usize) -> Vec<String> {
    use mujoco_rs::prelude::MjtObjBase;
    let d = e.data();
    let m = d.model();
    d.contact()
        .iter()
        .filter_map(|c| {
            let (a, b) = (c.geom[0] as usize, c.geom[1] as usize);
            let other = if a == g { b } else if b == g { a } else { return None };
            let body = m.geom_bodyid()[other] as usize;
            Some(format!(
                "{}({:.3})",
                m.id_to_name(MjtObjBase::mjOBJ_BODY, body).unwrap_or("?"),
                c.dist
            ))
        })
        .collect()
}

/// Debug: every contact of a body whose name holds `part`, as "body-other(dist)".
fn contacts_of(e: &TaskEnv, part: &str) -> Vec<String> {
    use mujoco_rs::prelude::MjtObjBase;
    let d = e.data();
    let m = d.model();
    let name = |g: i32| {
        let body = m.geom_bodyid()[g as usize] as usize;
        m.id_to_name(MjtObjBase::mjOBJ_BODY, body).unwrap_or("?").to_owned()
    };
    d.contact()
        .iter()
        .filter_map(|c| {
            let (a, b) = (name(c.geom[0]), name(c.geom[1]));
            let (a, b) = if a.contains(part) { (a, b) } else if b.contains(part) { (b, a) } else { return None };
            Some(format!("{a}-{b}({:.3})", c.dist))
        })
        .collect()
}

/// Plans bimanual_microwave_cook on an environment just restored from its initial state.
pub(crate) fn plan(env: TaskEnv, id: &str) -> Result<Planned, SimError> {
    let s = env.state();
    let right_home = [s[3], s[4], s[5], s[6]];
    let mut rec = Recorder::new(env);
    let show = |rec: &Recorder, what: &str| {
        if debug() {
            let e = rec.env();
            let q: Vec<f64> = (1..=7)
                .map(|i| kin::joint(e, &format!("joint{i}_left")).unwrap_or(f64::NAN))
                .collect();
            eprintln!("  left arm joints {q:.2?}");
            eprintln!(
                "{what}: step {} door {:.3} dog {:.3?} tcpL {:.3?} tcpR {:.3?} closed {:?} in {:?} pressed {:?}",
                e.steps(),
                kin::joint(e, "microjoint").unwrap_or(f64::NAN),
                kin::body(e, "hot_dog").map(|b| b.0).unwrap_or_default(),
                kin::tcp(e, LEFT).0,
                kin::tcp(e, RIGHT).0,
                e.checker().value("door_closed"),
                e.checker().value("food_inside"),
                e.checker().value("start_pressed"),
            );
        }
    };
    let door = |e: &TaskEnv| kin::joint(e, "microjoint");
    // The door's frame: offsets from the hinge as they are at the closed door.
    let e = rec.env();
    let hinge = kin::anchor(e, "microjoint")?;
    let theta0 = door(e)?;
    let bar = rz(kin::sub(kin::geom(e, "door_handle")?.0, hinge), -theta0);
    // The hook: left fingers pointing along the door toward its free edge through the gap
    // between the bar and the door, palm toward the door (thumb down), the knuckles
    // just past the bar's inner edge.
    let gap = (bar[0] + BAR_DEPTH) / 2.0;
    let side: f64 = std::env::var("MW_SIDE").ok().and_then(|v| v.parse().ok()).unwrap_or(1.0);
    let hook_in: f64 = std::env::var("MW_HI").ok().and_then(|v| v.parse().ok()).unwrap_or(HOOK_IN);
    let alpha: f64 = side * std::env::var("MW_AL").ok().and_then(|v| v.parse().ok()).unwrap_or(HOOK_YAW);
    // The hook turned by alpha about the vertical through the gap at the bar.
    let pivot = [gap, bar[1], 0.0];
    let hook_rel = [gap - FINGERS_OUT, bar[1] + side * (BAR_WIDTH + hook_in), bar[2] + HOOK_UP];
    let hook = |theta: f64, out: f64, along: f64, h: [f64; HAND_DOF]| {
        let local = kin::add(hook_rel, [out, side * along, 0.0]);
        let local = kin::add(pivot, rz(kin::sub(local, pivot), alpha));
        Pose {
            p: kin::add(hinge, rz(local, theta)),
            q: frame(
                rz([0.0, -side, 0.0], theta + alpha),
                rz([1.0, 0.0, 0.0], theta + alpha),
            ),
            h,
        }
    };
    // The right hand's clamp across the hot dog, fingers along its width (+x-ish).
    let dog_geom = super::geom_of_body(e, "hot_dog")
        .ok_or_else(|| SimError::Spec("no hot dog collision geom".into()))?;
    let (dp, dm) = (e.data().geom_xpos()[dog_geom], e.data().geom_xmat()[dog_geom]);
    let mut d = [dm[1], dm[4], 0.0];
    if d[0] < 0.0 {
        d = [-d[0], -d[1], 0.0];
    }
    let d = kin::horizontal(d);
    let yaw0 = d[1].atan2(d[0]);
    let rq = kin::qmul(kin::yaw(yaw0), right_home);
    let fx: f64 = std::env::var("MW_FX").ok().and_then(|v| v.parse().ok()).unwrap_or(FOOD_X);
    let fdn: f64 = std::env::var("MW_FD").ok().and_then(|v| v.parse().ok()).unwrap_or(FOOD_DOWN);
    let mut grip = kin::sub(dp, kin::scale(d, fx));
    grip[2] = dp[2] + fdn;
    let rpose = |p: V3, h: [f64; HAND_DOF]| Pose { p, q: rq, h };
    // The oven's frame and the hot dog's way in.
    let (mp, mm) = kin::body(e, "microwave_object")?;
    let oven = |p: V3| kin::add(mp, kin::mulv(&mm, p));
    let into = kin::horizontal(kin::mulv(&mm, [0.0, 1.0, 0.0]));
    let floor = mp[2] - 0.126;
    let iyaw = into[1].atan2(into[0]);
    let level = kin::qmul(kin::yaw(iyaw), right_home);
    let pyaw = iyaw + std::env::var("MW_PY").ok().and_then(|v| v.parse().ok()).unwrap_or(PLACE_YAW);

    show(&rec, "home");
    // Both hands to their first poses, then in.
    rec.go_many(
        &[
            hook(theta0, -0.1, 0.15, HOOK).goal(LEFT),
            rpose(kin::add(grip, [0.0, 0.0, 0.1]), CLAMP_OPEN).goal(RIGHT),
        ],
        90,
        |_| false,
    )?;
    rec.settle(0.01, 30)?;
    show(&rec, "pre-hook far");
    rec.go_many(
        &[
            hook(theta0, 0.0, 0.15, HOOK).goal(LEFT),
            rpose(grip, CLAMP_OPEN).goal(RIGHT),
        ],
        40,
        |_| false,
    )?;
    rec.settle(0.005, 30)?;
    show(&rec, "at the handle and the hot dog");
    snap(&mut rec, "a_at");
    if debug() {
        eprintln!("  left contacts {:?}", contacts_of(rec.env(), "_left"));
        eprintln!("  right contacts {:?}", contacts_of(rec.env(), "_right"));
    }
    snap_at(&mut rec, "a_grip0", dp, 0.4);
    if debug() {
        let e = rec.env();
        let m = e.data().geom_xmat()[dog_geom];
        let tm = kin::qmat(kin::tcp(e, RIGHT).1);
        eprintln!(
            "PRE long {:.1} yaw0 {:.1} hand x {:.1}",
            m[3].atan2(m[0]).to_degrees(),
            yaw0.to_degrees(),
            tm[3].atan2(tm[0]).to_degrees()
        );
    }
    for k in 0..3 {
        rec.go_many(
            &[
                hook(theta0, 0.0, 0.0, HOOK).goal(LEFT),
                rpose(grip, CLOSE).goal(RIGHT),
            ],
            10,
            |_| false,
        )?;
        snap_at(&mut rec, &format!("a_grip{}", k + 1), dp, 0.4);
    }
    rec.wait(10)?;
    show(&rec, "hooked and clamped");
    snap(&mut rec, "a_hooked");

    // Pull the door open (the target leads the hook out from the door at the door's
    // angle); the right hand lifts the hot dog and takes it beside the opening, clear
    // of the door's sweep, turning to its placing orientation (fingers into the oven,
    // pitched up so the wrist stays below the oven's top edge).
    let lat = [-pyaw.sin(), pyaw.cos(), 0.0];
    let pq = kin::qmul(
        kin::axis_angle(lat, -PITCH),
        kin::qmul(kin::yaw(pyaw), right_home),
    );
    let mut spot = oven([PLACE_X, DROP_Y, 0.0]);
    spot[2] = floor + 0.03 + DROP_UP;
    let aside = kin::add(spot, [-0.35, -0.2, 0.1]);
    let mut track = Track::default()
        .then(rpose(kin::add(grip, [0.0, 0.0, 0.15]), CLOSE), 50)
        .then(
            Pose {
                p: aside,
                q: pq,
                h: CLOSE,
            },
            70,
        );
    let mut pulling = true;
    for _ in 0..PULL_STEPS + 120 {
        if rec.done() {
            break;
        }
        let theta = door(rec.env())?;
        pulling &= theta > std::env::var("MW_OT").ok().and_then(|v| v.parse().ok()).unwrap_or(OPEN_TO) && rec.env().steps() < 250 + PULL_STEPS;
        let left = if pulling {
            hook(theta, -PULL, 0.0, HOOK)
        } else {
            hook(theta, 0.0, 0.0, HOOK)
        };
        let right = track.next(now(&rec, RIGHT));
        if right.is_none() && !pulling {
            break;
        }
        let right = right.unwrap_or(now(&rec, RIGHT));
        rec.go_many(&[left.goal(LEFT), right.goal(RIGHT)], 1, |_| false)?;
        if debug() && rec.env().steps() % 20 == 0 {
            eprintln!("    pull step {} door {theta:.3}", rec.env().steps());
        }
    }
    show(&rec, "door open, hot dog lifted");
    if debug() {
        let e = rec.env();
        let q: Vec<f64> = (1..=7)
            .map(|i| kin::joint(e, &format!("joint{i}_left")).unwrap_or(f64::NAN))
            .collect();
        eprintln!("  left arm joints {q:.2?}");
    }
    snap(&mut rec, "b_open");

    // In over the floor's front edge, down, let go: the fingers straighten (up, as
    // the hand is pitched), the thumb folds up; back out.
    let e = rec.env();
    let off = kin::sub(e.data().geom_xpos()[dog_geom], kin::tcp(e, RIGHT).0);
    if debug() {
        let m = e.data().geom_xmat()[dog_geom];
        let a = m[3].atan2(m[0]) - pyaw;
        eprintln!("  hot dog's long axis {:.1} deg from the fingers, offset {off:.3?}", a.to_degrees());
    }
    let place = kin::sub(spot, off);
    let front = kin::add(kin::sub(place, kin::scale(into, 0.14)), [0.0, 0.0, 0.02]);
    rec.go(RIGHT, front, pq, CLOSE, 50)?;
    rec.go(RIGHT, kin::add(place, [0.0, 0.0, 0.02]), pq, CLOSE, 50)?;
    rec.go(RIGHT, place, pq, CLOSE, 15)?;
    rec.settle(0.005, 30)?;
    show(&rec, "placed");
    if debug() {
        eprintln!("  floor {floor:.3} spot {spot:.3?} place target {place:.3?} right contacts {:?}", contacts_of(rec.env(), "_right"));
    }
    snap_at(&mut rec, "c_placed", spot, 0.5);
    rec.go(RIGHT, place, pq, PUSH, 10)?;
    rec.wait(12)?;
    show(&rec, "released");
    snap_at(&mut rec, "c_released", spot, 0.5);
    let back = kin::sub(place, kin::scale(into, 0.14));
    rec.go(RIGHT, back, pq, PUSH, 30)?;
    show(&rec, "back");

    // The right hand backs out toward the start button; the left pushes the door shut
    // and holds it.
    let e = rec.env();
    let button = kin::geom(e, "start_button")?.0;
    let press_tip = rz([0.176, 0.054, -0.051], iyaw);
    let out = kin::sub(button, kin::scale(into, 0.0306));
    let ready = kin::sub(kin::sub(out, kin::scale(into, 0.03)), press_tip);
    let wait = kin::add(ready, [-0.12, -0.25, 0.15]);
    let mut track = Track::default()
        .then(
            Pose {
                p: kin::add(back, [0.0, -0.15, 0.0]),
                q: pq,
                h: PUSH,
            },
            40,
        )
        .then(
            Pose {
                p: wait,
                q: level,
                h: PRESS,
            },
            50,
        );
    for _ in 0..250 {
        if rec.done() {
            break;
        }
        let e = rec.env();
        let theta = door(e)?;
        let r = kin::sub(kin::tcp(e, RIGHT).0, hinge);
        let clear = (r[0] * r[0] + r[1] * r[1]).sqrt() > CLEAR;
        let out = if clear {
            SHUT_HOLD + (SHUT - SHUT_HOLD) * (-theta / 0.05).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let left = hook(theta, out, 0.0, SHUT_HAND);
        let right = track.next(now(&rec, RIGHT));
        let closed = theta.abs() < 0.004;
        if right.is_none() && closed {
            break;
        }
        let right = right.unwrap_or(now(&rec, RIGHT));
        rec.go_many(&[left.goal(LEFT), right.goal(RIGHT)], 1, |_| false)?;
    }
    show(&rec, "door shut");
    if debug() {
        eprintln!("  left contacts {:?}", contacts_of(rec.env(), "_left"));
        eprintln!("  door contacts {:?}", contacts_of(rec.env(), "door"));
    }
    snap(&mut rec, "e_shut");
    // The left fingers slide out of the handle and the hand backs away; the right
    // index finger comes in front of the button.
    let theta = door(rec.env())?;
    rec.go(LEFT, hook(theta, 0.0, 0.13, HOOK).p, hook(theta, 0.0, 0.13, HOOK).q, HOOK, 25)?;
    let away = kin::add(hook(theta, -0.15, 0.13, HOOK).p, [0.0, 0.0, 0.08]);
    rec.go(LEFT, away, hook(theta, 0.0, 0.13, HOOK).q, HOOK, 25)?;
    show(&rec, "left away");
    rec.go(RIGHT, ready, level, PRESS, 40)?;
    let arrived = |e: &TaskEnv| kin::norm(kin::sub(kin::tcp(e, RIGHT).0, ready)) < 0.004;
    rec.go_many(&[], 30, arrived)?;
    // Guarded press: 2 mm a step toward the button until it is touched.
    let pressed = |e: &TaskEnv| e.checker().value("start_pressed") == Some(true);
    let deep = kin::add(ready, kin::scale(into, 0.045));
    rec.go_many(
        &[Pose {
            p: deep,
            q: level,
            h: PRESS,
        }
        .goal(RIGHT)],
        25,
        pressed,
    )?;
    show(&rec, "pressed");
    if debug() {
        let e = rec.env();
        let b = crate::checker::name_id(e.data().model(), dexjoco_core::NameKind::Geom, "start_button").unwrap();
        eprintln!("  button touched by {:?}", touching(e, b));
    }
    rec.wait(20)?;
    show(&rec, "end");
    snap(&mut rec, "f_end");
    rec.finish(id)
}
