//! `augment` at scale, end to end through the binary: worker processes (output identical
//! whatever -j is; a crashed worker's unit retried, or reported, never left half written),
//! shards into one folder then the finalize (identical to one run), the dry-run plan, and
//! the settings fingerprint (a resume with other settings refused, --overwrite starting
//! clean, episodes of another dataset under the same names refused).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

mod common;

fn cli() -> Command {
    let mut c = common::dexjoco();
    c.current_dir(dexjoco_testkit::workspace_root())
        .env("DEXJOCO_LOG", "warn");
    c
}

const EPISODE: &str = "datasets/demos/click_mouse/episode_000000";

/// `augment` of one sample episode, small and short (12 frames: the task is not done yet,
/// so `--keep-failed` keeps the replays), with `extra` arguments.
fn augment(jobs: usize, out: &Path, extra: &[&str]) -> Command {
    let mut c = cli();
    c.args(["-q", "-j", &jobs.to_string(), "augment", EPISODE])
        .args(["--replays", "4", "--size", "32", "--quality", "fast"])
        .args(["--max-frames", "12", "--keep-failed", "--out"])
        .arg(out)
        .args(extra);
    c
}

/// A finished run's stdout. Exit code 3 is expected: 12 frames do not complete the task.
fn ok(out: &Output) -> String {
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        matches!(out.status.code(), Some(0 | 3)) && !stdout.contains("UNIT FAILED"),
        "{:?}\nstdout: {}\nstderr: {}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn tree(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    dexjoco_testkit::file_tree(dir)
}

#[test]
fn worker_processes_give_identical_bytes_and_a_crashed_worker_is_retried_or_reported() {
    let tmp = tempfile::tempdir().unwrap();
    let one = tmp.path().join("one");
    ok(&augment(1, &one, &[]).output().unwrap());
    let reference = tree(&one);
    assert!(reference.contains_key("click_mouse/episode_000000__r03/replay.json"));
    assert!(reference.contains_key("augment_report.json"));

    // Two worker processes: the same bytes, report and contact sheet included.
    let two = tmp.path().join("two");
    ok(&augment(2, &two, &[]).output().unwrap());
    assert_eq!(tree(&two), reference);

    // A worker that crashes mid-unit on the first attempt: retried, same bytes.
    let crashed = tmp.path().join("crashed");
    let out = augment(2, &crashed, &[])
        .env(dexjoco_augment::FAULT_ENV, "click_mouse/episode_000000@1")
        .output()
        .unwrap();
    ok(&out);
    assert_eq!(tree(&crashed), reference);

    // Crashing on the retry too: the unit is reported failed (exit 3), nothing of it is
    // left half written, and the next run completes it.
    let failed = tmp.path().join("failed");
    let out = augment(1, &failed, &[])
        .env(dexjoco_augment::FAULT_ENV, "click_mouse/episode_000000@2")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(3), "{out:?}");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("UNIT FAILED: click_mouse/episode_000000"),
        "{stdout}"
    );
    assert!(!failed.join(".staging").exists());
    assert!(
        !failed.join("click_mouse").exists(),
        "no replay of the failed unit"
    );
    let report: serde_json::Value =
        serde_json::from_slice(&fs_err::read(failed.join("augment_report.json")).unwrap()).unwrap();
    assert_eq!(report["failed_units"][0]["episode"], "episode_000000");
    assert!(
        report["failed_units"][0]["reason"]
            .as_str()
            .unwrap()
            .contains("worker process ended"),
        "{report}"
    );
    ok(&augment(2, &failed, &[]).output().unwrap());
    assert_eq!(tree(&failed), reference);
}

#[test]
fn a_worker_that_stalls_before_its_first_frame_is_killed_named_and_its_work_done_elsewhere() {
    let tmp = tempfile::tempdir().unwrap();
    let one = tmp.path().join("one");
    ok(&augment(1, &one, &[]).output().unwrap());
    let reference = tree(&one);

    // Worker 0 opens its renderer and hangs, as a driver can on its first render: killed
    // at the deadline and named with its EGL device; worker 1 renders everything.
    let stalled = tmp.path().join("stalled");
    let started = std::time::Instant::now();
    let out = augment(2, &stalled, &["--first-frame-timeout", "3"])
        .env(dexjoco_augment::STALL_ENV, "0")
        .output()
        .unwrap();
    ok(&out);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains(
            "worker process 0 drew no frame within 3 s of opening its renderer (on EGL device 0 ("
        ) && stderr.contains("it was killed"),
        "{stderr}"
    );
    assert!(
        started.elapsed().as_secs() < 60,
        "the run waited for the stalled worker"
    );
    assert_eq!(tree(&stalled), reference);

    // No worker renders: the run fails (exit 1), naming each worker and what to do, and
    // writes no replay.
    let none = tmp.path().join("none");
    let out = augment(2, &none, &["--first-frame-timeout", "3"])
        .env(dexjoco_augment::STALL_ENV, "all")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    for needle in [
        "no worker process could render",
        "worker process 0 drew no frame",
        "worker process 1 drew no frame",
        "mujoco issue 3444",
        "--first-frame-timeout",
    ] {
        assert!(stderr.contains(needle), "missing '{needle}' in:\n{stderr}");
    }
    assert!(!none.join("click_mouse").exists());
    assert!(!none.join(".staging").exists());
}

#[test]
fn shards_run_at_once_into_one_folder_then_the_finalize_equals_one_run() {
    let tmp = tempfile::tempdir().unwrap();
    let single = tmp.path().join("single");
    ok(&augment(1, &single, &[]).output().unwrap());

    let shared = tmp.path().join("shared");
    let children: Vec<_> = ["0/2", "1/2"]
        .iter()
        .map(|s| {
            augment(1, &shared, &["--shard", s])
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    let mut rendered = 0;
    for c in children {
        let stdout = ok(&c.wait_with_output().unwrap());
        let n: usize = stdout
            .split("augment shard ")
            .nth(1)
            .and_then(|s| s.split(": ").nth(1))
            .and_then(|s| s.split(' ').next())
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("{stdout}"));
        // Balanced: 4 equal replays over 2 shards.
        assert_eq!(n, 2, "{stdout}");
        rendered += n;
    }
    assert_eq!(rendered, 4);
    assert!(
        !shared.join("augment_report.json").exists(),
        "shards write no report"
    );
    let stdout = ok(&augment(2, &shared, &[]).output().unwrap());
    assert!(stdout.contains("(0 rendered now"), "{stdout}");
    assert_eq!(tree(&shared), tree(&single));

    // `--shard auto` reads a Slurm array's index and count; a bad shard is a usage error.
    let auto = tmp.path().join("auto");
    ok(&augment(1, &auto, &["--shard", "auto"])
        .env("SLURM_ARRAY_TASK_ID", "1")
        .env("SLURM_ARRAY_TASK_COUNT", "2")
        .output()
        .unwrap());
    let names: Vec<String> = fs_err::read_dir(auto.join("click_mouse"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names.len(), 2, "{names:?}");
    let out = augment(1, &auto, &["--shard", "2/2"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "{out:?}");
}

#[test]
fn dry_run_prints_the_plan_and_an_estimate_and_renders_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let out_dir = tmp.path().join("out");
    let stdout = ok(&augment(2, &out_dir, &["--dry-run"]).output().unwrap());
    assert!(
        stdout.contains("| click_mouse | 1 | 4 | 0 | 48 |"),
        "{stdout}"
    );
    assert!(stdout.contains("1 worker process:"), "{stdout}");
    assert!(stdout.contains("4 nodes like this one:"), "{stdout}");
    assert!(!out_dir.join("click_mouse").exists());
    // After a real run, everything is done; another --size would be refused.
    ok(&augment(2, &out_dir, &[]).output().unwrap());
    let stdout = ok(&augment(2, &out_dir, &["--dry-run"]).output().unwrap());
    assert!(
        stdout.contains("| click_mouse | 1 | 4 | 4 | 0 |"),
        "{stdout}"
    );
    let mut other = augment(2, &out_dir, &["--dry-run"]);
    other.args(["--size", "48"]);
    let stdout = ok(&other.output().unwrap());
    assert!(stdout.contains("width: 48 (was 32)"), "{stdout}");
}

/// A copy of the sample episode under the same name with one action value changed.
fn changed_copy(root: &Path) -> PathBuf {
    let tasks = dexjoco_core::TaskSet::builtin();
    let mut ep =
        dexjoco_formats::read_episode(&dexjoco_testkit::workspace_root().join(EPISODE), tasks)
            .unwrap();
    ep.arrays.get_mut("action").unwrap().row_mut(5)[20] += 1e-3;
    let dir = root.join("click_mouse/episode_000000");
    dexjoco_formats::raw::write_replay_zarr(&dir, &ep).unwrap();
    dir
}

#[test]
fn a_resume_with_other_settings_or_another_dataset_is_refused_and_overwrite_starts_clean() {
    let tmp = tempfile::tempdir().unwrap();
    let out_dir = tmp.path().join("out");
    ok(&augment(1, &out_dir, &[]).output().unwrap());
    let first = tree(&out_dir);

    // Another --size into the same folder: refused, naming the difference; nothing changes.
    let mut c = augment(1, &out_dir, &[]);
    c.args(["--size", "48"]);
    let out = c.output().unwrap();
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("width: 48 (was 32)") && err.contains("--overwrite"),
        "{err}"
    );
    assert_eq!(tree(&out_dir), first);

    // Another dataset whose episode has the same name but other content: refused.
    let other = changed_copy(&tmp.path().join("other"));
    let mut c = cli();
    c.args(["-q", "-j", "1", "augment"])
        .arg(&other)
        .args(["--replays", "4", "--size", "32", "--quality", "fast"])
        .args(["--max-frames", "12", "--keep-failed", "--out"])
        .arg(&out_dir);
    let out = c.output().unwrap();
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("other content of episode 'click_mouse/episode_000000'"),
        "{err}"
    );

    // --overwrite starts clean: the result equals a fresh run with the new settings, and
    // what augment did not write stays.
    fs_err::write(out_dir.join("notes.txt"), "mine").unwrap();
    let mut c = augment(1, &out_dir, &["--overwrite"]);
    c.args(["--size", "48"]);
    ok(&c.output().unwrap());
    let fresh = tmp.path().join("fresh");
    let mut c = augment(1, &fresh, &[]);
    c.args(["--size", "48"]);
    ok(&c.output().unwrap());
    let mut now = tree(&out_dir);
    assert_eq!(now.remove("notes.txt").as_deref(), Some(&b"mine"[..]));
    assert_eq!(now, tree(&fresh));

    // Fewer --replays afterwards: the report still lists every replay on disk (what
    // convert reads).
    let mut c = augment(1, &fresh, &[]);
    c.args(["--size", "48", "--replays", "2"]);
    ok(&c.output().unwrap());
    let report: serde_json::Value =
        serde_json::from_slice(&fs_err::read(fresh.join("augment_report.json")).unwrap()).unwrap();
    assert_eq!(report["replays"].as_array().unwrap().len(), 4);
}

#[test]
fn one_writer_per_output_folder_but_the_shards_of_one_split_share_it() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    fs_err::create_dir_all(&out).unwrap();
    let mut holder = common::sleeper();
    let pid = holder.id();
    let refused = |extra: &[&str]| {
        let o = augment(1, &out, extra).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert_eq!(o.status.code(), Some(1), "{extra:?}: {err}");
        assert!(err.contains(&format!("{pid}@")), "{extra:?}: {err}");
    };

    // A running unsharded augment: neither another run nor a shard may write.
    common::lock_of(&out.join(".lock"), pid);
    refused(&[]);
    refused(&["--shard", "0/2"]);
    fs_err::remove_file(out.join(".lock")).unwrap();

    // A running shard 1/2: shard 0/2 works beside it; an unsharded run, the same shard
    // twice and a shard of another split are refused.
    common::lock_of(&out.join(".lock-shard-1-of-2"), pid);
    refused(&[]);
    refused(&["--shard", "1/2"]);
    refused(&["--shard", "0/3"]);
    ok(&augment(1, &out, &["--shard", "0/2"]).output().unwrap());
    assert!(!out.join(".lock-shard-0-of-2").exists(), "released");

    // Once the holder has ended, its lock is taken over.
    holder.kill().unwrap();
    holder.wait().unwrap();
    ok(&augment(1, &out, &[]).output().unwrap());
    assert!(!out.join(".lock").exists(), "released");
    assert!(out.join("augment_report.json").is_file());

    // --overwrite would remove the other shards' replays: refused with --shard.
    let o = augment(1, &out, &["--shard", "0/2", "--overwrite"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{o:?}");
}

#[test]
fn a_full_disk_stops_the_run_with_exit_1_and_a_rerun_with_space_completes_it() {
    let tmp = tempfile::tempdir().unwrap();
    let whole = tmp.path().join("whole");
    ok(&augment(2, &whole, &[]).output().unwrap());
    // The same run into a file system of 150 KiB (about two of the four replays), in a
    // mount namespace of its own; what it leaves is copied out before the mount goes.
    let (mnt, kept) = (tmp.path().join("small"), tmp.path().join("kept"));
    fs_err::create_dir_all(&mnt).unwrap();
    let run = augment(2, &mnt.join("aug"), &[]);
    let mut c = Command::new("unshare");
    common::without_behaviour_env(&mut c)
        .current_dir(dexjoco_testkit::workspace_root())
        .env("DEXJOCO_LOG", "warn")
        .env("MNT", &mnt)
        .env("KEPT", &kept)
        .args(["-m", "sh", "-c"])
        .arg(
            "mount -t tmpfs -o size=150k tmpfs \"$MNT\" || exit 99; \"$@\"; s=$?; \
             cp -a \"$MNT/aug\" \"$KEPT\"; exit $s",
        )
        .arg("sh")
        .arg(run.get_program())
        .args(run.get_args());
    let out = c.output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("the disk is full, the run stopped")
            && stderr.contains("No space left on device")
            && stderr.contains(&mnt.join("aug").display().to_string())
            && stderr.contains("free"),
        "{stderr}"
    );
    // Nothing partial: whole replays (each with its record) and no staging left.
    let staged = fs_err::read_dir(kept.join(".staging")).map_or(0, Iterator::count);
    assert_eq!(staged, 0, "{stderr}");
    let replays: Vec<_> = fs_err::read_dir(kept.join("click_mouse"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .collect();
    assert!(replays.len() < 4, "the run was not stopped: {replays:?}");
    assert!(replays.iter().all(|r| r.join("replay.json").is_file()));
    // With space, the rerun renders the rest: the bytes of the uninterrupted run.
    ok(&augment(2, &kept, &[]).output().unwrap());
    assert!(tree(&kept) == tree(&whole), "the completed run differs");
}
