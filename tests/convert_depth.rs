//! `convert --depth` end to end on real depth: augment renders two replays of the sample
//! demo with `--depth` (32 px, 12 frames), convert carries the archives into LeRobot
//! v3.0 and Diffusion Policy, and the real readers read them back: lerobot 0.6.1
//! (`meta.depth_keys`, every item's depth against lerobot's own quantize/dequantize of the
//! archive, the video's codes against `quantize_depth`) and Diffusion Policy's
//! `ReplayBuffer` (bit for bit). LeRobot v2.1 refuses `--depth`; an episode without its
//! archive is left out and named.

use std::path::{Path, PathBuf};
use std::process::Output;

mod common;

const CAMERAS: [&str; 2] = ["front", "third_person"];

fn run(args: &[&str]) -> Output {
    common::dexjoco()
        .current_dir(dexjoco_testkit::workspace_root())
        .env("DEXJOCO_LOG", "warn")
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

#[test]
fn depth_reaches_lerobot_and_diffusion_policy_as_rendered() {
    let tmp = tempfile::tempdir().unwrap();
    let aug = tmp.path().join("aug");
    let replays = augment_with_depth(&aug);
    let v3 = tmp.path().join("v3");
    let out = convert(&aug, &v3, "lerobot-v3");
    assert!(out.status.success(), "convert v3: {}", text(&out.stderr));
    let dp = tmp.path().join("dp");
    let out = convert(&aug, &dp, "diffusion-policy");
    assert!(out.status.success(), "convert dp: {}", text(&out.stderr));
    check_info(&v3);
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
