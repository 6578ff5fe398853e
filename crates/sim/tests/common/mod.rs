//! Shared helpers of the simulation tests.
#![allow(dead_code)]

use std::sync::{Mutex, OnceLock};

use dexjoco_core::TaskSpec;
use dexjoco_sim::{Scene, load_task_scene};

/// The task specs of the repository.
pub fn specs() -> Vec<TaskSpec> {
    TaskSpec::load_dir(&dexjoco_testkit::workspace_root().join("schemas/tasks"))
        .expect("task specs")
}

/// One task spec.
pub fn spec(id: &str) -> TaskSpec {
    specs().into_iter().find(|s| s.id == id).expect("task")
}

/// Loads a task's reference scene once per test binary.
pub fn scene(id: &str) -> Scene {
    static CACHE: OnceLock<Mutex<Vec<(String, Scene)>>> = OnceLock::new();
    let cache = CACHE.get_or_init(|| Mutex::new(Vec::new()));
    if let Some((_, s)) = cache.lock().unwrap().iter().find(|(k, _)| k == id) {
        return s.clone();
    }
    let s = load_task_scene(
        &dexjoco_sim::SceneSource::Dir(dexjoco_testkit::reference_scene_dir()),
        &spec(id),
    )
    .expect("reference scene loads");
    cache.lock().unwrap().push((id.to_owned(), s.clone()));
    s
}
