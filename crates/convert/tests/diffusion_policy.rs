//! Diffusion Policy output opened by Diffusion Policy's own `ReplayBuffer` class under
//! zarr 2.x (both its backends), arrays equal to the source; `--videos` beside it.
//! (openpi's `norm_stats.json` is checked against openpi's own code in `openpi_norm_stats.rs`.)
//!
//! The `ReplayBuffer` class is real-stanford/diffusion_policy's
//! `diffusion_policy/common/replay_buffer.py` at commit [`DP_COMMIT`], kept outside the
//! repository (see [`diffusion_policy_dir`]).

mod common;

use std::path::PathBuf;

use common::{colour, fixture, selection};
use dexjoco_convert::{ConvertOptions, OutputFormat, VideoOptions, convert};
use dexjoco_core::Episode;
use dexjoco_core::NoProgress;
use serde_json::Value;

/// The pinned commit of real-stanford/diffusion_policy.
const DP_COMMIT: &str = "5ba07ac6661db573af695b419a7947ecb704690f";
/// sha256 of `diffusion_policy/common/replay_buffer.py` at [`DP_COMMIT`].
const DP_REPLAY_BUFFER_SHA256: &str =
    "c8d59f208525ed5c2164b67f85faf8642251d408533eec1639282076a79d80b4";

/// The folder holding `diffusion_policy/common/replay_buffer.py`: `$DEXJOCO_DIFFUSION_POLICY`,
/// else `~/.cache/dexjoco-data/diffusion_policy-<commit>`. Panics with the way to get it.
fn diffusion_policy_dir() -> PathBuf {
    let dir = std::env::var_os("DEXJOCO_DIFFUSION_POLICY").map_or_else(
        || {
            PathBuf::from(std::env::var_os("HOME").expect("HOME"))
                .join(format!(".cache/dexjoco-data/diffusion_policy-{DP_COMMIT}"))
        },
        PathBuf::from,
    );
    assert!(
        dir.join("diffusion_policy/common/replay_buffer.py")
            .is_file(),
        "Diffusion Policy's replay_buffer.py is missing from {}: run `scripts/setup.sh --python`, \
         which takes it (checked by sha256) from GitHub or from \
         ../shared/third_party/diffusion_policy-{DP_COMMIT}/ (or set DEXJOCO_DIFFUSION_POLICY)",
        dir.display()
    );
    dir
}

fn options(videos: bool) -> ConvertOptions {
    ConvertOptions {
        format: OutputFormat::DiffusionPolicy,
        selection: selection(),
        video: VideoOptions::default(),
        videos,
        batch: 2,
        ..ConvertOptions::default()
    }
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

#[test]
fn replay_buffer_opens_in_diffusion_policy_with_source_values() {
    let fx = fixture();
    let out_dir = tempfile::tempdir().unwrap();
    let out = out_dir.path().join("dp");
    let summary = convert(
        fx.inputs.iter().cloned().map(Ok),
        &out,
        &options(true),
        &NoProgress,
    )
    .unwrap();
    assert_eq!((summary.episodes, summary.frames), (3, 32));
    let zarr = out.join("replay_buffer.zarr");
    let dp = diffusion_policy_dir();
    let got = dexjoco_testkit::run_python_json(
        "dp_replay_buffer_load.py",
        &[dp.to_str().unwrap(), zarr.to_str().unwrap()],
    );
    assert_eq!(got["replay_buffer_sha256"], DP_REPLAY_BUFFER_SHA256);
    assert_eq!(got["n_episodes"], 3);
    assert_eq!(got["episode_ends"], serde_json::json!([10, 23, 32]));
    assert_eq!(got["last_episode_action_len"], 9);
    let arrays = &got["arrays"];
    assert_eq!(arrays["action"]["dtype"], "float64");
    assert_eq!(arrays["action"]["shape"], serde_json::json!([32, 22]));
    assert_eq!(arrays["state"]["shape"], serde_json::json!([32, 23]));
    assert_eq!(arrays["front"]["dtype"], "uint8");
    assert_eq!(arrays["front"]["shape"], serde_json::json!([32, 64, 64, 3]));
    assert_eq!(arrays["wrist"]["chunks"], serde_json::json!([1, 64, 64, 3]));
    assert_eq!(arrays["action"]["compressor"]["cname"], "lz4");

    let action = &arrays["action"]["values"];
    let state = &arrays["state"]["values"];
    let ts = floats(&arrays["timestamp"]["values"]);
    let mut row = 0;
    for (e, input) in fx.inputs.iter().enumerate() {
        let ep = &input.episode;
        let rotvec = ep.array(Episode::ACTION_ROTVEC).unwrap();
        let st = ep.array(Episode::STATE).unwrap();
        for (f, src) in (fx.starts[e]..ep.len()).enumerate() {
            // float64 end to end: exact.
            assert_eq!(floats(&action[row]), rotvec.row(src), "action e{e} f{f}");
            assert_eq!(floats(&state[row]), &st.row(src)[..23], "state e{e} f{f}");
            assert!((ts[row] - f as f64 / 30.0).abs() < 1e-12);
            for (c, key) in ["front", "wrist"].iter().enumerate() {
                let mean = floats(&arrays[*key]["frame_means"][row]);
                let want = colour(e, c, src);
                for ch in 0..3 {
                    assert!(
                        (mean[ch] - f64::from(want[ch])).abs() <= 3.0,
                        "{key} e{e} f{f} ch{ch}: {} vs {}",
                        mean[ch],
                        want[ch]
                    );
                }
            }
            row += 1;
        }
    }
    assert_eq!(row, 32);

    // Videos beside the store, one per episode and camera, trimmed like the arrays.
    let map: Value =
        serde_json::from_str(&fs_err::read_to_string(out.join("videos/name_map.json")).unwrap())
            .unwrap();
    assert_eq!(map["cameras"], serde_json::json!(["front", "wrist"]));
    assert_eq!(map["episodes"][1], "episode_000001");
    for (e, n) in [10usize, 13, 9].iter().enumerate() {
        for c in 0..2 {
            let v = out.join(format!("videos/{e}/{c}.mp4"));
            let frames = dexjoco_video::decode_rgb(&v).unwrap();
            assert_eq!(frames.len(), *n, "{}", v.display());
            let first = &frames[0][..3];
            let want = colour(e, c, fx.starts[e]);
            for ch in 0..3 {
                assert!(
                    (i32::from(first[ch]) - i32::from(want[ch])).abs() <= 6,
                    "{} first frame",
                    v.display()
                );
            }
        }
    }
}

#[test]
fn frames_only_store_without_videos_and_camera_names_checked() {
    let fx = fixture();
    let out_dir = tempfile::tempdir().unwrap();
    let out = out_dir.path().join("dp");
    let opts = options(false);
    convert(fx.inputs.iter().cloned().map(Ok), &out, &opts, &NoProgress).unwrap();
    assert!(out.join("replay_buffer.zarr/data/front/.zarray").is_file());
    assert!(!out.join("videos").exists());
    assert!(!out.join("norm_stats.json").exists());
    assert!(!out.join(".work").exists());

    // A camera named like a data array is refused, naming the episode.
    let mut opts = options(false);
    opts.selection
        .default
        .cameras
        .insert("state".into(), "front".into());
    let err = convert(
        fx.inputs.iter().cloned().map(Ok),
        &out_dir.path().join("dp2"),
        &opts,
        &NoProgress,
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("episode_000000") && err.contains("'state'"),
        "{err}"
    );
    assert!(!out_dir.path().join("dp2").exists());
}
