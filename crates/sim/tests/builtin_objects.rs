//! The built-in task objects (`assets/builtin/objects/<task>.xml`) of nine tasks, checked in
//! the DexJoCo reference robot and arena: each reference scene is rebuilt with its own
//! objects (includes, inline bodies, sensors) replaced by the fragment. For every task: the
//! scene compiles, the task spec resolves every name, the objects rest stably while the arm
//! holds its home pose and the checker stays quiet, the objects are visible in a rendered
//! frame, and the articulations mean what the spec measures (driving a joint or posing an
//! object flips the spec's nodes).

mod common;

use std::path::{Path, PathBuf};

use dexjoco_core::{NameKind, PoseSource, TaskSpec};
use dexjoco_sim::mujoco_rs::prelude::{MjData, MjModel};
use dexjoco_sim::{
    CameraView, EnvOptions, RenderQuality, RenderSettings, Renderer, Scene, TaskEnv, name_id,
    unresolved_names,
};

/// Control steps of the "hold" run (0.02 s each).
const HOLD_STEPS: usize = 150;

fn fragment(task: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("assets/builtin/objects")
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
    let xmls = common::scene_dir();
    for e in std::fs::read_dir(&xmls).unwrap() {
        let e = e.unwrap();
        let link = dir.join(e.file_name());
        if !link.exists() {
            std::os::unix::fs::symlink(e.path(), link).unwrap();
        }
    }
    let src = std::fs::read_to_string(xmls.join(&spec.scene)).unwrap();
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
    std::fs::write(&path, s).unwrap();
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
    let mut env = TaskEnv::new(&t.scene, &t.spec, EnvOptions::default()).unwrap();
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
    let xml = std::fs::read_to_string(fragment(&t.spec.id)).unwrap();
    let i = xml.find("<body name=\"").expect("a body") + "<body name=\"".len();
    let name = &xml[i..i + xml[i..].find('"').unwrap()];
    id(&t.scene.model, NameKind::Body, name)
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
    basic("water_plant", 0.005);
}

#[test]
fn pinch_tongs() {
    basic("pinch_tongs", 0.002);
}

#[test]
fn fold_glasses() {
    basic("fold_glasses", 0.005);
}

#[test]
fn pick_bucket() {
    basic("pick_bucket", 0.005);
}

#[test]
fn hammer_nail() {
    basic("hammer_nail", 0.005);
}

#[test]
fn bimanual_microwave_cook() {
    basic("bimanual_microwave_cook", 0.005);
}

#[test]
fn bimanual_photograph() {
    basic("bimanual_photograph", 0.003);
}

#[test]
fn bimanual_hanoi() {
    basic("bimanual_hanoi", 0.005);
}

#[test]
fn bimanual_assembly() {
    basic("bimanual_assembly", 0.003);
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
