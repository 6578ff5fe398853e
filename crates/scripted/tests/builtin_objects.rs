//! The built-in task objects (`assets/builtin/objects/<task>.xml`) of nine tasks, checked in
//! the DexJoCo reference robot and arena: each reference scene is rebuilt with its own
//! objects (includes, inline bodies, sensors) replaced by the fragment. For every task: the
//! scene compiles, the task spec resolves every name, the objects rest stably while the arm
//! holds its home pose and the checker stays quiet, the objects are visible in a rendered
//! frame, and the articulations mean what the spec measures (driving a joint or posing an
//! object flips the spec's nodes).

#[path = "../../sim/tests/common/mod.rs"]
mod common;

use std::path::{Path, PathBuf};

use dexjoco_core::{NameKind, PoseSource, TaskSpec};
use dexjoco_render::{CameraView, RenderQuality, RenderSettings, Renderer};
use dexjoco_sim::mujoco_rs::prelude::{MjData, MjModel};
use dexjoco_sim::{EnvOptions, Scene, TaskEnv, name_id, unresolved_names};

/// Control steps of the "hold" run (0.02 s each).
const HOLD_STEPS: usize = 100;

fn fragment(task: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../sim/assets/builtin/objects")
        .join(format!("{task}.xml"))
}

/// Removes every `start .. end` span (end included) for which `keep` says no.
fn remove_spans(s: &str, start: &str, end: &str, keep: impl Fn(&str) -> bool) -> String {
    let mut out = String::with_capacity(s.len());
    let mut rest = s;
    while let Some(i) = rest.find(start) {
        let j = rest[i..].find(end).expect("span closes") + i + end.len();
        out.push_str(&rest[..i]);
        if keep(&rest[i..j]) {
            out.push_str(&rest[i..j]);
        }
        rest = &rest[j..];
    }
    out.push_str(rest);
    out
}

/// The reference scene of `spec` with its task objects removed (object includes, the
/// scene's sensors, the glasses case, the photograph logo and region) and, if given, the
/// fragment included instead. Written into `dir` beside links to the reference files, so
/// the robot's and arena's relative asset paths resolve.
fn compose(spec: &TaskSpec, dir: &Path, fragment: Option<&Path>) -> PathBuf {
    let xmls = dexjoco_testkit::reference_scene_dir();
    for e in fs_err::read_dir(&xmls).unwrap() {
        let e = e.unwrap();
        let link = dir.join(e.file_name());
        if !link.exists() {
            std::os::unix::fs::symlink(e.path(), link).unwrap();
        }
    }
    let src = fs_err::read_to_string(xmls.join(&spec.scene)).unwrap();
    let s = remove_spans(&src, "<!--", "-->", |_| false);
    let s = remove_spans(&s, "<include ", "/>", |inc| inc.contains("\"panda_allegro"));
    let s = remove_spans(&s, "<sensor>", "</sensor>", |_| false);
    let s = remove_spans(&s, "<body name=\"open_box\"", "</body>", |_| false);
    let mut s = remove_spans(&s, "<geom name=\"photograph_", "/>", |_| false);
    if let Some(f) = fragment {
        let at = s.rfind("</mujoco>").expect("closing tag");
        s.insert_str(at, &format!("  <include file=\"{}\"/>\n", f.display()));
    }
    let path = dir.join(if fragment.is_some() {
        "with_objects.xml"
    } else {
        "without_objects.xml"
    });
    fs_err::write(&path, s).unwrap();
    path
}

struct Task {
    spec: TaskSpec,
    scene: Scene,
    _dir: tempfile::TempDir,
}

fn task(id: &str) -> Task {
    let spec = common::spec(id);
    let dir = tempfile::tempdir().unwrap();
    let path = compose(&spec, dir.path(), Some(&fragment(id)));
    let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{id}: the scene compiles: {e}"));
    let missing = unresolved_names(&spec, &scene.model);
    assert!(
        missing.is_empty(),
        "{id}: names do not resolve: {missing:?}"
    );
    Task {
        spec,
        scene,
        _dir: dir,
    }
}

fn id(model: &MjModel, kind: NameKind, name: &str) -> usize {
    name_id(model, kind, name).unwrap_or_else(|| panic!("{} '{name}'", kind.as_str()))
}

fn qpos_adr(model: &MjModel, joint: &str) -> usize {
    model.jnt_qposadr()[id(model, NameKind::Joint, joint)] as usize
}

fn dof_adr(model: &MjModel, joint: &str) -> usize {
    model.jnt_dofadr()[id(model, NameKind::Joint, joint)] as usize
}

/// The free joints of the task's objects (state objects and derived poses).
fn free_joints(spec: &TaskSpec) -> Vec<String> {
    let objects = spec.state.objects.iter().map(|o| &o.source);
    let derived = spec.state.derived.iter().map(|d| &d.target);
    objects
        .chain(derived)
        .filter_map(|s| match s {
            PoseSource::FreeJoint(j) => Some(j.clone()),
            _ => None,
        })
        .collect()
}

fn hold(env: &mut TaskEnv, steps: usize) {
    let zeros = vec![0.0; env.spec().setup.action_dim()];
    for k in 0..steps {
        let v = env.step(&zeros).unwrap();
        assert!(
            !v.success && !v.failure,
            "{}: verdict {v:?} at step {k} while holding still",
            env.spec().id
        );
    }
}

/// Builds the environment, holds still for `HOLD_STEPS` and checks the objects rest.
fn rests(t: &Task) -> TaskEnv {
    let id = &t.spec.id;
    // A reset as the reference draws it: table offset dh, placements and yaws (fixed draws).
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let mut uniform = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let state0 = TaskEnv::sample_initial_state(&t.scene, &t.spec, &mut uniform).unwrap();
    let mut env =
        TaskEnv::from_initial_state(&t.scene, &t.spec, &state0, EnvOptions::default()).unwrap();
    let model = t.scene.model.clone();
    let joints = free_joints(&t.spec);
    assert!(!joints.is_empty(), "{id}: has free objects");
    let start: Vec<[f64; 3]> = joints
        .iter()
        .map(|j| {
            let a = qpos_adr(&model, j);
            env.data().qpos()[a..a + 3].try_into().unwrap()
        })
        .collect();
    hold(&mut env, HOLD_STEPS);
    for (j, p0) in joints.iter().zip(&start) {
        let a = qpos_adr(&model, j);
        let d = dof_adr(&model, j);
        let p = &env.data().qpos()[a..a + 3];
        let moved =
            ((p[0] - p0[0]).powi(2) + (p[1] - p0[1]).powi(2) + (p[2] - p0[2]).powi(2)).sqrt();
        assert!(moved < 0.02, "{id}: {j} moved {moved:.4} m while resting");
        let v = &env.data().qvel()[d..d + 6];
        assert!(
            v.iter().all(|x| x.is_finite() && x.abs() < 0.05),
            "{id}: {j} still moves after {HOLD_STEPS} steps: {v:?}"
        );
    }
    assert!(
        env.data().qvel().iter().all(|v| v.is_finite()),
        "{id}: qvel finite"
    );
    env
}

/// Renders the spec's first camera with and without the objects (their geoms hidden) and
/// returns the share of pixels that differ.
fn visible_share(t: &Task, env: &mut TaskEnv) -> f64 {
    let settings = RenderSettings {
        width: 224,
        height: 224,
        quality: RenderQuality::FAST,
        depth: false,
        geometry: dexjoco_render::Geometry::Full,
    };
    let cam = t.scene.camera_id(&t.spec.cameras[0].camera).unwrap();
    let model = &*t.scene.model;
    // The fragment is included last: its bodies have the highest ids.
    let first = fragment_first_body(t);
    let mut r = Renderer::new(model, settings).unwrap();
    let with = r.render(env.data_mut(), CameraView::Fixed(cam)).unwrap();
    let mut hidden = model.clone();
    let bodies: Vec<i32> = hidden.geom_bodyid().to_vec();
    for (g, b) in bodies.iter().enumerate() {
        if *b as usize >= first {
            hidden.geom_group_mut()[g] = 5;
        }
    }
    let mut data = MjData::new(&hidden);
    data.qpos_mut().copy_from_slice(env.data().qpos());
    data.mocap_pos_mut().copy_from_slice(env.data().mocap_pos());
    data.mocap_quat_mut()
        .copy_from_slice(env.data().mocap_quat());
    data.forward();
    let mut r = Renderer::new(&hidden, settings).unwrap();
    let without = r.render(&mut data, CameraView::Fixed(cam)).unwrap();
    if let Some(dir) = std::env::var_os("DEXJOCO_OBJECTS_PNG") {
        let dir = PathBuf::from(dir);
        with.save_png(&dir.join(format!("{}.png", t.spec.id)))
            .unwrap();
    }
    let differ = with
        .rgb
        .chunks(3)
        .zip(without.rgb.chunks(3))
        .filter(|(a, b)| a.iter().zip(*b).any(|(x, y)| x.abs_diff(*y) > 30))
        .count();
    differ as f64 / (224.0 * 224.0)
}

/// The id of the fragment's first body (the first body named in its file).
fn fragment_first_body(t: &Task) -> usize {
    let xml = fs_err::read_to_string(fragment(&t.spec.id)).unwrap();
    let i = xml.find("<body name=\"").expect("a body") + "<body name=\"".len();
    let name = &xml[i..i + xml[i..].find('"').unwrap()];
    id(&t.scene.model, NameKind::Body, name)
}

fn step0(env: &mut TaskEnv) -> dexjoco_sim::Verdict {
    let zeros = vec![0.0; env.spec().setup.action_dim()];
    env.step(&zeros).unwrap()
}

/// Steps with a generalized force on one joint; returns the verdicts.
fn push(env: &mut TaskEnv, joint: &str, force: f64, steps: usize) -> Vec<dexjoco_sim::Verdict> {
    let d = dof_adr(&env.data().model_clone(), joint);
    env.data_mut().qfrc_applied_mut()[d] = force;
    let v = (0..steps).map(|_| step0(env)).collect();
    env.data_mut().qfrc_applied_mut()[d] = 0.0;
    v
}

/// Puts a free object at `pos` with orientation `quat` (current one if `None`), at rest.
fn teleport(env: &mut TaskEnv, joint: &str, pos: [f64; 3], quat: Option<[f64; 4]>) {
    let model = env.data().model_clone();
    let (a, d) = (qpos_adr(&model, joint), dof_adr(&model, joint));
    let data = env.data_mut();
    data.qpos_mut()[a..a + 3].copy_from_slice(&pos);
    if let Some(q) = quat {
        data.qpos_mut()[a + 3..a + 7].copy_from_slice(&q);
    }
    data.qvel_mut()[d..d + 6].iter_mut().for_each(|v| *v = 0.0);
    data.forward();
}

fn qpos(env: &TaskEnv, joint: &str) -> f64 {
    env.data().qpos()[qpos_adr(&env.data().model_clone(), joint)]
}

fn node(env: &TaskEnv, name: &str) -> bool {
    env.checker()
        .value(name)
        .unwrap_or_else(|| panic!("node {name}"))
}

/// Every basic check of one task; returns the environment after the hold.
fn basic(task_id: &str, min_visible: f64) -> (Task, TaskEnv) {
    let t = task(task_id);
    let mut env = rests(&t);
    let share = visible_share(&t, &mut env);
    assert!(
        share > min_visible,
        "{task_id}: the objects cover only {:.2} % of the {} camera",
        share * 100.0,
        t.spec.cameras[0].camera
    );
    (t, env)
}

#[test]
fn water_plant() {
    let (t, mut env) = basic("water_plant", 0.005);
    let m = &t.scene.model;
    // Pulling the trigger past 0.34 latches it; with the nozzle away from the plant the
    // episode fails.
    let v = push(&mut env, "joint_0", 0.6, 10);
    assert!(qpos(&env, "joint_0") > 0.34, "{}", qpos(&env, "joint_0"));
    assert!(node(&env, "trigger") && v.last().unwrap().failure);
    // The spring returns it: released below 0.25.
    for _ in 0..60 {
        step0(&mut env);
    }
    assert!(qpos(&env, "joint_0") < 0.25 && !node(&env, "trigger"));
    // The bottle lying on top of the plant, nozzle within the cylinder: 30 steps of spraying
    // water the plant.
    let plant = env.data().xpos()[id(m, NameKind::Body, "plant")];
    teleport(
        &mut env,
        "spray_root",
        [plant[0], plant[1], plant[2] + 0.185],
        None,
    );
    let v = push(&mut env, "joint_0", 0.6, 36);
    assert!(v.iter().all(|v| !v.failure), "no spill over the plant");
    let first = v.iter().position(|v| v.success);
    assert!(matches!(first, Some(28..=33)), "watered at step {first:?}");
}

#[test]
fn pinch_tongs() {
    let (_t, mut env) = basic("pinch_tongs", 0.002);
    // Three squeezes, each released so the spring reopens the tongs past 0.1.
    for k in 0..3 {
        push(&mut env, "joint_0", -3.0, 15);
        assert!(
            qpos(&env, "joint_0") <= -0.07,
            "squeeze {k}: {}",
            qpos(&env, "joint_0")
        );
        for _ in 0..25 {
            step0(&mut env);
        }
        assert!(
            qpos(&env, "joint_0") >= 0.1,
            "reopened {k}: {}",
            qpos(&env, "joint_0")
        );
    }
    assert!(node(&env, "pinches"), "three pinches counted");
    assert!(
        !node(&env, "lifted") && !node(&env, "done"),
        "still on the table"
    );
}

#[test]
fn fold_glasses() {
    let (t, mut env) = basic("fold_glasses", 0.005);
    let m = &t.scene.model;
    assert!(!node(&env, "left_folded") && !node(&env, "right_folded"));
    let (d0, d1) = (dof_adr(m, "glass_joint_0"), dof_adr(m, "glass_joint_1"));
    env.data_mut().qfrc_applied_mut()[d0] = 0.1;
    env.data_mut().qfrc_applied_mut()[d1] = 0.1;
    for _ in 0..60 {
        step0(&mut env);
    }
    assert!(
        node(&env, "left_folded") && node(&env, "right_folded"),
        "both temples folded"
    );
    assert!(!node(&env, "in_case"));
    // Folded glasses standing in the case: held 50 steps.
    let case = env.data().xpos()[id(m, NameKind::Body, "open_box")];
    teleport(
        &mut env,
        "glass_root",
        [case[0], case[1], case[2] + 0.017],
        Some([0.5, 0.5, -0.5, -0.5]),
    );
    let v: Vec<_> = (0..60).map(|_| step0(&mut env)).collect();
    let first = v.iter().position(|v| v.success);
    assert!(matches!(first, Some(48..=52)), "stowed at step {first:?}");
}

#[test]
fn pick_bucket() {
    let (t, mut env) = basic("pick_bucket", 0.005);
    let m = &t.scene.model;
    // The handle swings up about its hinge.
    push(&mut env, "bucket_joint_0", 0.2, 20);
    assert!(
        qpos(&env, "bucket_joint_0") > 0.5,
        "{}",
        qpos(&env, "bucket_joint_0")
    );
    // Food in the bucket, then the bucket 0.2 m up: done at once.
    let b = env.data().xpos()[id(m, NameKind::Body, "bucket")];
    teleport(
        &mut env,
        "boxed_food_0_freejoint",
        [b[0], b[1], b[2] - 0.034],
        Some([1.0, 0.0, 0.0, 0.0]),
    );
    let v: Vec<_> = (0..10).map(|_| step0(&mut env)).collect();
    assert!(node(&env, "food_in_bucket") && !v.iter().any(|v| v.success));
    for j in ["bucket_root", "boxed_food_0_freejoint"] {
        let a = qpos_adr(m, j);
        let p: [f64; 3] = env.data().qpos()[a..a + 3].try_into().unwrap();
        teleport(&mut env, j, [p[0], p[1], p[2] + 0.2], None);
    }
    assert!(step0(&mut env).success, "food in the lifted bucket");
}

#[test]
fn hammer_nail() {
    let (t, mut env) = basic("hammer_nail", 0.005);
    let m = &t.scene.model;
    let (face, nail) = (id(m, NameKind::Geom, "face"), id(m, NameKind::Body, "nail"));
    let hammer = id(m, NameKind::Body, "hammer_body");
    let z0 = env.data().xpos()[nail][2];
    // Blows: the hammer, face down, 2 cm above the nail head and falling at 1 m/s.
    let mut first = None;
    for blow in 0..4 {
        let head = env.data().xpos()[nail];
        let (f, o) = (env.data().geom_xpos()[face], env.data().xpos()[hammer]);
        let pos = [
            head[0] - (f[0] - o[0]),
            head[1] - (f[1] - o[1]),
            head[2] + 0.0084 + 0.0065 + 0.02 - (f[2] - o[2]),
        ];
        teleport(&mut env, "hammer_joint", pos, None);
        let d = dof_adr(m, "hammer_joint");
        env.data_mut().qvel_mut()[d + 2] = -1.0;
        for _ in 0..4 {
            if step0(&mut env).success && first.is_none() {
                first = Some(blow);
            }
        }
    }
    let depth = env.checker().output("nail", "depth").unwrap();
    assert!(depth >= 0.04, "depth {depth}");
    assert!(first.is_some(), "driven");
    // The nail visibly sank by the depth.
    let sunk = z0 - env.data().xpos()[nail][2];
    assert!((sunk - depth).abs() < 1e-9, "sank {sunk}, depth {depth}");
}

#[test]
fn bimanual_microwave_cook() {
    let (t, mut env) = basic("bimanual_microwave_cook", 0.005);
    let m = &t.scene.model;
    assert!(
        node(&env, "door_closed") && !node(&env, "food_inside") && !node(&env, "start_pressed")
    );
    // The door opens (negative angle) ...
    push(&mut env, "microjoint", -8.0, 40);
    assert!(
        qpos(&env, "microjoint") < -0.8 && !node(&env, "door_closed"),
        "door at {}",
        qpos(&env, "microjoint")
    );
    // ... the hot dog goes on the turntable ...
    let mw = id(m, NameKind::Body, "microwave_object");
    let c = env.data().xpos()[mw];
    teleport(
        &mut env,
        "hot_dog_free",
        [c[0] + 0.03, c[1] + 0.05, c[2] - 0.07],
        None,
    );
    // ... and the door closes again.
    push(&mut env, "microjoint", 8.0, 40);
    for _ in 0..5 {
        step0(&mut env);
    }
    assert!(node(&env, "door_closed"), "{}", qpos(&env, "microjoint"));
    assert!(
        node(&env, "food_inside") && !node(&env, "done"),
        "cooked without pressing start"
    );
}

#[test]
fn bimanual_photograph() {
    let (t, mut env) = basic("bimanual_photograph", 0.003);
    let m = &t.scene.model;
    assert!(!node(&env, "aimed") && !node(&env, "level"));
    // Turn the camera 90 degrees (lens from +y to +x) and hold it in front of the logo.
    let a = qpos_adr(m, "camera_root");
    let q: [f64; 4] = env.data().qpos()[a + 3..a + 7].try_into().unwrap();
    let (c, s) = (
        std::f64::consts::FRAC_1_SQRT_2,
        -std::f64::consts::FRAC_1_SQRT_2,
    );
    let turned = [
        c * q[0] - s * q[3],
        c * q[1] - s * q[2],
        c * q[2] + s * q[1],
        c * q[3] + s * q[0],
    ];
    let p: [f64; 3] = env.data().qpos()[a..a + 3].try_into().unwrap();
    teleport(&mut env, "camera_root", p, Some(turned));
    let site = env.data().site_xpos()[id(m, NameKind::Site, "view_direction_site")];
    let target = env.data().geom_xpos()[id(m, NameKind::Geom, "photograph_target_region_visual")];
    let p = [
        p[0] + target[0] - site[0],
        p[1] + target[1] - site[1],
        p[2] + target[2] - site[2],
    ];
    teleport(&mut env, "camera_root", p, None);
    let v = step0(&mut env);
    assert!(node(&env, "aimed") && node(&env, "level"));
    assert!(
        !node(&env, "shutter") && !v.success,
        "no photo without pressing the shutter"
    );
}

#[test]
fn bimanual_hanoi() {
    let (t, mut env) = basic("bimanual_hanoi", 0.005);
    let m = &t.scene.model;
    // Medium, then small onto post C (over the large disk): solved, held 20 steps.
    let c = env.data().site_xpos()[id(m, NameKind::Site, "hanoi_post_c_site")];
    let top = env.data().xpos()[id(m, NameKind::Body, "hanoi_base")][2] + 0.036;
    let h = 0.02475;
    teleport(
        &mut env,
        "hanoi_disk_medium_joint",
        [c[0], c[1], top + 3.0 * h],
        Some([1.0, 0.0, 0.0, 0.0]),
    );
    teleport(
        &mut env,
        "hanoi_disk_small_joint",
        [c[0], c[1], top + 5.0 * h],
        Some([1.0, 0.0, 0.0, 0.0]),
    );
    let v: Vec<_> = (0..25).map(|_| step0(&mut env)).collect();
    assert!(v.iter().all(|v| !v.failure));
    let first = v.iter().position(|v| v.success);
    assert!(matches!(first, Some(18..=21)), "solved at step {first:?}");
}

#[test]
fn bimanual_assembly() {
    let (t, mut env) = basic("bimanual_assembly", 0.003);
    let m = &t.scene.model;
    // The peg upright in the socket, its end on the bottom plate: held 30 steps.
    let tray = env.data().xpos()[id(m, NameKind::Body, "industreal_tray_insert_round_peg_8mm")];
    teleport(
        &mut env,
        "industreal_round_peg_8mm_joint",
        [tray[0], tray[1], tray[2] + 0.0155 - 0.0135 + 0.001],
        Some([1.0, 0.0, 0.0, 0.0]),
    );
    let v: Vec<_> = (0..40).map(|_| step0(&mut env)).collect();
    let first = v.iter().position(|v| v.success);
    assert!(matches!(first, Some(28..=34)), "inserted at step {first:?}");
}

#[test]
fn the_composer_keeps_the_robot_and_drops_the_objects() {
    let spec = common::spec("water_plant");
    let dir = tempfile::tempdir().unwrap();
    let path = compose(&spec, dir.path(), None);
    let scene = Scene::load(&path).unwrap();
    let missing = unresolved_names(&spec, &scene.model);
    assert!(
        missing.contains(&"joint 'spray_root'".to_owned()),
        "{missing:?}"
    );
    assert!(name_id(&scene.model, NameKind::Site, "table_top").is_some());
}
