//! What the store needs of an input besides reading it: its content hash (the id), the
//! problems named after it, and a quarantined copy kept when a new one cannot be made.

use std::io::Read;
use std::path::Path;

use dexjoco_formats::episodes::Source;
use dexjoco_formats::error::io_err;
use dexjoco_formats::manifest::SourceKind;
use dexjoco_formats::{Problem, raw};
use sha2::{Digest, Sha256};

use crate::error::Result;

/// A quarantine folder being replaced whose new copy of the input could not be made
/// (the input is gone or unreadable) keeps the copy made by an earlier run.
pub(crate) fn keep_quarantined_copy(staged: &Path, old: &Path) -> Result<()> {
    let (new_copy, old_copy) = (staged.join("source"), old.join("source"));
    if !dexjoco_formats::fs::is_non_empty_dir(&new_copy) && old_copy.is_dir() {
        if new_copy.exists() {
            fs_err::remove_dir_all(&new_copy).map_err(io_err("remove", &new_copy))?;
        }
        fs_err::rename(&old_copy, &new_copy).map_err(io_err("rename", &old_copy))?;
    }
    Ok(())
}

/// `sha256` hex of a source and its size; MCAP files' bytes are returned for reading.
pub(crate) fn hash_source(source: &Source) -> Result<(String, u64, Option<Vec<u8>>)> {
    match source.kind {
        SourceKind::Mcap => {
            let bytes = fs_err::read(&source.path).map_err(io_err("read", &source.path))?;
            let hash = hex(&Sha256::digest(&bytes));
            Ok((hash, bytes.len() as u64, Some(bytes)))
        }
        SourceKind::Raw => {
            let files = raw::list_files(&source.path, Path::new(""))?;
            let mut h = Sha256::new();
            let mut total = 0u64;
            let mut buf = vec![0u8; 1 << 16];
            for rel in files {
                let p = source.path.join(&rel);
                let mut f = fs_err::File::open(&p).map_err(io_err("read", &p))?;
                let name = rel.to_string_lossy();
                h.update((name.len() as u64).to_le_bytes());
                h.update(name.as_bytes());
                let len = f.metadata().map_err(io_err("read", &p))?.len();
                h.update(len.to_le_bytes());
                loop {
                    let n = f.read(&mut buf).map_err(io_err("read", &p))?;
                    if n == 0 {
                        break;
                    }
                    h.update(&buf[..n]);
                    total += n as u64;
                }
            }
            Ok((hex(&h.finalize()), total, None))
        }
    }
}

/// Every problem names the input and the episode id, also where the reader could not.
pub(crate) fn name_problems(mut problems: Vec<Problem>, source: &Path, id: &str) -> Vec<Problem> {
    for p in &mut problems {
        if p.file.as_deref() != Some(source) {
            if let Some(inner) = p.file.take().filter(|f| f != source) {
                p.message = format!("{} (in '{}')", p.message, inner.display());
            }
            p.file = Some(source.to_owned());
        }
        if p.episode.is_none() {
            p.episode = Some(id.to_owned());
        }
    }
    problems
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

pub(crate) fn hex16(bytes: &[u8]) -> String {
    hex(&bytes[..8])
}
