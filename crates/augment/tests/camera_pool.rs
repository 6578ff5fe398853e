//! Building a camera pose pool: poses on the requested sphere band, deterministic, the
//! kept ones less occluded than the rest, and an occlusion score that sees blockers.

use dexjoco_augment::{CameraPool, PoolOptions, build_pool, occlusion};
use dexjoco_core::NameKind;
use dexjoco_core::TaskSpec;
use dexjoco_sim::{EnvOptions, SceneSource, TaskEnv, load_task_scene, name_id};

#[test]
fn pools_are_on_the_band_deterministic_and_keep_the_least_occluded() {
    let spec = TaskSpec::builtin("click_mouse").unwrap();
    let scene = load_task_scene(&SceneSource::BuiltIn, spec).unwrap();
    let options = PoolOptions {
        count: 20,
        candidates: 300,
        distance: 1.4,
        elevation: (-2.0, -60.0),
        azimuth: (-150.0, 150.0),
        seed: 3,
    };
    let a = build_pool(&scene, spec, &options).unwrap();
    assert_eq!(a.kept.len(), 20);
    assert_eq!(a.candidates.len(), 300);
    assert!(a.targets > 0 && !a.target_bodies.is_empty());
    for c in &a.candidates {
        let p = c.pose;
        assert!((-150.0..=150.0).contains(&p.azimuth), "{p:?}");
        assert!((-60.0..=-2.0).contains(&p.elevation), "{p:?}");
        let x = p.position();
        let r = (x[0].powi(2) + x[1].powi(2) + (x[2] - 1.0).powi(2)).sqrt();
        assert!((r - 1.4).abs() < 1e-9, "{r}");
        assert!((0.0..=1.0).contains(&c.occlusion));
    }
    // This wide band reaches behind the robot and low over the table: some candidates
    // must be occluded, and the kept ones are the least occluded.
    let worst_kept = a.kept.iter().map(|k| k.occlusion).fold(0.0, f64::max);
    let mean_all = a.candidates.iter().map(|c| c.occlusion).sum::<f64>() / 300.0;
    let mean_kept = a.kept.iter().map(|c| c.occlusion).sum::<f64>() / 20.0;
    assert!(a.candidates.iter().any(|c| c.occlusion > 0.0));
    // Enough candidates see every target point: the kept ones all do.
    assert_eq!(worst_kept, 0.0, "a kept pose is occluded");
    assert!(mean_kept < mean_all, "{mean_kept} vs {mean_all}");
    let better_dropped = a
        .candidates
        .iter()
        .filter(|c| !a.kept.contains(c) && c.occlusion < worst_kept)
        .count();
    assert_eq!(better_dropped, 0, "a less occluded candidate was dropped");
    // Sampling is uniform on the sphere: about half the band's area lies below the
    // altitude whose sine is the middle of the band's sines.
    let (s_lo, s_hi) = (2f64.to_radians().sin(), 60f64.to_radians().sin());
    let mid = ((s_lo + s_hi) / 2.0).asin().to_degrees();
    let below = a
        .candidates
        .iter()
        .filter(|c| -c.pose.elevation < mid)
        .count();
    assert!(
        (110..=190).contains(&below),
        "{below} of 300 below {mid:.1} deg"
    );

    // Same seed, same pool; another seed, another pool.
    assert_eq!(build_pool(&scene, spec, &options).unwrap(), a);
    let other = build_pool(&scene, spec, &PoolOptions { seed: 4, ..options }).unwrap();
    assert_ne!(other.kept, a.kept);

    // The written file is a pool augment reads.
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("pool.json");
    fs_err::write(&f, a.to_json()).unwrap();
    let pool = CameraPool::load(&f).unwrap();
    assert_eq!(pool.poses, a.pool("x").poses);

    // Bad options are refused with a message.
    let e = build_pool(
        &scene,
        spec,
        &PoolOptions {
            count: 400,
            ..options
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("count"), "{e}");
}

#[test]
fn occlusion_sees_the_table_between_the_camera_and_the_mouse() {
    let spec = TaskSpec::builtin("click_mouse").unwrap();
    let scene = load_task_scene(&SceneSource::BuiltIn, spec).unwrap();
    let s0 = TaskEnv::default_initial_state(&scene, spec).unwrap();
    let mut env = TaskEnv::from_initial_state(&scene, spec, &s0, EnvOptions::default()).unwrap();
    let m = scene.model.clone();
    let joint = name_id(&m, NameKind::Joint, "mouse_root").unwrap();
    let body = m.jnt_bodyid()[joint] as usize;
    let p = env.data().xpos()[body];
    let target = [(p, body)];
    // From under the table top: hidden.
    let below = [p[0], p[1], 0.3];
    assert_eq!(occlusion(env.data_mut(), below, &target), 1.0);
    // From straight above, higher than the hand: in view.
    let above = [p[0], p[1], p[2] + 0.25];
    assert_eq!(occlusion(env.data_mut(), above, &target), 0.0);
}
