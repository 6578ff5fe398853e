//! The bimanual_microwave_cook planner (probe).

use dexjoco_core::HAND_DOF;

use super::kin::{self, Q, V3};
use super::{CLOSE, Goal, OPEN, Planned, Recorder, debug};
use crate::env::TaskEnv;
use crate::error::SimError;

const RIGHT: usize = 0;
const LEFT: usize = 1;
/// The hot dog's centre from the TCP along the fingers, and below it.
const FOOD_X: f64 = 0.09;
const FOOD_DOWN: f64 = 0.11;
/// How far the hand's target leads the hook out from the door while pulling (m).
const PULL: f64 = 0.08;
/// How far the door opens (rad).
const OPEN_TO: f64 = -0.75;
/// Where the hot dog goes (microwave frame): across the opening (x), where it is let
/// go and how deep the fingertips push its near side (y).
const PLACE_X: f64 = 0.05;
const DROP_Y: f64 = -0.14;
const PUSH_Y: f64 = -0.11;

/// Straight fingers, thumb curled in.
const HOOK: [f64; HAND_DOF] = [
    0.0, 0.1, 0.1, 0.1, 0.0, 0.1, 0.1, 0.1, 0.0, 0.1, 0.1, 0.1, 1.2, 0.3, 0.3, 0.3,
];

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

/// With `DEXJOCO_PLAN_SNAP` set: wide pictures of the scene (from above-behind, from
/// the left, from the right).
fn snap(rec: &mut Recorder, name: &str) {
    snap_at(rec, name, [-0.3, 0.0, 1.1], 1.0);
}

/// As [`snap`], looking at `lookat` from `scale` times the usual distance.
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
            (2, 45.0, -20.0, 0.8),
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

/// The clamp's approach: fingers half curled, the thumb already turned under the palm.
const CLAMP_OPEN: [f64; HAND_DOF] = [
    0.0, 0.4, 0.4, 0.3, 0.0, 0.4, 0.4, 0.3, 0.0, 0.4, 0.4, 0.3, 1.4, 0.5, 0.8, 0.8,
];

/// Straight fingers, the thumb tucked under the palm.
const PUSH: [f64; HAND_DOF] = [
    0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.3, 0.4, 0.4, 0.4,
];

/// Plans bimanual_microwave_cook on an environment just restored from its initial state.
pub(crate) fn plan(env: TaskEnv, id: &str) -> Result<Planned, SimError> {
    let s = env.state();
    let right_home = [s[3], s[4], s[5], s[6]];
    let left_home = [s[10], s[11], s[12], s[13]];
    let mut rec = Recorder::new(env);
    let e = rec.env();
    let hinge = kin::anchor(e, "microjoint")?;
    let bar = kin::geom(e, "door_handle")?.0;
    let show = |rec: &Recorder, what: &str| {
        if debug() {
            let e = rec.env();
            eprintln!(
                "{what}: step {} door {:.3} dog {:.3?} tcpL {:.3?} tgtL {:.3?} tcpR {:.3?} {:?} {:?} {:?}",
                e.steps(),
                kin::joint(e, "microjoint").unwrap_or(f64::NAN),
                kin::body(e, "hot_dog").map(|b| b.0).unwrap_or_default(),
                kin::tcp(e, LEFT).0,
                e.targets()[LEFT].0,
                kin::tcp(e, RIGHT).0,
                e.checker().value("door_closed"),
                e.checker().value("food_inside"),
                e.checker().value("start_pressed"),
            );
        }
    };
    if debug() {
        let e = rec.env();
        eprintln!("hinge {hinge:.3?} bar {bar:.3?} homes {right_home:.3?} {left_home:.3?}");
        for g in [
            "fingertip_ff_right",
            "fingertip_mf_right",
            "fingertip_rf_right",
            "thumbtip_right",
            "fingertip_ff_left",
            "fingertip_mf_left",
            "fingertip_rf_left",
            "thumbtip_left",
        ] {
            if let Ok(p) = kin::geom(e, g) {
                eprintln!("  {g} {:.3?}", p.0);
            }
        }
        eprintln!("  tcp {:.3?} {:.3?}", kin::tcp(e, 0).0, kin::tcp(e, 1).0);
    }
    if std::env::var_os("MW_HANDPROBE").is_some() {
        for (name, h) in [("open", OPEN), ("close", CLOSE), ("push", PUSH)] {
            rec.go(RIGHT, kin::tcp(rec.env(), RIGHT).0, right_home, h, 60)?;
            let e = rec.env();
            let (t, q) = kin::tcp(e, RIGHT);
            let m = kin::qmat(q);
            for g in ["fingertip_ff_right", "fingertip_mf_right", "fingertip_rf_right", "thumbtip_right"] {
                let w = kin::sub(kin::geom(e, g)?.0, t);
                // hand frame: m^T w
                let h = [
                    m[0] * w[0] + m[3] * w[1] + m[6] * w[2],
                    m[1] * w[0] + m[4] * w[1] + m[7] * w[2],
                    m[2] * w[0] + m[5] * w[1] + m[8] * w[2],
                ];
                eprintln!("{name} {g} world {w:.3?} hand {h:.3?}");
            }
        }
    }
    // The hook: left fingers pointing -y through the gap between the bar and the door,
    // palm toward the door (thumb down). Offsets at the closed door, from the hinge.
    let gap_x = (bar[0] + 0.0096 + hinge[0]) / 2.0 - hinge[0];
    let hook_rel = [gap_x - 0.03, bar[1] + 0.018 + 0.09 - hinge[1], bar[2] - hinge[2]];
    let hook_at = |phi: f64, dx: f64, dy: f64| -> (V3, Q) {
        let p = kin::add(hinge, rz(kin::add(hook_rel, [dx, dy, 0.0]), phi));
        let q = frame(rz([0.0, -1.0, 0.0], phi), rz([1.0, 0.0, 0.0], phi));
        (p, q)
    };
    // The right hand's cage pinch across the hot dog, fingers along its width (+x-ish).
    let e = rec.env();
    let dog_geom = super::geom_of_body(e, "hot_dog")
        .ok_or_else(|| SimError::Spec("no hot dog collision geom".into()))?;
    let (dp, dm) = (e.data().geom_xpos()[dog_geom], e.data().geom_xmat()[dog_geom]);
    let mut d = [dm[1], dm[4], 0.0];
    if d[0] < 0.0 {
        d = [-d[0], -d[1], 0.0];
    }
    let d = kin::horizontal(d);
    let rq = kin::qmul(kin::yaw(d[1].atan2(d[0])), right_home);
    let mut grip = kin::sub(dp, kin::scale(d, FOOD_X));
    grip[2] = dp[2] + FOOD_DOWN;
    let (p0, q0) = hook_at(0.0, -0.1, 0.15);
    rec.go_many(
        &[
            Goal::new(LEFT, p0, q0, HOOK),
            Goal::new(RIGHT, kin::add(grip, [0.0, 0.0, 0.1]), rq, CLAMP_OPEN),
        ],
        100,
        |_| false,
    )?;
    rec.settle(0.005, 60)?;
    show(&rec, "pre-hook far");
    snap(&mut rec, "a_prehook_far");
    let (p1, _) = hook_at(0.0, 0.0, 0.15);
    rec.go_many(
        &[
            Goal::new(LEFT, p1, q0, HOOK),
            Goal::new(RIGHT, grip, rq, CLAMP_OPEN),
        ],
        40,
        |_| false,
    )?;
    rec.settle(0.004, 40)?;
    show(&rec, "pre-hook");
    snap_at(&mut rec, "b_pregrasp", dp, 0.4);
    let (p2, _) = hook_at(0.0, 0.0, 0.0);
    rec.go_many(
        &[
            Goal::new(LEFT, p2, q0, HOOK),
            Goal::new(RIGHT, grip, rq, CLOSE),
        ],
        30,
        |_| false,
    )?;
    rec.settle(0.004, 40)?;
    show(&rec, "hooked");
    snap_at(&mut rec, "b_grasped", dp, 0.4);
    snap(&mut rec, "b_hooked");
    // Pull the door open: the hand's angle about the hinge leads the door's; the right
    // hand lifts the hot dog meanwhile.
    let lift = kin::add(grip, [0.0, 0.0, 0.2]);
    let mut phi = 0.0;
    let n = 200;
    for k in 1..=n {
        let theta = kin::joint(rec.env(), "microjoint")?;
        phi = theta;
        let (p, q) = hook_at(theta, -PULL, 0.0);
        let t = (k as f64 / 100.0).min(1.0);
        let rp = kin::add(grip, kin::scale(kin::sub(lift, grip), t));
        rec.go_many(
            &[Goal::new(LEFT, p, q, HOOK), Goal::new(RIGHT, rp, rq, CLOSE)],
            1,
            |_| false,
        )?;
        if k % 25 == 0 {
            show(&rec, &format!("pull {phi:.2}"));
        }
        if theta < OPEN_TO + 0.02 {
            break;
        }
    }
    show(&rec, "pulled");
    let dog_now = rec.env().data().geom_xpos()[dog_geom];
    snap_at(&mut rec, "c_lifted", dog_now, 0.4);
    snap(&mut rec, "c_pulled");
    // The hot dog into the cavity: measure where it sits in the hand, carry it in front
    // of the opening, in over the floor's front edge, down, let go; then push it deeper
    // with straight fingers.
    let e = rec.env();
    let (mp, mm) = kin::body(e, "microwave_object")?;
    let oven = |p: V3| kin::add(mp, kin::mulv(&mm, p));
    let into = kin::horizontal(kin::mulv(&mm, [0.0, 1.0, 0.0]));
    let floor = mp[2] - 0.126;
    let pyaw = into[1].atan2(into[0]);
    let pq = kin::qmul(kin::yaw(pyaw), right_home);
    let dog_now = e.data().geom_xpos()[dog_geom];
    let yaw0 = d[1].atan2(d[0]);
    let off = rz(kin::sub(dog_now, kin::tcp(e, RIGHT).0), pyaw - yaw0);
    let mut spot = oven([PLACE_X, DROP_Y, 0.0]);
    spot[2] = floor + 0.03 + 0.015;
    let place = kin::sub(spot, off);
    let front = kin::add(kin::sub(place, kin::scale(into, 0.12)), [0.0, 0.0, 0.03]);
    for k in 0..5 {
        rec.go_many(&[Goal::new(RIGHT, front, pq, CLOSE)], 20, |_| false)?;
        show(&rec, &format!("carry {k}"));
        let dog_now = rec.env().data().geom_xpos()[dog_geom];
        snap_at(&mut rec, &format!("carry{k}"), dog_now, 0.5);
    }
    rec.settle(0.006, 40)?;
    show(&rec, "in front");
    snap(&mut rec, "d_front");
    rec.go(RIGHT, kin::add(place, [0.0, 0.0, 0.03]), pq, CLOSE, 50)?;
    rec.go(RIGHT, place, pq, CLOSE, 20)?;
    rec.settle(0.005, 40)?;
    show(&rec, "placed");
    snap(&mut rec, "e_placed");
    rec.go(RIGHT, place, pq, OPEN, 20)?;
    let back = kin::add(kin::sub(place, kin::scale(into, 0.1)), [0.0, 0.0, 0.03]);
    rec.go(RIGHT, back, pq, PUSH, 40)?;
    rec.settle(0.005, 40)?;
    show(&rec, "let go");
    snap(&mut rec, "f_letgo");
    let e = rec.env();
    let tip = kin::sub(kin::geom(e, "fingertip_mf_right")?.0, kin::tcp(e, RIGHT).0);
    let mut aim = oven([PLACE_X, PUSH_Y, 0.0]);
    aim[2] = floor + 0.03;
    let push = kin::sub(aim, tip);
    let start = kin::sub(push, kin::scale(into, 0.12));
    rec.go(RIGHT, start, pq, PUSH, 30)?;
    rec.settle(0.004, 40)?;
    rec.go(RIGHT, push, pq, PUSH, 60)?;
    rec.settle(0.004, 40)?;
    show(&rec, "pushed");
    snap(&mut rec, "g_pushed");
    rec.go(RIGHT, start, pq, PUSH, 40)?;
    show(&rec, "out");
    let _ = (OPEN, right_home);
    rec.finish(id)
}
