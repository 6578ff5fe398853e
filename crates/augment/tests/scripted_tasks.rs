//! Every task with a scripted planner, end to end: a demonstration planned from a random
//! reset on the built-in scene succeeds, is written in the raw layout, and replays
//! through `augment` (one rendered replay of one camera, 32 px) to success with state
//! deviation 0; the deliberately wrong plans reach their task's failure condition.

use std::path::Path;

use dexjoco_augment::{AugmentConfig, augment};
use dexjoco_core::TaskSpec;
use dexjoco_render::RenderSettings;
use dexjoco_scripted::{self as scripted, Variant};
use dexjoco_sim::{SceneSource, TaskEnv, load_task_scene};
use rand::{Rng, SeedableRng};

/// A random reset of `task` (seeded), its scene and spec.
fn reset(task: &str, seed: u64) -> (dexjoco_sim::Scene, TaskSpec, Vec<f64>) {
    let spec = TaskSpec::builtin(task).expect("a built-in task");
    let scene = load_task_scene(&SceneSource::BuiltIn, spec).unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let s0 = TaskEnv::sample_initial_state(&scene, spec, &mut || rng.random::<f64>()).unwrap();
    (scene, spec.clone(), s0)
}

/// Every subtask of a successful plan ended, each within its span, the last on the
/// success step, and within the documented agreement of the planner's own phase end.
fn assert_segmented(task: &str, planned: &scripted::Planned, success: usize) {
    let spans = &planned.subtasks;
    assert!(!spans.is_empty(), "{task}: no subtasks");
    assert_eq!(
        planned.phase_disagreements(),
        Vec::<String>::new(),
        "{task}"
    );
    for s in spans {
        let (Some(start), Some(end)) = (s.start, s.end) else {
            panic!("{task}: subtask '{}' did not end: {spans:?}", s.id);
        };
        assert!(start <= end && end <= success, "{task}: {s:?}");
    }
    assert_eq!(
        spans.last().unwrap().end,
        Some(success),
        "{task}: {spans:?}"
    );
}

/// Plans `task` from a random reset, writes it, replays it through augment.
fn plan_record_replay(task: &str, seed: u64) {
    let (scene, spec, s0) = reset(task, seed);
    let planned = scripted::plan(&scene, &spec, &s0, &format!("{task}_test"), Variant::Demo)
        .unwrap_or_else(|e| panic!("{task}: {e}"));
    let ep = &planned.episode;
    let at = planned
        .success_at
        .unwrap_or_else(|| panic!("{task}: the plan did not succeed in {} steps", ep.len()));
    assert_eq!(at, ep.len() - 1, "{task}: recorded up to the success step");
    assert!(!planned.failed);
    assert_eq!(ep.task, task);
    assert_segmented(task, &planned, at);

    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in").join(task).join("episode_000000");
    dexjoco_formats::raw::write_replay_zarr(&input, ep).unwrap();
    let camera = spec.cameras[0].camera.clone();
    let config = AugmentConfig {
        replays: 1,
        seed: 3,
        cameras: vec![camera],
        settings: RenderSettings {
            width: 32,
            height: 32,
            ..RenderSettings::default()
        },
        contact_sheet: false,
        // Strict: the replay must succeed on the very step the plan did.
        extend_steps: 0,
        ..AugmentConfig::new(vec![dir.path().join("in")], dir.path().join("out"))
    };
    let report = augment(&config, &dexjoco_core::NoProgress).unwrap();
    assert_eq!(report.episodes.len(), 1, "{task}: {:?}", report.skipped);
    let e = &report.episodes[0];
    assert!(e.success, "{task}: the replay did not succeed");
    assert_eq!(
        e.first_success,
        Some(at),
        "{task}: success on the same step"
    );
    assert_eq!(e.max_state_deviation, 0.0, "{task}: replay != recording");
    assert_eq!(
        e.subtasks, planned.subtasks,
        "{task}: the replay's subtasks are the plan's"
    );
    assert_eq!(
        e.replays_kept, 1,
        "{task}: the rendered replay was not kept"
    );
    assert!(Path::new(&config.out).is_dir());
}

#[test]
fn click_mouse_plans_and_replays() {
    plan_record_replay("click_mouse", 11);
}

#[test]
fn bimanual_assembly_plans_and_replays() {
    plan_record_replay("bimanual_assembly", 18);
}

#[test]
fn bimanual_hanoi_plans_and_replays() {
    plan_record_replay("bimanual_hanoi", 21);
}

#[test]
fn bimanual_microwave_cook_plans_and_replays() {
    plan_record_replay("bimanual_microwave_cook", 22);
}

#[test]
fn bimanual_photograph_plans_and_replays() {
    plan_record_replay("bimanual_photograph", 19);
}

#[test]
fn bimanual_unlock_ipad_plans_and_replays() {
    plan_record_replay("bimanual_unlock_ipad", 12);
}

#[test]
fn fold_glasses_plans_and_replays() {
    plan_record_replay("fold_glasses", 17);
}

#[test]
fn hammer_nail_plans_and_replays() {
    plan_record_replay("hammer_nail", 13);
}

#[test]
fn pick_bucket_plans_and_replays() {
    plan_record_replay("pick_bucket", 20);
}

#[test]
fn pinch_tongs_plans_and_replays() {
    plan_record_replay("pinch_tongs", 14);
}

#[test]
fn water_plant_plans_and_replays() {
    plan_record_replay("water_plant", 16);
}

#[test]
fn every_task_with_a_planner_is_tested_here() {
    let tested = [
        "bimanual_assembly",
        "bimanual_hanoi",
        "bimanual_microwave_cook",
        "bimanual_photograph",
        "bimanual_unlock_ipad",
        "click_mouse",
        "fold_glasses",
        "hammer_nail",
        "pick_bucket",
        "pinch_tongs",
        "water_plant",
    ];
    assert_eq!(scripted::PLANNED_TASKS, tested);
    // Every DexJoCo task has a planner.
    assert_eq!(dexjoco_core::TaskSet::builtin().ids(), tested.to_vec());
}

#[test]
fn wrong_plans_reach_the_failure_condition() {
    // bimanual_unlock_ipad: a wrong second digit fails the episode.
    let (scene, spec, s0) = reset("bimanual_unlock_ipad", 15);
    let p = scripted::plan(&scene, &spec, &s0, "wrong", Variant::Wrong).unwrap();
    assert!(p.failed, "a wrong digit did not fail the episode");
    assert_eq!(p.success_at, None);
    // The failure is on the last recorded step, and a replay reaches it there too.
    let mut env = TaskEnv::from_initial_state(&scene, &spec, &s0, Default::default()).unwrap();
    let r = env
        .rollout(p.episode.array(dexjoco_core::Episode::ACTION).unwrap())
        .unwrap();
    assert_eq!(r.first_failure(), Some(p.episode.len() - 1));
    assert!(!r.succeeded());
    // water_plant: pulling the trigger right after lifting the bottle, far from the plant.
    let (scene, spec, s0) = reset("water_plant", 15);
    let p = scripted::plan(&scene, &spec, &s0, "wrong", Variant::Wrong).unwrap();
    assert!(
        p.failed,
        "pulling the trigger away from the plant did not fail"
    );
    assert_eq!(p.success_at, None);
    // bimanual_hanoi: the medium disk set down on the base between two posts.
    let (scene, spec, s0) = reset("bimanual_hanoi", 15);
    let p = scripted::plan(&scene, &spec, &s0, "wrong", Variant::Wrong).unwrap();
    assert!(p.failed, "a disk on the table did not fail the episode");
    assert_eq!(p.success_at, None);
    // A task without a failure condition has no wrong plan.
    let (scene, spec, s0) = reset("pinch_tongs", 15);
    assert!(scripted::plan(&scene, &spec, &s0, "wrong", Variant::Wrong).is_err());
}
