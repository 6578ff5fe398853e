//! LeRobot v2.1 output: the layout openpi's pinned lerobot reads, converted to v3.0 by
//! lerobot 0.6.1's own `convert_dataset_v21_to_v30` (offline, local root), then loaded
//! by lerobot with every frame, value, task and video colour checked against the source.

mod common;

use common::{check_items, fixture, load, selection};
use dexjoco_convert::{ConvertOptions, OutputFormat, VideoCodec, VideoOptions, convert};
use dexjoco_core::NoProgress;
use serde_json::Value;

fn read_json(p: &std::path::Path) -> Value {
    serde_json::from_str(&fs_err::read_to_string(p).unwrap()).unwrap()
}

#[test]
fn v21_converts_with_lerobots_script_and_loads() {
    let fx = fixture();
    let out_dir = tempfile::tempdir().unwrap();
    let out = out_dir.path().join("v21");
    let opts = ConvertOptions {
        format: OutputFormat::LeRobotV21,
        selection: selection(),
        // Every episode encoded with the same settings (H.264 here).
        video: VideoOptions {
            codec: VideoCodec::H264,
            reencode: false,
        },
        batch: 2,
        ..ConvertOptions::default()
    };
    let s = convert(fx.inputs.iter().cloned().map(Ok), &out, &opts, &NoProgress).unwrap();
    assert_eq!((s.episodes, s.frames), (3, 32));
    assert_eq!((s.videos_copied, s.videos_encoded), (0, 6));

    let info = read_json(&out.join("meta/info.json"));
    assert_eq!(info["codebase_version"], "v2.1");
    assert_eq!(info["total_videos"], 6);
    assert_eq!(info["total_chunks"], 1);
    for e in 0..3 {
        assert!(
            out.join(format!("data/chunk-000/episode_{e:06}.parquet"))
                .is_file()
        );
        let v = out.join(format!(
            "videos/chunk-000/observation.images.wrist/episode_{e:06}.mp4"
        ));
        let times = dexjoco_video::frame_times(&v).unwrap();
        assert_eq!(times.len(), [10, 13, 9][e], "{}", v.display());
        assert!(times[0].abs() < 1e-6, "episode {e} video starts at 0");
    }
    let episodes = fs_err::read_to_string(out.join("meta/episodes.jsonl")).unwrap();
    let lines: Vec<Value> = episodes
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 3);
    assert_eq!(lines[1]["length"], 13);
    let stats = fs_err::read_to_string(out.join("meta/episodes_stats.jsonl")).unwrap();
    let first: Value = serde_json::from_str(stats.lines().next().unwrap()).unwrap();
    assert_eq!(first["stats"]["action"]["count"][0], 10);
    assert!(first["stats"]["observation.images.front"]["mean"][0][0][0].is_number());
    let tasks = fs_err::read_to_string(out.join("meta/tasks.jsonl")).unwrap();
    assert!(tasks.contains("Click the mouse."), "{tasks}");

    // The parquet carries the huggingface features the v2.1 loader builds its types from.
    let run = dexjoco_testkit::run_python_json("lerobot_v21_to_v30.py", &[out.to_str().unwrap()]);
    assert_eq!(run["hf_features"]["action"]["length"], 22);
    assert_eq!(run["hf_features"]["task_index"]["dtype"], "int64");
    assert_eq!(run["hf_types"]["observation.state"], "List");
    let converted = read_json(&out.join("meta/info.json"));
    assert_eq!(converted["codebase_version"], "v3.0");
    let loaded = load(&out, "pyav");
    check_items(&fx, &loaded, 6.0); // a second lossy generation (H.264 crf 21)
}
