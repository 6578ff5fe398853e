//! Multi-task merge: one-arm episodes (two tasks) and a two-arm episode in one LeRobot
//! v3.0 dataset with a task table, one-arm fields in the right-arm slots of the two-arm
//! layout, cameras mapped to shared names; read back by lerobot 0.6.1.

mod common;

use std::collections::BTreeMap;
use std::path::PathBuf;

use common::{fixture, load, write_video};
use dexjoco_convert::{
    ConvertOptions, InputEpisode, Selection, TaskSelection, VideoOptions, convert,
};
use dexjoco_core::NoProgress;
use dexjoco_core::{ArmSetup, CameraStream, Episode, FrameArray};

fn bimanual_episode(dir: &std::path::Path) -> InputEpisode {
    let n = 8;
    let action: Vec<Vec<f64>> = (0..n)
        .map(|k| {
            let mut r: Vec<f64> = (0..46)
                .map(|j| 0.5 + 0.01 * j as f64 + 0.02 * k as f64)
                .collect();
            for q in [3, 26] {
                r[q..q + 4].copy_from_slice(&[1.0, 0.0, 0.0, 0.0]);
            }
            r
        })
        .collect();
    let state: Vec<Vec<f64>> = (0..n)
        .map(|k| {
            (0..60)
                .map(|j| -1.0 + 0.003 * (k * 60 + j) as f64)
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
        id: "bimanual_000000".into(),
        task: "bimanual_unlock_ipad".into(),
        prompt: String::new(),
        fps: 30.0,
        arrays,
        cameras: vec![],
    };
    episode.compute_action_rotvec(ArmSetup::Bimanual).unwrap();
    let ep_dir = dir.join(&episode.id);
    fs_err::create_dir_all(ep_dir.join("videos")).unwrap();
    for (c, cam) in ["ego", "wrist_right"].iter().enumerate() {
        let rel = PathBuf::from(format!("videos/{cam}.mp4"));
        write_video(&ep_dir.join(&rel), n, |k| {
            [200, (5 * k) as u8, (30 + 100 * c) as u8]
        });
        episode.cameras.push(CameraStream {
            name: (*cam).into(),
            video: Some(rel),
            depth: None,
        });
    }
    InputEpisode {
        episode,
        dir: ep_dir,
    }
}

/// One-arm cameras `front`, `handcam_rgb` and two-arm `ego`, `wrist_right` mapped to the
/// shared `base`, `wrist`; one-arm episodes merged into the two-arm layout.
fn merge_selection() -> Selection {
    let one_arm = TaskSelection {
        cameras: BTreeMap::from([
            ("base".into(), "front".into()),
            ("wrist".into(), "handcam_rgb".into()),
        ]),
        ..TaskSelection::default()
    };
    let two_arm = TaskSelection {
        cameras: BTreeMap::from([
            ("base".into(), "ego".into()),
            ("wrist".into(), "wrist_right".into()),
        ]),
        ..TaskSelection::default()
    };
    Selection {
        default: one_arm,
        tasks: BTreeMap::from([("bimanual_unlock_ipad".into(), two_arm)]),
        merge_bimanual: true,
        ..Selection::default()
    }
}

#[test]
fn one_arm_and_two_arm_tasks_merge_into_the_two_arm_layout() {
    let fx = fixture();
    let extra = tempfile::tempdir().unwrap();
    let mut inputs = fx.inputs.clone();
    inputs.push(bimanual_episode(extra.path()));
    let selection = merge_selection();
    let out_dir = tempfile::tempdir().unwrap();
    let out = out_dir.path().join("merged");
    let opts = ConvertOptions {
        selection: selection.clone(),
        video: VideoOptions::default(),
        ..ConvertOptions::default()
    };
    let s = convert(inputs.iter().cloned().map(Ok), &out, &opts, &NoProgress).unwrap();
    assert_eq!((s.episodes, s.frames), (4, 40));
    let info: serde_json::Value =
        serde_json::from_str(&fs_err::read_to_string(out.join("meta/info.json")).unwrap()).unwrap();
    assert_eq!(info["total_tasks"], 3);
    assert_eq!(info["features"]["action"]["shape"][0], 44);
    assert_eq!(info["features"]["observation.state"]["shape"][0], 46);
    assert_eq!(
        info["features"]["observation.state"]["names"][14],
        "right.hand_qpos[0]"
    );

    let loaded = load(&out, "pyav");
    check_loaded(&loaded, &fx.inputs, &inputs);

    // Without the merge the widths differ: the two-arm episode is left out, and the
    // reason says how to fix it.
    let opts = ConvertOptions {
        selection: Selection {
            merge_bimanual: false,
            ..selection
        },
        ..ConvertOptions::default()
    };
    let s = convert(
        inputs.into_iter().map(Ok),
        &out_dir.path().join("x"),
        &opts,
        &NoProgress,
    )
    .unwrap();
    assert_eq!(s.episodes, 3);
    assert_eq!(s.failed.len(), 1, "{:?}", s.failed);
    let f = &s.failed[0];
    assert_eq!(f.episode, "bimanual_000000");
    assert!(
        f.reason.contains("widths") && f.reason.contains("select the same arrays"),
        "{}",
        f.reason
    );
}

/// What lerobot loads of the merged dataset: one-arm values in the right-arm slots, the
/// two-arm episode's own values, shared camera names. `one_arm` are the fixture's
/// inputs, `inputs` all four.
fn check_loaded(loaded: &serde_json::Value, one_arm: &[InputEpisode], inputs: &[InputEpisode]) {
    let items = loaded["items"].as_array().unwrap();
    assert_eq!(items.len(), 40);
    let f32s = |v: &serde_json::Value| -> Vec<f32> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap() as f32)
            .collect()
    };
    // Episode 1 (one arm, water_plant), its first kept frame (source frame 2).
    let it = &items[10];
    assert_eq!(it["episode_index"], 1);
    assert_eq!(
        it["task"],
        "Grasp the watering can and apply water to the plant."
    );
    let src = &one_arm[1].episode;
    let rotvec = src.array(Episode::ACTION_ROTVEC).unwrap().row(2);
    let state = src.array(Episode::STATE).unwrap().row(2);
    let action = f32s(&it["action"]);
    let obs = f32s(&it["state"]);
    let f = |v: &[f64]| -> Vec<f32> { v.iter().map(|x| *x as f32).collect() };
    assert_eq!(action[..22], f(rotvec)[..], "right-arm action slots");
    assert!(
        action[22..].iter().all(|x| *x == 0.0),
        "left-arm action slots"
    );
    assert_eq!(obs[..7], f(&state[..7])[..], "right TCP");
    assert_eq!(
        obs[10..14],
        [1.0, 0.0, 0.0, 0.0],
        "left TCP quaternion: identity"
    );
    assert_eq!(obs[14..30], f(&state[7..23])[..], "right hand");
    assert!(obs[30..].iter().all(|x| *x == 0.0), "left hand");
    // The two-arm episode keeps its own values.
    let it = &items[32];
    assert_eq!(it["episode_index"], 3);
    assert_eq!(
        it["task"],
        "Grasp the iPad and enter the password 123 to unlock the device."
    );
    let src = &inputs[3].episode;
    let rotvec = src.array(Episode::ACTION_ROTVEC).unwrap().row(0);
    assert_eq!(f32s(&it["action"]), f(rotvec));
    assert_eq!(
        f32s(&it["state"]),
        f(&src.array(Episode::STATE).unwrap().row(0)[..46])
    );
    // Shared camera names: the two-arm ego camera is `base`.
    let base = &it["images"]["observation.images.base"];
    assert!((base[0].as_f64().unwrap() - 200.0).abs() <= 3.0, "{base}");
}
