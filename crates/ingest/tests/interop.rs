//! Interop in both directions with the real Python readers and writers (zarr-python 2,
//! the Python `mcap` library), values compared bit for bit.

use std::path::{Path, PathBuf};

use dexjoco_core::{Episode, TaskSet, TaskSpec};
use dexjoco_formats::{Status, discover};

fn task_info(id: &str) -> Option<&'static TaskSpec> {
    TaskSpec::builtin(id)
}

fn read_stored_episode(dir: &Path) -> dexjoco_formats::Result<Episode> {
    dexjoco_formats::read_episode(dir, TaskSet::builtin())
}
use dexjoco_formats::EpisodeMeta;
use dexjoco_formats::mcap::{read_episode_mcap, write_episode_mcap};
use dexjoco_ingest::{IngestOptions, Outcome, Store};
use dexjoco_testkit::{run_python, run_python_json};
use serde_json::Value;

fn path_str(p: &Path) -> &str {
    p.to_str().expect("utf-8 temp path")
}

fn values(v: &Value) -> Vec<f64> {
    v["values"]
        .as_array()
        .expect("values")
        .iter()
        .map(|x| x.as_f64().expect("number"))
        .collect()
}

fn assert_bits(name: &str, got: &[f64], want: &[f64]) {
    assert_eq!(got.len(), want.len(), "{name}: lengths");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert_eq!(g.to_bits(), w.to_bits(), "{name}[{i}]: {g} != {w}");
    }
}

fn ingest_all(inputs: &[PathBuf], store: &Path) -> dexjoco_ingest::IngestSummary {
    let mut s = Store::open(store).unwrap();
    let sources = discover(inputs, Some(store)).unwrap();
    s.ingest(
        &sources,
        &IngestOptions::default(),
        &dexjoco_core::NoProgress,
    )
    .unwrap()
}

fn landed_episode(store: &Path, summary: &dexjoco_ingest::IngestSummary, i: usize) -> Episode {
    let r = &summary.sources[i];
    assert_eq!(r.outcome, Outcome::Landed, "{r:?}");
    read_stored_episode(&store.join(&r.path)).unwrap()
}

#[test]
fn raw_folders_written_by_zarr_python_are_ingested_bit_exact() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in");
    // (task, frames, flags): current float64 layout, bimanual, and the older releases'
    // float32 state with the old pick_bucket object order and no action_rotvec.
    let cases: &[(&str, usize, &[&str])] = &[
        ("click_mouse", 40, &[]),
        ("bimanual_assembly", 25, &[]),
        (
            "pick_bucket",
            30,
            &["--float32-state", "--no-rotvec", "--old-pick-bucket-order"],
        ),
        ("bimanual_hanoi", 12, &["--no-rotvec"]),
    ];
    let mut expected = Vec::new();
    let mut dirs = Vec::new();
    for (i, (task, frames, flags)) in cases.iter().enumerate() {
        let dir = input.join(task).join(format!("episode_{i:06}"));
        dirs.push(dir.clone());
        let frames_s = frames.to_string();
        let seed = i.to_string();
        let mut args = vec![path_str(&dir), task, frames_s.as_str(), seed.as_str()];
        args.extend_from_slice(flags);
        expected.push(run_python_json("make_raw_fixture.py", &args));
    }
    let store = tmp.path().join("store");
    let summary = ingest_all(std::slice::from_ref(&input), &store);
    assert_eq!(summary.sources.len(), cases.len());
    for (c, (task, frames, flags)) in cases.iter().enumerate() {
        // Discovery walks folders in name order: find each case's report by its path.
        let i = summary
            .sources
            .iter()
            .position(|s| s.source == dirs[c])
            .unwrap();
        let ep = landed_episode(&store, &summary, i);
        let want = &expected[c];
        assert_eq!(ep.task, *task);
        assert_eq!(ep.len(), *frames);
        assert_bits(
            "action",
            ep.array("action").unwrap().as_slice(),
            &values(&want["action"]),
        );
        assert_bits(
            "timestamp",
            ep.array("timestamp").unwrap().as_slice(),
            &values(&want["timestamp"]),
        );
        let mut state = values(&want["state"]);
        if flags.contains(&"--old-pick-bucket-order") {
            let w = 38;
            for row in state.chunks_exact_mut(w) {
                let food: Vec<f64> = row[23..30].to_vec();
                row.copy_within(30..37, 23);
                row[30..37].copy_from_slice(&food);
            }
            assert!(
                summary.sources[i]
                    .notes
                    .iter()
                    .any(|n| n.contains("older object order"))
            );
        }
        assert_bits("state", ep.array("state").unwrap().as_slice(), &state);
        let rotvec = ep.array("action_rotvec").unwrap().as_slice();
        if flags.contains(&"--no-rotvec") {
            // Computed here; SciPy's values agree to rounding.
            let scipy = values(&want["scipy_action_rotvec"]);
            for (g, w) in rotvec.iter().zip(&scipy) {
                assert!((g - w).abs() < 1e-12, "computed rotvec {g} vs SciPy {w}");
            }
            assert!(
                summary.sources[i]
                    .notes
                    .iter()
                    .any(|n| n.contains("computed"))
            );
        } else {
            assert_bits("action_rotvec", rotvec, &values(&want["action_rotvec"]));
        }
    }
}

#[test]
fn stored_episodes_are_read_by_zarr_python_as_the_recorder_writes_them() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in/water_plant/episode_000000");
    let want = run_python_json(
        "make_raw_fixture.py",
        &[
            path_str(&input),
            "water_plant",
            "50",
            "9",
            "--float32-state",
        ],
    );
    let store = tmp.path().join("store");
    let summary = ingest_all(&[tmp.path().join("in")], &store);
    let ep_dir = store.join(&summary.sources[0].path);
    assert_eq!(
        summary.sources[0].path,
        Path::new("water_plant/episode_000000")
    );
    let got = run_python_json("read_raw_episode.py", &[path_str(&ep_dir)]);

    let files: Vec<&str> = got["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_str().unwrap())
        .collect();
    assert!(
        !files.iter().any(|f| f.ends_with(".zattrs")),
        "no .zattrs: {files:?}"
    );
    for name in ["action", "action_rotvec", "state", "timestamp"] {
        let a = &got["arrays"][format!("data/{name}")];
        assert_eq!(a["dtype"], "float64", "{name}");
        assert_eq!(a["compressor"]["id"], "blosc");
        assert_eq!(a["compressor"]["cname"], "zstd");
        assert_eq!(a["compressor"]["clevel"], 5);
        assert_eq!(a["compressor"]["shuffle"], 2, "bitshuffle");
        assert_eq!(a["zarray"]["chunks"][0], 50, "one chunk per episode");
        assert_eq!(a["zarray"]["fill_value"], 0.0);
    }
    assert_eq!(
        got["arrays"]["data/timestamp"]["shape"],
        serde_json::json!([50])
    );
    assert_eq!(
        got["arrays"]["data/state"]["shape"],
        serde_json::json!([50, 38])
    );
    let ends = &got["arrays"]["meta/episode_ends"];
    assert_eq!(ends["dtype"], "int64");
    assert_eq!(ends["compressor"], Value::Null);
    assert_eq!(ends["zarray"]["chunks"], serde_json::json!([1024]));
    assert_eq!(ends["values"], serde_json::json!([50]));
    // Values: the float32 state was widened exactly; the rest is bit-identical.
    for name in ["action", "action_rotvec", "state", "timestamp"] {
        assert_bits(
            name,
            &values(&got["arrays"][format!("data/{name}")]),
            &values(&want[name]),
        );
    }
}

#[test]
fn mcap_files_written_by_python_are_ingested_bit_exact() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in");
    fs_err::create_dir_all(&input).unwrap();
    let cases: &[(&str, &[&str])] = &[
        ("click_mouse", &[]),
        ("bimanual_photograph", &["--extras"]),
        ("fold_glasses", &["--no-rotvec"]),
    ];
    let mut expected = Vec::new();
    for (i, (task, flags)) in cases.iter().enumerate() {
        let file = input.join(format!("{i}_{task}.mcap"));
        let seed = (100 + i).to_string();
        let mut args = vec![path_str(&file), task, "33", seed.as_str()];
        args.extend_from_slice(flags);
        expected.push(run_python_json("make_mcap_fixture.py", &args));
    }
    let store = tmp.path().join("store");
    let summary = ingest_all(std::slice::from_ref(&input), &store);
    for (i, (task, flags)) in cases.iter().enumerate() {
        let ep = landed_episode(&store, &summary, i);
        assert_eq!(ep.task, *task);
        let want = &expected[i];
        for name in ["action", "state", "timestamp"] {
            assert_bits(
                name,
                ep.array(name).unwrap().as_slice(),
                &values(&want[name]),
            );
        }
        if flags.is_empty() {
            assert_bits(
                "action_rotvec",
                ep.array("action_rotvec").unwrap().as_slice(),
                &values(&want["action_rotvec"]),
            );
        }
        let notes = &summary.sources[i].notes;
        if flags.contains(&"--extras") {
            for topic in [
                "/camera/front/image",
                "/teleop/right/fingertips",
                "/teleop/right/wrist_pose",
            ] {
                assert!(
                    notes.iter().any(|n| n.contains(topic)),
                    "{topic} named in {notes:?}"
                );
            }
        }
    }
    // The metadata record's operator/date reach the reader.
    let bytes = fs_err::read(input.join("0_click_mouse.mcap")).unwrap();
    let t = read_episode_mcap(Path::new("x.mcap"), &bytes, TaskSet::builtin()).unwrap();
    assert_eq!(t.meta.operator.as_deref(), Some("fixture"));
    assert_eq!(
        t.meta.extra.get("rig").map(String::as_str),
        Some("vision-pro")
    );
}

#[test]
fn raw_to_mcap_to_raw_is_bit_exact_and_python_reads_our_mcap() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in");
    let mut expected = Vec::new();
    for (i, task) in ["hammer_nail", "bimanual_microwave_cook"]
        .iter()
        .enumerate()
    {
        let dir = input
            .join(i.to_string())
            .join(format!("{task}_demo_{i}_2026-01-02_03-04-05_000000"));
        expected.push(run_python_json(
            "make_raw_fixture.py",
            &[path_str(&dir), task, "21", "5"],
        ));
    }
    let store = tmp.path().join("store");
    let summary = ingest_all(std::slice::from_ref(&input), &store);
    let mcap_dir = tmp.path().join("mcap");
    for (i, want) in expected.iter().enumerate() {
        let stored = landed_episode(&store, &summary, i);
        let task = task_info(&stored.task).unwrap();
        let file = mcap_dir.join(format!("{i}.mcap"));
        write_episode_mcap(&file, &stored, task, &EpisodeMeta::default()).unwrap();

        // The Python mcap library reads it: schemas, channels, metadata, values.
        let py = run_python_json("read_mcap.py", &[path_str(&file)]);
        assert_eq!(py["metadata"]["dexjoco.episode"]["task"], stored.task);
        assert_eq!(py["metadata"]["dexjoco.episode"]["schema_version"], "1");
        assert_eq!(py["metadata"]["dexjoco.episode"]["episode_id"], stored.id);
        let arms = task.setup.arm_names();
        for arm in arms {
            assert_eq!(
                py["channels"][format!("/{arm}/pose_command")]["schema"],
                "foxglove.PoseInFrame"
            );
            assert_eq!(py["counts"][format!("/{arm}/hand_target")], 21);
        }
        let state: Vec<f64> = py["state"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|r| r.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()))
            .collect();
        assert_bits("python state", &state, &values(&want["state"]));
        let mut action = Vec::new();
        for k in 0..21 {
            for arm in arms {
                action.extend(
                    py["actions"][arm][k]
                        .as_array()
                        .unwrap()
                        .iter()
                        .map(|x| x.as_f64().unwrap()),
                );
            }
        }
        assert_bits("python action", &action, &values(&want["action"]));
    }

    // And back into a store: every array bit-identical to the original raw folder.
    let store2 = tmp.path().join("store2");
    let summary2 = ingest_all(std::slice::from_ref(&mcap_dir), &store2);
    for (i, want) in expected.iter().enumerate() {
        let ep = landed_episode(&store2, &summary2, i);
        for name in ["action", "action_rotvec", "state", "timestamp"] {
            assert_bits(
                name,
                ep.array(name).unwrap().as_slice(),
                &values(&want[name]),
            );
        }
    }
    let m = Store::open(&store2).unwrap();
    assert!(m.manifest().episodes.iter().all(|e| e.status == Status::Ok));
    // A store's replay.zarr was written by zarrs: reading it with zarr-python works too.
    run_python(
        "read_raw_episode.py",
        &[path_str(&store2.join(&summary2.sources[1].path))],
    );
}
