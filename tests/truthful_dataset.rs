//! A dataset that tells the truth, end to end (issue #27): augment renders two replays of
//! the sample demo with `--depth` (32 px, 12 frames), a blank run injected into the second
//! one's front camera (the render checks' test hook); convert leaves the flagged replay
//! out by default, and with `--include-failed --include-flagged --depth
//! --privileged-state` carries outcomes, flags, randomization draws, depth and the
//! privileged state into LeRobot v3.0 and Diffusion Policy; the real readers read each
//! back: lerobot 0.6.1 (episode columns against each `replay.json`, `privileged.state`
//! against the replayed state, `meta.depth_keys`, every item's depth against lerobot's
//! own quantize/dequantize of the archive, the video's codes against `quantize_depth`) and
//! Diffusion Policy's `ReplayBuffer` (depth bit for bit). LeRobot v2.1 refuses `--depth`;
//! an episode without its archive is left out and named; `stats --dataset` counts the flag.

use std::path::{Path, PathBuf};
use std::process::Output;

mod common;

const CAMERAS: [&str; 2] = ["front", "third_person"];

/// The defect injected: frames 3-5 of the second replay's front camera drawn black.
const DEFECT: &str = "r01:blank:front:3-5";

fn run(args: &[&str]) -> Output {
    common::dexjoco()
        .current_dir(dexjoco_testkit::workspace_root())
        .env("DEXJOCO_LOG", "warn")
        .env(dexjoco_augment::RENDER_DEFECT_ENV, DEFECT)
        .args(args)
        .output()
        .unwrap()
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn convert(input: &Path, out: &Path, format: &str) -> Output {
    run(&[
        "-q",
        "convert",
        input.to_str().unwrap(),
        "--depth",
        "--privileged-state",
        "--include-failed",
        "--include-flagged",
        "--format",
        format,
        "--out",
        out.to_str().unwrap(),
    ])
}

/// The replay folders augment made, in the order convert reads them.
fn replays(aug: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = fs_err::read_dir(aug.join("click_mouse"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.join("replay.json").is_file())
        .collect();
    v.sort();
    v
}

/// Two replays of the sample demo with `--depth` at 32 px, 12 frames, two cameras; their
/// folders in the order convert reads them.
fn augment_with_depth(aug: &Path) -> Vec<PathBuf> {
    let out = run(&[
        "-q",
        "-j",
        "1",
        "augment",
        "datasets/demos/click_mouse/episode_000000",
        "--replays",
        "2",
        "--size",
        "32",
        "--quality",
        "fast",
        "--max-frames",
        "12",
        "--keep-failed",
        "--depth",
        // With the demo's own third_person camera: two cameras.
        "-c",
        "front",
        "--out",
        aug.to_str().unwrap(),
    ]);
    // Cut at 12 frames the replays fail their task (exit code 3); --keep-failed keeps them.
    assert!(
        matches!(out.status.code(), Some(0 | 3)),
        "augment: {}",
        text(&out.stderr)
    );
    let replays = replays(aug);
    assert_eq!(replays.len(), 2);
    replays
}

/// The depth feature as lerobot 0.6.1 describes it.
fn check_info(v3: &Path) {
    let info: serde_json::Value =
        serde_json::from_slice(&fs_err::read(v3.join("meta/info.json")).unwrap()).unwrap();
    let f = &info["features"]["observation.images.front_depth"];
    assert_eq!(f["dtype"], "video");
    assert_eq!(f["shape"], serde_json::json!([32, 32, 1]));
    assert_eq!(f["info"]["is_depth_map"], true);
    assert_eq!(f["info"]["depth_unit"], "m");
    assert_eq!(f["info"]["video.codec"], "hevc");
    assert_eq!(f["info"]["video.pix_fmt"], "gray12le");
    assert_eq!(f["info"]["video.shift"], 3.5);
}

/// lerobot 0.6.1 and Diffusion Policy's `ReplayBuffer` read the depth back.
fn check_readers(v3: &Path, dp: &Path, replays: &[PathBuf]) {
    let mut args = vec![
        v3.to_str().unwrap().to_owned(),
        std::env::var("DEXJOCO_DIFFUSION_POLICY").expect(
            "DEXJOCO_DIFFUSION_POLICY: Diffusion Policy's checkout (scripts/setup.sh --python)",
        ),
        dp.join("replay_buffer.zarr").to_str().unwrap().to_owned(),
    ];
    for cam in CAMERAS {
        let npz: Vec<String> = replays
            .iter()
            .map(|r| {
                r.join(format!("videos/{cam}_depth.npz"))
                    .to_str()
                    .unwrap()
                    .to_owned()
            })
            .collect();
        args.push(format!("{cam}={}", npz.join(",")));
    }
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let got = dexjoco_testkit::run_python_json("depth_check.py", &args);
    check_labels(&got, replays);
    assert_eq!(
        got["depth_keys"],
        serde_json::json!([
            "observation.images.front_depth",
            "observation.images.third_person_depth"
        ])
    );
    assert_eq!(got["len"], 24);
    for cam in CAMERAS {
        let c = &got["cameras"][cam];
        assert_eq!(c["video_frames"], 24, "{cam}: {c}");
        // Our quantizer's codes, through the lossless stream, are lerobot's: numpy's
        // float32 log is not correctly rounded (ours is), so a value within one ulp of a
        // code boundary may land on the neighbouring code on some CPU; none did here.
        assert!(c["code_max_diff"].as_i64().unwrap() <= 1, "{cam}: {c}");
        let (n, codes) = (
            c["code_mismatches"].as_u64().unwrap(),
            c["codes"].as_u64().unwrap(),
        );
        assert!(n * 1000 <= codes, "{cam}: {c}");
        // lerobot returns exactly its dequantization of those codes, in mm...
        assert_eq!(c["item_shape"], serde_json::json!([1, 32, 32]), "{cam}");
        assert_eq!(c["item_dtype"], "float32", "{cam}");
        assert_eq!(c["item_mismatches"], 0, "{cam}: {c}");
        // ... which is the rendered depth within half a code step (and the mm rounding).
        assert_eq!(c["beyond_bound"], 0, "{cam}: {c}");
        let err = c["max_err_mm"].as_f64().unwrap();
        assert!(err > 0.0 && err < 3.0, "{cam}: {err} mm");
        // Statistics in the stored unit (m), returned by lerobot in mm, sampled exactly.
        let min = c["stats"]["min"][0][0][0].as_f64().unwrap();
        let max = c["stats"]["max"][0][0][0].as_f64().unwrap();
        assert!(
            (min - c["source_min_mm"].as_f64().unwrap()).abs() < 1e-6,
            "{c}"
        );
        assert!(
            (max - c["source_max_mm"].as_f64().unwrap()).abs() < 1e-6,
            "{c}"
        );
        assert_eq!(c["stats"]["count"], serde_json::json!([24]));
        let d = &got["dp"][cam];
        assert_eq!(d["dtype"], "float32", "{cam}: {d}");
        assert_eq!(d["shape"], serde_json::json!([24, 32, 32]));
        assert_eq!(d["chunks"], serde_json::json!([1, 32, 32]));
        assert_eq!(d["compressor"], "blosc");
        assert_eq!(d["bitwise_equal"], true, "{cam}");
    }
}

/// Each episode's outcome and randomization columns are its replay record's, and its
/// privileged state is the replayed state's columns after the proprioception, named
/// from the task spec.
fn check_labels(got: &serde_json::Value, replays: &[PathBuf]) {
    let spec = dexjoco_core::TaskSpec::builtin("click_mouse").unwrap();
    let proprio = spec.setup.proprio_dim();
    let layout = spec.state_layout();
    let names: Vec<String> = (proprio..layout.width())
        .map(|c| layout.column_name(c))
        .collect();
    assert_eq!(got["privileged_names"], serde_json::json!(names));
    let labels = got["labels"].as_array().unwrap();
    assert_eq!(labels.len(), replays.len());
    let mut rows = got["privileged"].as_array().unwrap().iter();
    for (e, (l, dir)) in labels.iter().zip(replays).enumerate() {
        let rec: serde_json::Value =
            serde_json::from_slice(&fs_err::read(dir.join("replay.json")).unwrap()).unwrap();
        assert_eq!(l["outcome/success"], rec["success"], "{e}: {l}");
        assert_eq!(l["outcome/extended"], rec["extended"], "{e}: {l}");
        assert_eq!(l["outcome/steps"], rec["steps"], "{e}: {l}");
        let flags: Vec<&str> = rec["flags"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| f["check"].as_str().unwrap())
            .collect();
        assert_eq!(l["outcome/flags"], serde_json::json!(flags), "{e}: {l}");
        assert_eq!(flags, if e == 1 { vec!["blank_frame"] } else { vec![] });
        let sample = &rec["sample"];
        assert_eq!(l["randomization/seed"], sample["seed"], "{e}: {l}");
        assert_eq!(l["randomization/table"], sample["table"], "{e}: {l}");
        assert_eq!(
            l["randomization/camera_azimuth"], sample["camera"]["azimuth"],
            "{e}: {l}"
        );
        let state = dexjoco_formats::raw::read_raw_episode(dir, spec)
            .unwrap()
            .episode;
        let state = state.array("state").unwrap();
        for k in 0..state.len() {
            let want: Vec<f32> = state.row(k)[proprio..].iter().map(|v| *v as f32).collect();
            let row: Vec<f32> = rows
                .next()
                .unwrap()
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap() as f32)
                .collect();
            assert_eq!(row, want, "episode {e} frame {k}");
        }
    }
    assert!(rows.next().is_none());
}

/// Without `--include-flagged` the flagged replay is left out and named (exit code 3);
/// `stats --dataset` counts it in its health section.
fn check_flagged_left_out(aug: &Path, tmp: &Path) {
    let out = run(&[
        "-q",
        "convert",
        aug.to_str().unwrap(),
        "--include-failed",
        "--out",
        tmp.join("default").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(3), "{}", text(&out.stderr));
    let all = format!("{}{}", text(&out.stdout), text(&out.stderr));
    assert!(
        all.contains("blank_frame on front, frames 3-5") && all.contains("--include-flagged"),
        "{all}"
    );
    let out = run(&[
        "stats",
        "--dataset",
        aug.to_str().unwrap(),
        "--out",
        tmp.join("stats").to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let stats: serde_json::Value = serde_json::from_slice(
        &fs_err::read(tmp.join("stats/dataset/dataset_stats.json")).unwrap(),
    )
    .unwrap();
    let o = &stats["health"]["outcomes"][0];
    assert_eq!(
        (&o["replays"], &o["flagged"]),
        (&serde_json::json!(2), &serde_json::json!(1)),
        "{o}"
    );
}

#[test]
fn a_labelled_depth_and_privileged_dataset_reaches_lerobot_and_diffusion_policy() {
    let tmp = tempfile::tempdir().unwrap();
    let aug = tmp.path().join("aug");
    let replays = augment_with_depth(&aug);
    check_flagged_left_out(&aug, tmp.path());
    let v3 = tmp.path().join("v3");
    let out = convert(&aug, &v3, "lerobot-v3");
    assert!(out.status.success(), "convert v3: {}", text(&out.stderr));
    let dp = tmp.path().join("dp");
    let out = convert(&aug, &dp, "diffusion-policy");
    assert!(out.status.success(), "convert dp: {}", text(&out.stderr));
    check_info(&v3);
    dexjoco_testkit::lerobot_doctor_passes(&v3);
    check_readers(&v3, &dp, &replays);

    // LeRobot v2.1 refuses --depth, before writing anything.
    let v21 = tmp.path().join("v21");
    let out = convert(&aug, &v21, "lerobot-v2.1");
    assert!(!out.status.success());
    let err = text(&out.stderr);
    assert!(
        err.contains("--format lerobot-v2.1: --depth is not supported") && err.contains("v3.0"),
        "{err}"
    );
    assert!(!v21.exists());

    // A replay without its archive is left out, naming the file.
    let missing = replays[1].join("videos/front_depth.npz");
    fs_err::remove_file(&missing).unwrap();
    let out = convert(&aug, &tmp.path().join("v3b"), "lerobot-v3");
    assert_eq!(out.status.code(), Some(3), "{}", text(&out.stderr));
    let all = format!("{}{}", text(&out.stdout), text(&out.stderr));
    assert!(
        all.contains(missing.to_str().unwrap()) && all.contains("no depth archive"),
        "{all}"
    );
}
