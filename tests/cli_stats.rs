//! `dexjoco-data stats` end to end: exit codes, stdout, and the files it writes.

use std::path::Path;
use std::process::Output;

mod common;

fn stats(work: &Path, args: &[&str]) -> Output {
    common::dexjoco()
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .arg("--work-dir")
        .arg(work)
        .arg("stats")
        .args(args)
        .output()
        .expect("run dexjoco-data")
}

#[test]
fn language_eval_without_a_path_runs_on_the_example() {
    let work = tempfile::tempdir().unwrap();
    let out = stats(work.path(), &["--language-eval"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stdout.contains("EXAMPLE INPUT") && stdout.contains("Verdict: "),
        "{stdout}"
    );
    assert!(
        stdout.contains("Chi-square test of independence") && stdout.contains("dof 36"),
        "{stdout}"
    );
    assert!(stderr.contains("not results"), "{stderr}");
    let dir = work.path().join("stats/language-eval");
    for f in [
        "heatmap.png",
        "heatmap.svg",
        "language_eval.json",
        "summary.md",
        "precision.csv",
    ] {
        assert!(dir.join(f).is_file(), "{f} not written");
    }
}

#[test]
fn success_table_and_json_output() {
    let work = tempfile::tempdir().unwrap();
    let out_dir = work.path().join("report");
    let out = stats(
        work.path(),
        &[
            "--success-table",
            "datasets/examples/success-table",
            "--out",
            out_dir.to_str().unwrap(),
            "--json",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON on stdout");
    assert_eq!(json["success_table"]["tasks"].as_array().unwrap().len(), 11);
    assert!(json.get("language_eval").is_none());
    for f in [
        "success_table.md",
        "success_table.tex",
        "success_table.csv",
        "success_table.json",
    ] {
        assert!(
            out_dir.join("success-table").join(f).is_file(),
            "{f} not written"
        );
    }
}

#[test]
fn errors_have_exit_codes_and_hints() {
    let work = tempfile::tempdir().unwrap();
    let out = stats(work.path(), &[]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("nothing to do") && stderr.contains("hint:"),
        "{stderr}"
    );

    let out = stats(work.path(), &["--language-eval", "no/such/trials.csv"]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("no/such/trials.csv"), "{stderr}");

    let out = stats(work.path(), &["--language-eval", "--alpha", "2"]);
    assert_eq!(out.status.code(), Some(2));

    let out = stats(work.path(), &["--language-eval", "--js-base", "10"]);
    assert_eq!(
        out.status.code(),
        Some(2),
        "clap refuses bases other than 2 and e"
    );
}

#[test]
fn dataset_statistics_of_raw_episode_folders_leave_out_unreadable_ones() {
    let work = tempfile::tempdir().unwrap();
    let data = work.path().join("raw");
    // Two click_mouse episodes (40 and 60 frames) and one bimanual_hanoi episode (50),
    // written as the DexJoCo recorder writes them.
    for (task, frames, k) in [
        ("click_mouse", 40, 0),
        ("click_mouse", 60, 1),
        ("bimanual_hanoi", 50, 0),
    ] {
        let info = dexjoco_core::TaskSpec::builtin(task).unwrap();
        let ep = dexjoco_core::synth::episode(info, frames, 7 + k as u64);
        let dir = data.join(task).join(format!("episode_{k:06}"));
        dexjoco_formats::raw::write_replay_zarr(&dir, &ep).unwrap();
    }
    // Subtask spans: a scripted plan's record on one, an eval record on the other (the
    // click never ended); the Hanoi episode has none and is not counted.
    let spans = |click_end: serde_json::Value| {
        serde_json::json!({"subtasks": [
            {"id": "push_mouse", "text": "move the mouse onto the pad", "start": 0, "end": 9},
            {"id": "click", "text": "click", "start": 10, "end": click_end},
        ]})
    };
    let ep = |k: usize| data.join(format!("click_mouse/episode_{k:06}"));
    fs_err::write(ep(0).join("plan.json"), spans(39.into()).to_string()).unwrap();
    fs_err::write(
        ep(1).join("episode.json"),
        spans(serde_json::Value::Null).to_string(),
    )
    .unwrap();
    let out = stats(
        work.path(),
        &["--dataset", data.to_str().unwrap(), "--json"],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let d = &json["dataset"];
    assert_eq!(d["episodes"], 3, "{d}");
    assert_eq!(d["frames"], 150);
    let sub = d["subtasks"].as_array().unwrap();
    let row = |i: usize, k: &str| sub[i][k].clone();
    assert_eq!(sub.len(), 2, "click_mouse's two subtasks only: {sub:?}");
    assert_eq!(
        (row(0, "completed"), row(0, "rollouts")),
        (2.into(), 2.into())
    );
    assert_eq!(
        (row(1, "completed"), row(1, "mean_steps")),
        (1.into(), 30.0.into())
    );
    let stats_dir = work.path().join("stats/dataset");
    for f in ["dataset_stats.json", "summary.md", "source_norm_stats.json"] {
        assert!(stats_dir.join(f).is_file(), "{f} missing");
    }

    // A broken episode (an empty replay.zarr) is named and left out; exit code 3.
    fs_err::create_dir_all(data.join("click_mouse/episode_000009/replay.zarr")).unwrap();
    let out = stats(
        work.path(),
        &["--dataset", data.to_str().unwrap(), "--json"],
    );
    assert_eq!(
        out.status.code(),
        Some(3),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stderr).contains("episode_000009"));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["dataset"]["episodes"], 3);
}
