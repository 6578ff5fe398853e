//! One task-set option for every command that reads tasks: `--tasks-dir`, the same flag
//! with the same help everywhere. A task of one's own (a built-in spec copied under a new
//! id) goes through ingest, stats --dataset, convert (lerobot reads its prompt as the
//! task) and export with it; without it, each command's error names `--tasks-dir`, a flag
//! it has, never `--task`.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

mod common;

const TASK: &str = "my_mouse";
const PROMPT: &str = "Push my own mouse onto its pad.";

/// Every command that reads task specs.
const COMMANDS: [&str; 8] = [
    "ingest", "export", "scripted", "augment", "cameras", "convert", "stats", "render",
];

/// The binary with `args`, run in `dir` (its default work folder lies there).
fn cli_in(dir: &Path, args: &[&str]) -> Command {
    let mut c = common::dexjoco();
    c.current_dir(dir)
        .env("DEXJOCO_LOG", "warn")
        .args(["-q", "-j", "2"])
        .args(args);
    c
}

/// Runs `c`, asserting its exit code; returns stdout and stderr together.
fn run(c: &mut Command, code: i32) -> String {
    let out: Output = c.output().unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(out.status.code(), Some(code), "{c:?}:\n{text}");
    text
}

/// Every `--task...` flag the text names is `--tasks-dir`.
fn names_only_tasks_dir(text: &str) {
    assert!(text.contains("--tasks-dir"), "{text}");
    assert!(
        text.match_indices("--task")
            .all(|(i, _)| text[i..].starts_with("--tasks-dir")),
        "a flag other than --tasks-dir: {text}"
    );
}

/// A folder holding one spec: click_mouse's, under the id [`TASK`] with [`PROMPT`].
fn tasks_dir(root: &Path) -> PathBuf {
    let dir = root.join("tasks");
    fs_err::create_dir_all(&dir).unwrap();
    let spec = fs_err::read_to_string(
        dexjoco_testkit::workspace_root().join("schemas/tasks/click_mouse.toml"),
    )
    .unwrap();
    let prompt = dexjoco_core::TaskSpec::builtin("click_mouse")
        .unwrap()
        .prompt
        .clone();
    let spec = spec
        .replace("id = \"click_mouse\"", &format!("id = \"{TASK}\""))
        .replace(&prompt, PROMPT);
    fs_err::write(dir.join(format!("{TASK}.toml")), spec).unwrap();
    dir
}

/// Two raw episodes of [`TASK`] (spec in `tasks`): `<root>/raw/my_mouse/episode_00000N`,
/// each with a short front video.
fn raw_episodes(root: &Path, tasks: &Path) -> PathBuf {
    let set = dexjoco_core::TaskSet::with_dir(Some(tasks)).unwrap();
    let spec = set.get(TASK).unwrap();
    let input = root.join("raw");
    let frames = 8;
    for i in 0..2 {
        let mut ep = dexjoco_core::synth::episode(spec, frames, i);
        ep.id = format!("episode_{i:06}");
        let dir = input.join(TASK).join(&ep.id);
        dexjoco_formats::raw::write_replay_zarr(&dir, &ep).unwrap();
        fs_err::create_dir_all(dir.join("videos")).unwrap();
        let video = dexjoco_video::VideoSpec {
            width: 32,
            height: 32,
            fps: 30,
            codec: dexjoco_video::Codec::DEXJOCO,
        };
        let mut w =
            dexjoco_video::VideoWriter::create(dir.join("videos/front.mp4"), video).unwrap();
        for k in 0..frames {
            w.write_frame(&vec![(k * 20) as u8; 32 * 32 * 3]).unwrap();
        }
        w.finish().unwrap();
    }
    input
}

#[test]
fn every_command_that_reads_tasks_takes_the_same_tasks_dir() {
    let mut helps = Vec::new();
    for command in COMMANDS {
        let help = run(&mut cli_in(Path::new("."), &[command, "--help"]), 0);
        let at = help
            .find("--tasks-dir <DIR>")
            .unwrap_or_else(|| panic!("{command} has no --tasks-dir:\n{help}"));
        // The help up to the next option, wrapping aside.
        let mut lines = help[at..].lines();
        let first = lines.next().unwrap_or_default();
        let text = std::iter::once(first)
            .chain(lines.take_while(|l| !l.trim().is_empty() && !l.trim_start().starts_with('-')))
            .flat_map(str::split_whitespace)
            .collect::<Vec<_>>()
            .join(" ");
        helps.push((command, text));
    }
    for (command, text) in &helps {
        assert_eq!(text, &helps[0].1, "{command}'s --tasks-dir help differs");
    }
}

#[test]
fn a_task_of_ones_own_goes_through_ingest_stats_convert_and_export() {
    let tmp = tempfile::tempdir().unwrap();
    let cli = |args: &[&str]| cli_in(tmp.path(), args);
    let tasks = tasks_dir(tmp.path());
    let raw = raw_episodes(tmp.path(), &tasks);
    let store = tmp.path().join("store");
    let (tasks, raw, store) = (
        tasks.to_str().unwrap(),
        raw.to_str().unwrap(),
        store.to_str().unwrap(),
    );

    // Without the spec: each command names --tasks-dir.
    let refused = run(
        cli(&["convert", raw, "--out"]).arg(tmp.path().join("no")),
        1,
    );
    names_only_tasks_dir(&refused);
    assert!(
        refused.contains(&format!("unknown task '{TASK}'")),
        "{refused}"
    );
    let out = tmp.path().join("stats-none");
    names_only_tasks_dir(&run(cli(&["stats", "--dataset", raw, "--out"]).arg(out), 1));
    let usage = run(&mut cli(&["cameras", "--task", TASK]), 2);
    names_only_tasks_dir(&usage);

    run(
        &mut cli(&["ingest", raw, "--out", store, "--tasks-dir", tasks]),
        0,
    );
    let manifest = fs_err::read_to_string(Path::new(store).join("manifest.json")).unwrap();
    assert!(
        manifest.contains(&format!("\"task\": \"{TASK}\"")),
        "{manifest}"
    );

    let stats = run(
        cli(&["stats", "--dataset", store, "--tasks-dir", tasks, "--out"])
            .arg(tmp.path().join("stats")),
        0,
    );
    assert!(
        stats.contains(&format!("| {TASK} | {PROMPT} | 2 |")),
        "{stats}"
    );
    // Its state columns are named after its spec.
    let json = tmp.path().join("stats/dataset/dataset_stats.json");
    let json: serde_json::Value = serde_json::from_slice(&fs_err::read(json).unwrap()).unwrap();
    assert_eq!(
        json["tasks"][0]["arrays"]["state"]["columns"][23],
        "mouse.pose[0]"
    );

    let dataset = tmp.path().join("ds");
    run(
        cli(&["convert", store, "--tasks-dir", tasks, "--out"]).arg(&dataset),
        0,
    );
    dexjoco_testkit::lerobot_doctor_passes(&dataset);
    let read = dexjoco_testkit::run_python_json("lerobot_tasks.py", &[dataset.to_str().unwrap()]);
    assert_eq!(read["tasks"], serde_json::json!({"0": PROMPT}));

    let logs = tmp.path().join("mcap");
    run(
        cli(&[
            "export",
            "--to",
            "mcap",
            store,
            "--tasks-dir",
            tasks,
            "--out",
        ])
        .arg(&logs),
        0,
    );
    assert!(logs.join(format!("{TASK}_episode_000000.mcap")).is_file());
}
