//! What the health section reads beside an episode's arrays: its folder's replay record
//! (`replay.json`) and the bytes of its videos, and the content digests duplicates are
//! found by.

use std::io::Read as _;
use std::path::Path;

use dexjoco_core::Episode;
use dexjoco_formats::raw::{REPLAY_RECORD, ReplayLabel, read_replay_label};
use sha2::{Digest, Sha256};

use crate::error::StatsError;

/// What an episode's folder holds beside its arrays.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct EpisodeFiles {
    /// The replay record (`None`: a recording, or a source that is not a folder).
    pub label: Option<ReplayLabel>,
    /// SHA-256 (hex) of the episode's video files, camera by camera in the episode's
    /// camera order (name and bytes); `None` when it has no video file.
    pub videos_sha256: Option<String>,
    /// Where each of its task's subtasks ran, from its folder's replay, plan or eval
    /// record ([`dexjoco_formats::raw::read_subtask_spans`]).
    pub subtasks: Option<Vec<dexjoco_core::SubtaskSpan>>,
}

fn hex(digest: &[u8]) -> String {
    use std::fmt::Write as _;
    digest.iter().fold(String::new(), |mut s, b| {
        let _ = write!(s, "{b:02x}");
        s
    })
}

impl EpisodeFiles {
    /// Reads the replay record and hashes the videos of `episode`, read from `path` (an
    /// episode folder; a file, e.g. MCAP, has neither; videos not in the folder are
    /// left out of the digest). Fails naming the file when the record is unreadable or
    /// a video cannot be read.
    pub fn read(path: &Path, episode: &Episode) -> Result<Self, StatsError> {
        if !path.is_dir() {
            return Ok(Self::default());
        }
        let label = read_replay_label(path).map_err(|e| StatsError::Invalid {
            path: path.join(REPLAY_RECORD),
            row: None,
            message: e.to_string(),
        })?;
        let mut hasher = Sha256::new();
        let mut any = false;
        let mut buf = vec![0u8; 1 << 16];
        for c in &episode.cameras {
            let Some(video) = &c.video else { continue };
            let file = path.join(video);
            if !file.is_file() {
                // Not stored beside the arrays (the reader names missing videos itself).
                continue;
            }
            let mut f = fs_err::File::open(&file)?;
            hasher.update(c.name.as_bytes());
            hasher.update([0]);
            loop {
                let n = f.read(&mut buf)?;
                if n == 0 {
                    break;
                }
                hasher.update(&buf[..n]);
            }
            any = true;
        }
        Ok(Self {
            label,
            videos_sha256: any.then(|| hex(&hasher.finalize())),
            subtasks: dexjoco_formats::raw::read_subtask_spans(path),
        })
    }
}

/// SHA-256 (hex) of an episode's arrays: each array's name, width, frame count and
/// values (little-endian f64 bits), in name order. Task, id and prompt are not in it.
pub fn arrays_sha256(episode: &Episode) -> String {
    let mut h = Sha256::new();
    for (name, a) in &episode.arrays {
        h.update(name.as_bytes());
        h.update([0]);
        h.update((a.width() as u64).to_le_bytes());
        h.update((a.len() as u64).to_le_bytes());
        let bytes: Vec<u8> = a.as_slice().iter().flat_map(|v| v.to_le_bytes()).collect();
        h.update(&bytes);
    }
    hex(&h.finalize())
}
