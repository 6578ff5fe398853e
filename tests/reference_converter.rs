//! Converter parity: the DexJoCo reference converter (`dexjoco-dc-single-lerobot` and
//! `dexjoco-dc-single-zarr`, run in place from `../shared/third_party` by
//! `tests/python/reference_converter.py`, with its `rand_full` configs) and
//! `dexjoco-data convert` (LeRobot v3.0 and Diffusion Policy, `--config` the same folder)
//! on the same raw episodes with videos: the hammer_nail sample demonstration, ingested
//! and augmented twice (its first 29 frames are static, so both sides must trim them);
//! in the second replay those frames' actions differ below float32's resolution, static
//! to the reference's LeRobot writer (float32) but not to its Zarr writer (float64).
//! Compared: episodes, lengths, frames (by their pictures too), action and state values,
//! task strings, camera keys, video frame counts and the replay buffer's arrays. The
//! intended differences are listed in docs/reference-parity.md ("Converter").

mod common;

use std::path::{Path, PathBuf};

use common::dexjoco;
use serde_json::Value;

/// The task: its sample demonstration starts with static frames.
const TASK: &str = "hammer_nail";

/// Our augment output camera -> the reference recorder's name, as the reference's
/// `rand_full/selected_data.yaml` asks for them.
const CAMERA_NAMES: [(&str, &str); 2] =
    [("third_person", "random_camera"), ("handcam_rgb", "wrist")];

fn run_ok(cmd: &mut std::process::Command, what: &str) {
    let out = cmd.output().unwrap_or_else(|e| panic!("{what}: {e}"));
    assert!(
        out.status.success(),
        "{what} failed ({}):\n{}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The demonstration ingested and augmented (2 replays, 64 px, a wrist camera too),
/// videos renamed to the reference recorder's camera names; returns the task folder.
fn raw_episodes(work: &Path) -> PathBuf {
    let demo = dexjoco_testkit::workspace_root()
        .join("datasets/demos")
        .join(TASK);
    run_ok(
        dexjoco()
            .arg("ingest")
            .arg(&demo)
            .arg("--work-dir")
            .arg(work)
            .arg("-q"),
        "ingest",
    );
    run_ok(
        dexjoco()
            .args([
                "augment",
                "--replays",
                "2",
                "--size",
                "64",
                "--quality",
                "fast",
            ])
            .args(["--camera", "handcam_rgb", "-q", "--work-dir"])
            .arg(work)
            .arg(work.join("ingest")),
        "augment",
    );
    let dir = work.join("augment").join(TASK);
    for ep in fs_err::read_dir(&dir).unwrap() {
        let videos = ep.unwrap().path().join("videos");
        for (ours, reference) in CAMERA_NAMES {
            fs_err::rename(
                videos.join(format!("{ours}.mp4")),
                videos.join(format!("{reference}.mp4")),
            )
            .unwrap();
        }
    }
    dir
}

/// Makes the static leading action rows of the episode in `dir` differ below float32's
/// resolution (`x += k * 1e-11`, the first moving row unchanged); returns how many rows.
fn nudge_static_rows(dir: &Path) -> usize {
    use dexjoco_core::Episode;
    let spec = dexjoco_core::TaskSpec::builtin(TASK).unwrap();
    let mut ep = dexjoco_formats::raw::read_raw_episode(dir, spec)
        .unwrap()
        .episode;
    let action = &ep.arrays[Episode::ACTION_ROTVEC];
    let rows = (0..action.len() - 1)
        .find(|&i| action.row(i) != action.row(i + 1))
        .unwrap();
    for name in [Episode::ACTION, Episode::ACTION_ROTVEC] {
        let a = ep.arrays.get_mut(name).unwrap();
        for k in 0..rows {
            a.row_mut(k)[0] += (rows - k) as f64 * 1e-11;
        }
    }
    fs_err::remove_dir_all(dir.join("replay.zarr")).unwrap();
    dexjoco_formats::raw::write_replay_zarr(dir, &ep).unwrap();
    rows
}

/// The folder of Diffusion Policy's `replay_buffer.py`.
fn diffusion_policy_dir() -> PathBuf {
    let recorded = dexjoco_testkit::workspace_root().join(".deps/diffusion-policy-path");
    let dir = std::env::var_os("DEXJOCO_DIFFUSION_POLICY").map_or_else(
        || PathBuf::from(fs_err::read_to_string(&recorded).unwrap_or_default().trim()),
        PathBuf::from,
    );
    assert!(
        dir.join("diffusion_policy/common/replay_buffer.py")
            .is_file(),
        "Diffusion Policy's replay_buffer.py is missing (looked at $DEXJOCO_DIFFUSION_POLICY and {}): \
         run `scripts/setup.sh --python`",
        recorded.display()
    );
    dir
}

fn configs() -> PathBuf {
    dexjoco_testkit::upstream_dir().join("converter-configs/rand_full")
}

/// Runs a reference console script on `input` into `out`, its flags from the configs.
fn reference(entry: &str, input: &Path, out: &Path) {
    let code = dexjoco_testkit::reference_code_dir().join("dexjoco-data-converter/src");
    let s = |p: &Path| p.to_string_lossy().into_owned();
    dexjoco_testkit::run_python(
        "reference_converter.py",
        &[
            "run",
            "--code",
            &s(&code),
            "--diffusion-policy",
            &s(&diffusion_policy_dir()),
            "--configs",
            &s(&configs()),
            "--task",
            TASK,
            entry,
            "--input",
            &s(input),
            "--output",
            &s(out),
        ],
    );
}

/// Our conversion of `input` into `out` with the same configs.
fn ours(input: &Path, out: &Path, extra: &[&str]) {
    run_ok(
        dexjoco()
            .arg("convert")
            .arg(input)
            .arg("--config")
            .arg(configs())
            .arg("--out")
            .arg(out)
            .args(extra)
            .arg("-q"),
        "dexjoco-data convert",
    );
}

/// The config's instruction for [`TASK`] (`language_instructions.yaml`: `task: "text"`).
fn instruction() -> String {
    let text = fs_err::read_to_string(configs().join("language_instructions.yaml")).unwrap();
    let line = text
        .lines()
        .find_map(|l| l.strip_prefix(&format!("{TASK}:")))
        .expect("the task's instruction");
    line.trim().trim_matches('"').to_owned()
}

fn thumbs(v: &Value) -> Vec<Vec<f64>> {
    serde_json::from_value(v.clone()).unwrap()
}

/// Mean absolute difference of two thumbnail sequences with `b` shifted by `shift`.
fn mean_diff(a: &[Vec<f64>], b: &[Vec<f64>], shift: i64) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for (i, fa) in a.iter().enumerate() {
        let Some(fb) = usize::try_from(i as i64 + shift)
            .ok()
            .and_then(|j| b.get(j))
        else {
            continue;
        };
        sum += fa.iter().zip(fb).map(|(x, y)| (x - y).abs()).sum::<f64>();
        n += fa.len();
    }
    sum / n as f64
}

/// The same frames in two encodings of one camera: as many, and in step (no shift of up
/// to 3 frames matches better), within what two lossy encodes differ by.
fn same_frames(reference: &Value, ours: &Value, what: &str) -> f64 {
    let (a, b) = (thumbs(reference), thumbs(ours));
    assert_eq!(a.len(), b.len(), "{what}: decoded frames");
    let d0 = mean_diff(&a, &b, 0);
    for shift in [-3i64, -2, -1, 1, 2, 3] {
        let d = mean_diff(&a, &b, shift);
        assert!(
            d0 < d,
            "{what}: frames shifted by {shift} match better ({d} <= {d0})"
        );
    }
    assert!(d0 < 4.0, "{what}: mean grey difference {d0}");
    d0
}

/// The LeRobot datasets: same episodes, frames, values, tasks, cameras, video frames;
/// `lengths`: each episode's frames after the reference's trimming.
fn check_lerobot(r: &Value, o: &Value, lengths: &[usize]) {
    assert_eq!(r["fps"], o["fps"]);
    assert_eq!(r["camera_keys"], o["camera_keys"]);
    assert_eq!(
        r["camera_keys"].as_array().unwrap().len(),
        CAMERA_NAMES.len()
    );
    for key in ["action", "observation.state"] {
        assert_eq!(r["features"][key], o["features"][key], "{key}");
    }
    assert_eq!(r["tasks"], o["tasks"]);
    assert_eq!(r["tasks"], serde_json::json!([instruction()]));
    let (re, oe) = (
        r["episodes"].as_array().unwrap(),
        o["episodes"].as_array().unwrap(),
    );
    assert_eq!(re.len(), lengths.len(), "reference episodes");
    assert_eq!(oe.len(), re.len(), "our episodes");
    for ((a, b), &expected) in re.iter().zip(oe).zip(lengths) {
        let len = a["length"].as_u64().unwrap() as usize;
        assert_eq!(len, expected, "the reference's episode {}", a["index"]);
        for field in [
            "index",
            "length",
            "rows",
            "tasks",
            "frame_tasks",
            "first_last_task",
        ] {
            assert_eq!(a[field], b[field], "episode {}: {field}", a["index"]);
        }
        // Exact: both sides store float32, and the JSON keeps every bit.
        assert!(a["action"] == b["action"], "episode {}: action", a["index"]);
        assert!(a["state"] == b["state"], "episode {}: state", a["index"]);
        for key in r["camera_keys"].as_array().unwrap() {
            let key = key.as_str().unwrap();
            let what = format!("LeRobot episode {} {key}", a["index"]);
            assert_eq!(a["videos"][key].as_array().unwrap().len(), len, "{what}");
            let d = same_frames(&a["videos"][key], &b["videos"][key], &what);
            eprintln!("{what}: {len} frames, mean grey difference {d:.2}");
        }
    }
}

/// The Diffusion Policy outputs: the reference's arrays equal ours (timestamps from each
/// episode's first kept frame on our side); the same videos. `lengths`, `skipped`: each
/// episode's frames after the reference's trimming, and the static frames it drops.
fn check_zarr(r: &Value, o: &Value, lengths: &[usize], skipped: &[usize]) {
    assert_eq!(r["episode_ends"], o["episode_ends"]);
    let ends: Vec<usize> = serde_json::from_value(r["episode_ends"].clone()).unwrap();
    let expected: Vec<usize> = lengths
        .iter()
        .scan(0, |end, n| {
            *end += n;
            Some(*end)
        })
        .collect();
    assert_eq!(ends, expected, "the reference's episode ends");
    let (ra, oa) = (
        r["arrays"].as_object().unwrap(),
        o["arrays"].as_object().unwrap(),
    );
    let ours_only: Vec<&String> = oa.keys().filter(|k| !ra.contains_key(*k)).collect();
    // The camera frames, and each frame's subtask (the replays carry their spans).
    let cameras: Vec<&str> = CAMERA_NAMES.iter().map(|(_, r)| *r).collect();
    let mut extra = cameras.clone();
    extra.push("subtask_index");
    extra.sort_unstable();
    assert_eq!(
        ours_only, extra,
        "our extra arrays are the camera frames and the subtask index"
    );
    for key in ["action", "state"] {
        for field in ["dtype", "shape", "values"] {
            assert!(ra[key][field] == oa[key][field], "{key}: {field}");
        }
    }
    let (rt, ot): (Vec<f64>, Vec<f64>) = (
        serde_json::from_value(ra["timestamp"]["values"].clone()).unwrap(),
        serde_json::from_value(oa["timestamp"]["values"].clone()).unwrap(),
    );
    assert_eq!(rt.len(), ot.len());
    let mut start = 0;
    for (e, &end) in ends.iter().enumerate() {
        // The reference keeps the raw time of the first kept frame; ours starts at 0.
        let first = skipped[e] as f64 / 30.0;
        assert!(
            (rt[start] - first).abs() < 1e-9,
            "episode {e} starts at {}",
            rt[start]
        );
        for k in start..end {
            let rebased = rt[k] - rt[start];
            assert!(
                (ot[k] - rebased).abs() < 1e-9,
                "timestamp {k}: {} vs {rebased}",
                ot[k]
            );
        }
        start = end;
    }
    assert_eq!(r["camera_files"], o["camera_files"]);
    let (rv, ov) = (
        r["videos"].as_array().unwrap(),
        o["videos"].as_array().unwrap(),
    );
    assert_eq!(rv.len(), ends.len());
    for (e, (a, b)) in rv.iter().zip(ov).enumerate() {
        let len = ends[e] - if e == 0 { 0 } else { ends[e - 1] };
        for cam in &cameras {
            let what = format!("Diffusion Policy episode {e} {cam}");
            assert_eq!(a[cam].as_array().unwrap().len(), len, "{what}");
            let d = same_frames(&a[cam], &b[cam], &what);
            eprintln!("{what}: {len} frames, mean grey difference {d:.2}");
        }
    }
}

#[test]
fn the_reference_converter_and_ours_write_the_same_datasets() {
    let tmp = tempfile::tempdir().unwrap();
    let input = raw_episodes(&tmp.path().join("work"));
    let spec = dexjoco_core::TaskSpec::builtin(TASK).unwrap();
    let mut dirs: Vec<PathBuf> = fs_err::read_dir(&input)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    dirs.sort();
    let static_rows = nudge_static_rows(&dirs[1]);
    assert!(
        static_rows > 0,
        "the demonstration starts with static frames"
    );
    let raw_lengths: Vec<usize> = dirs
        .iter()
        .map(|d| {
            dexjoco_formats::raw::read_raw_episode(d, spec)
                .unwrap()
                .episode
                .len()
        })
        .collect();
    let out = |name: &str| tmp.path().join(name);
    reference("dexjoco-dc-single-lerobot", &input, &out("ref-lerobot"));
    reference("dexjoco-dc-single-zarr", &input, &out("ref-zarr"));
    ours(&input, &out("ours-lerobot"), &[]);
    ours(
        &input,
        &out("ours-zarr"),
        &["--format", "diffusion-policy", "--videos"],
    );
    let s = |name: &str| out(name).to_string_lossy().into_owned();
    let d = dexjoco_testkit::run_python_json(
        "reference_converter.py",
        &[
            "describe",
            "--diffusion-policy",
            &diffusion_policy_dir().to_string_lossy(),
            "--lerobot",
            &s("ref-lerobot"),
            "--lerobot",
            &s("ours-lerobot"),
            "--zarr",
            &s("ref-zarr"),
            "--zarr",
            &s("ours-zarr"),
        ],
    );
    // Compared as float32, both episodes start static; as recorded (float64), the
    // nudged one moves from its first frame.
    let trimmed = |skipped: [usize; 2]| -> Vec<usize> {
        raw_lengths
            .iter()
            .zip(skipped)
            .map(|(n, k)| n - k)
            .collect()
    };
    check_lerobot(
        &d[s("ref-lerobot")],
        &d[s("ours-lerobot")],
        &trimmed([static_rows; 2]),
    );
    check_zarr(
        &d[s("ref-zarr")],
        &d[s("ours-zarr")],
        &trimmed([static_rows, 0]),
        &[static_rows, 0],
    );
}
