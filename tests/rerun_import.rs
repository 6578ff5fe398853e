//! Rerun opens what `convert` writes: a LeRobot v3.0 dataset made from a sample
//! demonstration (augment: two randomized replays and the wrist camera) loads through
//! Rerun's own LeRobot importer (`rerun <dataset>`, rerun-sdk 0.41 in the test venv)
//! with every episode as a recording, and in each the action and state series, the task
//! text and both cameras' videos cover every frame, and its subtasks (lerobot 0.6's
//! `language_persistent` rows) show as text: one per subtask of click_mouse, and a
//! `task_aug` row for the instruction and each of the task spec's prompt variants.

mod common;

use common::sample_lerobot_dataset;

#[test]
fn rerun_loads_every_episode_with_its_series_and_videos() {
    let tmp = tempfile::tempdir().unwrap();
    let dataset = sample_lerobot_dataset(
        &tmp.path().join("work"),
        "click_mouse/episode_000001",
        2,
        48,
    );
    let info: serde_json::Value =
        serde_json::from_slice(&fs_err::read(dataset.join("meta/info.json")).unwrap()).unwrap();
    let episodes = info["total_episodes"].as_u64().unwrap() as usize;
    let frames = info["total_frames"].as_u64().unwrap();
    assert_eq!(episodes, 2);

    let variants = dexjoco_core::TaskSpec::builtin("click_mouse")
        .unwrap()
        .prompt_variants
        .len();
    assert!(variants > 0, "click_mouse's spec has prompt variants");
    let rrd = tmp.path().join("dataset.rrd");
    let report = dexjoco_testkit::run_python(
        "rerun_import.py",
        &[dataset.to_str().unwrap(), rrd.to_str().unwrap()],
    );
    let report: serde_json::Value = serde_json::from_str(report.trim()).unwrap();
    assert_eq!(
        report["recordings"],
        serde_json::json!(["episode_0", "episode_1"]),
        "{report}"
    );
    let contents = report["contents"].as_array().unwrap();
    assert_eq!(contents.len(), episodes, "{report}");
    let mut total = 0;
    for rec in contents {
        let length = rec["scalars"]["action"].as_u64().unwrap();
        assert!(length > 100, "{rec}");
        assert_eq!(rec["scalars"]["observation.state"], length, "{rec}");
        assert_eq!(rec["task_rows"], length, "{rec}");
        assert_eq!(
            rec["language"],
            serde_json::json!({
                "/language_persistent/subtask/assistant": 2,
                "/language_persistent/task_aug/user": 1 + variants
            }),
            "{rec}"
        );
        for camera in ["third_person", "handcam_rgb"] {
            assert_eq!(
                rec["video_samples"][format!("observation.images.{camera}")],
                length,
                "{camera}: {rec}"
            );
        }
        total += length;
    }
    assert_eq!(total, frames, "{report}");
}
