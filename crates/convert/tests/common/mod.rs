//! The fixture the conversion tests share: three single-arm episodes of two tasks with
//! solid-colour H.264 videos, two of them with static leading frames.

#![allow(dead_code)]

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use dexjoco_convert::{InputEpisode, Selection, TaskSelection};
use dexjoco_core::{CameraStream, Episode, FrameArray};
use dexjoco_video::{Codec, Keyframes, VideoSpec, VideoWriter};
use serde_json::Value;

pub const SIZE: u32 = 64; // SVT-AV1 needs at least 64 rows

/// The colour of camera `cam`'s frame `k` of episode `ep`: solid, so that decoding is
/// near-exact and a frame off by one is obvious (green steps by 12 per frame).
pub fn colour(ep: usize, cam: usize, k: usize) -> [u8; 3] {
    [
        (40 + 70 * ep) as u8,
        (10 + 12 * k) as u8,
        (60 + 120 * cam) as u8,
    ]
}

pub struct Fixture {
    pub _dir: tempfile::TempDir,
    pub inputs: Vec<InputEpisode>,
    /// Per episode: first kept frame.
    pub starts: Vec<usize>,
}

/// Three single-arm episodes of two tasks, cameras `front` and `handcam_rgb` in H.264 as
/// augment writes them (a keyframe where convert cuts the static leading frames);
/// episodes 0 and 1 begin with static frames.
pub fn fixture() -> Fixture {
    fixture_with(true)
}

/// [`fixture`], with `keyframes_at_cuts` false as the DexJoCo recorder writes videos
/// (x264's keyframe interval alone: convert re-encodes to cut).
pub fn fixture_with(keyframes_at_cuts: bool) -> Fixture {
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
        fs_err::create_dir_all(ep_dir.join("videos")).unwrap();
        for (c, cam) in ["front", "handcam_rgb"].iter().enumerate() {
            let rel = PathBuf::from(format!("videos/{cam}.mp4"));
            let keyframes = Keyframes {
                interval: None,
                at: if keyframes_at_cuts {
                    dexjoco_core::possible_cuts(&episode)
                } else {
                    Vec::new()
                },
            };
            write_video_with(&ep_dir.join(&rel), n, |k| colour(e, c, k), &keyframes);
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

pub fn write_video(path: &Path, n: usize, colour: impl Fn(usize) -> [u8; 3]) {
    write_video_with(path, n, colour, &Keyframes::default());
}

pub fn write_video_with(
    path: &Path,
    n: usize,
    colour: impl Fn(usize) -> [u8; 3],
    keyframes: &Keyframes,
) {
    let spec = VideoSpec {
        width: SIZE,
        height: SIZE,
        fps: 30,
        codec: Codec::DEXJOCO,
    };
    let mut w = VideoWriter::create_with(path, spec, keyframes).unwrap();
    for k in 0..n {
        let c = colour(k);
        let frame: Vec<u8> = (0..SIZE * SIZE).flat_map(|_| c).collect();
        w.write_frame(&frame).unwrap();
    }
    w.finish().unwrap();
}

pub fn selection() -> Selection {
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

/// Loads a LeRobot v3.0 dataset with lerobot 0.6.1 (`backend`: pyav or torchcodec),
/// after lerobot-doctor's checks pass on it.
pub fn load(root: &Path, backend: &str) -> Value {
    dexjoco_testkit::lerobot_doctor_passes(root);
    dexjoco_testkit::run_python_json("lerobot_v3_load.py", &[root.to_str().unwrap(), backend])
}

/// Checks every item lerobot read against the fixture's source (frames after the
/// trimmed start; video colours within `tolerance`).
pub fn check_items(fx: &Fixture, loaded: &Value, tolerance: f64) {
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
