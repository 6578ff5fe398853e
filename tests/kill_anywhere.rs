//! Kill anywhere: `ingest` and `convert` killed (SIGKILL) at several points (as soon as
//! they start, while an episode is being written, just after one is renamed into place,
//! after a share of the run's time, and between the two renames of a replacement) and
//! run again end byte-identical to a run never interrupted, with no staging, partial,
//! aside or lock file left.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use dexjoco_core::{TaskSet, synth};
use dexjoco_formats::raw;
use dexjoco_testkit::file_tree;

mod common;

fn bin() -> Command {
    let mut c = common::dexjoco();
    c.env("DEXJOCO_LOG", "error")
        .stdout(Stdio::null())
        .stderr(Stdio::null());
    c
}

/// Runs to the end; returns the exit code.
fn finish(mut c: Command) -> i32 {
    c.status().unwrap().code().unwrap_or(-1)
}

/// When to kill a run, given the episodes landed before it started.
type KillPoint = Box<dyn Fn(usize) -> Box<dyn Fn() -> bool>>;

/// Starts a run and SIGKILLs it when `when` holds (polled every millisecond) or after
/// `deadline`; returns whether it was killed before it ended by itself.
fn kill_when(mut c: Command, when: &dyn Fn() -> bool, deadline: Duration) -> bool {
    let mut child: Child = c.spawn().unwrap();
    let t0 = Instant::now();
    loop {
        if child.try_wait().unwrap().is_some() {
            return false;
        }
        if when() || t0.elapsed() >= deadline {
            child.kill().unwrap();
            child.wait().unwrap();
            return true;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// Names in `dir` (recursively) that a finished run must not leave: work in progress,
/// staging, a replaced folder's old copy, a lock.
fn leftovers(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let Ok(rd) = fs_err::read_dir(dir) else {
        return out;
    };
    for e in rd.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if name == ".staging"
            || name.contains(".partial-")
            || (name.starts_with('.') && name.ends_with(".old"))
            || name.ends_with(".lock")
            || name.contains(".tmp")
        {
            out.push(e.path());
        }
        if e.path().is_dir() {
            out.extend(leftovers(&e.path()));
        }
    }
    out
}

fn count_entries(dir: &Path) -> usize {
    fs_err::read_dir(dir).map_or(0, Iterator::count)
}

/// Landed episode folders of a store.
fn landed(store: &Path) -> usize {
    TaskSet::builtin()
        .iter()
        .map(|t| count_entries(&store.join(&t.id)))
        .sum()
}

/// 36 raw episodes (the tasks in turn) and a rejected input, under `root/in`.
fn ingest_input(root: &Path) -> PathBuf {
    let input = root.join("in");
    let tasks: Vec<_> = TaskSet::builtin().iter().collect();
    for i in 0..36 {
        let task = tasks[i % tasks.len()];
        let ep = synth::episode(task, 400, i as u64);
        raw::write_replay_zarr(&input.join(&task.id).join(format!("episode_{i:06}")), &ep).unwrap();
    }
    // A rejected input too: its quarantine copy is part of the store.
    fs_err::write(input.join("broken.mcap"), b"not an mcap file").unwrap();
    input
}

/// Where the ingest runs into `store` are killed, in turn: the last two only by their
/// deadlines (a third and two thirds of a run).
fn ingest_kill_points(store: &Path) -> Vec<(&'static str, KillPoint)> {
    let s = store.to_owned();
    let staging = store.join(".staging");
    vec![
        (
            "as soon as the store is locked",
            Box::new(move |_| {
                let s = s.clone();
                Box::new(move || s.join(".lock").exists())
            }),
        ),
        (
            "while an episode is staged",
            Box::new(move |_| {
                let st = staging.clone();
                Box::new(move || count_entries(&st) > 0)
            }),
        ),
        (
            "just after an episode is renamed into place",
            Box::new({
                let s = store.to_owned();
                move |before| {
                    let s = s.clone();
                    Box::new(move || landed(&s) > before)
                }
            }),
        ),
        ("after a third of a run", Box::new(|_| Box::new(|| false))),
        (
            "after two thirds of a run",
            Box::new(|_| Box::new(|| false)),
        ),
    ]
}

/// Whatever a kill leaves, every landed folder of `store` is a whole episode.
fn assert_whole_episodes(store: &Path, what: &str) {
    for t in TaskSet::builtin().iter() {
        for e in fs_err::read_dir(store.join(&t.id)).into_iter().flatten() {
            let dir = e.unwrap().path();
            dexjoco_formats::read_episode(&dir, TaskSet::builtin())
                .unwrap_or_else(|e| panic!("killed {what}: {}: {e}", dir.display()));
        }
    }
}

#[test]
fn ingest_killed_anywhere_then_rerun_equals_an_uninterrupted_run() {
    let tmp = tempfile::tempdir().unwrap();
    let input = ingest_input(tmp.path());
    let tasks: Vec<_> = TaskSet::builtin().iter().collect();
    let ingest_with = |store: &Path, overwrite: bool| {
        let mut c = bin();
        c.args(["-j", "1", "ingest"])
            .arg(&input)
            .arg("--out")
            .arg(store);
        if overwrite {
            c.arg("--overwrite");
        }
        c
    };
    let ingest = |store: &Path| ingest_with(store, false);

    let clean = tmp.path().join("clean");
    let t0 = Instant::now();
    assert_eq!(finish(ingest(&clean)), 3, "the broken input is rejected");
    let whole = t0.elapsed();
    let expected = file_tree(&clean);

    let store = tmp.path().join("store");
    let mut killed = 0;
    for (i, (what, when)) in ingest_kill_points(&store).iter().enumerate() {
        let deadline = match i {
            3 => whole / 3,
            4 => whole * 2 / 3,
            _ => whole * 3,
        };
        let before = landed(&store);
        if kill_when(ingest(&store), &*when(before), deadline) {
            killed += 1;
            assert_whole_episodes(&store, what);
        }
    }
    assert!(killed >= 4, "only {killed} of the runs were killed");
    assert_eq!(finish(ingest(&store)), 3);
    assert_eq!(leftovers(&store), Vec::<PathBuf>::new());
    let got = file_tree(&store);
    assert_eq!(
        got.keys().collect::<Vec<_>>(),
        expected.keys().collect::<Vec<_>>()
    );
    assert!(
        got == expected,
        "the store differs from an uninterrupted run"
    );

    // Killed between the two renames of a replacement (--overwrite): the stored episode
    // is aside, its folder missing. The next run puts it back.
    let task_dir = store.join(&tasks[0].id);
    fs_err::rename(
        task_dir.join("episode_000000"),
        task_dir.join(".episode_000000.old"),
    )
    .unwrap();
    assert_eq!(finish(ingest(&store)), 3);
    assert!(
        file_tree(&store) == expected,
        "the aside episode is put back"
    );

    // An --overwrite run killed midway, then completed: the same store.
    assert!(kill_when(ingest_with(&store, true), &|| false, whole / 2));
    assert_eq!(finish(ingest_with(&store, true)), 3);
    assert_eq!(leftovers(&store), Vec::<PathBuf>::new());
    assert!(
        file_tree(&store) == expected,
        "redone in place, byte for byte"
    );
}

/// Raw episode folders with an H.264 camera each, for convert.
fn convert_input(root: &Path, n: usize) -> PathBuf {
    let input = root.join("episodes");
    let task = dexjoco_core::TaskSpec::builtin("click_mouse").unwrap();
    for e in 0..n {
        let frames = 20 + e;
        let mut ep = synth::episode(task, frames, e as u64);
        ep.cameras.clear();
        let d = input.join("click_mouse").join(format!("episode_{e:06}"));
        raw::write_replay_zarr(&d, &ep).unwrap();
        fs_err::create_dir_all(d.join("videos")).unwrap();
        let spec = dexjoco_video::VideoSpec {
            width: 64,
            height: 64,
            fps: 30,
            codec: dexjoco_video::Codec::DEXJOCO,
        };
        let mut w = dexjoco_video::VideoWriter::create(d.join("videos/front.mp4"), spec).unwrap();
        for k in 0..frames {
            w.write_frame(&vec![((k * 7 + e * 13) % 256) as u8; 64 * 64 * 3])
                .unwrap();
        }
        w.finish().unwrap();
    }
    input
}

#[test]
fn convert_killed_anywhere_then_rerun_equals_an_uninterrupted_run() {
    let tmp = tempfile::tempdir().unwrap();
    let input = convert_input(tmp.path(), 24);
    let runs = tmp.path().join("runs");
    fs_err::create_dir_all(&runs).unwrap();
    let convert = |out: &str, overwrite: bool| {
        let mut c = bin();
        c.current_dir(&runs)
            .args(["-j", "1", "convert"])
            .arg(&input)
            .args(["--out", out]);
        if overwrite {
            c.arg("--overwrite");
        }
        c
    };
    let t0 = Instant::now();
    assert_eq!(finish(convert("clean", false)), 0);
    let whole = t0.elapsed();
    let expected = file_tree(&runs.join("clean"));

    let ds = runs.join("ds");
    let partial_has_data = {
        let runs = runs.clone();
        move || {
            fs_err::read_dir(&runs)
                .into_iter()
                .flatten()
                .flatten()
                .any(|e| {
                    e.file_name().to_string_lossy().starts_with(".ds.partial-")
                        && e.path().join("data").exists()
                })
        }
    };
    let lock = runs.join(".ds.lock");
    let deadlines = [whole * 3, whole * 3, whole / 3, whole * 2 / 3];
    let mut killed = 0;
    for (i, deadline) in deadlines.into_iter().enumerate() {
        let when: Box<dyn Fn() -> bool> = match i {
            0 => {
                let lock = lock.clone();
                Box::new(move || lock.exists())
            }
            1 => Box::new(partial_has_data.clone()),
            _ => Box::new(|| false),
        };
        // Runs after the first complete one replace it: --overwrite.
        if kill_when(convert("ds", ds.exists()), &*when, deadline) {
            killed += 1;
        }
        // A dataset is there whole, or not at all.
        if ds.exists() {
            assert!(
                file_tree(&ds) == expected,
                "run {i}: a partial dataset at the output"
            );
        }
    }
    assert!(killed >= 3, "only {killed} of the runs were killed");
    assert_eq!(finish(convert("ds", ds.exists())), 0);
    assert!(file_tree(&ds) == expected);

    // Killed between the two renames of a replacement: the old dataset aside, the new
    // one complete in a staging folder of a process that is gone.
    fs_err::rename(&ds, runs.join(".ds.old")).unwrap();
    dexjoco_formats::fs::copy_tree(&runs.join("clean"), &runs.join(".ds.partial-4000000")).unwrap();
    // Without --overwrite the old dataset is put back, and not replaced.
    assert_eq!(finish(convert("ds", false)), 1);
    assert!(file_tree(&ds) == expected);
    assert_eq!(finish(convert("ds", true)), 0);
    assert!(file_tree(&ds) == expected);
    assert_eq!(leftovers(&runs), Vec::<PathBuf>::new());
}
