//! Dataset statistics and their files.

use std::collections::BTreeMap;

use dexjoco_core::{Episode, FrameArray};
use dexjoco_stats::{DatasetStats, StatsError};

fn episode(id: &str, task: &str, frames: usize, action_w: usize, state_w: usize) -> Episode {
    let mut arrays = BTreeMap::new();
    let ramp = |w: usize| {
        FrameArray::new(
            w,
            (0..frames * w)
                .map(|k| (k / w) as f64 + 0.01 * (k % w) as f64)
                .collect(),
        )
        .unwrap()
    };
    arrays.insert(Episode::ACTION.into(), ramp(action_w));
    arrays.insert(Episode::STATE.into(), ramp(state_w));
    arrays.insert(
        Episode::TIMESTAMP.into(),
        Episode::regular_timestamps(frames, 30.0),
    );
    Episode {
        id: id.into(),
        task: task.into(),
        prompt: String::new(),
        fps: 30.0,
        arrays,
        cameras: vec![],
    }
}

#[test]
fn counts_lengths_and_files() {
    let episodes = vec![
        episode("a", "click_mouse", 10, 23, 31),
        episode("b", "click_mouse", 20, 23, 31),
        episode("c", "pinch_tongs", 30, 23, 31),
    ];
    let s = DatasetStats::compute(&episodes).unwrap();
    assert_eq!((s.episodes, s.frames), (3, 60));
    assert_eq!(s.fps, [30.0]);
    assert_eq!(
        (s.lengths.min, s.lengths.max, s.lengths.median),
        (10, 30, 20.0)
    );
    assert_eq!(s.lengths.std, Some(10.0));
    assert_eq!(
        s.tasks
            .iter()
            .map(|t| (t.task.as_str(), t.episodes, t.frames))
            .collect::<Vec<_>>(),
        [("click_mouse", 2, 30), ("pinch_tongs", 1, 30)]
    );
    // Same widths everywhere: dataset-wide stats of action and state, not timestamps.
    assert_eq!(s.arrays.keys().collect::<Vec<_>>(), ["action", "state"]);
    let action = &s.arrays["action"];
    assert_eq!(action.frames, 60);
    assert_eq!(action.columns[3], "arm.quat_wxyz[0]");
    assert_eq!(action.histogram[0].iter().sum::<u64>(), 60);
    assert_eq!(s.arrays["state"].columns[30], "privileged[7]");

    let dir = tempfile::tempdir().unwrap();
    let files = s.write(dir.path()).unwrap();
    for name in [
        "dataset_stats.json",
        "summary.md",
        "source_norm_stats.json",
        "source_norm_stats/click_mouse.json",
        "episode_lengths.png",
        "action_distribution.svg",
        "state_distribution.png",
    ] {
        assert!(
            files.contains(&dir.path().join(name)),
            "{name} missing from {files:?}"
        );
    }
    let png = image::open(dir.path().join("action_distribution.png")).unwrap();
    assert!(png.width() > 1000, "{}", png.width());
    let norm: serde_json::Value = serde_json::from_str(
        &fs_err::read_to_string(dir.path().join("source_norm_stats.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(
        norm["norm_stats"]["actions"]["mean"]
            .as_array()
            .unwrap()
            .len(),
        23
    );
    let md = s.to_markdown();
    assert!(
        md.contains("| click_mouse | 2 | 30 | 15.0 ± 7.1 | 10 | 20 |"),
        "{md}"
    );
}

#[test]
fn widths_must_agree_within_a_task() {
    let episodes = vec![
        episode("a", "click_mouse", 5, 23, 31),
        episode("b", "click_mouse", 5, 23, 38),
    ];
    let err = DatasetStats::compute(&episodes).unwrap_err();
    assert!(matches!(err, StatsError::Width { .. }));
    let msg = err.to_string();
    assert!(
        msg.contains("episode 'b'") && msg.contains("state") && msg.contains("38"),
        "{msg}"
    );
    assert!(DatasetStats::compute(&[]).is_err());
}
