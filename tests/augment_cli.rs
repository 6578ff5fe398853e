//! The `augment` command end to end: a run killed anywhere (early, midway, late; twice)
//! and run again completes with no duplicate and no partial replay, byte-identical to an
//! uninterrupted run.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod common;

fn cli() -> Command {
    let mut c = common::dexjoco();
    c.env("DEXJOCO_LOG", "warn");
    c
}

fn augment(out: &Path) -> Command {
    let mut c = cli();
    c.current_dir(dexjoco_testkit::workspace_root())
        .args(["-q", "-j", "1", "augment"])
        .arg("datasets/demos/click_mouse/episode_000000")
        .args(["--replays", "6", "--size", "64", "--quality", "fast"])
        .arg("--out")
        .arg(out);
    c
}

/// Finished replay folders (those holding their record).
fn finished(out: &Path) -> Vec<PathBuf> {
    let dir = out.join("click_mouse");
    let mut v: Vec<PathBuf> = fs_err::read_dir(&dir)
        .map(|rd| rd.flatten().map(|e| e.path()).collect())
        .unwrap_or_default();
    v.sort();
    v
}

/// The `stats --dataset` summary of the augment output: its 6 replays, made in one place
/// (so with no warning).
fn assert_stats_summary(stdout: &str) {
    assert!(stdout.contains("6 episodes"), "{stdout}");
    assert!(
        stdout.contains("## Where the replays were made") && !stdout.contains("**Warning:**"),
        "{stdout}"
    );
}

#[test]
fn an_augment_killed_midway_resumes_without_duplicates_or_partial_replays() {
    let tmp = tempfile::tempdir().unwrap();
    let killed = tmp.path().join("killed");
    let mut child = augment(&killed)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while finished(&killed).is_empty() {
        assert!(child.try_wait().unwrap().is_none(), "ended before the kill");
        assert!(
            start.elapsed() < Duration::from_secs(300),
            "no replay written"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    // Its worker processes stop within a frame; one that was renaming a finished replay
    // completes that rename (a whole replay) first.
    std::thread::sleep(Duration::from_secs(1));
    let before = finished(&killed);
    assert!(before.len() < 6, "killed after the end");
    // Only whole replays were renamed into place.
    for d in &before {
        assert!(d.join("replay.json").is_file(), "{}", d.display());
        assert!(d.join("videos/third_person.mp4").is_file());
    }

    let out = augment(&killed).output().unwrap();
    assert!(
        out.status.success(),
        "{:?}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    let resumed = String::from_utf8_lossy(&out.stdout).into_owned();
    let after = finished(&killed);
    assert_eq!(after.len(), 6);
    assert!(!killed.join(".staging").exists());
    let report: serde_json::Value =
        serde_json::from_slice(&fs_err::read(killed.join("augment_report.json")).unwrap()).unwrap();
    assert_eq!(report["replays"].as_array().unwrap().len(), 6);
    // What this run rendered is said on the terminal, not in the report (which is the same
    // bytes whether a run was interrupted or not).
    assert!(report.get("rendered_now").is_none());
    assert!(
        resumed.contains(&format!("({} rendered now", 6 - before.len())),
        "{resumed}"
    );

    // Same bytes as a run that was never interrupted.
    let clean = tmp.path().join("clean");
    let out = augment(&clean).output().unwrap();
    assert!(
        out.status.success(),
        "{:?}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    let a = dexjoco_testkit::file_tree(&killed);
    let b = dexjoco_testkit::file_tree(&clean);
    assert_eq!(a.len(), b.len());
    assert_eq!(a, b);

    // Killed anywhere else: early (before any replay landed; killed twice), or late (5 of
    // 6 in place, the last being written or renamed): the same bytes, no leftovers.
    for point in [0, 5] {
        let dir = tmp.path().join(format!("killed-{point}"));
        let landed = killed_at(&dir, point);
        assert!(landed < 6, "killed at {point} after the end");
        if point == 0 {
            killed_at(&dir, 0);
        }
        let out = augment(&dir).output().unwrap();
        assert!(out.status.success(), "point {point}: {out:?}");
        assert!(
            !dir.join(".staging").exists(),
            "point {point}: staging left"
        );
        assert_eq!(
            dexjoco_testkit::file_tree(&dir),
            b,
            "point {point}: not the bytes of an uninterrupted run"
        );
    }

    // `stats --dataset` on the augment output reads the replays and the report.
    let stats_out = tmp.path().join("stats");
    let out = cli()
        .args(["-q", "stats", "--dataset"])
        .arg(&clean)
        .arg("--out")
        .arg(&stats_out)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{:?}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    assert_stats_summary(&stdout);
    assert!(
        stdout.contains("| click_mouse | 1 | 1 (100 %) | 6 | 6 | 6 | 0 | 100 % | 0e0 |"),
        "{stdout}"
    );
    let replays: serde_json::Value = serde_json::from_slice(
        &fs_err::read(stats_out.join("dataset/replay_success.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(replays["tasks"][0]["replays_successful"], 6);
}

/// Kills (SIGKILL) a run at `point`: as soon as it has staged anything (`0`: early, before
/// any replay landed), or once `point` replays are in place (mid-run, while others are
/// being written and renamed).
fn killed_at(out: &Path, point: usize) -> usize {
    let mut child = augment(out)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let start = Instant::now();
    loop {
        let reached = if point == 0 {
            out.join(".staging").is_dir()
        } else {
            finished(out).len() >= point
        };
        if reached {
            break;
        }
        assert!(child.try_wait().unwrap().is_none(), "ended before the kill");
        assert!(
            start.elapsed() < Duration::from_secs(300),
            "never reached {point}"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    finished(out).len()
}
