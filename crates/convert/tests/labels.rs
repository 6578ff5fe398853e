//! Labelled outcomes and privileged state: replays' records (`replay.json`, as augment
//! writes them) become per-episode metadata that lerobot 0.6.1 loads (LeRobot v3.0
//! `meta/episodes` columns) and Diffusion Policy's `ReplayBuffer` opens (`meta/` arrays,
//! `meta/.zattrs`); flagged replays are left out unless `include_flagged`; the task
//! spec's privileged state columns go under `privileged.state` / `data/privileged_state`.
//! The filtering snippets of docs/commands/convert.md are run as they are written (only the
//! path changed).

mod common;

use std::path::Path;

use common::{Fixture, fixture, selection};
use dexjoco_convert::{ConvertOptions, OutputFormat, VideoCodec, VideoOptions, convert};
use dexjoco_core::{Episode, NoProgress, TaskSet};
use serde_json::{Value, json};

/// A seed above `i64::MAX`: the column must hold it unsigned.
const SEED0: u64 = 18_000_000_000_000_000_001;

/// Episode 0 succeeded (with a dynamics draw), episode 1 is a recording (no record),
/// episode 2 failed its task after an extension and a render check flagged it. All
/// three are made `click_mouse` episodes (the fixture's 31 state columns are its spec's).
fn labelled_fixture() -> Fixture {
    let mut fx = fixture();
    fx.inputs[1].episode.task = "click_mouse".into();
    // The environment state a simulating stage records, as wide as the task's (here: made
    // up, every row and column different).
    let width = dexjoco_core::TaskSpec::builtin("click_mouse")
        .unwrap()
        .environment_state_names()
        .len();
    for (e, input) in fx.inputs.iter_mut().enumerate() {
        let rows: Vec<Vec<f64>> = (0..input.episode.len())
            .map(|f| {
                (0..width)
                    .map(|c| (e * 1000 + f * 10 + c) as f64 * 0.125)
                    .collect()
            })
            .collect();
        input
            .episode
            .insert_rows(Episode::ENVIRONMENT_STATE, &rows)
            .unwrap();
    }
    let sample = |seed: u64, cam: usize, az: f64, table: &str| {
        json!({
            "seed": seed, "camera_index": cam,
            "camera": {"azimuth": az, "elevation": -14.5, "distance": 1.4},
            "table_index": cam + 1, "table": table,
            "headlight_ambient": [0.1, 0.2, 0.3], "headlight_diffuse": [0.4, 0.5, 0.6],
            "lights": [{"pos_offset": [0.01, 0.02], "dir_offset": [0.1, -0.1], "diffuse": [0.3, 0.3, 0.3]}]
        })
    };
    let record = |e: usize, body: Value| {
        let ep = &fx.inputs[e].episode;
        let mut r = json!({
            "name": format!("{}__r00", ep.id), "task": ep.task, "episode": ep.id, "replay": 0,
            "max_state_deviation": 0.0, "deviation_at": null,
            "videos": ["videos/front.mp4", "videos/handcam_rgb.mp4"],
            "source_hash": "sha256:00",
        });
        r.as_object_mut()
            .unwrap()
            .extend(body.as_object().unwrap().clone());
        fs_err::write(
            fx.inputs[e].dir.join("replay.json"),
            serde_json::to_string_pretty(&r).unwrap(),
        )
        .unwrap();
    };
    record(
        0,
        json!({
            "sample": sample(SEED0, 3, 70.0, "table_tex_05"),
            "success": true, "first_success": 5, "steps": 12, "recorded_steps": 12,
            "extended": false, "flags": [],
            "dynamics": [{"kind": "mass_scale", "target": "mouse", "original": 0.1, "value": 0.12}]
        }),
    );
    record(
        2,
        json!({
            "sample": sample(7, 0, -30.0, "table_wood"),
            "success": false, "first_success": null, "steps": 9, "recorded_steps": 7,
            "extended": true,
            "flags": [
                {"check": "frozen_video", "camera": "front", "first_frame": 2, "last_frame": 6,
                 "detail": "video still while the state moved 0.2 m"},
                {"check": "non_finite", "array": "state", "first_frame": 3, "last_frame": 3,
                 "detail": "NaN in column 24"}
            ]
        }),
    );
    fx
}

fn options(format: OutputFormat) -> ConvertOptions {
    ConvertOptions {
        format,
        selection: selection(),
        batch: 2,
        include_failed: true,
        include_flagged: true,
        state_features: Some(dexjoco_convert::StateFeatures {
            tasks: TaskSet::builtin().clone(),
            environment: true,
            privileged: true,
        }),
        ..ConvertOptions::default()
    }
}

/// Writes `code` into `dir` and runs it in the test venv with `args`; its stdout is JSON.
fn run_python(dir: &Path, name: &str, code: &str, args: &[&str]) -> Value {
    let path = dir.join(name);
    fs_err::write(&path, code).unwrap();
    dexjoco_testkit::run_python_json(path.to_str().unwrap(), args)
}

/// The `n`-th ```python block of docs/commands/convert.md's "Filtering on outcomes in
/// Python" section.
fn readme_snippet(n: usize) -> String {
    let page = dexjoco_testkit::workspace_root().join("docs/commands/convert.md");
    let page = fs_err::read_to_string(page).unwrap();
    let section = page
        .split("### Filtering on outcomes in Python")
        .nth(1)
        .expect("docs/commands/convert.md has the section");
    let section = section.split("\n##").next().unwrap();
    section
        .split("```python\n")
        .nth(n + 1)
        .and_then(|b| b.split("```").next())
        .expect("the python block")
        .to_owned()
}

/// The environment state of episode `e` at source frame `src`.
fn environment_row(fx: &Fixture, e: usize, src: usize) -> Vec<f64> {
    let a = fx.inputs[e]
        .episode
        .array(Episode::ENVIRONMENT_STATE)
        .unwrap();
    a.row(src).to_vec()
}

/// Asserts that `items` (one row per kept frame, as the reader returned them) hold `want`'s
/// value for each kept frame `src` of each episode `e`, in order.
fn assert_rows_read_back(fx: &Fixture, items: &Value, want: impl Fn(usize, usize) -> Vec<f32>) {
    let items = items.as_array().unwrap();
    let mut row = 0;
    for (e, input) in fx.inputs.iter().enumerate() {
        for src in fx.starts[e]..input.episode.len() {
            let got: Vec<f32> = items[row]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap() as f32)
                .collect();
            assert_eq!(got, want(e, src), "episode {e} frame {src}");
            row += 1;
        }
    }
}

/// The privileged values of episode `e` frame `f` (source frame `src`): state columns
/// 23..31 of the fixture, as float32.
fn privileged_row(fx: &Fixture, e: usize, src: usize) -> Vec<f32> {
    let st = fx.inputs[e].episode.array(Episode::STATE).unwrap();
    st.row(src)[23..31].iter().map(|v| *v as f32).collect()
}

const PRIVILEGED_NAMES: [&str; 8] = [
    "mouse.pose[0]",
    "mouse.pose[1]",
    "mouse.pose[2]",
    "mouse.pose[3]",
    "mouse.pose[4]",
    "mouse.pose[5]",
    "mouse.pose[6]",
    "dh[0]",
];

#[test]
fn flagged_replays_are_left_out_unless_included() {
    let mut fx = labelled_fixture();
    // A task whose spec lays out another state width: left out with the reason.
    fx.inputs[1].episode.task = "water_plant".into();
    let out_dir = tempfile::tempdir().unwrap();
    let mut opts = options(OutputFormat::LeRobotV3);
    opts.include_flagged = false;
    let s = convert(
        fx.inputs.iter().cloned().map(Ok),
        &out_dir.path().join("v3"),
        &opts,
        &NoProgress,
    )
    .unwrap();
    assert_eq!(s.episodes, 1, "{s:?}");
    let failed: Vec<(&str, &str)> = s
        .failed
        .iter()
        .map(|f| (f.episode.as_str(), f.reason.as_str()))
        .collect();
    assert_eq!(failed.len(), 2, "{failed:?}");
    assert_eq!(failed[0].0, "episode_000001");
    assert!(
        failed[0]
            .1
            .contains("the state has 31 columns, task 'water_plant''s spec lays out 38"),
        "{}",
        failed[0].1
    );
    assert_eq!(failed[1].0, "episode_000002");
    assert!(
        failed[1].1.contains("replay.json")
            && failed[1].1.contains("frozen_video on front, frames 2-6")
            && failed[1].1.contains("non_finite in state, frames 3-3")
            && failed[1].1.contains("--include-flagged"),
        "{}",
        failed[1].1
    );
}

/// The label columns lerobot read back, per episode of [`labelled_fixture`].
fn check_v3_labels(eps: &[Value]) {
    // Episode 0: succeeded, a dynamics draw, the seed above i64::MAX.
    let e0 = &eps[0];
    assert_eq!(e0["outcome/success"], true);
    assert_eq!(e0["outcome/first_success"], 5);
    assert_eq!(e0["outcome/extended"], false);
    assert_eq!(
        (
            e0["outcome/steps"].clone(),
            e0["outcome/recorded_steps"].clone()
        ),
        (json!(12), json!(12))
    );
    assert_eq!(e0["outcome/flagged"], false);
    assert_eq!(e0["outcome/flags"], json!([]));
    assert_eq!(e0["randomization/seed"].as_u64(), Some(SEED0));
    assert_eq!(e0["randomization/camera_index"], 3);
    assert_eq!(e0["randomization/camera_azimuth"], 70.0);
    assert_eq!(e0["randomization/camera_elevation"], -14.5);
    assert_eq!(e0["randomization/camera_distance"], 1.4);
    assert_eq!(e0["randomization/table_index"], 4);
    assert_eq!(e0["randomization/table"], "table_tex_05");
    assert_eq!(
        e0["randomization/headlight_diffuse"],
        json!([0.4, 0.5, 0.6])
    );
    let dynamics: Value =
        serde_json::from_str(e0["randomization/dynamics"].as_str().unwrap()).unwrap();
    assert_eq!(dynamics[0]["value"], 0.12);
    let lights: Value = serde_json::from_str(e0["randomization/lights"].as_str().unwrap()).unwrap();
    assert_eq!(lights[0]["dir_offset"], json!([0.1, -0.1]));
    // Episode 1: a recording: every label null.
    for (k, v) in eps[1].as_object().unwrap() {
        if k.starts_with("outcome/") || k.starts_with("randomization/") {
            assert_eq!(*v, Value::Null, "{k} of the recording");
        }
    }
    // Episode 2: failed after an extension, flagged twice, no dynamics.
    let e2 = &eps[2];
    assert_eq!(e2["outcome/success"], false);
    assert_eq!(e2["outcome/first_success"], Value::Null);
    assert_eq!(e2["outcome/extended"], true);
    assert_eq!(e2["outcome/recorded_steps"], 7);
    assert_eq!(e2["outcome/checked"], true);
    assert_eq!(e2["outcome/flagged"], true);
    assert_eq!(e2["outcome/flags"], json!(["frozen_video", "non_finite"]));
    assert!(
        e2["outcome/flag_details"][0]
            .as_str()
            .unwrap()
            .starts_with("frozen_video on front, frames 2-6")
    );
    assert_eq!(e2["randomization/dynamics"], Value::Null);
    assert_eq!(e2["randomization/camera_azimuth"], -30.0);
}

#[test]
fn lerobot_v3_loads_the_outcomes_and_privileged_state() {
    let fx = labelled_fixture();
    let out_dir = tempfile::tempdir().unwrap();
    let out = out_dir.path().join("v3");
    let s = convert(
        fx.inputs.iter().cloned().map(Ok),
        &out,
        &options(OutputFormat::LeRobotV3),
        &NoProgress,
    )
    .unwrap();
    assert_eq!(
        (s.episodes, s.frames, s.failed.len()),
        (3, 32, 0),
        "{:?}",
        s.failed
    );
    dexjoco_testkit::lerobot_doctor_passes(&out);
    // The same as LeRobot v2.1, for lerobot's own v2.1 -> v3.0 script.
    let v21 = out_dir.path().join("v21");
    let mut opts = options(OutputFormat::LeRobotV21);
    opts.video = VideoOptions {
        codec: VideoCodec::H264,
        reencode: false,
    };
    convert(fx.inputs.iter().cloned().map(Ok), &v21, &opts, &NoProgress).unwrap();
    let readme = readme_snippet(0).replace("datasets/click_mouse", out.to_str().unwrap());
    let got = run_python(
        out_dir.path(),
        "load.py",
        &LEROBOT_SCRIPT.replace("README_SNIPPET", &readme),
        &[out.to_str().unwrap(), v21.to_str().unwrap()],
    );
    let eps = got["episodes"].as_array().unwrap();
    assert_eq!(eps.len(), 3);
    // v2.1 (episodes.jsonl), converted by lerobot's script, carries the same labels.
    // (The seed as a decimal string there: pyarrow takes JSON integers as int64.)
    let mut v21 = got["v21_episodes"].clone();
    for (e, ep) in v21.as_array_mut().unwrap().iter_mut().enumerate() {
        let seed = &mut ep["randomization/seed"];
        assert_eq!(
            *seed,
            json!(eps[e]["randomization/seed"].as_u64().map(|s| s.to_string()))
        );
        *seed = eps[e]["randomization/seed"].clone();
    }
    assert_eq!(v21, got["episodes"]);
    assert_eq!(got["v21_privileged"], got["privileged"]);
    check_v3_labels(eps);

    // The privileged state: its own feature, float32 with names, not a policy input.
    assert_eq!(got["privileged_feature"]["dtype"], "float32");
    assert_eq!(got["privileged_feature"]["names"], json!(PRIVILEGED_NAMES));
    assert_eq!(
        got["policy_inputs"],
        json!([
            "action",
            "observation.environment_state",
            "observation.images.front",
            "observation.images.wrist",
            "observation.state"
        ])
    );
    // The environment state: LeRobot's key, a policy input, float32 with names, per frame.
    let env_names = dexjoco_core::TaskSpec::builtin("click_mouse")
        .unwrap()
        .environment_state_names();
    assert_eq!(got["environment_feature"]["names"], json!(env_names));
    assert_eq!(got["v21_environment"], got["environment"]);
    assert_rows_read_back(&fx, &got["environment"], |e, src| {
        environment_row(&fx, e, src)
            .iter()
            .map(|v| *v as f32)
            .collect()
    });
    assert_eq!(got["stats_count"], json!([32]));
    assert_eq!(got["episode_stats_columns"], got["state_stats_columns"]);
    assert_eq!(got["privileged"].as_array().unwrap().len(), 32);
    assert_rows_read_back(&fx, &got["privileged"], |e, src| {
        privileged_row(&fx, e, src)
    });
    // The README's snippet keeps the episode that succeeded unflagged, and loads it.
    assert_eq!(got["readme_keep"], json!([0]));
    assert_eq!(got["readme_len"], 10);
    assert_eq!(got["recordings"], json!([1]));
}

/// Loads the dataset (and the v2.1 one after lerobot's conversion script), prints their
/// episode labels and the privileged state of every frame (from the data files, without
/// decoding video), and runs the README's snippet.
const LEROBOT_SCRIPT: &str = r#"
import json, os, sys
os.environ["HF_HUB_OFFLINE"] = "1"
os.environ.setdefault("HF_DATASETS_OFFLINE", "1")
from lerobot.datasets.lerobot_dataset import LeRobotDataset
from lerobot.utils.feature_utils import dataset_to_policy_features

root = sys.argv[1]
full = LeRobotDataset("local/labels", root=root, video_backend="pyav")
cols = [k for k in full.meta.episodes.column_names if k.startswith(("outcome/", "randomization/"))]
episodes = [{k: full.meta.episodes[i][k] for k in cols} for i in range(full.meta.total_episodes)]
import pyarrow.parquet as pq
ep_file = pq.read_table(os.path.join(root, "meta/episodes/chunk-000/file-000.parquet"))
README_SNIPPET
readme_keep = keep
from lerobot.scripts.convert_dataset_v21_to_v30 import convert_dataset
convert_dataset("local/v21", root=sys.argv[2], push_to_hub=False)
v21 = LeRobotDataset("local/v21", root=sys.argv[2], video_backend="pyav")
v21_episodes = [{k: v21.meta.episodes[i][k] for k in cols} for i in range(v21.meta.total_episodes)]
recordings = meta.filter_episodes(lambda ep: ep["outcome/success"] is None)
print(json.dumps({
    "episodes": episodes,
    "privileged_feature": full.meta.features["privileged.state"],
    "policy_inputs": sorted(dataset_to_policy_features(full.meta.features)),
    "stats_count": [int(x) for x in full.meta.stats["privileged.state"]["count"]],
    "episode_stats_columns": len([c for c in ep_file.column_names if c.startswith("stats/privileged.state/")]),
    "state_stats_columns": len([c for c in ep_file.column_names if c.startswith("stats/observation.state/")]),
    "privileged": [[float(x) for x in row] for row in full.hf_dataset["privileged.state"]],
    "environment_feature": full.meta.features["observation.environment_state"],
    "environment": [[float(x) for x in row] for row in full.hf_dataset["observation.environment_state"]],
    "v21_environment": [[float(x) for x in row] for row in v21.hf_dataset["observation.environment_state"]],
    "v21_episodes": v21_episodes,
    "v21_privileged": [[float(x) for x in row] for row in v21.hf_dataset["privileged.state"]],
    "readme_keep": readme_keep,
    "recordings": recordings,
    "readme_len": len(ds),
}))
"#;

#[test]
fn diffusion_policy_store_carries_the_outcomes_and_privileged_state() {
    let fx = labelled_fixture();
    let out_dir = tempfile::tempdir().unwrap();
    let out = out_dir.path().join("dp");
    let s = convert(
        fx.inputs.iter().cloned().map(Ok),
        &out,
        &options(OutputFormat::DiffusionPolicy),
        &NoProgress,
    )
    .unwrap();
    assert_eq!((s.episodes, s.frames), (3, 32));
    let zarr = out.join("replay_buffer.zarr");
    let readme = readme_snippet(1).replace(
        "datasets/click_mouse_dp/replay_buffer.zarr",
        zarr.to_str().unwrap(),
    );
    let dp = std::env::var("DEXJOCO_DIFFUSION_POLICY").expect(
        "DEXJOCO_DIFFUSION_POLICY: the folder holding diffusion_policy/common/replay_buffer.py",
    );
    let got = run_python(
        out_dir.path(),
        "load_dp.py",
        &DP_SCRIPT.replace("README_SNIPPET", &readme),
        &[&dp, zarr.to_str().unwrap()],
    );
    assert_eq!(got["n_episodes"], 3);
    let m = &got["meta"];
    assert_eq!(m["success"], json!([true, false, false]));
    assert_eq!(m["first_success"], json!([5, -1, -1]));
    assert_eq!(m["extended"], json!([false, false, true]));
    assert_eq!(m["flagged"], json!([false, false, true]));
    assert_eq!(m["steps"], json!([12, -1, 9]));
    assert_eq!(m["seed"][0].as_u64(), Some(SEED0));
    assert_eq!(m["camera_index"], json!([3, -1, 0]));
    assert_eq!(m["camera_azimuth"], json!([70.0, "nan", -30.0]));
    assert_eq!(m["headlight_ambient"][0], json!([0.1, 0.2, 0.3]));
    assert_eq!(got["dtypes"]["success"], "bool");
    assert_eq!(got["dtypes"]["seed"], "uint64");
    let records = got["records"].as_array().unwrap();
    assert_eq!(
        records[1],
        json!({"episode": "episode_000001", "label": null})
    );
    assert_eq!(records[2]["label"]["flags"][0]["camera"], "front");
    assert_eq!(records[0]["label"]["dynamics"][0]["target"], "mouse");
    assert_eq!(records[0]["label"]["sample"]["table"], "table_tex_05");
    // The README's snippet: successful and unflagged: episode 0; all records read.
    assert_eq!(got["readme_keep"], json!([0]));
    assert_eq!(got["readme_records"], 3);

    assert_eq!(got["privileged_names"], json!(PRIVILEGED_NAMES));
    assert_eq!(got["privileged_dtype"], "float64");
    let rows = got["privileged"].as_array().unwrap();
    assert_eq!(rows.len(), 32);
    let mut row = 0;
    for (e, input) in fx.inputs.iter().enumerate() {
        let st = input.episode.array(Episode::STATE).unwrap();
        for src in fx.starts[e]..input.episode.len() {
            let got: Vec<f64> = rows[row]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect();
            assert_eq!(got, &st.row(src)[23..31], "episode {e} frame {src}"); // float64: exact
            row += 1;
        }
    }
    let env_names = dexjoco_core::TaskSpec::builtin("click_mouse")
        .unwrap()
        .environment_state_names();
    assert_eq!(got["environment_names"], json!(env_names));
    let rows = got["environment"].as_array().unwrap();
    let mut row = 0;
    for (e, input) in fx.inputs.iter().enumerate() {
        for src in fx.starts[e]..input.episode.len() {
            let got: Vec<f64> = serde_json::from_value(rows[row].clone()).unwrap();
            assert_eq!(got, environment_row(&fx, e, src), "episode {e} frame {src}");
            row += 1;
        }
    }
}

/// Opens the store with Diffusion Policy's ReplayBuffer (both backends), prints the label
/// arrays, the records, the privileged state, and runs the README's snippet.
const DP_SCRIPT: &str = r#"
import json, sys
import numpy as np
import zarr
dp_dir, path = sys.argv[1], sys.argv[2]
sys.path.insert(0, dp_dir)
from diffusion_policy.common.replay_buffer import ReplayBuffer

disk = ReplayBuffer.create_from_path(path, mode="r")
mem = ReplayBuffer.copy_from_path(path)
names = ["success", "first_success", "extended", "flagged", "steps", "seed", "camera_index",
         "camera_azimuth", "headlight_ambient"]
def plain(a):
    if a.dtype.kind == "f":
        return [plain(x) if np.ndim(x) else ("nan" if np.isnan(x) else float(x)) for x in a]
    return a.tolist()
for k in names:
    assert np.array_equal(disk.meta[k][:], mem.meta[k], equal_nan=mem.meta[k].dtype.kind == "f"), k
README_SNIPPET
print(json.dumps({
    "n_episodes": int(disk.n_episodes),
    "meta": {k: plain(mem.meta[k]) for k in names},
    "dtypes": {k: str(mem.meta[k].dtype) for k in names},
    "records": zarr.open(path, mode="r")["meta"].attrs["episodes"],
    "privileged": mem["privileged_state"].tolist(),
    "privileged_dtype": str(mem["privileged_state"].dtype),
    "privileged_names": zarr.open(path, mode="r")["data/privileged_state"].attrs["names"],
    "environment": mem["environment_state"].tolist(),
    "environment_names": zarr.open(path, mode="r")["data/environment_state"].attrs["names"],
    "readme_keep": keep,
    "readme_records": len(records),
}))
"#;

/// The fixture with subtask spans in its replay records: episode 0 (12 frames, 2 leading
/// frames trimmed) pushed the mouse on frames 0-4 and clicked on 5-11; episode 2 (9
/// frames) pushed on 0-6 and never clicked (the click starts on 7 and runs to the end).
fn fixture_with_subtasks() -> (Fixture, Vec<Vec<dexjoco_core::SubtaskSpan>>) {
    let fx = labelled_fixture();
    let span = |id: &str, text: &str, start: usize, end: Option<usize>| dexjoco_core::SubtaskSpan {
        id: id.into(),
        text: text.into(),
        start: Some(start),
        end,
    };
    let spans = vec![
        vec![
            span("push_mouse", "move the mouse onto the pad", 0, Some(4)),
            span("click", "click the left mouse button", 5, Some(11)),
        ],
        Vec::new(),
        vec![
            span("push_mouse", "move the mouse onto the pad", 0, Some(6)),
            span("click", "click the left mouse button", 7, None),
        ],
    ];
    for (e, s) in spans.iter().enumerate() {
        let path = fx.inputs[e].dir.join("replay.json");
        let Ok(text) = fs_err::read_to_string(&path) else {
            continue;
        };
        let mut r: Value = serde_json::from_str(&text).unwrap();
        r["subtasks"] = serde_json::to_value(s).unwrap();
        fs_err::write(&path, serde_json::to_string_pretty(&r).unwrap()).unwrap();
    }
    (fx, spans)
}

#[test]
fn each_frames_subtask_reads_back_from_every_format_as_the_labels_say() {
    let (fx, spans) = fixture_with_subtasks();
    let task = fx.inputs[0].episode.task.clone();
    let instruction = (options(OutputFormat::LeRobotV3).selection)
        .instruction(&task, &fx.inputs[0].episode.prompt);
    let dir = tempfile::tempdir().unwrap();
    let roots: Vec<_> = [
        ("v3", OutputFormat::LeRobotV3),
        ("v21", OutputFormat::LeRobotV21),
        ("dp", OutputFormat::DiffusionPolicy),
    ]
    .into_iter()
    .map(|(name, format)| {
        let root = dir.path().join(name);
        let mut opts = options(format);
        opts.selection.prompt_variants = [(
            task.clone(),
            vec!["press it".to_owned(), "click".to_owned()],
        )]
        .into();
        let dirs = fx.inputs.iter().map(|i| i.dir.as_path());
        opts.v3.language_slots = dexjoco_convert::language_slots(dirs, &opts.selection);
        assert_eq!(
            opts.v3.language_slots, 5,
            "2 subtask rows at most, and 3 task_aug rows (the instruction, 2 variants)"
        );
        convert(fx.inputs.iter().cloned().map(Ok), &root, &opts, &NoProgress).unwrap();
        root
    })
    .collect();
    dexjoco_testkit::lerobot_doctor_passes(&roots[0]);
    let got = dexjoco_testkit::run_python_json(
        "lerobot_subtasks.py",
        &[
            roots[0].to_str().unwrap(),
            roots[1].to_str().unwrap(),
            roots[2].to_str().unwrap(),
        ],
    );
    // Expected: at each kept frame, the spans running there (frame numbers of the
    // replay, after the trimmed start); a recording has none.
    let mut want: Vec<Value> = Vec::new();
    for (e, input) in fx.inputs.iter().enumerate() {
        for src in fx.starts[e]..input.episode.len() {
            let running: Vec<&str> = spans[e]
                .iter()
                .filter(|s| s.start.is_some_and(|a| a <= src) && s.end.is_none_or(|b| src <= b))
                .map(|s| s.text.as_str())
                .collect();
            want.push(if running.is_empty() {
                Value::Null
            } else {
                json!(running.join(" and "))
            });
        }
    }
    assert_eq!(want.len(), 32);
    assert_eq!(want[0], json!("move the mouse onto the pad"));
    assert_eq!(
        want[3],
        json!("click the left mouse button"),
        "episode 0's click from its frame 5"
    );
    for format in ["v3", "v21", "dp"] {
        assert_eq!(got[format], json!(want), "{format}");
    }
    // Every episode's prompt variants, the instruction first, whatever its subtask rows.
    let aug = json!([instruction, "press it", "click"]);
    assert_eq!(got["task_aug"], json!([aug, aug, aug]));
}
