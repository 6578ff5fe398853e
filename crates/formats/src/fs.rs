//! File-system primitives every writer uses: atomic file writes (temporary file in the
//! same folder, synced, renamed, the folder synced), whole-folder replacement, tree copies
//! and syncs.
//!
//! A reader never sees half a file or half a folder written through these: a file
//! appears complete under its name or not at all, and a replaced folder is either the
//! old one or the new one, whole.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::{FormatError, Result, io_err};

/// What names the temporary file of an atomic write: `.<file name>.partial-<random>`.
pub const PARTIAL_MARK: &str = ".partial-";

/// Writes a file atomically: a temporary file in the same folder, synced, renamed.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut tmp = temp_file_beside(path)?;
    tmp.write_all(bytes).map_err(io_err("write", tmp.path()))?;
    persist_synced(tmp, path)
}

/// A temporary file in `path`'s folder (created if needed), named
/// `.<file name>.partial-<random>` so that a killed writer's leftover is recognized
/// ([`remove_partial_files`]).
pub fn temp_file_beside(path: &Path) -> Result<tempfile::NamedTempFile> {
    let dir = path.parent().unwrap_or(Path::new("."));
    fs_err::create_dir_all(dir).map_err(io_err("create", dir))?;
    let name = path
        .file_name()
        .map_or_else(|| "file".into(), |n| n.to_string_lossy().into_owned());
    tempfile::Builder::new()
        .prefix(&format!(".{name}{PARTIAL_MARK}"))
        .tempfile_in(dir)
        .map_err(io_err("create a temporary file in", dir))
}

/// Removes the temporary files of atomic writes that a killed writer left directly in
/// `dir` (files named `.<name>.partial-<random>`; folders are left alone). Only the
/// folder's one writer, holding its lock, may call it: another writer's file in progress
/// has the same kind of name. Returns how many were removed.
pub fn remove_partial_files(dir: &Path) -> Result<usize> {
    let rd = match fs_err::read_dir(dir) {
        Ok(rd) => rd,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
        Err(e) => return Err(io_err("list", dir)(e)),
    };
    let mut removed = 0;
    for e in rd.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        let is_file = e.file_type().is_ok_and(|t| t.is_file());
        if is_file && name.starts_with('.') && name.contains(PARTIAL_MARK) {
            let p = e.path();
            fs_err::remove_file(&p).map_err(io_err("remove", &p))?;
            tracing::debug!(file = %p.display(), "removed a killed write's temporary file");
            removed += 1;
        }
    }
    Ok(removed)
}

/// Syncs a fully written temporary file and renames it to `path` (mode 0644).
pub fn persist_synced(tmp: tempfile::NamedTempFile, path: &Path) -> Result<()> {
    // Temporary files are created owner-only; the finished file is an ordinary one.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        tmp.as_file()
            .set_permissions(std::fs::Permissions::from_mode(0o644))
            .map_err(io_err("set permissions of", tmp.path()))?;
    }
    tmp.as_file()
        .sync_all()
        .map_err(io_err("sync", tmp.path()))?;
    tmp.persist(path).map_err(|e| FormatError::Io {
        op: "rename into",
        path: path.to_owned(),
        source: e.error,
    })?;
    sync_dir(parent_of(path))
}

/// The name a replaced folder is moved aside to while its replacement is renamed in:
/// `.NAME.old` beside it (hidden, so discovery never reads it).
pub fn aside_path(to: &Path) -> PathBuf {
    sibling(to, "", ".old")
}

/// `<parent of path>/.<name><infix><suffix>`.
fn sibling(path: &Path, infix: &str, suffix: &str) -> PathBuf {
    let name = path
        .file_name()
        .map_or_else(|| "out".into(), |n| n.to_string_lossy().into_owned());
    path.with_file_name(format!(".{name}{infix}{suffix}"))
}

/// Moves a staged folder to `to`, replacing what is there (the old copy is moved aside
/// to [`aside_path`] first, so `to` is always either the old or the new folder, whole;
/// a run killed between the two renames is undone by [`recover_replaced`]).
pub fn replace_dir(staged: &Path, to: &Path) -> Result<()> {
    if let Some(parent) = to.parent() {
        fs_err::create_dir_all(parent).map_err(io_err("create", parent))?;
    }
    let aside = aside_path(to);
    if fs_err::symlink_metadata(&aside).is_ok() {
        // Left by a replacement that completed but was killed before cleaning up.
        remove_any(&aside)?;
    }
    if fs_err::symlink_metadata(to).is_ok() {
        fs_err::rename(to, &aside).map_err(io_err("rename", to))?;
        fs_err::rename(staged, to).map_err(io_err("rename", staged))?;
        sync_dir(parent_of(to))?;
        // The replacement is done; a left-over old copy is removed by the next replace.
        let _ = remove_any(&aside);
    } else {
        fs_err::rename(staged, to).map_err(io_err("rename", staged))?;
        sync_dir(parent_of(to))?;
    }
    Ok(())
}

fn remove_any(path: &Path) -> Result<()> {
    let meta = fs_err::symlink_metadata(path).map_err(io_err("read", path))?;
    if meta.is_dir() {
        fs_err::remove_dir_all(path).map_err(io_err("remove", path))
    } else {
        fs_err::remove_file(path).map_err(io_err("remove", path))
    }
}

/// Undoes what a [`replace_dir`] killed midway left at `to`: when `to` is missing and
/// its old copy is aside, the old copy is put back; when both exist, the old copy is
/// removed. Returns whether anything was done.
pub fn recover_replaced(to: &Path) -> Result<bool> {
    let aside = aside_path(to);
    if fs_err::symlink_metadata(&aside).is_err() {
        return Ok(false);
    }
    if fs_err::symlink_metadata(to).is_err() {
        tracing::warn!(
            "'{}' was being replaced when a run stopped: the previous copy is put back",
            to.display()
        );
        fs_err::rename(&aside, to).map_err(io_err("rename", &aside))?;
    } else {
        remove_any(&aside)?;
    }
    Ok(true)
}

/// [`recover_replaced`] for every `.NAME.old` in `dir` (none when `dir` is missing).
pub fn recover_replaced_in(dir: &Path) -> Result<usize> {
    let Ok(rd) = fs_err::read_dir(dir) else {
        return Ok(0);
    };
    let mut names: Vec<String> = rd
        .flatten()
        .filter_map(|e| e.file_name().to_str().map(str::to_owned))
        .filter(|n| n.starts_with('.') && n.ends_with(".old") && n.len() > 5)
        .collect();
    names.sort();
    let mut done = 0;
    for n in names {
        let to = dir.join(&n[1..n.len() - 4]);
        if recover_replaced(&to)? {
            done += 1;
        }
    }
    Ok(done)
}

/// File name of the lock of a folder written beside it: `.NAME.lock`.
pub fn output_lock_name(to: &Path) -> String {
    sibling(to, "", ".lock")
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// A folder written whole and renamed into place: the lock `.NAME.lock` beside it (one
/// writer per output), an empty staging folder `.NAME.partial-PID` beside it, and on
/// [`StagedDir::commit`] the replacement of the folder. Dropped uncommitted, the
/// staging folder is removed; a killed run's staging folder is removed by the next
/// [`StagedDir::begin`] of the same folder.
#[derive(Debug)]
pub struct StagedDir {
    staged: PathBuf,
    to: PathBuf,
    committed: bool,
    _lock: crate::lock::DirLock,
}

impl StagedDir {
    /// Takes the lock of `to` (failing with [`FormatError::Locked`] when another run
    /// writes it), undoes a replacement a killed run left half done, removes the
    /// staging folders of earlier runs and creates this run's. Nothing at `to` is
    /// touched until [`StagedDir::commit`].
    pub fn begin(to: &Path) -> Result<Self> {
        // `.`, `..` or `/` name no folder to put a staging folder beside: resolved first.
        let resolved;
        let to = if to.file_name().is_none() || to.ends_with("..") {
            resolved = resolve(to);
            resolved.as_path()
        } else {
            to
        };
        let parent = match to.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        fs_err::create_dir_all(&parent).map_err(io_err("create", &parent))?;
        let lock = crate::lock::DirLock::acquire_named(&parent, &output_lock_name(to))?;
        recover_replaced(to)?;
        for leaked in leaked_partials(to)? {
            tracing::info!(
                "removing '{}', left by a run that stopped",
                leaked.display()
            );
            remove_any(&leaked)?;
        }
        let staged = sibling(to, ".partial-", &std::process::id().to_string());
        fs_err::create_dir_all(&staged).map_err(io_err("create", &staged))?;
        Ok(Self {
            staged,
            to: to.to_path_buf(),
            committed: false,
            _lock: lock,
        })
    }

    /// The staging folder to write into.
    pub fn path(&self) -> &Path {
        &self.staged
    }

    /// The folder it replaces.
    pub fn target(&self) -> &Path {
        &self.to
    }

    /// Syncs the staging folder and renames it to the target, replacing what is there
    /// (the rename synced too).
    pub fn commit(mut self) -> Result<()> {
        sync_tree(&self.staged)?;
        replace_dir(&self.staged, &self.to)?;
        self.committed = true;
        Ok(())
    }
}

impl Drop for StagedDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = fs_err::remove_dir_all(&self.staged);
        }
    }
}

/// Files a command writes into a folder it shares with other runs and commands (render's
/// images, a camera pool), staged: each is written under its own name into a hidden
/// staging folder inside that folder (`.NAME.partial-<random>`), and
/// [`StagedFiles::publish`] renames them all into place and syncs the folder. A name that
/// already exists there is refused, unless `overwrite`, when it is asked for and again
/// at publish: before anything of the run is published. Dropped unpublished, the staging
/// folder is removed.
#[derive(Debug)]
pub struct StagedFiles {
    dir: PathBuf,
    staging: tempfile::TempDir,
    overwrite: bool,
    names: Vec<String>,
}

impl StagedFiles {
    /// Starts staging files for `dir` (created if needed); `overwrite`: they may replace
    /// files of the same names.
    pub fn begin(dir: &Path, overwrite: bool) -> Result<Self> {
        fs_err::create_dir_all(dir).map_err(io_err("create", dir))?;
        let staging = tempfile::Builder::new()
            .prefix(".staged-files.partial-")
            .tempdir_in(dir)
            .map_err(io_err("create a staging folder in", dir))?;
        Ok(Self {
            dir: dir.to_path_buf(),
            staging,
            overwrite,
            names: Vec::new(),
        })
    }

    /// Where to write the file `name` now (in the staging folder); fails with
    /// [`FormatError::WouldReplace`] when `dir/name` exists and overwriting is not allowed.
    pub fn file(&mut self, name: &str) -> Result<PathBuf> {
        let target = self.dir.join(name);
        if !self.overwrite && fs_err::symlink_metadata(&target).is_ok() {
            return Err(FormatError::WouldReplace { path: target });
        }
        self.names.push(name.to_owned());
        Ok(self.staging.path().join(name))
    }

    /// Where `name` will be once published.
    pub fn target(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }

    /// Syncs the staged files and renames each into place (replacing a file of the same
    /// name), then syncs the folder. Names asked for but not written are left out.
    pub fn publish(self) -> Result<()> {
        sync_tree(self.staging.path())?;
        // Asked again: a file may have appeared (another run) since it was asked for.
        if !self.overwrite {
            for name in &self.names {
                let target = self.dir.join(name);
                if fs_err::symlink_metadata(&target).is_ok() {
                    return Err(FormatError::WouldReplace { path: target });
                }
            }
        }
        for name in &self.names {
            let staged = self.staging.path().join(name);
            if fs_err::symlink_metadata(&staged).is_err() {
                continue;
            }
            let target = self.dir.join(name);
            fs_err::rename(&staged, &target).map_err(io_err("rename", &staged))?;
        }
        sync_dir(&self.dir)
    }
}

/// The `.NAME.partial-*` folders beside `to` (staging folders of runs that stopped;
/// only called under `to`'s lock, so none belongs to a live run).
fn leaked_partials(to: &Path) -> Result<Vec<PathBuf>> {
    let prefix = sibling(to, ".partial-", "")
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let parent = to.parent().filter(|p| !p.as_os_str().is_empty());
    let parent = parent.unwrap_or(Path::new("."));
    let mut out: Vec<PathBuf> = fs_err::read_dir(parent)
        .map_err(io_err("list", parent))?
        .flatten()
        .filter(|e| {
            e.file_name()
                .to_str()
                .and_then(|n| n.strip_prefix(&prefix))
                .is_some_and(|pid| !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit()))
        })
        .map(|e| e.path())
        .collect();
    out.sort();
    Ok(out)
}

/// `path` made absolute with every link resolved, also when its last components do
/// not exist yet (they are appended to the resolved existing part; `.` and `..` among
/// them are applied lexically).
pub fn resolve(path: &Path) -> PathBuf {
    let abs = if path.is_absolute() {
        path.to_path_buf()
    } else {
        std::env::current_dir()
            .unwrap_or_else(|_| PathBuf::from("/"))
            .join(path)
    };
    let mut existing = abs.as_path();
    let mut rest = Vec::new();
    loop {
        if let Ok(real) = existing.canonicalize() {
            let mut out = real;
            for c in rest.iter().rev() {
                match c {
                    std::path::Component::ParentDir => {
                        out.pop();
                    }
                    std::path::Component::CurDir => {}
                    c => out.push(c),
                }
            }
            return out;
        }
        match (existing.parent(), existing.components().next_back()) {
            (Some(p), Some(c)) => {
                rest.push(c);
                existing = p;
            }
            _ => return abs,
        }
    }
}

/// Whether `a` and `b` are the same folder or one lies inside the other (after
/// [`resolve`]).
pub fn overlaps(a: &Path, b: &Path) -> bool {
    let (a, b) = (resolve(a), resolve(b));
    a.starts_with(&b) || b.starts_with(&a)
}

/// How an output path meets an input path.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Overlap {
    /// The same path.
    Same,
    /// The output holds the input.
    Holds,
    /// The output lies inside the input.
    Inside,
}

impl Overlap {
    /// How `output` meets `input` (links resolved), when it does.
    pub fn of(output: &Path, input: &Path) -> Option<Self> {
        let (o, i) = (resolve(output), resolve(input));
        if o == i {
            Some(Self::Same)
        } else if i.starts_with(&o) {
            Some(Self::Holds)
        } else if o.starts_with(&i) {
            Some(Self::Inside)
        } else {
            None
        }
    }

    /// In words: `is`, `holds`, `lies inside`.
    pub fn words(self) -> &'static str {
        match self {
            Self::Same => "is",
            Self::Holds => "holds",
            Self::Inside => "lies inside",
        }
    }
}

/// The rule every command that writes applies before it writes anything: no output is,
/// holds or lies inside what the command reads (links resolved). Returns the first
/// `(output, input, how)` that breaks it.
pub fn first_overlap<'a>(
    outputs: &[&'a Path],
    inputs: &[&'a Path],
) -> Option<(&'a Path, &'a Path, Overlap)> {
    outputs.iter().find_map(|o| {
        inputs
            .iter()
            .find_map(|i| Overlap::of(o, i).map(|how| (*o, *i, how)))
    })
}

/// Whether `inner` is `outer` or lies inside it (after [`resolve`]).
pub fn is_within(inner: &Path, outer: &Path) -> bool {
    resolve(inner).starts_with(resolve(outer))
}

/// Refuses to write `path` when a folder on the way to it from `root` (`root` itself
/// excluded: the user named it) is a symbolic link: writing there would write wherever the
/// link points, outside the folder. The file itself may be a link: [`write_atomic`]
/// replaces a link, never writes through it.
pub fn check_no_linked_folders(root: &Path, path: &Path) -> Result<()> {
    let Ok(rel) = path.strip_prefix(root) else {
        return Ok(());
    };
    let mut at = root.to_path_buf();
    let mut parts: Vec<_> = rel.components().collect();
    parts.pop();
    for c in parts {
        at.push(c);
        if fs_err::symlink_metadata(&at).is_ok_and(|m| m.file_type().is_symlink()) {
            return Err(FormatError::Linked {
                target: fs_err::read_link(at.as_path()).ok(),
                path: at,
            });
        }
    }
    Ok(())
}

/// Refuses an output folder that holds a symbolic link anywhere inside it: a stage that
/// resumes into its output writes into the folders it finds there, and dexjoco-data never
/// makes links, so a link there was put by someone else and could lead its writes outside
/// the folder. `out` itself may be a link (the user named it). Returns the first link
/// found.
pub fn refuse_links_within(out: &Path) -> Result<()> {
    let mut stack = vec![out.to_path_buf()];
    while let Some(dir) = stack.pop() {
        let Ok(entries) = fs_err::read_dir(&dir) else {
            continue;
        };
        let mut entries: Vec<_> = entries.flatten().collect();
        entries.sort_by_key(fs_err::DirEntry::file_name);
        for e in entries {
            match e.file_type() {
                Ok(t) if t.is_symlink() => {
                    let path = e.path();
                    return Err(FormatError::Linked {
                        target: fs_err::read_link(&path).ok(),
                        path,
                    });
                }
                Ok(t) if t.is_dir() => stack.push(e.path()),
                _ => {}
            }
        }
    }
    Ok(())
}

/// Copies a file or a folder tree (symlinks are followed).
pub fn copy_tree(from: &Path, to: &Path) -> Result<()> {
    if from.is_dir() {
        fs_err::create_dir_all(to).map_err(io_err("create", to))?;
        for e in fs_err::read_dir(from).map_err(io_err("list", from))? {
            let e = e.map_err(io_err("list", from))?;
            copy_tree(&e.path(), &to.join(e.file_name()))?;
        }
        Ok(())
    } else {
        fs_err::copy(from, to).map_err(io_err("copy", from))?;
        Ok(())
    }
}

/// Flushes every file and folder of a tree to disk, before the tree is renamed into
/// place; a file that cannot be read or synced is an error (links are left alone).
pub fn sync_tree(path: &Path) -> Result<()> {
    let meta = fs_err::symlink_metadata(path).map_err(io_err("read", path))?;
    if meta.is_dir() {
        for e in fs_err::read_dir(path).map_err(io_err("list", path))? {
            let e = e.map_err(io_err("list", path))?;
            sync_tree(&e.path())?;
        }
        sync_dir(path)
    } else if meta.is_file() {
        fs_err::File::open(path)
            .and_then(|f| f.sync_all())
            .map_err(io_err("sync", path))
    } else {
        Ok(())
    }
}

/// Flushes a folder's entries (names created, renamed or removed in it) to disk, so that
/// a rename into it survives a power loss. A file system that cannot sync folders at all
/// (`EINVAL`) is let be; any other failure is an error.
pub fn sync_dir(dir: &Path) -> Result<()> {
    let synced = fs_err::File::open(dir).and_then(|f| f.sync_all());
    match synced {
        Err(e) if e.kind() == std::io::ErrorKind::InvalidInput => Ok(()),
        r => r.map_err(io_err("sync", dir)),
    }
}

/// The folder `path` is in (`.` for a bare name).
fn parent_of(path: &Path) -> &Path {
    path.parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// True when `dir` exists and has any entry.
pub fn is_non_empty_dir(dir: &Path) -> bool {
    fs_err::read_dir(dir).is_ok_and(|mut d| d.next().is_some())
}

/// Whether `e`, or any error it comes from, is a full disk or an exhausted quota: an
/// I/O error ENOSPC or EDQUOT, or a program's message that says so (ffmpeg prints
/// `strerror`'s words). A full disk concerns a whole run, not one of its inputs.
pub fn out_of_space(e: &(dyn std::error::Error + 'static)) -> bool {
    const WORDS: [&str; 2] = ["No space left on device", "Disk quota exceeded"];
    let mut next = Some(e);
    while let Some(e) = next {
        if let Some(io) = e.downcast_ref::<std::io::Error>()
            && (matches!(
                io.kind(),
                std::io::ErrorKind::StorageFull | std::io::ErrorKind::QuotaExceeded
            ) || matches!(io.raw_os_error(), Some(28 | 122)))
        {
            return true;
        }
        let text = e.to_string();
        if WORDS.iter().any(|w| text.contains(w)) {
            return true;
        }
        next = e.source();
    }
    false
}

/// The bytes free for an unprivileged writer on the file system holding `path` (or its
/// nearest existing ancestor), when the system says.
pub fn free_bytes(path: &Path) -> Option<u64> {
    let mut p = Some(path);
    while let Some(dir) = p {
        if dir.exists() {
            let s = rustix::fs::statvfs(dir).ok()?;
            return Some(s.f_bavail.saturating_mul(s.f_frsize));
        }
        p = dir.parent();
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sync_tree_syncs_files_and_folders_and_a_failure_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let tree = dir.path().join("tree");
        fs_err::create_dir_all(tree.join("a/b")).unwrap();
        fs_err::write(tree.join("a/b/c.bin"), b"1").unwrap();
        sync_tree(&tree).unwrap();
        sync_dir(dir.path()).unwrap();
        // What cannot be read is an error, not skipped.
        let missing = tree.join("gone");
        match sync_tree(&missing) {
            Err(FormatError::Io { path, .. }) => assert_eq!(path, missing),
            other => panic!("{other:?}"),
        }
        assert!(sync_dir(&missing).is_err());
    }

    #[test]
    fn staged_files_refuse_to_replace_without_overwrite_and_publish_whole() {
        let dir = tempfile::tempdir().unwrap();
        fs_err::write(dir.path().join("old.png"), b"old").unwrap();
        let mut files = StagedFiles::begin(dir.path(), false).unwrap();
        fs_err::write(files.file("new.png").unwrap(), b"new").unwrap();
        // Nothing is visible before publish.
        assert!(!dir.path().join("new.png").exists());
        match files.file("old.png") {
            Err(FormatError::WouldReplace { path }) => assert_eq!(path, dir.path().join("old.png")),
            other => panic!("{other:?}"),
        }
        // Refused: dropped, nothing is published and no staging is left.
        drop(files);
        let names = |d: &Path| -> Vec<String> {
            let mut v: Vec<String> = fs_err::read_dir(d)
                .unwrap()
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect();
            v.sort();
            v
        };
        assert_eq!(names(dir.path()), ["old.png"]);
        // A file that appears after it was asked for is not replaced either.
        let mut files = StagedFiles::begin(dir.path(), false).unwrap();
        fs_err::write(files.file("late.png").unwrap(), b"ours").unwrap();
        fs_err::write(dir.path().join("late.png"), b"theirs").unwrap();
        assert!(matches!(
            files.publish(),
            Err(FormatError::WouldReplace { .. })
        ));
        assert_eq!(
            fs_err::read(dir.path().join("late.png")).unwrap(),
            b"theirs"
        );
        fs_err::remove_file(dir.path().join("late.png")).unwrap();
        let mut files = StagedFiles::begin(dir.path(), true).unwrap();
        fs_err::write(files.file("old.png").unwrap(), b"again").unwrap();
        fs_err::write(files.file("new.png").unwrap(), b"new").unwrap();
        files.publish().unwrap();
        assert_eq!(names(dir.path()), ["new.png", "old.png"]);
        assert_eq!(fs_err::read(dir.path().join("old.png")).unwrap(), b"again");
    }

    #[test]
    fn a_killed_atomic_write_leaves_a_temporary_that_the_next_writer_removes() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("manifest.json");
        // What a writer killed between create and rename leaves.
        let tmp = temp_file_beside(&target).unwrap();
        let (_, left) = tmp.keep().unwrap();
        let name = left.file_name().unwrap().to_string_lossy().into_owned();
        assert!(name.starts_with(".manifest.json.partial-"), "{name}");
        // Not to be touched: finished files, other dot files, folders.
        write_atomic(&target, b"{}").unwrap();
        fs_err::write(dir.path().join(".lock"), b"1").unwrap();
        fs_err::create_dir(dir.path().join(".data.partial-123")).unwrap();
        assert_eq!(remove_partial_files(dir.path()).unwrap(), 1);
        assert!(!left.exists());
        assert!(target.exists() && dir.path().join(".lock").exists());
        assert!(dir.path().join(".data.partial-123").is_dir());
        assert_eq!(remove_partial_files(&dir.path().join("absent")).unwrap(), 0);
    }
}
