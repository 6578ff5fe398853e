//! The bimanual_microwave_cook planner. The left hand hooks the door handle (fingers slid
//! from the hinge side through the gap between the bar and the door, palm toward the
//! door) and pulls the door open along its arc, its target led out from the door at the
//! measured hinge angle; meanwhile the right hand clamps the hot dog (thumb turned under
//! the palm on its near side, fingers curled over its far side), lifts it and turns it
//! fingers-up. The right hand carries the hot dog in over the oven's floor, lets go and
//! backs out of the door's sweep; the left hand pushes the door shut with its fingertips,
//! slides out of the handle and backs away; the right index finger then presses the start
//! button with a guarded move, re-aimed by where the fingertip is measured to be, ending
//! on the success step.

use dexjoco_core::{HAND_DOF, NameKind};

use super::hands::microwave_cook::{CLAMP_OPEN, HOOK, PRESS, RELEASE, SHUT_HAND};
use super::kin::{self, Q, V3};
use super::{CLOSE, Goal, Planned, Recorder, debug};
use crate::PlanError;
use dexjoco_sim::TaskEnv;
use dexjoco_sim::name_id;

const RIGHT: usize = 0;
const LEFT: usize = 1;

/// The straight index fingertip (its collision geom's centre) from the TCP with the hand
/// palm down, fingers along x (the robot's kinematics).
const INDEX_TIP: V3 = [0.176, 0.054, -0.035];
/// The most the press target is shifted per round toward the button (m).
const AIM_MAX: f64 = 0.05;
/// The fingertip's offset from the button's centre below which the press is not
/// re-aimed (m; the button's face is 50 mm square).
const AIM_TOL: f64 = 0.005;

/// The finger plane's offset from the TCP along the palm normal.
const FINGERS_OUT: f64 = 0.03;
/// The left TCP from the bar's inner edge along the door (toward the hinge) when
/// hooked, and above the bar's middle (the lowest fingertip stays above the button).
const HOOK_IN: f64 = 0.09;
const HOOK_UP: f64 = 0.015;
/// The hook turned about the vertical through the gap, fingertips toward the door (rad):
/// the left wrist stays farther from its arm's base as the door opens.
const HOOK_YAW: f64 = 0.2;
/// How far the left target leads the hook out from the door while pulling (m), and
/// into the door while pushing it shut (blended down to `SHUT_HOLD` over the last
/// 0.05 rad, so the door is not pushed past its stop).
const PULL: f64 = 0.1;
const SHUT: f64 = 0.06;
const SHUT_HOLD: f64 = 0.015;
/// How far the door opens (rad), and the most control steps the pull may take.
const OPEN_TO: f64 = -0.75;
const PULL_STEPS: usize = 280;
/// The right TCP's distance from the hinge beyond which the door may swing shut.
const CLEAR: f64 = 0.56;
/// The hot dog's centre from the TCP along the fingers, and below it, when clamped.
const FOOD_X: f64 = 0.1;
const FOOD_DOWN: f64 = 0.09;
/// Where the hot dog goes (microwave frame): across the opening (x) and in (y); how
/// far above the floor it is let go.
const PLACE_X: f64 = 0.05;
const DROP_Y: f64 = -0.09;
const DROP_UP: f64 = 0.02;
/// The right hand's yaw from straight into the oven (toward its own side) and pitch
/// (fingers up, so the wrist stays below the oven's top edge) while placing (rad).
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
        [
            0.25 * s,
            (m[7] - m[5]) / s,
            (m[2] - m[6]) / s,
            (m[3] - m[1]) / s,
        ]
    } else if m[0] > m[4] && m[0] > m[8] {
        let s = (1.0 + m[0] - m[4] - m[8]).sqrt() * 2.0;
        [
            (m[7] - m[5]) / s,
            0.25 * s,
            (m[1] + m[3]) / s,
            (m[2] + m[6]) / s,
        ]
    } else if m[4] > m[8] {
        let s = (1.0 + m[4] - m[0] - m[8]).sqrt() * 2.0;
        [
            (m[2] - m[6]) / s,
            (m[1] + m[3]) / s,
            0.25 * s,
            (m[5] + m[7]) / s,
        ]
    } else {
        let s = (1.0 + m[8] - m[0] - m[4]).sqrt() * 2.0;
        [
            (m[3] - m[1]) / s,
            (m[2] + m[6]) / s,
            (m[5] + m[7]) / s,
            0.25 * s,
        ]
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

/// A queue of straight moves for one arm, stepped alongside the other arm's closed loop.
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

    /// The next step's target, blending from `now` (the target when the move began),
    /// or `None` when every move is done.
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
    Pose {
        p,
        q,
        h: rec.hands[arm],
    }
}

/// One step: both arms' targets set to `left` and `right`.
fn step(rec: &mut Recorder, left: Pose, right: Pose) -> Result<(), PlanError> {
    rec.go_many(&[left.goal(LEFT), right.goal(RIGHT)], 1, |_| false)?;
    Ok(())
}

/// Diagnostics: the bodies in contact with geom `g`, or with a body whose name holds
/// `part` (as "body-other").
fn contacts(e: &TaskEnv, g: Option<usize>, part: &str) -> Vec<String> {
    use mujoco_rs::prelude::MjtObjBase;
    let d = e.data();
    let m = d.model();
    let body = |g: usize| {
        let b = m.geom_bodyid()[g] as usize;
        m.id_to_name(MjtObjBase::mjOBJ_BODY, b).unwrap_or("?")
    };
    d.contact()
        .iter()
        .filter_map(|c| {
            let (a, b) = (c.geom[0] as usize, c.geom[1] as usize);
            let (a, b) = match g {
                Some(g) if a == g => (a, b),
                Some(g) if b == g => (b, a),
                None if body(a).contains(part) => (a, b),
                None if body(b).contains(part) => (b, a),
                _ => return None,
            };
            Some(format!("{}-{}", body(a), body(b)))
        })
        .collect()
}

/// With `DEXJOCO_PLAN_SNAP` set: pictures around `lookat` (from behind and above, from
/// the right, from the front right, from above; `scale` times the usual distances).
fn snap(rec: &mut Recorder, name: &str, lookat: V3, scale: f64) {
    let views = [
        (0.0, -45.0, 1.3),
        (90.0, -10.0, 0.9),
        (30.0, -35.0, 0.8),
        (0.0, -88.0, 1.3),
    ]
    .map(
        |(azimuth, elevation, distance)| dexjoco_render::CameraView::Orbit {
            lookat,
            distance: distance * scale,
            azimuth,
            elevation,
        },
    );
    rec.snap_views(name, (640, 480), &views);
}

/// Plans bimanual_microwave_cook on an environment just restored from its initial state.
pub(crate) fn plan(env: TaskEnv, id: &str) -> Result<Planned, PlanError> {
    let s = env.state();
    let right_home = [s[3], s[4], s[5], s[6]];
    let mut rec = Recorder::new(env);
    let setup = Setup::measure(rec.env(), right_home)?;
    grip_handle_and_hot_dog(&mut rec, &setup)?;
    let spot = pull_door_open(&mut rec, &setup)?;
    let back = place_hot_dog(&mut rec, &setup, spot)?;
    let ready = shut_door(&mut rec, &setup, back)?;
    press_start(&mut rec, &setup, ready)?;
    rec.finish(id)
}

/// Where the pictures of [`snap`] look by default.
const VIEW: V3 = [-0.3, 0.0, 1.1];

/// The microwave's door angle (rad; 0 closed, negative open).
fn door_angle(e: &TaskEnv) -> Result<f64, PlanError> {
    kin::joint(e, "microjoint")
}

/// In debug mode, prints the door, the hot dog and the success nodes after a phase.
fn show(rec: &Recorder, what: &str) {
    if debug() {
        let e = rec.env();
        eprintln!(
            "{what}: step {} door {:.3} hot dog {:.3?} closed {:?} inside {:?} pressed {:?}",
            e.steps(),
            door_angle(e).unwrap_or(f64::NAN),
            kin::body(e, "hot_dog").map(|b| b.0).unwrap_or_default(),
            e.checker().value("door_closed"),
            e.checker().value("food_inside"),
            e.checker().value("start_pressed"),
        );
    }
}

/// The scene as the plan measures it at the start: the door's frame and the hook on its
/// handle, the clamp across the hot dog, the oven's frame and the hand's orientations
/// for placing and pressing, the start button.
#[derive(Debug)]
struct Setup {
    hinge: V3,
    theta0: f64,
    pivot: V3,
    hook_rel: V3,
    dog: usize,
    dp: V3,
    grip: V3,
    rq: Q,
    mp: V3,
    mm: [f64; 9],
    into: V3,
    floor: f64,
    iyaw: f64,
    level: Q,
    pq: Q,
    button: usize,
    button_depth: f64,
    tip: usize,
}

impl Setup {
    /// Measures the scene of an environment just restored from its initial state.
    fn measure(e: &TaskEnv, right_home: Q) -> Result<Self, PlanError> {
        let geom_id = |name: &str| {
            name_id(e.data().model(), NameKind::Geom, name)
                .ok_or_else(|| PlanError::lacks("geom", name))
        };
        // The door's frame: offsets from the hinge as they are with the door closed.
        let hinge = kin::anchor(e, "microjoint")?;
        let theta0 = door_angle(e)?;
        let bar = rz(kin::sub(kin::geom(e, "door_handle")?.0, hinge), -theta0);
        // The bar's half width along the door and half depth (its box, microwave frame).
        let [bar_width, bar_depth, _] = e.data().model().geom_size()[geom_id("door_handle")?];
        // The hook: left fingers pointing along the door toward its free edge through the gap
        // between the bar and the door, palm toward the door (thumb down), turned about the
        // vertical through the gap at the bar.
        let gap = (bar[0] + bar_depth) / 2.0;
        let pivot = [gap, bar[1], 0.0];
        let hook_rel = [
            gap - FINGERS_OUT,
            bar[1] + bar_width + HOOK_IN,
            bar[2] + HOOK_UP,
        ];
        // The right hand's clamp across the hot dog, fingers along its width (+x-ish).
        let dog = super::geom_of_body(e, "hot_dog")
            .ok_or_else(|| PlanError::lacks("collision geom of body", "hot_dog"))?;
        let (dp, dm) = (e.data().geom_xpos()[dog], e.data().geom_xmat()[dog]);
        let mut d = [dm[1], dm[4], 0.0];
        if d[0] < 0.0 {
            d = [-d[0], -d[1], 0.0];
        }
        let d = kin::horizontal(d);
        let rq = kin::qmul(kin::yaw(d[1].atan2(d[0])), right_home);
        let mut grip = kin::sub(dp, kin::scale(d, FOOD_X));
        grip[2] = dp[2] + FOOD_DOWN;
        // The oven's frame; the hand placing (yawed, pitched) and pressing (level).
        let (mp, mm) = kin::body(e, "microwave_object")?;
        let into = kin::horizontal(kin::mulv(&mm, [0.0, 1.0, 0.0]));
        let floor = mp[2] - 0.126;
        let iyaw = into[1].atan2(into[0]);
        let level = kin::qmul(kin::yaw(iyaw), right_home);
        let pyaw = iyaw + PLACE_YAW;
        let pq = kin::qmul(
            kin::axis_angle([-pyaw.sin(), pyaw.cos(), 0.0], -PITCH),
            kin::qmul(kin::yaw(pyaw), right_home),
        );
        let button = geom_id("start_button")?;
        let button_depth = e.data().model().geom_size()[button][1];
        let tip = super::geom_of_body(e, "ff_tip_right")
            .ok_or_else(|| PlanError::lacks("collision geom of body", "ff_tip_right"))?;
        Ok(Self {
            hinge,
            theta0,
            pivot,
            hook_rel,
            dog,
            dp,
            grip,
            rq,
            mp,
            mm,
            into,
            floor,
            iyaw,
            level,
            pq,
            button,
            button_depth,
            tip,
        })
    }

    /// The left hand hooked in the handle with the door at `theta`, moved `out` from
    /// the door and `along` it toward the hinge side.
    fn hook(&self, theta: f64, out: f64, along: f64, h: [f64; HAND_DOF]) -> Pose {
        let local = kin::add(self.hook_rel, [out, along, 0.0]);
        let local = kin::add(self.pivot, rz(kin::sub(local, self.pivot), HOOK_YAW));
        Pose {
            p: kin::add(self.hinge, rz(local, theta)),
            q: frame(
                rz([0.0, -1.0, 0.0], theta + HOOK_YAW),
                rz([1.0, 0.0, 0.0], theta + HOOK_YAW),
            ),
            h,
        }
    }

    /// The right hand's clamp orientation at `p` with hand `h`.
    fn clamp(&self, p: V3, h: [f64; HAND_DOF]) -> Pose {
        Pose { p, q: self.rq, h }
    }

    /// A point given in the oven's frame, in world coordinates.
    fn oven(&self, p: V3) -> V3 {
        kin::add(self.mp, kin::mulv(&self.mm, p))
    }
}

/// Both hands above their grips, then in: the left fingers slide into the gap while
/// the right hand clamps the hot dog.
fn grip_handle_and_hot_dog(rec: &mut Recorder, setup: &Setup) -> Result<(), PlanError> {
    rec.go_many(
        &[
            setup.hook(setup.theta0, -0.1, 0.15, HOOK).goal(LEFT),
            setup
                .clamp(kin::add(setup.grip, [0.0, 0.0, 0.1]), CLAMP_OPEN)
                .goal(RIGHT),
        ],
        90,
        |_| false,
    )?;
    rec.settle(0.01, 30)?;
    rec.go_many(
        &[
            setup.hook(setup.theta0, 0.0, 0.15, HOOK).goal(LEFT),
            setup.clamp(setup.grip, CLAMP_OPEN).goal(RIGHT),
        ],
        40,
        |_| false,
    )?;
    rec.settle(0.005, 30)?;
    show(rec, "at the handle and the hot dog");
    snap(rec, "a_grip", setup.dp, 0.4);
    rec.go_many(
        &[
            setup.hook(setup.theta0, 0.0, 0.0, HOOK).goal(LEFT),
            setup.clamp(setup.grip, CLOSE).goal(RIGHT),
        ],
        10,
        |_| false,
    )?;
    rec.wait(30)?;
    show(rec, "hooked and clamped");
    snap(rec, "b_hooked", VIEW, 1.0);
    Ok(())
}

/// Pull the door open; the right hand lifts the hot dog and takes it beside the
/// opening, clear of the door's sweep, turning to its placing orientation. Returns the
/// spot where the hot dog goes.
fn pull_door_open(rec: &mut Recorder, setup: &Setup) -> Result<V3, PlanError> {
    let mut spot = setup.oven([PLACE_X, DROP_Y, 0.0]);
    spot[2] = setup.floor + 0.03 + DROP_UP;
    let aside = kin::add(spot, [-0.35, -0.2, 0.1]);
    let mut track = Track::default()
        .then(
            setup.clamp(kin::add(setup.grip, [0.0, 0.0, 0.15]), CLOSE),
            50,
        )
        .then(
            Pose {
                p: aside,
                q: setup.pq,
                h: CLOSE,
            },
            70,
        );
    let start = rec.env().steps();
    let mut pulling = true;
    while !rec.done() {
        let theta = door_angle(rec.env())?;
        let was_pulling = pulling;
        pulling &= theta > OPEN_TO && rec.env().steps() < start + PULL_STEPS;
        if was_pulling && !pulling {
            // The door is open as far as the pull takes it.
            rec.phase("open_door");
        }
        let left = setup.hook(theta, if pulling { -PULL } else { 0.0 }, 0.0, HOOK);
        let lifting = track.moves.len() == 2;
        let Some(right) = track
            .next(now(rec, RIGHT))
            .or(pulling.then(|| now(rec, RIGHT)))
        else {
            break;
        };
        step(rec, left, right)?;
        if lifting && track.moves.len() < 2 {
            // The hot dog is clamped and lifted.
            rec.phase("grasp_hot_dog");
        }
    }
    show(rec, "door open, hot dog lifted");
    snap(rec, "c_open", VIEW, 1.0);
    Ok(spot)
}

/// In over the floor's front edge, down to `spot`, let go (the fingers straighten
/// upward, the thumb folds up), back out. Returns where the right hand backed out to.
fn place_hot_dog(rec: &mut Recorder, setup: &Setup, spot: V3) -> Result<V3, PlanError> {
    let e = rec.env();
    let place = kin::sub(
        spot,
        kin::sub(e.data().geom_xpos()[setup.dog], kin::tcp(e, RIGHT).0),
    );
    let front = kin::add(
        kin::sub(place, kin::scale(setup.into, 0.14)),
        [0.0, 0.0, 0.02],
    );
    rec.go(RIGHT, front, setup.pq, CLOSE, 50)?;
    rec.go(
        RIGHT,
        kin::add(place, [0.0, 0.0, 0.02]),
        setup.pq,
        CLOSE,
        50,
    )?;
    rec.go(RIGHT, place, setup.pq, CLOSE, 15)?;
    rec.settle(0.005, 30)?;
    show(rec, "placed");
    if debug() {
        eprintln!(
            "  right arm touching {:?}",
            contacts(rec.env(), None, "_right")
        );
    }
    snap(rec, "d_placed", spot, 0.5);
    rec.go(RIGHT, place, setup.pq, RELEASE, 10)?;
    rec.wait(12)?;
    // The hot dog is let go on the oven's floor (the hand then backs out).
    rec.phase("place_hot_dog");
    let back = kin::sub(place, kin::scale(setup.into, 0.14));
    rec.go(RIGHT, back, setup.pq, RELEASE, 30)?;
    show(rec, "let go");
    Ok(back)
}

/// The right hand waits aside (coming from `back`), clear of the door's sweep and of
/// the left arm; once it is clear the left hand pushes the door shut. Returns where the
/// right index finger presses from.
fn shut_door(rec: &mut Recorder, setup: &Setup, back: V3) -> Result<V3, PlanError> {
    let e = rec.env();
    let face = kin::sub(
        e.data().geom_xpos()[setup.button],
        kin::scale(setup.into, setup.button_depth),
    );
    let ready = kin::sub(
        kin::sub(face, kin::scale(setup.into, 0.03)),
        rz(INDEX_TIP, setup.iyaw),
    );
    let wait = kin::add(ready, [-0.12, -0.25, 0.15]);
    let mut track = Track::default()
        .then(
            Pose {
                p: kin::add(back, [0.0, -0.15, 0.0]),
                q: setup.pq,
                h: RELEASE,
            },
            40,
        )
        .then(
            Pose {
                p: wait,
                q: setup.level,
                h: PRESS,
            },
            50,
        );
    for _ in 0..250 {
        if rec.done() {
            break;
        }
        let e = rec.env();
        let theta = door_angle(e)?;
        let r = kin::sub(kin::tcp(e, RIGHT).0, setup.hinge);
        let out = if (r[0] * r[0] + r[1] * r[1]).sqrt() > CLEAR {
            SHUT_HOLD + (SHUT - SHUT_HOLD) * (-theta / 0.05).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let right = track.next(now(rec, RIGHT));
        if right.is_none() && theta.abs() < 0.004 {
            break;
        }
        let right = right.unwrap_or(now(rec, RIGHT));
        step(rec, setup.hook(theta, out, 0.0, SHUT_HAND), right)?;
    }
    rec.phase("close_door");
    show(rec, "door shut");
    snap(rec, "e_shut", VIEW, 1.0);
    Ok(ready)
}

/// The left fingers slide out of the handle and the hand backs away; the right index
/// finger comes in front of the button (`ready`), then presses it with a guarded move.
fn press_start(rec: &mut Recorder, setup: &Setup, ready: V3) -> Result<(), PlanError> {
    let theta = door_angle(rec.env())?;
    let slid = setup.hook(theta, 0.0, 0.13, HOOK);
    rec.go_many(
        &[
            slid.goal(LEFT),
            Goal::new(
                RIGHT,
                kin::sub(ready, kin::scale(setup.into, 0.03)),
                setup.level,
                PRESS,
            ),
        ],
        25,
        |_| false,
    )?;
    let away = kin::add(setup.hook(theta, -0.15, 0.13, HOOK).p, [0.0, 0.0, 0.08]);
    rec.go_many(
        &[
            Goal::new(LEFT, away, slid.q, HOOK),
            Goal::new(RIGHT, ready, setup.level, PRESS),
        ],
        25,
        |_| false,
    )?;
    let aim = aim_at_button(rec, setup, ready)?;
    let pressed = |e: &TaskEnv| e.checker().value("start_pressed") == Some(true);
    let deep = kin::add(aim, kin::scale(setup.into, 0.045));
    rec.go_many(&[Goal::new(RIGHT, deep, setup.level, PRESS)], 25, pressed)?;
    rec.phase("press_start");
    show(rec, "pressed");
    if debug() {
        let e = rec.env();
        let tip = e.data().geom_xpos()[setup.tip];
        eprintln!(
            "  tcp {:.4?} tip {:.4?} button {:.4?} tip contacts {:?}",
            kin::tcp(e, RIGHT).0,
            tip,
            e.data().geom_xpos()[setup.button],
            contacts(e, None, "ff_tip_right")
        );
        eprintln!(
            "  button touched by {:?}",
            contacts(rec.env(), Some(setup.button), "")
        );
    }
    rec.wait(20)?;
    snap(rec, "f_end", VIEW, 1.0);
    Ok(())
}

/// The right index fingertip in front of the button: waits for the TCP to arrive at
/// `ready`, measures where the fingertip is, and shifts the target across the press
/// direction by the fingertip's offset from the button's centre (the arm may settle
/// off its target, its elbow folded near its limit, so close to its base). Returns the
/// TCP target the press starts from.
fn aim_at_button(rec: &mut Recorder, setup: &Setup, ready: V3) -> Result<V3, PlanError> {
    let near = |to: V3| move |e: &TaskEnv| kin::norm(kin::sub(kin::tcp(e, RIGHT).0, to)) < 0.003;
    rec.go_many(&[], 60, near(ready))?;
    let e = rec.env();
    let off = kin::sub(
        e.data().geom_xpos()[setup.button],
        e.data().geom_xpos()[setup.tip],
    );
    let along = off[0] * setup.into[0] + off[1] * setup.into[1] + off[2] * setup.into[2];
    let across = kin::sub(off, kin::scale(setup.into, along));
    if debug() {
        eprintln!("  fingertip off the button by {across:.4?}");
    }
    if kin::norm(across) < AIM_TOL {
        return Ok(ready);
    }
    let aim = kin::add(
        ready,
        kin::scale(across, (AIM_MAX / kin::norm(across)).min(1.0)),
    );
    rec.go_many(&[Goal::new(RIGHT, aim, setup.level, PRESS)], 40, near(aim))?;
    Ok(aim)
}
