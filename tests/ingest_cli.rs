//! The `ingest`, `export` and `bench ingest` commands end to end: exit codes, a run
//! killed midway and re-run, MCAP export read by the Python `mcap` library.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use dexjoco_core::{TaskSet, TaskSpec, synth};
use dexjoco_formats::{Manifest, Status, raw};

mod common;

/// The 11 tasks in the paper's order.
fn tasks() -> Vec<&'static TaskSpec> {
    let mut t: Vec<_> = TaskSet::builtin().iter().collect();
    t.sort_by_key(|s| s.paper_order);
    t
}

fn read_stored_episode(dir: &Path) -> dexjoco_formats::Result<dexjoco_core::Episode> {
    dexjoco_formats::read_episode(dir, TaskSet::builtin())
}

fn cli() -> Command {
    let mut c = common::dexjoco();
    c.env("DEXJOCO_LOG", "warn");
    c
}

fn manifest(store: &Path) -> Manifest {
    serde_json::from_slice(&fs_err::read(store.join("manifest.json")).unwrap()).unwrap()
}

fn write_inputs(root: &Path, n: usize, frames: usize) {
    for i in 0..n {
        let tasks = tasks();
        let task = tasks[i % tasks.len()];
        let ep = synth::episode(task, frames, i as u64);
        raw::write_replay_zarr(&root.join(&task.id).join(format!("episode_{i:06}")), &ep).unwrap();
    }
}

#[test]
fn exit_code_is_3_when_anything_is_rejected_and_0_otherwise() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in");
    write_inputs(&input, 3, 20);
    let store = tmp.path().join("store");
    let out = cli()
        .args(["-q", "ingest"])
        .arg(&input)
        .arg("--store")
        .arg(&store)
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("3 landed"), "{stdout}");

    fs_err::write(input.join("empty.mcap"), b"").unwrap();
    let out = cli()
        .args(["-q", "ingest"])
        .arg(&input)
        .arg("--store")
        .arg(&store)
        .arg("--json")
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(3),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let sources = report["sources"].as_array().unwrap();
    assert_eq!(sources.len(), 4);
    let empty = sources
        .iter()
        .find(|s| s["source"].as_str().unwrap().ends_with("empty.mcap"))
        .unwrap();
    assert_eq!(empty["outcome"], "quarantined");
    assert_eq!(empty["problems"][0]["code"], "empty_file");
    assert_eq!(
        sources
            .iter()
            .filter(|s| s["outcome"] == "already_present")
            .count(),
        3
    );

    // A missing input is an error of the command, not a rejected episode.
    let out = cli()
        .args(["-q", "ingest", "/nonexistent/input", "--store"])
        .arg(&store)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("hint:"));
}

#[test]
fn an_ingest_killed_midway_completes_on_rerun_without_duplicates_or_half_episodes() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in");
    let n = 80;
    write_inputs(&input, n, 600);
    let store = tmp.path().join("store");

    let mut child = cli()
        .args(["-q", "-j", "1", "ingest"])
        .arg(&input)
        .arg("--store")
        .arg(&store)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // Kill it as soon as the first episode has landed (or staging has begun).
    let t0 = Instant::now();
    loop {
        let landed = store.join(&tasks()[0].id).join("episode_000000").exists();
        if landed {
            break;
        }
        assert!(
            child.try_wait().unwrap().is_none(),
            "the run ended before it could be killed"
        );
        assert!(t0.elapsed() < Duration::from_secs(120), "nothing landed");
        std::thread::sleep(Duration::from_millis(2));
    }
    let finished_early = child.try_wait().unwrap().is_some();
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(!finished_early, "the run was not interrupted");

    // What the killed run left: only whole episodes (each folder has its entry file and
    // reads back completely).
    let mut landed_before = 0;
    for task in tasks() {
        let Ok(rd) = fs_err::read_dir(store.join(&task.id)) else {
            continue;
        };
        for e in rd.flatten() {
            let ep = read_stored_episode(&e.path()).expect("a landed folder is a whole episode");
            assert_eq!(ep.len(), 600);
            landed_before += 1;
        }
    }
    assert!(
        landed_before < n,
        "killed before the end ({landed_before} of {n})"
    );

    let out = cli()
        .args(["-q", "ingest"])
        .arg(&input)
        .arg("--store")
        .arg(&store)
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    let m = manifest(&store);
    assert_eq!(m.episodes.len(), n);
    assert!(m.episodes.iter().all(|e| e.status == Status::Ok));
    let mut ids: Vec<&str> = m.episodes.iter().map(|e| e.id.as_str()).collect();
    ids.sort_unstable();
    ids.dedup();
    assert_eq!(ids.len(), n, "no duplicate ids");
    let mut folders = 0;
    for task in tasks() {
        for e in fs_err::read_dir(store.join(&task.id)).unwrap().flatten() {
            read_stored_episode(&e.path()).unwrap();
            folders += 1;
        }
    }
    assert_eq!(folders, n, "one folder per episode");
    assert!(!store.join(".staging").exists());
}

#[test]
fn export_writes_mcap_that_python_reads() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in");
    write_inputs(&input, 2, 15);
    let store = tmp.path().join("store");
    let out = cli()
        .args(["-q", "ingest"])
        .arg(&input)
        .arg("--store")
        .arg(&store)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0));
    let mcap_dir = tmp.path().join("mcap");
    let out = cli()
        .args(["-q", "export", "--to", "mcap"])
        .arg(&store)
        .arg("--out")
        .arg(&mcap_dir)
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let files: Vec<String> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(str::to_owned)
        .collect();
    assert_eq!(files.len(), 2);
    for f in &files {
        let py = dexjoco_testkit::run_python_json("read_mcap.py", &[f]);
        let task = py["metadata"]["dexjoco.episode"]["task"].as_str().unwrap();
        let info = TaskSpec::builtin(task).unwrap();
        assert_eq!(py["counts"]["/state"], 15);
        assert_eq!(py["state"][0].as_array().unwrap().len(), info.state.width);
    }
}

#[test]
fn bench_ingest_reports_episodes_and_megabytes_per_second() {
    let tmp = tempfile::tempdir().unwrap();
    let out = cli()
        .args(["-q", "--work-dir"])
        .arg(tmp.path())
        .args(["bench", "ingest", "--episodes", "4", "--frames", "30"])
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("episodes/s") && stdout.contains("MB/s"),
        "{stdout}"
    );
    assert!(tmp.path().join("bench/ingest.json").is_file());
}
