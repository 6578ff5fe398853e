//! Issue #16 ("Trust"), end to end through the binary: no command loses data, panics,
//! or fails silently in the cases found by trying the pipeline as a new user would.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use dexjoco_core::{Episode, FrameArray, TaskSpec, synth};
use dexjoco_formats::raw;
use dexjoco_testkit::file_tree;

mod common;
use common::{convert_input, dead_pid, lock_of, sleeper};

fn bin() -> Command {
    let mut c = common::dexjoco();
    c.env("DEXJOCO_LOG", "warn");
    c
}

fn run(cwd: &Path, args: &[&str]) -> Output {
    bin()
        .current_dir(cwd)
        .args(args)
        .output()
        .expect("binary runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Asserts the exit code, showing both streams when it differs.
fn code(out: &Output, expected: i32) {
    assert_eq!(
        out.status.code(),
        Some(expected),
        "stdout:\n{}\nstderr:\n{}",
        text(&out.stdout),
        text(&out.stderr)
    );
    assert!(
        !text(&out.stderr).contains("panicked"),
        "{}",
        text(&out.stderr)
    );
}

fn write_episodes(root: &Path, task: &str, n: usize, frames: usize) -> Vec<PathBuf> {
    let spec = TaskSpec::builtin(task).unwrap();
    (0..n)
        .map(|i| {
            let dir = root.join(task).join(format!("episode_{i:06}"));
            raw::write_replay_zarr(&dir, &synth::episode(spec, frames, i as u64 + 1)).unwrap();
            dir
        })
        .collect()
}

#[test]
fn convert_overwrite_never_removes_an_input_the_work_folder_or_a_foreign_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let w = tmp.path().join("w");
    let input = convert_input(&w);
    let before = file_tree(&input);
    let wd = ["--work-dir", s(&w)];

    // The case of the issue: the output folder holds the input.
    let out = run(
        tmp.path(),
        &[
            &wd[..],
            &["-q", "convert", s(&input), "--out", s(&w), "--overwrite"],
        ]
        .concat(),
    );
    code(&out, 2);
    let err = text(&out.stderr);
    assert!(
        err.contains("holds the input") && err.contains("hint:"),
        "{err}"
    );
    assert_eq!(file_tree(&input), before, "the input is untouched");

    // An output inside the input.
    let inside = input.join("click_mouse/ds");
    fs_err::create_dir_all(&inside).unwrap();
    fs_err::write(inside.join("keep.txt"), "x").unwrap();
    let out = run(
        tmp.path(),
        &[
            &wd[..],
            &["-q", "convert", s(&input), "-o", s(&inside), "--overwrite"],
        ]
        .concat(),
    );
    code(&out, 2);
    assert!(text(&out.stderr).contains("lies inside the input"));
    assert!(inside.join("keep.txt").is_file());
    fs_err::remove_dir_all(&inside).unwrap();

    // A folder holding the work folder (the input given elsewhere).
    let other = tmp.path().join("other-input");
    fs_err::rename(&input, &other).unwrap();
    let out = run(
        tmp.path(),
        &[
            &wd[..],
            &[
                "-q",
                "convert",
                s(&other),
                "--out",
                s(tmp.path()),
                "--overwrite",
            ],
        ]
        .concat(),
    );
    code(&out, 2);
    assert!(text(&out.stderr).contains("holds the input") || text(&out.stderr).contains("holds '"));
    assert!(w.is_dir() && other.is_dir());

    // A folder convert did not make.
    let foreign = tmp.path().join("foreign");
    fs_err::create_dir_all(&foreign).unwrap();
    fs_err::write(foreign.join("thesis.tex"), "years of work").unwrap();
    let out = run(
        tmp.path(),
        &[
            &wd[..],
            &[
                "-q",
                "convert",
                s(&other),
                "--out",
                s(&foreign),
                "--overwrite",
            ],
        ]
        .concat(),
    );
    code(&out, 1);
    assert!(text(&out.stderr).contains("not made by convert"));
    assert!(foreign.join("thesis.tex").is_file());

    // A dataset convert made is replaced with --overwrite, and refused without it.
    let ds = tmp.path().join("ds");
    let args = [&wd[..], &["-q", "convert", s(&other), "--out", s(&ds)]].concat();
    code(&run(tmp.path(), &args), 0);
    assert!(ds.join(".dexjoco-convert.json").is_file());
    let again = run(tmp.path(), &args);
    code(&again, 1);
    assert!(text(&again.stderr).contains("--overwrite"));
    code(&run(tmp.path(), &[&args[..], &["--overwrite"]].concat()), 0);
}

#[test]
fn convert_leaves_out_failed_replays_unless_asked_and_ignores_staging() {
    let tmp = tempfile::tempdir().unwrap();
    let input = convert_input(tmp.path());
    // augment --keep-failed: a replay record saying the task failed.
    let failed = input.join("click_mouse/episode_000001");
    fs_err::write(
        failed.join("replay.json"),
        r#"{"success": false, "name": "x"}"#,
    )
    .unwrap();
    fs_err::write(
        input.join("click_mouse/episode_000000/replay.json"),
        r#"{"success": true}"#,
    )
    .unwrap();
    // A killed augment's staged replay (a whole episode folder) must not be read.
    dexjoco_formats::fs::copy_tree(
        &input.join("click_mouse/episode_000000"),
        &input.join(".staging/click_mouse/episode_000000__r00"),
    )
    .unwrap();
    // A killed convert's staging folder beside the output (its pid is gone).
    let leaked = tmp.path().join(format!(".ds.partial-{}", dead_pid()));
    fs_err::create_dir_all(leaked.join("data")).unwrap();

    let out = run(tmp.path(), &["-q", "convert", s(&input), "--out", "ds"]);
    code(&out, 3);
    let stdout = text(&out.stdout);
    assert!(stdout.contains("1 episodes, 6 frames"), "{stdout}");
    assert!(
        stdout.contains("episode_000001")
            && stdout.contains("replay.json")
            && stdout.contains("--include-failed"),
        "{stdout}"
    );
    assert!(!leaked.exists(), "the leaked staging folder is removed");
    let beside: Vec<String> = fs_err::read_dir(tmp.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(beside.is_empty(), "{beside:?}");

    let out = run(
        tmp.path(),
        &[
            "-q",
            "convert",
            s(&input),
            "--out",
            "ds",
            "--overwrite",
            "--include-failed",
        ],
    );
    code(&out, 0);
    assert!(text(&out.stdout).contains("2 episodes, 13 frames"));

    // stats --dataset does not read .staging either.
    let out = run(
        tmp.path(),
        &[
            "-q",
            "--work-dir",
            "w",
            "stats",
            s(&input),
            "--dataset",
            "--json",
        ],
    );
    code(&out, 0);
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["dataset"]["episodes"], 2);
}

#[test]
fn a_second_run_on_the_same_output_refuses_at_once_naming_the_first() {
    let tmp = tempfile::tempdir().unwrap();
    let input = convert_input(tmp.path());
    let mut holder = sleeper();
    let pid = holder.id();
    let host = dexjoco_formats::lock::host_name();

    // convert: the lock beside the output folder.
    lock_of(&tmp.path().join(".ds.lock"), pid);
    let t0 = std::time::Instant::now();
    let out = run(tmp.path(), &["-q", "convert", s(&input), "--out", "ds"]);
    code(&out, 1);
    let err = text(&out.stderr);
    assert!(
        err.contains(&format!("{pid}@{host}")) && err.contains("hint:"),
        "{err}"
    );
    assert!(!tmp.path().join("ds").exists());

    // ingest: the store's lock.
    let recordings = tmp.path().join("recordings");
    write_episodes(&recordings, "click_mouse", 2, 10);
    let store = tmp.path().join("store");
    fs_err::create_dir_all(&store).unwrap();
    lock_of(&store.join(".lock"), pid);
    let out = run(
        tmp.path(),
        &["-q", "ingest", s(&recordings), "--out", s(&store)],
    );
    code(&out, 1);
    assert!(text(&out.stderr).contains(&format!("{pid}@{host}")));
    assert!(t0.elapsed().as_secs() < 30, "refused at once");

    // Once that process is gone, its locks are taken over.
    holder.kill().unwrap();
    holder.wait().unwrap();
    code(
        &run(tmp.path(), &["-q", "convert", s(&input), "--out", "ds"]),
        0,
    );
    code(
        &run(
            tmp.path(),
            &["-q", "ingest", s(&recordings), "--out", s(&store)],
        ),
        0,
    );
    assert!(!store.join(".lock").exists() && !tmp.path().join(".ds.lock").exists());
}

#[test]
fn ingest_overwrite_keeps_a_stored_episode_that_fails_its_recheck() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in");
    let spec = TaskSpec::builtin("click_mouse").unwrap();
    let mut ep = synth::episode(spec, 30, 1);
    // A quaternion 5e-4 off unit norm: inside the default tolerance (1e-3).
    let action = ep.arrays.get_mut(Episode::ACTION).unwrap();
    for k in 0..action.len() {
        for v in &mut action.row_mut(k)[3..7] {
            *v *= 1.0 + 5e-4;
        }
    }
    ep.compute_action_rotvec(spec.setup).unwrap();
    raw::write_replay_zarr(&input.join("click_mouse/episode_000000"), &ep).unwrap();
    let store = tmp.path().join("store");
    code(
        &run(tmp.path(), &["-q", "ingest", s(&input), "--out", s(&store)]),
        0,
    );
    let stored = store.join("click_mouse/episode_000000");
    let before = file_tree(&stored);

    // Redone under a tighter tolerance: it fails, and the stored episode stays.
    let out = run(
        tmp.path(),
        &[
            "-q",
            "ingest",
            s(&input),
            "--store",
            s(&store),
            "--force",
            "--quat-tolerance",
            "1e-4",
            "--json",
        ],
    );
    code(&out, 3);
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["sources"][0]["outcome"], "recheck_failed");
    assert_eq!(
        report["sources"][0]["problems"][0]["code"],
        "not_unit_quaternion"
    );
    assert_eq!(
        file_tree(&stored),
        before,
        "the stored episode is kept whole"
    );
    let manifest: serde_json::Value =
        serde_json::from_slice(&fs_err::read(store.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(manifest["episodes"][0]["status"], "ok");
    assert!(!store.join("quarantine").exists());
}

#[test]
fn export_gives_each_episode_its_own_file_and_never_replaces_one_unasked() {
    let tmp = tempfile::tempdir().unwrap();
    // Two stores with the same folder names.
    for (k, name) in ["a", "b"].into_iter().enumerate() {
        let input = tmp.path().join(format!("in-{name}"));
        write_episodes(&input, "click_mouse", 1, 10 + k);
        let store = tmp.path().join(name);
        code(
            &run(tmp.path(), &["-q", "ingest", s(&input), "--out", s(&store)]),
            0,
        );
    }
    let args = ["-q", "export", "--to", "mcap", "a", "b", "--out", "mcap"];
    let out = run(tmp.path(), &args);
    code(&out, 0);
    let files: Vec<&str> = std::str::from_utf8(&out.stdout).unwrap().lines().collect();
    assert_eq!(
        files,
        [
            "mcap/click_mouse_episode_000000.mcap",
            "mcap/click_mouse_episode_000000-2.mcap"
        ]
    );
    let a = fs_err::read(tmp.path().join(files[0])).unwrap();
    let b = fs_err::read(tmp.path().join(files[1])).unwrap();
    assert_ne!(a, b, "both episodes are kept");

    let again = run(tmp.path(), &args);
    code(&again, 1);
    assert!(text(&again.stderr).contains("--overwrite"));
    code(&run(tmp.path(), &[&args[..], &["--overwrite"]].concat()), 0);
}

#[test]
fn stats_replaces_its_folders_whole_and_leaves_out_an_episode_of_another_width() {
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("raw");
    write_episodes(&data, "click_mouse", 3, 20);
    // An earlier run's file that this run does not write.
    let dir = tmp.path().join("w/stats/dataset");
    fs_err::create_dir_all(&dir).unwrap();
    fs_err::write(dir.join("replay_success.md"), "stale").unwrap();
    let out = run(
        tmp.path(),
        &[
            "-q",
            "--work-dir",
            "w",
            "stats",
            "--dataset",
            s(&data),
            "--json",
        ],
    );
    code(&out, 0);
    assert!(
        !dir.join("replay_success.md").exists(),
        "no stale file remains"
    );
    assert!(dir.join("dataset_stats.json").is_file());
    let beside: Vec<String> = fs_err::read_dir(tmp.path().join("w/stats"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(beside, ["dataset"]);

    // One episode of another state width: left out and named, the rest described.
    let odd = data.join("click_mouse/episode_000001");
    let spec = TaskSpec::builtin("click_mouse").unwrap();
    let mut ep = synth::episode(spec, 20, 9);
    ep.arrays
        .insert(Episode::STATE.into(), FrameArray::zeros(20, 37));
    fs_err::remove_dir_all(&odd).unwrap();
    raw::write_replay_zarr(&odd, &ep).unwrap();
    let out = run(
        tmp.path(),
        &[
            "-q",
            "--work-dir",
            "w",
            "stats",
            "--dataset",
            s(&data),
            "--json",
        ],
    );
    code(&out, 3);
    let err = text(&out.stderr);
    assert!(
        err.contains("episode_000001") && err.contains("field 'state'") && err.contains("37"),
        "{err}"
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["dataset"]["episodes"], 2);
    assert_eq!(json["dataset_left_out"].as_array().unwrap().len(), 1);
}

#[test]
fn output_into_a_closed_pipe_neither_panics_nor_stops_the_work() {
    let tmp = tempfile::tempdir().unwrap();
    let mut child = bin()
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args([
            "--work-dir",
            s(tmp.path()),
            "stats",
            "--language-eval",
            "--success-table",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The reader goes away at once (as `| head -0` does).
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    code(&out, 0);
    assert!(
        tmp.path()
            .join("stats/success-table/success_table.md")
            .is_file(),
        "the work was done"
    );
}

#[test]
fn a_raw_episode_whose_timestamps_stop_early_is_named_not_a_panic() {
    let tmp = tempfile::tempdir().unwrap();
    let dirs = write_episodes(&tmp.path().join("in"), "click_mouse", 1, 12);
    let zarray = dirs[0].join("replay.zarr/data/timestamp/.zarray");
    let mut meta: serde_json::Value =
        serde_json::from_slice(&fs_err::read(&zarray).unwrap()).unwrap();
    meta["shape"][0] = 8.into();
    fs_err::write(&zarray, meta.to_string()).unwrap();
    // augment indexed the timestamps by the action's length (its replays of failed
    // episodes too, kept with --keep-failed) and panicked.
    let out = run(
        tmp.path(),
        &[
            "-q",
            "augment",
            s(&dirs[0]),
            "--replays",
            "1",
            "--max-frames",
            "12",
            "--keep-failed",
            "--size",
            "32",
            "--quality",
            "fast",
            "--out",
            "aug",
        ],
    );
    code(&out, 1);
    let err = text(&out.stderr);
    assert!(
        err.contains("field 'timestamp'")
            && err.contains("frame 8")
            && err.contains("episode_000000"),
        "{err}"
    );
    // ingest names it too.
    let out = run(
        tmp.path(),
        &["-q", "ingest", "in", "--out", "store", "--json"],
    );
    code(&out, 3);
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["sources"][0]["problems"][0]["code"], "wrong_length");
    assert_eq!(report["sources"][0]["problems"][0]["field"], "timestamp");
}

#[test]
fn render_task_all_names_a_scene_that_fails_and_exits_3() {
    let tmp = tempfile::tempdir().unwrap();
    let empty = tmp.path().join("no-scenes");
    fs_err::create_dir_all(&empty).unwrap();
    let out = run(
        tmp.path(),
        &[
            "-q",
            "render",
            "--task",
            "all",
            "--scene-dir",
            s(&empty),
            "--size",
            "16",
            "--quality",
            "fast",
        ],
    );
    code(&out, 3);
    let err = text(&out.stderr);
    assert!(
        err.contains("11 of 22 scene(s) could not be rendered")
            && err.contains("click_mouse (reference scene)"),
        "{err}"
    );
    assert!(
        tmp.path()
            .join("dexjoco-work/render/tasks_contact_sheet.png")
            .is_file()
    );
}

#[test]
fn one_vocabulary_and_one_exit_code_per_error_in_every_command() {
    let tmp = tempfile::tempdir().unwrap();
    let input = convert_input(tmp.path());
    let cwd = tmp.path();
    write_episodes(&cwd.join("recordings"), "pinch_tongs", 2, 10);
    // Inputs are positional; the older flags still work.
    code(&run(cwd, &["-q", "convert", s(&input), "--out", "a"]), 0);
    code(
        &run(cwd, &["-q", "convert", "--input", s(&input), "--out", "b"]),
        0,
    );
    code(
        &run(
            cwd,
            &["-q", "ingest", "recordings", "--store", "s1", "--force"],
        ),
        0,
    );
    code(
        &run(
            cwd,
            &["-q", "ingest", "recordings", "-o", "s2", "--overwrite"],
        ),
        0,
    );
    code(
        &run(cwd, &["-q", "--work-dir", "w", "stats", "s1", "--dataset"]),
        0,
    );
    code(
        &run(
            cwd,
            &[
                "-q",
                "--work-dir",
                "w",
                "stats",
                "--input",
                "s1",
                "--dataset",
            ],
        ),
        0,
    );
    // The same error, the same code.
    for args in [
        &["augment", "--replays", "0"][..],
        &["ingest", "x", "--quat-tolerance=-1"],
        &["ingest", "x", "--timestep-tolerance", "NaN"],
        &["ingest", "x", "--task", "no_such_task"],
        &["render", "--task", "no_such_task"],
        &["cameras", "--task", "no_such_task"],
        &["cameras", "--task", "click_mouse", "--count", "0"],
        &["render", "--size", "0"],
        &["bench", "render", "--size", "0"],
        &["bench", "augment", "--replays", "0"],
        &["convert", s(&input), "--norm-stats-horizon", "0"],
        &["stats", "s1", "--dataset", "--language-eval"],
    ] {
        let out = run(cwd, args);
        assert_eq!(
            out.status.code(),
            Some(2),
            "{args:?}: {}",
            text(&out.stderr)
        );
    }
    for args in [
        &["ingest", "missing/"][..],
        &["convert", "missing/"],
        &["export", "--to", "mcap", "missing/"],
        &["stats", "--dataset", "missing/"],
        &["stats", "--language-eval", "missing.csv"],
        &["render", "missing.xml"],
    ] {
        let out = run(cwd, args);
        assert_eq!(
            out.status.code(),
            Some(1),
            "{args:?}: {}",
            text(&out.stderr)
        );
        assert!(text(&out.stderr).contains("missing"), "{args:?}");
    }
    // -c is a camera everywhere it exists; convert's config is --config only.
    let out = run(cwd, &["convert", s(&input), "-c", "x.toml"]);
    assert_eq!(out.status.code(), Some(2));
    let help = text(&run(cwd, &["--help"]).stdout);
    assert!(
        help.contains("Exit codes") && !help.contains("\n  4 "),
        "{help}"
    );
    for sub in [
        &["render", "--help"][..],
        &["augment", "--help"],
        &["bench", "render", "--help"],
    ] {
        let h = text(&run(cwd, sub).stdout);
        assert!(
            h.contains("--size") && h.contains("--quality") && h.contains("-c, --camera"),
            "{sub:?}:\n{h}"
        );
    }
}
