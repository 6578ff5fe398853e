//! The episode store's manifest (`manifest.json`, written by `ingest`), as a file format:
//! every landed episode and rejected input with its source, hash, length, status,
//! problems and notes. Each landed episode folder also carries its own entry
//! (`.dexjoco-ingest.json`), so a store read by another stage knows each episode's id and
//! task without the manifest, and an interrupted ingest can rebuild it.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{FormatError, Problem, Result, io_err};

/// File name of a store's manifest.
pub const MANIFEST: &str = "manifest.json";
/// A landed episode's own manifest entry, inside its folder.
pub const ENTRY_FILE: &str = ".dexjoco-ingest.json";
/// Format name written in manifests.
pub const MANIFEST_FORMAT: &str = "dexjoco-data/ingest-manifest";
/// Manifest format version.
pub const MANIFEST_VERSION: u32 = 1;

/// What kind of input a source is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SourceKind {
    /// A DexJoCo raw episode folder (holding `replay.zarr`).
    Raw,
    /// An MCAP teleop log (one episode).
    Mcap,
}

/// Whether an entry's episode landed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Stored and valid.
    Ok,
    /// Rejected; the input is copied under `quarantine/<id>/`.
    Quarantined,
}

/// One episode (or rejected input) of a store.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ManifestEntry {
    /// Stable id: the first 16 hex digits of the input's SHA-256.
    pub id: String,
    /// Task id, when known.
    pub task: Option<String>,
    /// The input file or folder, as given.
    pub source: PathBuf,
    /// The input's kind.
    pub source_kind: SourceKind,
    /// `sha256:<hex>` of the input's bytes (folders: of every file's path and bytes).
    pub source_hash: String,
    /// Frames (0 when the input could not be read).
    pub length: usize,
    /// Landed or quarantined.
    pub status: Status,
    /// The episode folder (or quarantine folder), relative to the store.
    pub path: PathBuf,
    /// Why it was rejected (empty when landed).
    #[serde(default)]
    pub problems: Vec<Problem>,
    /// What reading changed or left out.
    #[serde(default)]
    pub notes: Vec<String>,
}

impl ManifestEntry {
    /// The entry a landed episode folder carries (`<dir>/.dexjoco-ingest.json`), if any.
    pub fn of_episode_dir(dir: &Path) -> Option<Self> {
        let bytes = fs_err::read(dir.join(ENTRY_FILE)).ok()?;
        serde_json::from_slice(&bytes).ok()
    }
}

/// A store's manifest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// Always [`MANIFEST_FORMAT`].
    pub format: String,
    /// Always [`MANIFEST_VERSION`].
    pub version: u32,
    /// Every entry, landed first in (task, path) order, then quarantined by id.
    pub episodes: Vec<ManifestEntry>,
}

impl Default for Manifest {
    fn default() -> Self {
        Self {
            format: MANIFEST_FORMAT.into(),
            version: MANIFEST_VERSION,
            episodes: Vec::new(),
        }
    }
}

impl Manifest {
    /// Reads `<store>/manifest.json`.
    pub fn read(store: &Path) -> Result<Self> {
        let path = store.join(MANIFEST);
        let bytes = fs_err::read(&path).map_err(io_err("read", &path))?;
        serde_json::from_slice(&bytes).map_err(|e| FormatError::Manifest {
            path,
            message: e.to_string(),
        })
    }

    /// The entry with this id.
    pub fn get(&self, id: &str) -> Option<&ManifestEntry> {
        self.episodes.iter().find(|e| e.id == id)
    }

    /// Adds an entry, or replaces the one with the same id.
    pub fn upsert(&mut self, entry: ManifestEntry) {
        match self.episodes.iter_mut().find(|e| e.id == entry.id) {
            Some(e) => *e = entry,
            None => self.episodes.push(entry),
        }
    }

    /// Puts the entries in manifest order: landed first by (task, path), then the rest.
    pub fn sort(&mut self) {
        self.episodes.sort_by(|a, b| {
            (a.status != Status::Ok, &a.task, &a.path, &a.id).cmp(&(
                b.status != Status::Ok,
                &b.task,
                &b.path,
                &b.id,
            ))
        });
    }

    /// The landed episodes' folders under `store`, in manifest order. A recorded path
    /// that would leave the store (absolute, or with a `..` or a name that is not a safe
    /// file name: [`dexjoco_core::safe_name`]) is not followed: a manifest names folders
    /// of its own store only.
    pub fn landed_dirs(&self, store: &Path) -> Vec<PathBuf> {
        self.episodes
            .iter()
            .filter(|e| e.status == Status::Ok && within_store(&e.path))
            .map(|e| store.join(&e.path))
            .collect()
    }

    /// Per-task counts of the landed episodes.
    pub fn landed_by_task(&self) -> BTreeMap<String, usize> {
        let mut m = BTreeMap::new();
        for e in self.episodes.iter().filter(|e| e.status == Status::Ok) {
            *m.entry(e.task.clone().unwrap_or_default()).or_default() += 1;
        }
        m
    }
}

/// Whether a path a manifest records stays inside its store: relative, each component a
/// safe file name.
fn within_store(path: &Path) -> bool {
    path.components().all(|c| match c {
        std::path::Component::Normal(n) => n
            .to_str()
            .is_some_and(|n| dexjoco_core::safe_name("store path", n).is_ok()),
        _ => false,
    }) && path.components().next().is_some()
}
