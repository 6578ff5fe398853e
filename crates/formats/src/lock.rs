//! One writer per output folder: `<dir>/.lock` names the process that writes the folder.
//! A lock left by a process that no longer exists (killed) is taken over.

use std::path::{Path, PathBuf};

use crate::error::{FormatError, Result, io_err};

/// File name of a folder's lock.
pub const LOCK_FILE: &str = ".lock";

/// Exclusive use of a folder by this process, released on drop.
#[derive(Debug)]
pub struct DirLock {
    path: PathBuf,
}

impl DirLock {
    /// Takes the lock of `dir` (which must exist), or fails with
    /// [`FormatError::Locked`] naming the process that holds it.
    pub fn acquire(dir: &Path) -> Result<Self> {
        use std::io::Write;
        let path = dir.join(LOCK_FILE);
        for _ in 0..3 {
            match fs_err::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&path)
            {
                Ok(mut f) => {
                    write!(f, "{}", std::process::id()).map_err(io_err("write", &path))?;
                    return Ok(Self { path });
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                    let owner = fs_err::read_to_string(&path)
                        .ok()
                        .and_then(|s| s.trim().parse::<u32>().ok());
                    match owner {
                        Some(pid) if process_exists(pid) => {
                            return Err(FormatError::Locked {
                                path: dir.to_owned(),
                                pid,
                            });
                        }
                        _ => {
                            tracing::info!("taking over the lock of a process that has ended");
                            let _ = fs_err::remove_file(&path);
                        }
                    }
                }
                Err(e) => return Err(io_err("create", &path)(e)),
            }
        }
        Err(FormatError::Locked {
            path: dir.to_owned(),
            pid: 0,
        })
    }
}

impl Drop for DirLock {
    fn drop(&mut self) {
        let _ = fs_err::remove_file(&self.path);
    }
}

/// Whether a process exists (Linux: /proc; elsewhere assumed alive, so a stale lock must
/// be removed by hand).
fn process_exists(pid: u32) -> bool {
    let proc = Path::new("/proc");
    !proc.is_dir() || proc.join(pid.to_string()).exists()
}
