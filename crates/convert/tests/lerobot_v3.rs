//! LeRobot v3.0 output read back by lerobot 0.6.1 itself (offline, `root=`), with both
//! video backends: every frame indexed, values equal to the source (as float32), task
//! text right, video frames decoded at the right time within tolerance.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use dexjoco_convert::{
    ConvertOptions, InputEpisode, Selection, Silent, TaskSelection, VideoCodec, VideoOptions,
    convert,
};
use dexjoco_core::{CameraStream, Episode, FrameArray};
use dexjoco_video::{Codec, VideoSpec, VideoWriter};
use serde_json::Value;

const SIZE: u32 = 64; // SVT-AV1 needs at least 64 rows

/// The colour of camera `cam`'s frame `k` of episode `ep`: solid, so that decoding is
/// near-exact and a frame off by one is obvious (green steps by 12 per frame).
fn colour(ep: usize, cam: usize, k: usize) -> [u8; 3] {
    [
        (40 + 70 * ep) as u8,
        (10 + 12 * k) as u8,
        (60 + 120 * cam) as u8,
    ]
}

struct Fixture {
    _dir: tempfile::TempDir,
    inputs: Vec<InputEpisode>,
    /// Per episode: first kept frame.
    starts: Vec<usize>,
}

/// Three single-arm episodes of two tasks, cameras `front` and `handcam_rgb` in H.264 as
/// the DexJoCo recorder writes them; episodes 0 and 1 begin with static frames.
fn fixture() -> Fixture {
    let dir = tempfile::tempdir().unwrap();
    let lens = [12usize, 15, 9];
    let tasks = ["click_mouse", "water_plant", "click_mouse"];
    let mut inputs = Vec::new();
    for (e, &n) in lens.iter().enumerate() {
        let mut action = Vec::new();
        for k in 0..n {
            let mut row = vec![0.0; 23];
            let moving = match e {
                0 => k.max(2) as f64,            // frames 0..=2 repeat a nonzero action
                1 => k.saturating_sub(1) as f64, // frames 0, 1 are all zeros
                _ => k as f64 + 1.0,
            };
            if !(e == 1 && k < 2) {
                row[0] = 0.1 * moving;
                row[3] = 1.0; // identity quaternion
                for (j, v) in row.iter_mut().enumerate().skip(7) {
                    *v = 0.01 * j as f64 + 0.001 * moving + 0.3 * e as f64;
                }
            }
            action.push(row);
        }
        let state: Vec<Vec<f64>> = (0..n)
            .map(|k| {
                (0..31)
                    .map(|j| (e * 1000 + k * 31 + j) as f64 / 997.0)
                    .collect()
            })
            .collect();
        let mut arrays = BTreeMap::new();
        arrays.insert(
            Episode::ACTION.into(),
            FrameArray::from_rows(&action).unwrap(),
        );
        arrays.insert(
            Episode::STATE.into(),
            FrameArray::from_rows(&state).unwrap(),
        );
        arrays.insert(
            Episode::TIMESTAMP.into(),
            Episode::regular_timestamps(n, 30.0),
        );
        let mut episode = Episode {
            id: format!("episode_{e:06}"),
            task: tasks[e].into(),
            prompt: String::new(),
            fps: 30.0,
            arrays,
            cameras: vec![],
        };
        episode
            .compute_action_rotvec(dexjoco_core::ArmSetup::SingleArm)
            .unwrap();
        let ep_dir = dir.path().join(&episode.id);
        std::fs::create_dir_all(ep_dir.join("videos")).unwrap();
        for (c, cam) in ["front", "handcam_rgb"].iter().enumerate() {
            let rel = PathBuf::from(format!("videos/{cam}.mp4"));
            write_video(&ep_dir.join(&rel), n, |k| colour(e, c, k));
            episode.cameras.push(CameraStream {
                name: (*cam).into(),
                video: Some(rel),
                depth: None,
            });
        }
        inputs.push(InputEpisode {
            episode,
            dir: ep_dir,
        });
    }
    Fixture {
        _dir: dir,
        inputs,
        starts: vec![2, 2, 0],
    }
}

fn write_video(path: &Path, n: usize, colour: impl Fn(usize) -> [u8; 3]) {
    let spec = VideoSpec {
        width: SIZE,
        height: SIZE,
        fps: 30,
        codec: Codec::DEXJOCO,
    };
    let mut w = VideoWriter::create(path, spec).unwrap();
    for k in 0..n {
        let c = colour(k);
        let frame: Vec<u8> = (0..SIZE * SIZE).flat_map(|_| c).collect();
        w.write_frame(&frame).unwrap();
    }
    w.finish().unwrap();
}

fn selection() -> Selection {
    let mut sel = Selection {
        default: TaskSelection {
            cameras: BTreeMap::from([
                ("front".into(), "front".into()),
                ("wrist".into(), "handcam_rgb".into()),
            ]),
            ..TaskSelection::default()
        },
        ..Selection::default()
    };
    sel.instructions
        .insert("click_mouse".into(), "Click the mouse.".into());
    sel
}

fn load(root: &Path, backend: &str) -> Value {
    dexjoco_testkit::run_python_json("lerobot_v3_load.py", &[root.to_str().unwrap(), backend])
}

fn check_items(fx: &Fixture, loaded: &Value, tolerance: f64) {
    let items = loaded["items"].as_array().unwrap();
    let kept: Vec<usize> = fx
        .inputs
        .iter()
        .zip(&fx.starts)
        .map(|(i, s)| i.episode.len() - s)
        .collect();
    assert_eq!(
        items.len(),
        kept.iter().sum::<usize>(),
        "every frame indexed"
    );
    assert_eq!(loaded["num_episodes"], 3);
    let mut index = 0;
    for (e, input) in fx.inputs.iter().enumerate() {
        let ep = &input.episode;
        let rotvec = ep.array(Episode::ACTION_ROTVEC).unwrap();
        let state = ep.array(Episode::STATE).unwrap();
        for f in 0..kept[e] {
            let it = &items[index];
            let src = fx.starts[e] + f;
            assert_eq!(it["index"], index);
            assert_eq!(it["episode_index"], e);
            assert_eq!(it["frame_index"], f);
            assert!((it["timestamp"].as_f64().unwrap() - f as f64 / 30.0).abs() < 1e-6);
            let want_task = if ep.task == "click_mouse" {
                "Click the mouse."
            } else {
                "Grasp the watering can and apply water to the plant."
            };
            assert_eq!(it["task"], want_task, "task text of episode {e}");
            // float32 on both sides (JSON parsing of doubles is not exact to the last bit).
            let got: Vec<f32> = it["action"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap() as f32)
                .collect();
            let want: Vec<f32> = rotvec.row(src).iter().map(|v| *v as f32).collect();
            assert_eq!(got, want, "action of episode {e} frame {f}");
            let got: Vec<f32> = it["state"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap() as f32)
                .collect();
            let want: Vec<f32> = state.row(src)[..23].iter().map(|v| *v as f32).collect();
            assert_eq!(got, want, "state of episode {e} frame {f}");
            for (c, key) in ["observation.images.front", "observation.images.wrist"]
                .iter()
                .enumerate()
            {
                let got = &it["images"][key];
                let want = colour(e, c, src);
                for ch in 0..3 {
                    let g = got[ch].as_f64().unwrap();
                    assert!(
                        (g - f64::from(want[ch])).abs() <= tolerance,
                        "{key} episode {e} frame {f} channel {ch}: decoded {g}, source {}",
                        want[ch]
                    );
                }
            }
            index += 1;
        }
    }
}

fn options(video: VideoOptions) -> ConvertOptions {
    ConvertOptions {
        selection: selection(),
        video,
        batch: 2, // several batches over three episodes
        ..ConvertOptions::default()
    }
}

#[test]
fn stream_copied_h264_loads_in_lerobot_with_pyav_and_torchcodec() {
    let fx = fixture();
    let out_dir = tempfile::tempdir().unwrap();
    let out = out_dir.path().join("dataset");
    let summary = convert(
        fx.inputs.iter().cloned().map(Ok),
        &out,
        &options(VideoOptions::default()),
        &Silent,
    )
    .unwrap();
    assert_eq!(
        (summary.episodes, summary.frames, summary.skipped_frames),
        (3, 32, 4)
    );
    assert_eq!((summary.videos_copied, summary.videos_encoded), (6, 0));
    // One file per camera; timestamps continuous: 36 frames at k / 30.
    let front = out.join("videos/observation.images.front/chunk-000/file-000.mp4");
    let times = dexjoco_video::frame_times(&front).unwrap();
    assert_eq!(times.len(), 36);
    for (k, t) in times.iter().enumerate() {
        assert!((t - k as f64 / 30.0).abs() < 1e-4, "frame {k} at {t}");
    }
    let info: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("meta/info.json")).unwrap())
            .unwrap();
    assert_eq!(info["codebase_version"], "v3.0");
    assert_eq!(info["total_frames"], 32);
    assert_eq!(info["total_tasks"], 2);
    assert_eq!(
        info["features"]["observation.images.front"]["info"]["video.codec"],
        "h264"
    );
    assert_eq!(info["features"]["action"]["shape"][0], 22);
    for backend in ["pyav", "torchcodec"] {
        let loaded = load(&out, backend);
        check_items(&fx, &loaded, 3.0);
        assert!(
            loaded["stats_keys"]
                .as_array()
                .unwrap()
                .iter()
                .any(|k| k == "observation.images.wrist"),
            "{backend}: image stats"
        );
    }
    // No leftovers beside the dataset.
    let names: Vec<String> = std::fs::read_dir(out_dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, vec!["dataset".to_owned()]);
    assert!(!out.join(".work").exists());
}

#[test]
fn reencoded_av1_loads_in_lerobot() {
    let fx = fixture();
    let out_dir = tempfile::tempdir().unwrap();
    let out = out_dir.path().join("dataset");
    let video = VideoOptions {
        codec: VideoCodec::Av1,
        reencode: true,
    };
    let summary = convert(
        fx.inputs.iter().cloned().map(Ok),
        &out,
        &options(video),
        &Silent,
    )
    .unwrap();
    assert_eq!((summary.videos_copied, summary.videos_encoded), (0, 6));
    let info =
        dexjoco_video::probe(&out.join("videos/observation.images.wrist/chunk-000/file-000.mp4"))
            .unwrap();
    assert_eq!((info.codec.as_str(), info.frames), ("av1", 32));
    let loaded = load(&out, "pyav");
    check_items(&fx, &loaded, 6.0); // AV1 crf 30 on 64x64: a few levels
}

#[test]
fn refuses_a_non_empty_output_and_bad_input_leaves_nothing() {
    let fx = fixture();
    let out_dir = tempfile::tempdir().unwrap();
    let out = out_dir.path().join("dataset");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("keep.txt"), "x").unwrap();
    let opts = options(VideoOptions::default());
    let err = convert(fx.inputs.iter().cloned().map(Ok), &out, &opts, &Silent).unwrap_err();
    assert!(err.to_string().contains("not empty"), "{err}");
    assert!(out.join("keep.txt").exists());

    // A missing camera: the error names episode and camera; nothing is left behind and
    // the old folder is untouched even with overwrite.
    let mut bad = fx.inputs.clone();
    bad[2].episode.cameras.retain(|c| c.name != "handcam_rgb");
    let opts = ConvertOptions {
        overwrite: true,
        ..opts
    };
    let err = convert(bad.into_iter().map(Ok), &out, &opts, &Silent)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("episode_000002") && err.contains("handcam_rgb"),
        "{err}"
    );
    assert!(out.join("keep.txt").exists());
    assert_eq!(std::fs::read_dir(out_dir.path()).unwrap().count(), 1);

    // Overwrite, with a bad-episodes list.
    let mut opts = opts;
    opts.selection.bad_episodes.insert("episode_000001".into());
    let s = convert(fx.inputs.iter().cloned().map(Ok), &out, &opts, &Silent).unwrap();
    assert_eq!(
        (s.episodes, s.excluded.clone()),
        (2, vec!["episode_000001".to_owned()])
    );
    assert!(!out.join("keep.txt").exists());
    assert!(out.join("meta/info.json").exists());
}

#[test]
fn size_caps_split_data_and_video_files_and_lerobot_follows() {
    let fx = fixture();
    let out_dir = tempfile::tempdir().unwrap();
    let out = out_dir.path().join("dataset");
    let mut opts = options(VideoOptions::default());
    // Caps below one episode: every episode opens new files.
    opts.v3.data_file_mb = 1e-9;
    opts.v3.video_file_mb = 1e-9;
    convert(fx.inputs.iter().cloned().map(Ok), &out, &opts, &Silent).unwrap();
    for f in 0..3 {
        assert!(
            out.join(format!("data/chunk-000/file-{f:03}.parquet"))
                .is_file(),
            "data file {f}"
        );
        assert!(
            out.join(format!(
                "videos/observation.images.wrist/chunk-000/file-{f:03}.mp4"
            ))
            .is_file(),
            "video file {f}"
        );
    }
    let loaded = load(&out, "pyav");
    check_items(&fx, &loaded, 3.0);
}
