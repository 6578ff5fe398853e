//! The 11 reference scenes load through a scene folder (`--scene-dir`), and every name
//! a task spec refers to resolves in its scene.

mod common;

use std::time::Instant;

use dexjoco_sim::{EnvOptions, Robot, Scene, SimError, TaskEnv, unresolved_names};

#[test]
fn every_spec_name_resolves_in_its_reference_scene() {
    let mut unresolved = Vec::new();
    for spec in common::specs() {
        let t = Instant::now();
        let scene = common::scene(&spec.id);
        eprintln!(
            "{}: {} loaded in {:.2} s",
            spec.id,
            spec.scene,
            t.elapsed().as_secs_f64()
        );
        for name in unresolved_names(&spec, &scene.model) {
            unresolved.push(format!("{}: {name}", spec.id));
        }
        if let Err(e) = Robot::new(&scene.model, spec.setup) {
            unresolved.push(format!("{}: {e}", spec.id));
        }
        for c in &spec.cameras {
            if scene.camera_id(&c.camera).is_err() {
                unresolved.push(format!("{}: camera '{}'", spec.id, c.camera));
            }
        }
    }
    assert!(
        unresolved.is_empty(),
        "names that do not resolve:\n{}",
        unresolved.join("\n")
    );
}

#[test]
fn every_task_env_builds_and_reports_its_state() {
    for spec in common::specs() {
        let scene = common::scene(&spec.id);
        let env = TaskEnv::new(&scene, &spec, EnvOptions::default()).unwrap();
        let s = env.state();
        assert_eq!(s.len(), spec.state.width, "{}", spec.id);
        assert!(s.iter().all(|v| v.is_finite()), "{}", spec.id);
        // TCP quaternion at home is about (0, -1, 0, 0) (or its negative).
        assert!(s[4].abs() > 0.99, "{}: {:?}", spec.id, &s[..7]);
    }
}

#[test]
fn a_missing_asset_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let xml = r#"<mujoco><asset><mesh name="m" file="no_such_mesh.obj"/></asset>
        <worldbody><geom type="mesh" mesh="m"/></worldbody></mujoco>"#;
    let path = dir.path().join("scene.xml");
    fs_err::write(&path, xml).unwrap();
    let err = Scene::load(&path).unwrap_err();
    assert!(matches!(err, SimError::Load { .. }));
    assert!(err.to_string().contains("no_such_mesh.obj"), "{err}");
    let err = Scene::load(dir.path().join("absent.xml")).unwrap_err();
    assert!(err.to_string().contains("absent.xml"), "{err}");
}

#[test]
fn a_spec_naming_absent_objects_lists_them() {
    let mut spec = common::spec("click_mouse");
    spec.nodes.insert(
        "extra".into(),
        dexjoco_core::Node::JointThreshold {
            joint: dexjoco_core::JointRef::Qpos("no_such_joint".into()),
            op: dexjoco_core::Cmp::Gt,
            value: 0.0,
        },
    );
    let scene = common::scene("click_mouse");
    assert_eq!(
        unresolved_names(&spec, &scene.model),
        ["joint 'no_such_joint'"]
    );
    let err = TaskEnv::new(&scene, &spec, EnvOptions::default())
        .unwrap_err()
        .to_string();
    assert!(err.contains("joint 'no_such_joint'"), "{err}");
}
