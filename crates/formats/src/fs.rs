//! File-system primitives every writer uses: atomic file writes (temporary file in the
//! same folder, synced, renamed), whole-folder replacement, tree copies and syncs.
//!
//! A reader never sees half a file or half a folder written through these: a file
//! appears complete under its name or not at all, and a replaced folder is either the
//! old one or the new one, whole.

use std::io::Write;
use std::path::Path;

use crate::error::{FormatError, Result, io_err};

/// Writes a file atomically: a temporary file in the same folder, synced, renamed.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = path.parent().unwrap_or(Path::new("."));
    fs_err::create_dir_all(dir).map_err(io_err("create", dir))?;
    let mut tmp =
        tempfile::NamedTempFile::new_in(dir).map_err(io_err("create a temporary file in", dir))?;
    tmp.write_all(bytes).map_err(io_err("write", tmp.path()))?;
    persist_synced(tmp, path)
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
    Ok(())
}

/// Moves a staged folder to `to`, replacing what is there (the old copy is moved aside
/// first, so `to` is always either the old or the new folder, whole).
pub fn replace_dir(staged: &Path, to: &Path) -> Result<()> {
    if let Some(parent) = to.parent() {
        fs_err::create_dir_all(parent).map_err(io_err("create", parent))?;
    }
    if to.exists() {
        let aside = staged.with_extension("old");
        if aside.exists() {
            fs_err::remove_dir_all(&aside).map_err(io_err("remove", &aside))?;
        }
        fs_err::rename(to, &aside).map_err(io_err("rename", to))?;
        fs_err::rename(staged, to).map_err(io_err("rename", staged))?;
        // The replacement is done; a left-over old copy is removed by the next replace.
        let _ = fs_err::remove_dir_all(&aside);
    } else {
        fs_err::rename(staged, to).map_err(io_err("rename", staged))?;
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

/// Flushes every file of a folder tree to disk (best effort), before the folder is
/// renamed into place.
pub fn sync_tree(dir: &Path) {
    if dir.is_dir() {
        if let Ok(rd) = fs_err::read_dir(dir) {
            for e in rd.flatten() {
                sync_tree(&e.path());
            }
        }
    } else if let Ok(f) = fs_err::File::open(dir) {
        let _ = f.sync_all();
    }
}

/// True when `dir` exists and has any entry.
pub fn is_non_empty_dir(dir: &Path) -> bool {
    fs_err::read_dir(dir).is_ok_and(|mut d| d.next().is_some())
}
