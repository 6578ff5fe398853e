//! One writer per output folder: the lock is created atomically (never visible empty),
//! names pid@host, is stale only when that pid is gone on this host, and several named
//! locks can share a folder.

use std::process::{Child, Command};
use std::sync::{Arc, Barrier};

use dexjoco_formats::lock::{LockOwner, host_name};
use dexjoco_formats::{DirLock, FormatError, LOCK_FILE};

fn lock_json(pid: u32, host: &str, started: Option<u64>) -> String {
    let mut v = serde_json::json!({"pid": pid, "host": host});
    if let Some(s) = started {
        v["started"] = s.into();
    }
    v.to_string()
}

/// A process that stays alive while the test runs.
fn sleeper() -> Child {
    Command::new("sleep").arg("60").spawn().expect("sleep runs")
}

/// The start time /proc gives a process (what a lock of it records).
fn start_time(pid: u32) -> Option<u64> {
    let stat = fs_err::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    let rest = &stat[stat.rfind(')')? + 1..];
    rest.split_whitespace().nth(19)?.parse().ok()
}

/// The pid of a process that has ended (and been reaped).
fn dead_pid() -> u32 {
    let mut c = Command::new("true").spawn().unwrap();
    let pid = c.id();
    c.wait().unwrap();
    pid
}

#[test]
fn of_many_threads_taking_one_lock_at_once_exactly_one_wins() {
    let tmp = tempfile::tempdir().unwrap();
    for round in 0..60 {
        let dir = tmp.path().join(format!("r{round}"));
        fs_err::create_dir(&dir).unwrap();
        let n = 12;
        let barrier = Arc::new(Barrier::new(n));
        let handles: Vec<_> = (0..n)
            .map(|_| {
                let (dir, barrier) = (dir.clone(), barrier.clone());
                std::thread::spawn(move || {
                    barrier.wait();
                    DirLock::acquire(&dir).ok()
                })
            })
            .collect();
        let held: Vec<DirLock> = handles
            .into_iter()
            .filter_map(|h| h.join().unwrap())
            .collect();
        assert_eq!(held.len(), 1, "round {round}: {} holders", held.len());
        // The file was complete whenever it was visible: it names us.
        let text = fs_err::read_to_string(dir.join(LOCK_FILE)).unwrap();
        let owner: LockOwner = serde_json::from_str(&text).unwrap();
        assert_eq!(owner.pid, std::process::id());
        assert_eq!(owner.host, host_name());
        drop(held);
        assert!(!dir.join(LOCK_FILE).exists());
        // No temporary or break file is left beside it.
        assert_eq!(fs_err::read_dir(&dir).unwrap().count(), 0);
    }
}

#[test]
fn a_second_taker_is_refused_at_once_naming_pid_at_host() {
    let tmp = tempfile::tempdir().unwrap();
    let first = DirLock::acquire(tmp.path()).unwrap();
    let t0 = std::time::Instant::now();
    let err = DirLock::acquire(tmp.path()).unwrap_err();
    assert!(t0.elapsed().as_secs_f64() < 1.0, "refused at once");
    let me = format!("{}@{}", std::process::id(), host_name());
    match &err {
        FormatError::Locked {
            pid, host, file, ..
        } => {
            assert_eq!(*pid, std::process::id());
            assert_eq!(*host, host_name());
            assert_eq!(*file, tmp.path().join(LOCK_FILE));
        }
        other => panic!("expected Locked, got {other:?}"),
    }
    assert!(err.to_string().contains(&me), "{err}");
    drop(first);
    DirLock::acquire(tmp.path()).unwrap();
}

#[test]
fn a_lock_is_stale_only_when_its_pid_is_gone_on_this_host() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let lock = dir.join(LOCK_FILE);
    let host = host_name();

    // A live process of this host holds it: refused, naming it.
    let mut alive = sleeper();
    let started = start_time(alive.id());
    assert!(started.is_some());
    fs_err::write(&lock, lock_json(alive.id(), &host, started)).unwrap();
    let err = DirLock::acquire(dir).unwrap_err().to_string();
    assert!(err.contains(&format!("{}@{host}", alive.id())), "{err}");
    assert_eq!(DirLock::live_locks(dir).unwrap().len(), 1);

    // The same pid with another start time is a reused pid: the owner is gone.
    fs_err::write(&lock, lock_json(alive.id(), &host, started.map(|s| s + 7))).unwrap();
    assert!(DirLock::live_locks(dir).unwrap().is_empty());
    drop(DirLock::acquire(dir).unwrap());

    // The owner ended (killed): taken over.
    alive.kill().unwrap();
    alive.wait().unwrap();
    fs_err::write(&lock, lock_json(alive.id(), &host, started)).unwrap();
    let taken = DirLock::acquire(dir).unwrap();
    assert_eq!(taken.owner().pid, std::process::id());
    drop(taken);

    // A lock of an older version (the pid alone) of a dead process: taken over.
    fs_err::write(&lock, dead_pid().to_string()).unwrap();
    drop(DirLock::acquire(dir).unwrap());

    // Another host cannot be checked from here: never taken over.
    let other = format!("{host}-elsewhere");
    fs_err::write(&lock, lock_json(dead_pid(), &other, None)).unwrap();
    let err = DirLock::acquire(dir).unwrap_err().to_string();
    assert!(err.contains(&other), "{err}");
    assert!(lock.exists());
}

#[test]
fn a_lock_being_written_in_place_is_not_taken_for_stale() {
    // Only file systems without hard links create a lock in place; a reader that finds
    // it empty must not remove it (the race of the first version of this lock).
    let tmp = tempfile::tempdir().unwrap();
    fs_err::write(tmp.path().join(LOCK_FILE), b"").unwrap();
    let err = DirLock::acquire(tmp.path()).unwrap_err();
    assert!(matches!(err, FormatError::Locked { .. }), "{err}");
    assert!(
        tmp.path().join(LOCK_FILE).exists(),
        "the young lock is kept"
    );
}

#[test]
fn named_locks_share_a_folder_and_the_live_ones_are_listed() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let a = DirLock::acquire_named(dir, ".lock-shard-1-of-2").unwrap();
    let b = DirLock::acquire_named(dir, ".lock-shard-2-of-2").unwrap();
    assert!(DirLock::acquire_named(dir, ".lock-shard-2-of-2").is_err());
    // A stale shard lock is not listed.
    fs_err::write(
        dir.join(".lock-shard-3-of-3"),
        lock_json(dead_pid(), &host_name(), None),
    )
    .unwrap();
    let live: Vec<String> = DirLock::live_locks(dir)
        .unwrap()
        .iter()
        .map(|o| o.file.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(live, [".lock-shard-1-of-2", ".lock-shard-2-of-2"]);
    // An unsharded run takes its own lock, then sees the shards and refuses.
    let whole = DirLock::acquire(dir).unwrap();
    let others: Vec<_> = DirLock::live_locks(dir)
        .unwrap()
        .into_iter()
        .filter(|o| o.file != whole.path())
        .collect();
    assert_eq!(others.len(), 2);
    drop((a, b, whole));
    assert!(DirLock::live_locks(dir).unwrap().is_empty());
}
