//! `dataset info/filter/split` against lerobot-edit-dataset 0.6.1 on the same inputs: a
//! dataset written by lerobot's own writer (as one from the Hub) and one of ours with
//! its per-episode labels. Both sides are read back with lerobot's reader
//! (tests/python/lerobot_edit_compare.py): the same episodes and frames in the same
//! order, equal columns; ours with bit-exact video frames, exact statistics and every
//! custom column kept; lerobot-doctor reports no FAIL on ours.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{dexjoco, said, succeeds};
use serde_json::Value;

/// Runs a Python script of tests/python with the test venv; its last stdout line as JSON.
fn python_json(script: &str, args: &[&str]) -> Value {
    python_json_env(script, args, &[])
}

/// As [`python_json`], with environment variables `env`.
fn python_json_env(script: &str, args: &[&str], env: &[(&str, &str)]) -> Value {
    let out = Command::new(dexjoco_testkit::python())
        .envs(env.iter().copied())
        .arg(
            dexjoco_testkit::workspace_root()
                .join("tests/python")
                .join(script),
        )
        .args(args)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    let last = text.lines().last().unwrap_or("");
    serde_json::from_str(last).unwrap_or_else(|e| {
        panic!(
            "{script} {args:?} printed no JSON ({e}):\n{text}\n{}",
            String::from_utf8_lossy(&out.stderr)
        )
    })
}

/// Compares an edited dataset with its source (see the script); panics on a difference.
fn compare(source: &Path, edited: &Path, kept: &[usize], flags: &[&str]) -> Value {
    let kept = serde_json::to_string(kept).unwrap();
    let mut args = vec![source.to_str().unwrap(), edited.to_str().unwrap(), &kept];
    args.extend_from_slice(flags);
    let report = python_json("lerobot_edit_compare.py", &args);
    assert_eq!(report["ok"], true, "{}: {report}", edited.display());
    report
}

/// lerobot-edit-dataset (the test venv's) on `root`, writing `new_root`.
fn lerobot_edit(root: &Path, new_root: &Path, operation: &[&str]) {
    let tool = dexjoco_testkit::python().with_file_name("lerobot-edit-dataset");
    let out = Command::new(&tool)
        .env("HF_HUB_OFFLINE", "1")
        .args(["--repo_id", "local/source", "--root"])
        .arg(root)
        .args(["--new_repo_id", "local/edited", "--new_root"])
        .arg(new_root)
        .args(operation)
        .output()
        .unwrap();
    assert!(
        new_root.join("meta/info.json").exists() || new_root.join("train").exists(),
        "lerobot-edit-dataset {operation:?} wrote nothing:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The bytes of every file under `dir`, by relative path.
fn tree(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut files = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in fs_err::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                files.push((
                    p.strip_prefix(dir).unwrap().to_path_buf(),
                    fs_err::read(&p).unwrap(),
                ));
            }
        }
    }
    files.sort();
    files
}

#[test]
fn filter_and_split_match_lerobot_edit_dataset_on_a_dataset_lerobot_wrote() {
    let dir = tempfile::tempdir().unwrap();
    let source = dir.path().join("small");
    let made = python_json("lerobot_small_dataset.py", &[source.to_str().unwrap(), "8"]);
    assert_eq!(made, 8);
    let before = tree(&source);

    // Delete episodes 1, 4, 6: ours and lerobot's.
    let ours = dir.path().join("ours_filtered");
    succeeds(
        dexjoco()
            .args(["-q", "dataset", "filter"])
            .arg(&source)
            .args(["--episodes", "1,4,6", "--drop", "--out"])
            .arg(&ours),
    );
    let theirs = dir.path().join("theirs_filtered");
    lerobot_edit(
        &source,
        &theirs,
        &[
            "--operation.type",
            "delete_episodes",
            "--operation.episode_indices",
            "[1, 4, 6]",
        ],
    );
    let kept = [0, 2, 3, 5, 7];
    let a = compare(&source, &ours, &kept, &["--exact-video", "--columns"]);
    let b = compare(&source, &theirs, &kept, &["--stats-report"]);
    assert_eq!(a["frames"], b["frames"]);
    assert_eq!(
        a["video_mean_error_max"], 0.0,
        "ours cut by stream copy: {a}"
    );
    dexjoco_testkit::lerobot_doctor_passes(&ours);

    // A seeded split, stratified per task; lerobot's split given the same episodes.
    let splits = dir.path().join("ours_split");
    succeeds(
        dexjoco()
            .args(["-q", "dataset", "split"])
            .arg(&source)
            .args(["--splits", "train=0.75,val=0.25", "--seed", "3", "--out"])
            .arg(&splits),
    );
    let record: Value =
        serde_json::from_str(&fs_err::read_to_string(splits.join("split.json")).unwrap()).unwrap();
    let episodes = |name: &str| -> Vec<usize> {
        record["splits"][name]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap() as usize)
            .collect()
    };
    let (train, val) = (episodes("train"), episodes("val"));
    // 3 episodes of one task and 5 of the other: 2 + 4 (0.75 of each, rounded by
    // largest remainder) and 1 + 1.
    assert_eq!((train.len(), val.len()), (6, 2), "{record}");
    let theirs_split = dir.path().join("theirs_split");
    let lists = format!(r#"{{"train": {train:?}, "val": {val:?}}}"#);
    lerobot_edit(
        &source,
        &theirs_split,
        &["--operation.type", "split", "--operation.splits", &lists],
    );
    for (name, kept) in [("train", &train), ("val", &val)] {
        let ours = compare(
            &source,
            &splits.join(name),
            kept,
            &["--exact-video", "--columns"],
        );
        let theirs = compare(&source, &theirs_split.join(name), kept, &["--stats-report"]);
        assert_eq!(ours["frames"], theirs["frames"], "{name}");
        dexjoco_testkit::lerobot_doctor_passes(&splits.join(name));
        let info: Value = serde_json::from_slice(
            &succeeds(
                dexjoco()
                    .args(["dataset", "info", "--json"])
                    .arg(splits.join(name)),
            )
            .stdout,
        )
        .unwrap();
        assert_eq!(info["episodes"], kept.len());
        assert_eq!(info["splits"][name], format!("0:{}", kept.len()));
    }
    restat_matches_lerobots_recompute_stats(dir.path(), &source);
    to_v21_round_trips_through_lerobots_converter(dir.path(), &source, 8);
    hostile_copies_are_refused(dir.path(), &source);
    assert!(before == tree(&source), "the source changed");
}

/// `dataset stats` on a copy of `source` against lerobot's recompute_stats: the same
/// frames; ours exact from every frame, lerobot's combined per episode.
fn restat_matches_lerobots_recompute_stats(dir: &Path, source: &Path) {
    let ours = dir.join("restat");
    dexjoco_formats::fs::copy_tree(source, &ours).unwrap();
    succeeds(dexjoco().args(["-q", "dataset", "stats"]).arg(&ours));
    assert!(
        ours.join("meta/stats.json.bak").exists(),
        "lerobot's own stats were not exact"
    );
    let theirs = dir.join("theirs_restat");
    lerobot_edit(source, &theirs, &["--operation.type", "recompute_stats"]);
    let all: Vec<usize> = (0..8).collect();
    compare(source, &theirs, &all, &["--stats-report"]);
    compare(&ours, &ours, &[], &["--stats-only"]);
}

#[test]
fn our_labels_survive_a_filter_by_outcome_and_reruns_are_byte_identical() {
    let dir = tempfile::tempdir().unwrap();
    let source = common::sample_lerobot_dataset(&dir.path().join("work"), "click_mouse", 2, 32);
    let info: Value = serde_json::from_slice(
        &succeeds(dexjoco().args(["dataset", "info", "--json"]).arg(&source)).stdout,
    )
    .unwrap();
    let n = info["episodes"].as_u64().unwrap() as usize;
    assert!(n >= 3, "{info}");
    let custom: Vec<&str> = info["custom_columns"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_str().unwrap())
        .collect();
    assert!(custom.contains(&"outcome/success"), "{custom:?}");

    // Successful episodes but the second: every custom column kept.
    let out = dir.path().join("filtered");
    let filter = |out: &Path| {
        succeeds(
            dexjoco()
                .args(["-q", "dataset", "filter"])
                .arg(&source)
                .args([
                    "--where",
                    "outcome/success == true",
                    "--episodes",
                    "1",
                    "--drop",
                    "--out",
                ])
                .arg(out),
        )
    };
    filter(&out);
    let kept: Vec<usize> = (0..n).filter(|i| *i != 1).collect();
    compare(&source, &out, &kept, &["--exact-video", "--columns"]);
    dexjoco_testkit::lerobot_doctor_passes(&out);

    // The same command again gives the same bytes.
    let again = dir.path().join("again");
    filter(&again);
    assert!(tree(&out) == tree(&again), "a rerun wrote other bytes");

    one_camera_matches_lerobots_remove_feature(dir.path(), &source, n);
    stats_in_place_equal_converts(dir.path(), &source);
    let v21 = to_v21_round_trips_through_lerobots_converter(dir.path(), &source, n);
    let lines = fs_err::read_to_string(v21.join("meta/episodes.jsonl")).unwrap();
    assert!(lines.contains("\"outcome/success\":true"), "{lines}");
    refusals_name_what_to_do(&source, &out, n);
    trimmed_episodes_keep_our_labels(dir.path(), &source, n);
}

/// `dataset trim --frames` on our dataset: the kept frames as stored, every custom column
/// kept, almost every video frame bit-exact.
fn trimmed_episodes_keep_our_labels(dir: &Path, source: &Path, n: usize) {
    let out = dir.join("trimmed");
    let run = succeeds(
        dexjoco()
            .args(["dataset", "trim"])
            .arg(source)
            .args([
                "--frames",
                "0=3..20",
                "--frames",
                &format!("{}=0..15", n - 1),
            ])
            .arg("--out")
            .arg(&out),
    );
    let kept: Vec<usize> = (0..n).collect();
    let frames = format!(r#"{{"0": [3, 20], "{}": [0, 15]}}"#, n - 1);
    let report = compare(source, &out, &kept, &["--columns", "--frames", &frames]);
    assert_smart_cut(&report, &String::from_utf8_lossy(&run.stderr));
    dexjoco_testkit::lerobot_doctor_passes(&out);

    // Refusals name what to do, and write nothing.
    let refused = |args: &[&str], says: &str| {
        let o = dexjoco()
            .args(["dataset", "trim"])
            .arg(source)
            .args(args)
            .output()
            .unwrap();
        assert!(
            !o.status.success() && said(&o).contains(says),
            "{args:?}: {}",
            said(&o)
        );
    };
    let elsewhere = dir.join("not_written");
    let to = elsewhere.to_str().unwrap();
    refused(
        &["--frames", "0=5..100000", "--out", to],
        "episode 0: frames 5..100000",
    );
    refused(&["--frames", "0=5", "--out", to], "EPISODE=FROM..TO");
    refused(
        &["--idle", "--column", "actoin", "--out", to],
        "no feature 'actoin'",
    );
    refused(&["--out", to], "give --idle, or --frames");
    refused(
        &["--frames", "0=1..5", "--out", out.to_str().unwrap()],
        "--overwrite",
    );
    assert!(!elsewhere.exists());
}

/// Every video frame of a trim's output is bit-exact but those its report says were
/// re-encoded by smart cuts (and those few within the script's error bound).
fn assert_smart_cut(report: &Value, stderr: &str) {
    let reencoded: u64 = stderr
        .split(" frames re-encoded by smart cuts")
        .next()
        .and_then(|s| s.rsplit('(').next())
        .and_then(|s| s.trim().parse().ok())
        .unwrap_or_else(|| panic!("no smart cut count in: {stderr}"));
    assert!(stderr.contains(", 0 re-encoded whole"), "{stderr}");
    let (all, exact) = (
        report["video_frames"].as_u64().unwrap(),
        report["video_frames_exact"].as_u64().unwrap(),
    );
    assert!(
        exact + reencoded >= all,
        "{exact} of {all} frames exact, {reencoded} re-encoded: {report}"
    );
    assert!(
        reencoded * 10 < all,
        "{reencoded} of {all} frames re-encoded"
    );
}

#[test]
fn trim_and_reencode_match_lerobots_tools() {
    let dir = tempfile::tempdir().unwrap();
    // 6 episodes holding still at both ends; 64 px (what SVT-AV1 1.4 encodes at least).
    let source = dir.path().join("idle");
    let made = python_json_env(
        "lerobot_small_dataset.py",
        &[source.to_str().unwrap(), "6", "64"],
        &[("IDLE", "4")],
    );
    assert_eq!(made, 6);
    let before = tree(&source);

    // Idle frames.
    let ours = dir.path().join("ours_trimmed");
    let run = succeeds(
        dexjoco()
            .args(["dataset", "trim"])
            .arg(&source)
            .args(["--idle", "--threshold", "0.01", "--out"])
            .arg(&ours),
    );
    // Episode e: 20 + 7 (e % 4) frames, still for 4 + e % 3 at the start (dropped) and
    // 4 at the end (the first of them moves: it differs from the frame before).
    let ranges: Vec<(usize, usize)> = (0..6).map(|e| (4 + e % 3, 20 + 7 * (e % 4) - 3)).collect();
    let frames: Value = ranges
        .iter()
        .enumerate()
        .map(|(e, r)| (e.to_string(), serde_json::json!([r.0, r.1])))
        .collect::<serde_json::Map<_, _>>()
        .into();
    let all: Vec<usize> = (0..6).collect();
    let report = compare(
        &source,
        &ours,
        &all,
        &["--columns", "--frames", &frames.to_string()],
    );
    assert_smart_cut(&report, &String::from_utf8_lossy(&run.stderr));
    dexjoco_testkit::lerobot_doctor_passes(&ours);
    // The data files hold exactly those frames (lerobot-doctor 0.2's trim, the one
    // other tool, reads only scalar action columns and keeps every frame here).
    let a = python_json("episode_lengths.py", &[ours.to_str().unwrap()]);
    let want: Vec<usize> = ranges.iter().map(|(f, t)| t - f).collect();
    assert_eq!(a["lengths"], serde_json::json!(want));

    reencode_matches_lerobots_reencode_videos(dir.path(), &source);

    // features on a dataset lerobot wrote: the state renamed, its values kept.
    let renamed = dir.path().join("renamed");
    succeeds(
        dexjoco()
            .args(["-q", "dataset", "features"])
            .arg(&source)
            .args(["--rename", "observation.state=observation.proprio", "--out"])
            .arg(&renamed),
    );
    let all: Vec<usize> = (0..6).collect();
    let flags = [
        "--exact-video",
        "--rename",
        "observation.state=observation.proprio",
    ];
    compare(&source, &renamed, &all, &flags);
    assert!(before == tree(&source), "the source changed");
}

/// `dataset reencode` to H.264 against lerobot-edit-dataset's reencode_videos: the same
/// frames within the script's error bound, H.264 in info.json, a keyframe at every
/// episode start in ours; the same bytes with 1 or 2 workers.
fn reencode_matches_lerobots_reencode_videos(dir: &Path, source: &Path) {
    let ours = dir.join("ours_h264");
    let reencode = |out: &Path, jobs: &str| {
        succeeds(
            dexjoco()
                .args(["-q", "-j", jobs, "dataset", "reencode"])
                .arg(source)
                .args(["--codec", "h264", "--crf", "23", "--gop", "2", "--out"])
                .arg(out),
        )
    };
    reencode(&ours, "2");
    let theirs = dir.join("theirs_h264");
    lerobot_edit(
        source,
        &theirs,
        &[
            "--operation.type",
            "reencode_videos",
            "--operation.rgb_encoder.vcodec",
            "h264",
            "--operation.rgb_encoder.crf",
            "23",
            "--operation.rgb_encoder.g",
            "2",
        ],
    );
    let all: Vec<usize> = (0..6).collect();
    let a = compare(source, &ours, &all, &["--columns", "--stats-report"]);
    let b = compare(source, &theirs, &all, &["--stats-report"]);
    assert_eq!(a["frames"], b["frames"]);
    for root in [&ours, &theirs] {
        let info: Value =
            serde_json::from_str(&fs_err::read_to_string(root.join("meta/info.json")).unwrap())
                .unwrap();
        let video = &info["features"]["observation.images.top"]["info"];
        assert_eq!(video["video.codec"], "h264", "{}: {video}", root.display());
    }
    let file = ours.join("videos/observation.images.top/chunk-000/file-000.mp4");
    let keyframes = dexjoco_video::keyframe_indices(&file).unwrap();
    let mut start = 0;
    for e in 0..6 {
        assert!(
            keyframes.contains(&start),
            "episode {e} starts at {start}: {keyframes:?}"
        );
        start += 20 + 7 * (e % 4);
    }
    dexjoco_testkit::lerobot_doctor_passes(&ours);
    let again = dir.join("ours_h264_j1");
    reencode(&again, "1");
    assert!(tree(&ours) == tree(&again), "-j1 and -j2 wrote other bytes");
}

/// A dataset of `episodes` episodes made by lerobot's own writer under `dir/name`
/// (further arguments of tests/python/lerobot_small_dataset.py after EPISODES).
fn lerobot_written(dir: &Path, name: &str, episodes: &str, more: &[&str]) -> PathBuf {
    let root = dir.join(name);
    let mut all = vec![root.to_str().unwrap(), episodes];
    all.extend_from_slice(more);
    python_json("lerobot_small_dataset.py", &all);
    root
}

#[test]
fn merge_matches_lerobots_merge() {
    let dir = tempfile::tempdir().unwrap();
    let a = lerobot_written(dir.path(), "a", "5", &[]);
    let b = lerobot_written(dir.path(), "b", "3", &[]);
    let ours = dir.path().join("ours_merged");
    succeeds(
        dexjoco()
            .args(["-q", "dataset", "merge"])
            .arg(&a)
            .arg(&b)
            .arg("--out")
            .arg(&ours),
    );
    let theirs = dir.path().join("theirs_merged");
    let tool = dexjoco_testkit::python().with_file_name("lerobot-edit-dataset");
    let roots = format!("['{}', '{}']", a.display(), b.display());
    let out = Command::new(&tool)
        .env("HF_HUB_OFFLINE", "1")
        .args(["--new_repo_id", "local/merged", "--new_root"])
        .arg(&theirs)
        .args(["--operation.type", "merge"])
        .args(["--operation.repo_ids", "['local/a', 'local/b']"])
        .args(["--operation.roots", &roots])
        .output()
        .unwrap();
    assert!(
        theirs.join("meta/info.json").exists(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // The same frames, videos and per-episode columns as lerobot's merge; ours with exact
    // statistics, and each source found again in ours.
    let all: Vec<usize> = (0..8).collect();
    compare(&theirs, &ours, &all, &["--exact-video", "--columns"]);
    let flags = |offset| ["--exact-video", "--columns", "--offset", offset];
    compare(&a, &ours, &[0, 1, 2, 3, 4], &flags("0"));
    compare(&b, &ours, &[0, 1, 2], &flags("5"));
    dexjoco_testkit::lerobot_doctor_passes(&ours);
}

#[test]
fn merge_names_what_differs_then_reconciles_camera_names_and_widths() {
    let dir = tempfile::tempdir().unwrap();
    let a = lerobot_written(dir.path(), "a", "5", &[]);
    // Its camera is named otherwise and its action is wider.
    let c = lerobot_written(dir.path(), "c", "3", &["32", "20", "front", "8"]);
    let merged = dir.path().join("reconciled");
    let merge = |extra: &[&str]| {
        dexjoco()
            .args(["dataset", "merge"])
            .arg(&a)
            .arg(&c)
            .arg("--out")
            .arg(&merged)
            .args(extra)
            .output()
            .unwrap()
    };
    let o = merge(&[]);
    assert!(
        !o.status.success() && said(&o).contains("--rename"),
        "{}",
        said(&o)
    );
    let rename = "observation.images.front=observation.images.top";
    let o = merge(&["--rename", rename]);
    assert!(
        !o.status.success() && said(&o).contains("--pad"),
        "{}",
        said(&o)
    );
    assert!(!merged.exists(), "a refused merge wrote something");
    let o = merge(&["--rename", rename, "--pad", "-q"]);
    assert!(o.status.success(), "{}", said(&o));
    let flags = ["--exact-video", "--columns", "--offset"];
    compare(
        &a,
        &merged,
        &[0, 1, 2, 3, 4],
        &[&flags[..], &["0"]].concat(),
    );
    compare(
        &c,
        &merged,
        &[0, 1, 2],
        &[&flags[..], &["5", "--rename", rename]].concat(),
    );
    dexjoco_testkit::lerobot_doctor_passes(&merged);
}

/// `dataset features` removing the wrist camera of `source` (our `n` episodes) and
/// renaming the other, against lerobot's remove_feature.
fn one_camera_matches_lerobots_remove_feature(dir: &Path, source: &Path, n: usize) {
    // A camera removed, the other renamed; lerobot's remove_feature on the same input.
    let (wrist, base) = (
        "observation.images.handcam_rgb",
        "observation.images.third_person",
    );
    let edited = dir.join("one_camera");
    let rename = format!("{base}=observation.images.base");
    succeeds(
        dexjoco()
            .args(["-q", "dataset", "features"])
            .arg(source)
            .args(["--remove", wrist, "--rename", &rename, "--out"])
            .arg(&edited),
    );
    let theirs = dir.join("theirs_one_camera");
    let feature_names = format!("['{wrist}']");
    lerobot_edit(
        source,
        &theirs,
        &[
            "--operation.type",
            "remove_feature",
            "--operation.feature_names",
            &feature_names,
        ],
    );
    let all: Vec<usize> = (0..n).collect();
    let flags = [
        "--exact-video",
        "--columns",
        "--offset",
        "0",
        "--rename",
        &rename,
    ];
    compare(
        &theirs,
        &edited,
        &all,
        &[&flags[..], &["--removed", wrist]].concat(),
    );
    dexjoco_testkit::lerobot_doctor_passes(&edited);
}

/// Refusals of `dataset filter` on `source` (`n` episodes), `out` existing.
fn refusals_name_what_to_do(source: &Path, out: &Path, n: usize) {
    // Refusals name what to do.
    let o = dexjoco()
        .args(["dataset", "filter"])
        .arg(source)
        .args(["--episodes", "0", "--out"])
        .arg(out)
        .output()
        .unwrap();
    assert!(
        !o.status.success() && said(&o).contains("--overwrite"),
        "{}",
        said(&o)
    );
    let o = dexjoco()
        .args(["dataset", "filter"])
        .arg(source)
        .args(["--where", "outcome/sucess == true"])
        .output()
        .unwrap();
    assert!(
        !o.status.success() && said(&o).contains("outcome/success"),
        "an unknown column lists the columns: {}",
        said(&o)
    );
    let o = dexjoco()
        .args(["dataset", "filter"])
        .arg(source)
        .args(["--episodes", &n.to_string()])
        .output()
        .unwrap();
    assert!(
        !o.status.success() && said(&o).contains("out of range"),
        "{}",
        said(&o)
    );
    let o = dexjoco()
        .args(["dataset", "filter"])
        .arg(source)
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(2),
        "no condition is a usage error: {}",
        said(&o)
    );
    let o = dexjoco()
        .args(["dataset", "filter"])
        .arg(source)
        .args(["--episodes", "0", "--out"])
        .arg(source.join("inner"))
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(2),
        "an output inside the source: {}",
        said(&o)
    );
}

/// `dataset stats --norm-stats` on a copy of `source` (converted from `dir/work`'s augment
/// output) writes the norm_stats.json `convert --norm-stats` writes for the same
/// episodes, byte for byte, and exact statistics (the previous file kept); an edit of a
/// dataset that has norm_stats.json writes it again for its own frames.
fn stats_in_place_equal_converts(dir: &Path, source: &Path) {
    let work = dir.join("work");
    let with_norm = dir.join("with_norm");
    succeeds(
        dexjoco()
            .args([
                "-q",
                "--work-dir",
                work.to_str().unwrap(),
                "convert",
                "--norm-stats",
                "--out",
            ])
            .arg(&with_norm),
    );
    let copy = dir.join("restat");
    dexjoco_formats::fs::copy_tree(source, &copy).unwrap();
    let o = succeeds(
        dexjoco()
            .args(["dataset", "stats", "--norm-stats"])
            .arg(&copy),
    );
    assert!(said(&o).contains("stats.json"), "{}", said(&o));
    let norm = |d: &Path| fs_err::read_to_string(d.join("norm_stats.json")).unwrap();
    assert_eq!(norm(&copy), norm(&with_norm));
    let n = python_json(
        "lerobot_edit_compare.py",
        &[
            copy.to_str().unwrap(),
            copy.to_str().unwrap(),
            "[]",
            "--stats-only",
        ],
    );
    assert_eq!(n["ok"], true, "{n}");
    // Filtered: its norm_stats.json is the one `dataset stats` computes for it.
    let filtered = dir.join("with_norm_filtered");
    succeeds(
        dexjoco()
            .args(["-q", "dataset", "filter"])
            .arg(&with_norm)
            .args(["--episodes", "0", "--drop", "--out"])
            .arg(&filtered),
    );
    let carried = norm(&filtered);
    succeeds(
        dexjoco()
            .args(["-q", "dataset", "stats", "--norm-stats"])
            .arg(&filtered),
    );
    assert_eq!(carried, norm(&filtered));
}

/// `dataset to-v21` of `source` (`n` episodes), then lerobot's own v2.1 to v3.0
/// converter on a copy: the same frames, bit-exact videos and per-episode columns as the
/// source. Returns the v2.1 dataset.
fn to_v21_round_trips_through_lerobots_converter(dir: &Path, source: &Path, n: usize) -> PathBuf {
    let v21 = dir.join("v21");
    succeeds(
        dexjoco()
            .args(["-q", "dataset", "to-v21"])
            .arg(source)
            .arg("--out")
            .arg(&v21),
    );
    let info: Value =
        serde_json::from_str(&fs_err::read_to_string(v21.join("meta/info.json")).unwrap()).unwrap();
    assert_eq!(info["codebase_version"], "v2.1");
    assert!(v21.join("data/chunk-000/episode_000000.parquet").is_file());
    let back = dir.join("v21_back_to_v30");
    dexjoco_formats::fs::copy_tree(&v21, &back).unwrap();
    python_json("lerobot_v21_to_v30.py", &[back.to_str().unwrap()]);
    let all: Vec<usize> = (0..n).collect();
    compare(source, &back, &all, &["--exact-video", "--stats-report"]);
    v21
}

/// Copies of `source` with a path template leaving the folder, and with a truncated
/// episode metadata file: each refused with the file named, nothing written.
fn hostile_copies_are_refused(dir: &Path, source: &Path) {
    let escaping = dir.join("escaping");
    dexjoco_formats::fs::copy_tree(source, &escaping).unwrap();
    let info_path = escaping.join("meta/info.json");
    let mut info: Value =
        serde_json::from_str(&fs_err::read_to_string(&info_path).unwrap()).unwrap();
    info["data_path"] = "../../outside/{chunk_index}-{file_index}.parquet".into();
    fs_err::write(&info_path, info.to_string()).unwrap();
    let out = dir.join("escaping_filtered");
    let o = dexjoco()
        .args(["dataset", "filter"])
        .arg(&escaping)
        .args(["--episodes", "0", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        !o.status.success() && said(&o).contains("leaves the dataset folder"),
        "{}",
        said(&o)
    );
    assert!(!out.exists() && !dir.join("outside").exists());

    let truncated = dir.join("truncated");
    dexjoco_formats::fs::copy_tree(source, &truncated).unwrap();
    let episodes = truncated.join("meta/episodes/chunk-000/file-000.parquet");
    let bytes = fs_err::read(&episodes).unwrap();
    fs_err::write(&episodes, &bytes[..bytes.len() / 2]).unwrap();
    let o = dexjoco()
        .args(["dataset", "info"])
        .arg(&truncated)
        .output()
        .unwrap();
    assert!(
        !o.status.success() && said(&o).contains("file-000.parquet"),
        "{}",
        said(&o)
    );
}
