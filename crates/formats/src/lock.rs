//! One writer per output folder: a lock file in the folder names the process that
//! writes it, as `{"pid": P, "host": H, "started": T}`.
//!
//! - **Atomic creation**: the owner's pid, host and process start time are written to a
//!   temporary file first, which is then hard-linked to the lock name (`link` fails
//!   when the name exists, on local file systems and NFS alike). A lock file is never
//!   visible empty or half written, so no reader can take a lock being created for a
//!   stale one. (Only where the file system has no hard links is the lock created in
//!   place, and a lock that does not parse is then taken for one being written for
//!   [`UNREADABLE_GRACE`].)
//! - **Stale** only when its process is gone: same host, and no process with that pid
//!   exists, or it is a zombie, or it started at another time (the pid was reused). A
//!   process on another host cannot be checked from here, so its owner keeps a
//!   heartbeat: while a lock is held, a thread refreshes the lock file's modification
//!   time every [`HEARTBEAT`]; a lock of another host is stale once that time is older
//!   than [`FOREIGN_LEASE`] (a shard killed on one cluster node is rerun on another a
//!   few minutes later).
//! - **Taking over** a stale lock goes through a second lock (`<name>.break`): the
//!   breaker re-reads the lock and removes it only if it still holds the stale owner,
//!   so two processes that find the same stale lock cannot both end up holding it.
//! - Several lock files can share a folder: [`DirLock::acquire_named`] takes one of
//!   another name (augment's shards each hold `.lock-shard-<i>-of-<n>`), and
//!   [`DirLock::live_locks`] lists the live ones, so a run that must be alone can take
//!   its own lock, then refuse while another is live. (Two such runs started at the
//!   same moment may both refuse; they never both go on.)
//!
//! A lock is released when its [`DirLock`] is dropped; a killed process leaves its
//! file, which the next run takes over.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use serde::{Deserialize, Serialize};

use crate::error::{FormatError, Result, io_err};

/// File name of a folder's lock.
pub const LOCK_FILE: &str = ".lock";

/// How long a lock file that does not parse is taken for one being written (only
/// possible on file systems without hard links).
pub const UNREADABLE_GRACE: Duration = Duration::from_secs(10);

/// How often a held lock's file gets its modification time refreshed.
pub const HEARTBEAT: Duration = Duration::from_secs(30);

/// How long a lock of another host stays live without a heartbeat (10 missed
/// heartbeats: generous for clock skew between hosts and a slow network file system).
pub const FOREIGN_LEASE: Duration = Duration::from_secs(300);

/// The process a lock file names.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct LockOwner {
    /// Process id.
    pub pid: u32,
    /// Host name of the machine the process runs on.
    pub host: String,
    /// Start time of the process (clock ticks after boot, Linux), so that a reused pid
    /// is not taken for the owner; absent where it cannot be read.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub started: Option<u64>,
    /// The lock file (not stored in it).
    #[serde(skip)]
    pub file: PathBuf,
}

impl std::fmt::Display for LockOwner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}@{}", self.pid, self.host)
    }
}

impl LockOwner {
    /// This process.
    pub fn current() -> Self {
        let pid = std::process::id();
        Self {
            pid,
            host: host_name(),
            started: process_start(pid),
            file: PathBuf::new(),
        }
    }

    /// Whether the owner may still run: for another host, whether its lock file had a
    /// heartbeat within [`FOREIGN_LEASE`] (or its age cannot be read); for this host,
    /// whether a process with its pid and start time exists and is not a zombie.
    pub fn is_alive(&self) -> bool {
        if self.host != host_name() {
            return fs_err::metadata(&self.file)
                .ok()
                .and_then(|m| m.modified().ok())
                .and_then(|t| t.elapsed().ok())
                .is_none_or(|age| age <= FOREIGN_LEASE);
        }
        match proc_stat(self.pid) {
            ProcState::Unknown => true,
            ProcState::Gone | ProcState::Zombie => false,
            ProcState::Running { started } => match (self.started, started) {
                (Some(a), Some(b)) => a == b,
                _ => true,
            },
        }
    }

    fn to_bytes(&self) -> Vec<u8> {
        let mut v = serde_json::to_vec(self).expect("a lock owner serializes");
        v.push(b'\n');
        v
    }
}

/// Exclusive use of a folder (or of one lock name in it) by this process, released on
/// drop.
#[derive(Debug)]
pub struct DirLock {
    path: PathBuf,
    owner: LockOwner,
    heartbeat: Option<Heartbeat>,
}

/// The thread that refreshes a held lock file's modification time; stopped on drop.
#[derive(Debug)]
struct Heartbeat {
    stop: std::sync::mpsc::Sender<()>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Heartbeat {
    /// Touches `path` every `every` while it still holds `bytes` (our lock).
    fn start(path: PathBuf, bytes: Vec<u8>, every: Duration) -> Option<Self> {
        let (stop, stopped) = std::sync::mpsc::channel::<()>();
        let thread = std::thread::Builder::new()
            .name("lock-heartbeat".into())
            .spawn(move || {
                while let Err(std::sync::mpsc::RecvTimeoutError::Timeout) =
                    stopped.recv_timeout(every)
                {
                    if fs_err::read(&path).ok().as_deref() != Some(&bytes[..]) {
                        return; // taken over or removed: not ours to touch
                    }
                    let touched = fs_err::OpenOptions::new()
                        .append(true)
                        .open(&path)
                        .and_then(|f| f.file().set_modified(std::time::SystemTime::now()));
                    if let Err(e) = touched {
                        tracing::warn!("lock heartbeat on '{}': {e}", path.display());
                    }
                }
            })
            .ok()?;
        Some(Self {
            stop,
            thread: Some(thread),
        })
    }
}

impl Drop for Heartbeat {
    fn drop(&mut self) {
        let _ = self.stop.send(());
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// What reading a lock file found.
enum Found {
    /// A complete lock of this owner, with the bytes read.
    Owner(LockOwner, Vec<u8>),
    /// The file is gone.
    Gone,
    /// The file does not parse; whether it is old enough to be taken for stale.
    Unreadable { old: bool, bytes: Vec<u8> },
}

static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

impl DirLock {
    /// Takes the lock `<dir>/.lock` (the folder must exist), or fails with
    /// [`FormatError::Locked`] naming the process that holds it.
    pub fn acquire(dir: &Path) -> Result<Self> {
        Self::acquire_named(dir, LOCK_FILE)
    }

    /// Takes the lock file `name` in `dir` (e.g. `.lock-shard-2-of-4`, or
    /// `.dataset.lock` for a folder written beside it), or fails with
    /// [`FormatError::Locked`] naming the live process (`pid@host`) that holds it. A
    /// lock of a process that has ended is taken over.
    pub fn acquire_named(dir: &Path, name: &str) -> Result<Self> {
        let path = dir.join(name);
        let mut owner = LockOwner::current();
        owner.file = path.clone();
        let bytes = owner.to_bytes();
        for attempt in 0..50 {
            if create_exclusive(&path, &bytes)? {
                remove_stale_temporaries(&path);
                let heartbeat = Heartbeat::start(path.clone(), bytes, HEARTBEAT);
                return Ok(Self {
                    path,
                    owner,
                    heartbeat,
                });
            }
            match read_lock(&path)? {
                Found::Gone => {}
                Found::Owner(holder, _) if holder.is_alive() => {
                    return Err(locked(dir, holder));
                }
                Found::Unreadable { old: false, .. } => {
                    return Err(locked(
                        dir,
                        LockOwner {
                            pid: 0,
                            host: "(a lock being written)".into(),
                            started: None,
                            file: path.clone(),
                        },
                    ));
                }
                Found::Owner(holder, seen) => {
                    tracing::info!(
                        "taking over the lock '{}' of {holder}, which has ended",
                        path.display()
                    );
                    break_stale(&path, &seen)?;
                }
                Found::Unreadable { old: true, bytes } => {
                    tracing::warn!("taking over the unreadable lock '{}'", path.display());
                    break_stale(&path, &bytes)?;
                }
            }
            std::thread::sleep(Duration::from_millis(2 + attempt));
        }
        match read_lock(&path)? {
            Found::Owner(holder, _) => Err(locked(dir, holder)),
            _ => Err(FormatError::Io {
                op: "take the lock",
                path,
                source: std::io::Error::other("other processes keep taking it over"),
            }),
        }
    }

    /// The live locks of `dir`: every lock file named `.lock` or `.lock-*` whose
    /// process may still run (those of ended processes are left out, not removed).
    /// Includes this process's own locks.
    pub fn live_locks(dir: &Path) -> Result<Vec<LockOwner>> {
        let mut out = Vec::new();
        let rd = match fs_err::read_dir(dir) {
            Ok(rd) => rd,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(out),
            Err(e) => return Err(io_err("list", dir)(e)),
        };
        let mut names: Vec<String> = rd
            .flatten()
            .filter_map(|e| e.file_name().to_str().map(str::to_owned))
            .filter(|n| n == LOCK_FILE || n.starts_with(".lock-"))
            // A lock file being created (see `create_exclusive`): the lock is its final
            // name, linked once the file is complete; the temporary is not a lock.
            .filter(|n| !n.contains(LOCK_TEMP_MARK))
            .collect();
        names.sort();
        for name in names {
            match read_lock(&dir.join(&name))? {
                Found::Owner(o, _) if o.is_alive() => out.push(o),
                Found::Unreadable { old: false, .. } => out.push(LockOwner {
                    pid: 0,
                    host: "(a lock being written)".into(),
                    started: None,
                    file: dir.join(&name),
                }),
                _ => {}
            }
        }
        Ok(out)
    }

    /// The lock file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// This process, as the lock names it.
    pub fn owner(&self) -> &LockOwner {
        &self.owner
    }
}

impl Drop for DirLock {
    fn drop(&mut self) {
        drop(self.heartbeat.take());
        // Only our own lock is removed (never one another process took over).
        if let Ok(Found::Owner(o, _)) = read_lock(&self.path)
            && o.pid == self.owner.pid
            && o.host == self.owner.host
            && o.started == self.owner.started
        {
            let _ = fs_err::remove_file(&self.path);
        }
    }
}

fn locked(dir: &Path, owner: LockOwner) -> FormatError {
    FormatError::Locked {
        path: dir.to_owned(),
        file: owner.file.clone(),
        pid: owner.pid,
        host: owner.host,
    }
}

/// What names a lock file's temporary while it is written (`<lock>.tmp-<pid>-<n>`).
const LOCK_TEMP_MARK: &str = ".tmp-";

/// Removes the temporaries of lock `path` (`<lock>.tmp-<pid>-<n>`) that a process killed
/// between writing and linking them left: one naming an owner that no longer runs
/// ([`LockOwner::is_alive`], as for a lock), or unreadable for [`UNREADABLE_GRACE`].
/// Best effort: called by the lock's new holder.
fn remove_stale_temporaries(path: &Path) {
    let (Some(dir), Some(name)) = (path.parent(), path.file_name()) else {
        return;
    };
    let prefix = format!("{}{LOCK_TEMP_MARK}", name.to_string_lossy());
    let Ok(entries) = fs_err::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        if !e.file_name().to_string_lossy().starts_with(&prefix) {
            continue;
        }
        let stale = match read_lock(&e.path()) {
            Ok(Found::Owner(owner, _)) => !owner.is_alive(),
            Ok(Found::Unreadable { old, .. }) => old,
            _ => false,
        };
        if stale {
            let _ = fs_err::remove_file(e.path());
        }
    }
}

/// Creates `path` holding `bytes`, complete before it becomes visible; `Ok(false)` when
/// it exists.
fn create_exclusive(path: &Path, bytes: &[u8]) -> Result<bool> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .map_or_else(|| "lock".into(), |n| n.to_string_lossy().into_owned());
    let tmp = dir.join(format!(
        "{name}{LOCK_TEMP_MARK}{}-{}",
        std::process::id(),
        TEMP_COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    {
        let mut f = fs_err::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)
            .map_err(io_err("create", &tmp))?;
        f.write_all(bytes).map_err(io_err("write", &tmp))?;
        f.sync_all().map_err(io_err("sync", &tmp))?;
    }
    let linked = fs_err::hard_link(&tmp, path);
    let _ = fs_err::remove_file(&tmp);
    match linked {
        Ok(()) => Ok(true),
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Ok(false),
        Err(e)
            if matches!(
                e.kind(),
                std::io::ErrorKind::Unsupported | std::io::ErrorKind::PermissionDenied
            ) =>
        {
            // No hard links here: create in place (a reader may see it half written,
            // see UNREADABLE_GRACE).
            match fs_err::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(path)
            {
                Ok(mut f) => {
                    f.write_all(bytes).map_err(io_err("write", path))?;
                    f.sync_all().map_err(io_err("sync", path))?;
                    Ok(true)
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Ok(false),
                Err(e) => Err(io_err("create", path)(e)),
            }
        }
        Err(e) => Err(io_err("create", path)(e)),
    }
}

fn read_lock(path: &Path) -> Result<Found> {
    let bytes = match fs_err::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Found::Gone),
        Err(e) => return Err(io_err("read", path)(e)),
    };
    let parsed = serde_json::from_slice::<LockOwner>(&bytes)
        .ok()
        .or_else(|| {
            // A lock of an older version: the pid alone, of this host.
            let pid = std::str::from_utf8(&bytes)
                .ok()?
                .trim()
                .parse::<u32>()
                .ok()?;
            Some(LockOwner {
                pid,
                host: host_name(),
                started: None,
                file: PathBuf::new(),
            })
        });
    Ok(match parsed {
        Some(mut o) => {
            o.file = path.to_owned();
            Found::Owner(o, bytes)
        }
        None => {
            let old = fs_err::metadata(path)
                .ok()
                .and_then(|m| m.modified().ok())
                .and_then(|t| t.elapsed().ok())
                .is_some_and(|age| age >= UNREADABLE_GRACE);
            Found::Unreadable { old, bytes }
        }
    })
}

/// Removes the stale lock `path` if it still holds `seen`, under the break lock.
fn break_stale(path: &Path, seen: &[u8]) -> Result<()> {
    let breaker = path.with_file_name(format!(
        "{}.break",
        path.file_name().unwrap_or_default().to_string_lossy()
    ));
    let mut me = LockOwner::current();
    me.file = breaker.clone();
    if !create_exclusive(&breaker, &me.to_bytes())? {
        // Another process is taking it over; or a breaker was killed midway.
        if let Found::Owner(b, _) = read_lock(&breaker)?
            && !b.is_alive()
        {
            let _ = fs_err::remove_file(&breaker);
        }
        return Ok(());
    }
    let still = fs_err::read(path).ok();
    if still.as_deref() == Some(seen) {
        let _ = fs_err::remove_file(path);
    }
    let _ = fs_err::remove_file(&breaker);
    Ok(())
}

/// This machine's host name (Linux: the kernel's; else `$HOSTNAME`, else `localhost`).
pub fn host_name() -> String {
    for f in ["/proc/sys/kernel/hostname", "/etc/hostname"] {
        if let Ok(s) = fs_err::read_to_string(f) {
            let s = s.trim();
            if !s.is_empty() {
                return s.to_owned();
            }
        }
    }
    std::env::var("HOSTNAME").unwrap_or_else(|_| "localhost".into())
}

enum ProcState {
    /// No such process.
    Gone,
    /// Ended, not yet reaped by its parent.
    Zombie,
    /// Alive, with its start time when known.
    Running { started: Option<u64> },
    /// Cannot tell (no /proc): taken as alive, so a stale lock is removed by hand.
    Unknown,
}

fn proc_stat(pid: u32) -> ProcState {
    let proc = Path::new("/proc");
    if !proc.join("self/stat").exists() {
        return ProcState::Unknown;
    }
    let Ok(stat) = fs_err::read_to_string(proc.join(pid.to_string()).join("stat")) else {
        return ProcState::Gone;
    };
    // `pid (comm) state ppid ...`: comm may hold spaces and parentheses.
    let Some(rest) = stat.rfind(')').map(|i| &stat[i + 1..]) else {
        return ProcState::Running { started: None };
    };
    let fields: Vec<&str> = rest.split_whitespace().collect();
    match fields.first() {
        Some(&"Z" | &"X" | &"x") => ProcState::Zombie,
        // Field 22 of stat (starttime) is the 20th after the state's field 3.
        _ => ProcState::Running {
            started: fields.get(19).and_then(|s| s.parse().ok()),
        },
    }
}

fn process_start(pid: u32) -> Option<u64> {
    match proc_stat(pid) {
        ProcState::Running { started } => started,
        _ => None,
    }
}

/// One writer per output folder. An unsharded run holds `<out>/.lock`; shard `I/N` holds
/// `<out>/.lock-shard-I-of-N`, so the shards of one split share the folder (they never
/// write the same replay). Either refuses while a run that could write the same replays
/// holds a lock there: an unsharded run refuses any shard, a shard refuses an unsharded
/// run and the shards of another split. Both take their own lock before looking, so of
/// two runs started together at least one sees the other.
pub fn lock_output(out: &Path, shard: Option<dexjoco_core::Shard>) -> Result<DirLock> {
    let own = match shard {
        None => LOCK_FILE.to_owned(),
        Some(s) => format!("{}-shard-{}-of-{}", LOCK_FILE, s.index, s.count),
    };
    let lock = DirLock::acquire_named(out, &own)?;
    let same_split = shard.map(|s| format!("-of-{}", s.count));
    for other in DirLock::live_locks(out)? {
        let name = other
            .file
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let compatible = name == own
            || same_split
                .as_deref()
                .is_some_and(|tail| name.starts_with(".lock-shard-") && name.ends_with(tail));
        if !compatible {
            return Err(FormatError::Locked {
                path: out.to_owned(),
                file: other.file,
                pid: other.pid,
                host: other.host,
            });
        }
    }
    Ok(lock)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn this_process_is_alive_and_reads_its_start_time() {
        let me = LockOwner::current();
        assert!(me.is_alive());
        assert!(me.started.is_some(), "/proc/self/stat gives the start time");
        let reused = LockOwner {
            started: me.started.map(|s| s + 1),
            ..me.clone()
        };
        assert!(!reused.is_alive(), "same pid, other start time: reused pid");
    }

    /// A lock file of another host, its modification time `age` ago.
    fn foreign_lock(dir: &Path, age: Duration) -> PathBuf {
        let me = LockOwner::current();
        let other = LockOwner {
            pid: 12345,
            host: format!("{}-elsewhere", me.host),
            started: None,
            file: PathBuf::new(),
        };
        let path = dir.join(LOCK_FILE);
        fs_err::write(&path, other.to_bytes()).unwrap();
        let f = fs_err::OpenOptions::new().append(true).open(&path).unwrap();
        f.file()
            .set_modified(std::time::SystemTime::now() - age)
            .unwrap();
        path
    }

    #[test]
    fn a_lock_being_written_by_another_shard_is_not_a_lock() {
        // Seen on a real Slurm run: shard 2 listed the locks while shard 3 was between
        // writing its temporary and linking it, and refused the folder.
        let dir = tempfile::tempdir().unwrap();
        let me = LockOwner::current();
        let tmp = dir
            .path()
            .join(format!(".lock-shard-3-of-4{LOCK_TEMP_MARK}{}-0", me.pid));
        fs_err::write(&tmp, me.to_bytes()).unwrap();
        assert!(DirLock::live_locks(dir.path()).unwrap().is_empty());
        let _lock = DirLock::acquire_named(dir.path(), ".lock-shard-2-of-4").unwrap();
        let live = DirLock::live_locks(dir.path()).unwrap();
        assert_eq!(live.len(), 1);
        assert!(live[0].file.ends_with(".lock-shard-2-of-4"));
    }

    #[test]
    fn a_temporary_left_by_a_killed_process_is_removed_by_the_next_holder() {
        // Seen in the kill tests: an ingest killed between writing its lock's temporary
        // and linking it left `.lock.tmp-<pid>-0` in the store.
        let dir = tempfile::tempdir().unwrap();
        let mut dead = LockOwner::current();
        dead.pid = u32::MAX - 1;
        dead.started = None;
        let left = dir
            .path()
            .join(format!(".lock{LOCK_TEMP_MARK}{}-0", dead.pid));
        fs_err::write(&left, dead.to_bytes()).unwrap();
        let me = LockOwner::current();
        let live = dir
            .path()
            .join(format!(".lock{LOCK_TEMP_MARK}{}-7", me.pid));
        fs_err::write(&live, me.to_bytes()).unwrap();
        let _lock = DirLock::acquire(dir.path()).unwrap();
        assert!(!left.exists(), "the dead process's temporary is removed");
        assert!(live.exists(), "a live writer's temporary is left alone");
    }

    #[test]
    fn another_hosts_lock_is_live_while_its_heartbeat_is_recent() {
        let dir = tempfile::tempdir().unwrap();
        foreign_lock(dir.path(), Duration::from_secs(60));
        let err = DirLock::acquire(dir.path()).unwrap_err().to_string();
        assert!(err.contains("12345@"), "{err}");
        assert_eq!(DirLock::live_locks(dir.path()).unwrap().len(), 1);
    }

    #[test]
    fn another_hosts_lock_without_a_heartbeat_for_the_lease_is_taken_over() {
        let dir = tempfile::tempdir().unwrap();
        foreign_lock(dir.path(), FOREIGN_LEASE + Duration::from_secs(60));
        assert!(DirLock::live_locks(dir.path()).unwrap().is_empty());
        let lock = DirLock::acquire(dir.path()).expect("a dead host's lock is stale");
        assert_eq!(lock.owner().pid, std::process::id());
    }

    #[test]
    fn a_held_lock_gets_its_heartbeat_and_the_heartbeat_stops_on_drop() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("hb");
        let bytes = LockOwner::current().to_bytes();
        fs_err::write(&path, &bytes).unwrap();
        let old = std::time::SystemTime::now() - Duration::from_secs(3600);
        let set_old = || {
            let f = fs_err::OpenOptions::new().append(true).open(&path).unwrap();
            f.file().set_modified(old).unwrap();
        };
        let mtime = || fs_err::metadata(&path).unwrap().modified().unwrap();
        set_old();
        let hb = Heartbeat::start(path.clone(), bytes, Duration::from_millis(20)).unwrap();
        let t = std::time::Instant::now();
        while mtime() == old && t.elapsed() < Duration::from_secs(10) {
            std::thread::sleep(Duration::from_millis(10));
        }
        assert!(mtime() > old, "the heartbeat refreshed the lock file");
        drop(hb);
        set_old();
        std::thread::sleep(Duration::from_millis(100));
        assert_eq!(mtime(), old, "no heartbeat after drop");
    }
}
