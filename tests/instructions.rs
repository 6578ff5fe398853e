//! An episode's own language instruction reaches the dataset: an MCAP log's prompt is
//! kept by `ingest` (in the raw layout), by `augment` (in each replay, listed in its
//! report), shown by `stats --dataset`, and written by `convert` as the LeRobot task that
//! lerobot reads, unless the convert config names another.

use std::path::Path;
use std::process::{Command, Output};

use dexjoco_core::{TaskSet, TaskSpec};
use dexjoco_formats::mcap::McapLog;
use dexjoco_formats::{EpisodeContainer, EpisodeMeta};

mod common;

const EPISODE: &str = "datasets/demos/click_mouse/episode_000000";
const INSTRUCTION: &str = "Type password two";

/// The binary, run in `dir` (its default work folder lies there).
fn cli(dir: &Path) -> Command {
    let mut c = common::dexjoco();
    c.current_dir(dir)
        .env("DEXJOCO_LOG", "warn")
        .args(["-q", "-j", "2"]);
    c
}

/// Runs `c`, asserting its exit code is one of `codes`.
fn run(c: &mut Command, codes: &[i32]) -> Output {
    let out = c.output().unwrap();
    assert!(
        out.status.code().is_some_and(|s| codes.contains(&s)),
        "{c:?}: {:?}\nstdout: {}\nstderr: {}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// The sample episode as an MCAP log whose prompt is [`INSTRUCTION`].
fn mcap_with_instruction(dir: &Path) {
    let root = dexjoco_testkit::workspace_root();
    let mut ep = dexjoco_formats::read_episode(&root.join(EPISODE), TaskSet::builtin()).unwrap();
    ep.prompt = INSTRUCTION.into();
    let task = TaskSpec::builtin(&ep.task).unwrap();
    McapLog
        .write(&dir.join("demo.mcap"), &ep, task, &EpisodeMeta::default())
        .unwrap();
}

/// The task text of every frame of a LeRobot dataset, as lerobot reads it (after
/// lerobot-doctor's checks pass on it).
fn lerobot_frame_tasks(dataset: &Path) -> Vec<String> {
    dexjoco_testkit::lerobot_doctor_passes(dataset);
    let got = dexjoco_testkit::run_python_json("lerobot_tasks.py", &[dataset.to_str().unwrap()]);
    serde_json::from_value(got["frames"].clone()).unwrap()
}

#[test]
fn an_mcap_prompt_goes_through_ingest_augment_and_convert_to_lerobot() {
    let tmp = tempfile::tempdir().unwrap();
    let (input, store, aug) = (
        tmp.path().join("in"),
        tmp.path().join("store"),
        tmp.path().join("aug"),
    );
    fs_err::create_dir_all(&input).unwrap();
    mcap_with_instruction(&input);

    run(
        cli(tmp.path())
            .arg("ingest")
            .arg(&input)
            .arg("--out")
            .arg(&store),
        &[0],
    );
    let attrs = store.join("click_mouse/episode_000000/replay.zarr/.zattrs");
    let attrs: serde_json::Value = serde_json::from_slice(&fs_err::read(&attrs).unwrap()).unwrap();
    assert_eq!(attrs["instruction"], INSTRUCTION);

    // 12 frames do not finish the task: --keep-failed keeps the replay (exit code 3).
    run(
        cli(tmp.path())
            .arg("augment")
            .arg(&store)
            .args(["--replays", "1", "--size", "32", "--quality", "fast"])
            .args(["--max-frames", "12", "--keep-failed", "--out"])
            .arg(&aug),
        &[0, 3],
    );
    // The replay of the stored episode (named after its store id).
    let replay = fs_err::read_dir(aug.join("click_mouse"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.to_string_lossy().ends_with("__r00"))
        .expect("the replay folder");
    let py = dexjoco_testkit::run_python_json("zarr_root_attrs.py", &[replay.to_str().unwrap()]);
    assert_eq!(py["attrs"]["instruction"], INSTRUCTION);
    let report = fs_err::read_to_string(aug.join("augment_report.md")).unwrap();
    assert!(
        report.contains(&format!("| click_mouse | {INSTRUCTION} |")),
        "{report}"
    );
    let json: serde_json::Value =
        serde_json::from_slice(&fs_err::read(aug.join("augment_report.json")).unwrap()).unwrap();
    assert_eq!(
        json["instructions"],
        serde_json::json!({"click_mouse": [INSTRUCTION]})
    );

    let stats = run(
        cli(tmp.path())
            .args(["stats", "--dataset"])
            .arg(&aug)
            .arg("--out")
            .arg(tmp.path().join("stats")),
        &[0],
    );
    let summary = String::from_utf8_lossy(&stats.stdout);
    assert!(
        summary.contains(&format!("| click_mouse | {INSTRUCTION} | 1 |")),
        "{summary}"
    );

    let dataset = tmp.path().join("ds");
    run(
        cli(tmp.path())
            .arg("convert")
            .arg(&aug)
            .arg("--include-failed")
            .arg("--out")
            .arg(&dataset),
        &[0],
    );
    let frames = lerobot_frame_tasks(&dataset);
    assert!(
        !frames.is_empty() && frames.iter().all(|t| t == INSTRUCTION),
        "{frames:?}"
    );

    // The convert config's instruction comes first.
    let config = tmp.path().join("selection.toml");
    fs_err::write(&config, "[instructions]\nclick_mouse = \"result of 1+1\"\n").unwrap();
    run(
        cli(tmp.path())
            .arg("convert")
            .arg(&aug)
            .arg("--include-failed")
            .arg("--config")
            .arg(&config)
            .arg("--overwrite")
            .arg("--out")
            .arg(&dataset),
        &[0],
    );
    let frames = lerobot_frame_tasks(&dataset);
    assert!(frames.iter().all(|t| t == "result of 1+1"), "{frames:?}");
}
