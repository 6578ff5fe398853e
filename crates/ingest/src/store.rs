//! The canonical episode store (the DexJoCo raw layout plus a manifest) and the ingest
//! pipeline: discover inputs, read and validate them in parallel, land the good episodes
//! atomically and quarantine the rest with their reasons.
//!
//! Store layout:
//! ```text
//! <store>/manifest.json                       every episode and rejected input, with problems
//! <store>/<task>/episode_000000/replay.zarr   the DexJoCo raw layout
//! <store>/<task>/episode_000000/videos/       copied from the source folder
//! <store>/<task>/episode_000000/.dexjoco-ingest.json   this episode's manifest entry
//! <store>/quarantine/<id>/reason.json         a rejected input's manifest entry
//! <store>/quarantine/<id>/source/...          a copy of the rejected input
//! <store>/.staging/<n>/                       work in progress, one folder per input of
//!                                             the run (removed on open)
//! <store>/.lock                               the pid of the process using the store
//! ```
//! An episode is written whole under `.staging/` and renamed into place, so a store never
//! holds half an episode. Each landed folder carries its own manifest entry, so an
//! interrupted run's manifest is rebuilt on the next open. Ids are the first 16 hex
//! digits of the SHA-256 of the input's bytes, so re-running on the same input skips it;
//! of several inputs with the same content in one run, the first in input order lands and
//! the others are named duplicates, whatever the thread timing.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use dexjoco_core::{Location, Progress, TaskSet};
use dexjoco_formats::error::io_err;
use dexjoco_formats::fs::{self as fs_replace, copy_tree, replace_dir, write_atomic};
use dexjoco_formats::manifest::{ENTRY_FILE, MANIFEST, Manifest, ManifestEntry, Status};
use dexjoco_formats::{DirLock, FormatError, ProblemCode, raw};
use dexjoco_formats::{ReadOptions, Source};
use rayon::prelude::*;
use sha2::{Digest, Sha256};

use crate::input::{hash_source, hex16, keep_quarantined_copy, name_problems};

use crate::error::{IngestError, Result};

mod report;

use dexjoco_formats::validate::{ValidationOptions, validate};
pub use report::{IngestSummary, Outcome, SourceReport};
use report::{duplicate_report, recheck_failed_report};

/// Folder of rejected inputs.
pub const QUARANTINE: &str = "quarantine";
/// Folder of work in progress.
pub const STAGING: &str = ".staging";
/// A quarantined input's manifest entry.
pub const REASON_FILE: &str = "reason.json";

/// Options of an ingest run.
#[derive(Debug, Clone)]
pub struct IngestOptions {
    /// Re-read and rewrite inputs already in the store (same folders, same ids).
    pub force: bool,
    /// The task of every raw folder, whatever its path says.
    pub task: Option<String>,
    /// Validation tolerances.
    pub validation: ValidationOptions,
    /// The known tasks (default: the built-in specs).
    pub tasks: TaskSet,
}

impl Default for IngestOptions {
    fn default() -> Self {
        Self {
            force: false,
            task: None,
            validation: ValidationOptions::default(),
            tasks: TaskSet::builtin().clone(),
        }
    }
}

/// A store of episodes in the DexJoCo raw layout with its manifest.
#[derive(Debug)]
pub struct Store {
    root: PathBuf,
    manifest: Manifest,
    _lock: DirLock,
}

/// A source read, checked and written to staging, waiting to be committed.
struct Prepared {
    source: Source,
    entry: ManifestEntry,
    /// The staged folder to rename into place (None: nothing to move).
    staged: Option<PathBuf>,
    outcome: Outcome,
    bytes: u64,
    /// A failure of the store itself (not of the input): stops the run.
    fatal: Option<IngestError>,
}

/// Why staging an input failed: the input is bad, or the store could not be written.
enum StageFailure {
    Input(IngestError),
    Store(IngestError),
}

impl From<IngestError> for StageFailure {
    fn from(e: IngestError) -> Self {
        Self::Input(e)
    }
}

impl From<FormatError> for StageFailure {
    fn from(e: FormatError) -> Self {
        Self::Input(e.into())
    }
}

/// A failure to write the store (not a problem of the input).
fn store_failure(e: FormatError) -> StageFailure {
    StageFailure::Store(e.into())
}

impl Store {
    /// Opens (creating) a store; clears work left in `.staging/` by an interrupted run
    /// and re-adds to the manifest any landed or quarantined folder it lacks.
    pub fn open(root: impl Into<PathBuf>) -> Result<Self> {
        let root = root.into();
        fs_err::create_dir_all(&root).map_err(io_err("create", &root))?;
        let lock = DirLock::acquire(&root)?;
        // The store is written into where it is: no link in it may lead elsewhere.
        dexjoco_formats::fs::refuse_links_within(&root)?;
        // A run killed while replacing a folder (under force) left its old copy aside;
        // one killed in an atomic write (the manifest) left its temporary file.
        fs_replace::recover_replaced_in(&root)?;
        fs_replace::remove_partial_files(&root)?;
        for e in fs_err::read_dir(&root)
            .map_err(io_err("list", &root))?
            .flatten()
        {
            if e.path().is_dir() && !e.file_name().to_string_lossy().starts_with('.') {
                fs_replace::recover_replaced_in(&e.path())?;
            }
        }
        let staging = root.join(STAGING);
        if staging.exists() {
            fs_err::remove_dir_all(&staging).map_err(io_err("remove", &staging))?;
        }
        let mut manifest = if root.join(MANIFEST).exists() {
            Manifest::read(&root)?
        } else {
            Manifest::default()
        };
        let mut recovered = 0;
        for entry_file in Self::entry_files(&root)? {
            let Ok(bytes) = fs_err::read(&entry_file) else {
                continue;
            };
            let Ok(entry) = serde_json::from_slice::<ManifestEntry>(&bytes) else {
                continue;
            };
            if manifest.get(&entry.id) != Some(&entry) {
                manifest.upsert(entry);
                recovered += 1;
            }
        }
        let mut store = Self {
            root,
            manifest,
            _lock: lock,
        };
        if recovered > 0 {
            tracing::info!(
                recovered,
                "manifest: re-added entries of an interrupted run"
            );
            store.save_manifest()?;
        }
        Ok(store)
    }

    fn entry_files(root: &Path) -> Result<Vec<PathBuf>> {
        let mut out = Vec::new();
        for e in fs_err::read_dir(root)
            .map_err(io_err("list", root))?
            .flatten()
        {
            let name = e.file_name();
            if name.to_string_lossy().starts_with('.') || !e.path().is_dir() {
                continue;
            }
            let file = if name == QUARANTINE {
                REASON_FILE
            } else {
                ENTRY_FILE
            };
            let Ok(rd) = fs_err::read_dir(e.path()) else {
                continue;
            };
            for sub in rd.flatten() {
                if sub.file_name().to_string_lossy().starts_with('.') {
                    continue;
                }
                let f = sub.path().join(file);
                if f.is_file() {
                    out.push(f);
                }
            }
        }
        out.sort();
        Ok(out)
    }

    /// The store folder.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// The manifest.
    pub fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    fn save_manifest(&mut self) -> Result<()> {
        self.manifest.sort();
        let json = serde_json::to_vec_pretty(&self.manifest).expect("manifest serializes");
        Ok(write_atomic(&self.root.join(MANIFEST), &json)?)
    }

    /// Ingests `sources` (in parallel over the current rayon pool), landing valid
    /// episodes and quarantining the rest. A bad input never stops the run.
    pub fn ingest(
        &mut self,
        sources: &[Source],
        opts: &IngestOptions,
        progress: &dyn Progress,
    ) -> Result<IngestSummary> {
        let t0 = Instant::now();
        progress.start(sources.len() as u64);
        let staging = self.root.join(STAGING);
        fs_err::create_dir_all(&staging).map_err(io_err("create", &staging))?;
        let mut next_index = self.scan_indices(&opts.tasks)?;
        let mut summary = IngestSummary::default();
        let mut seen: HashMap<String, PathBuf> = HashMap::new();
        // Batches keep memory bounded and commit in input order, so indices do not
        // depend on thread timing; each batch is durable before the next starts.
        let batch = (rayon::current_num_threads() * 4).max(8);
        for (b, chunk) in sources.chunks(batch).enumerate() {
            let prepared: Vec<Prepared> = chunk
                .par_iter()
                .enumerate()
                .map(|(i, s)| {
                    // Each input is staged in a folder of its own (its position in the
                    // run): inputs of the same content never share one. Which of them
                    // lands is decided at commit, in input order.
                    let slot = staging.join(format!("{:06}", b * batch + i));
                    let p = self.prepare(s, opts, &slot);
                    progress.advance(1, &s.path.display().to_string());
                    p
                })
                .collect();
            for p in prepared {
                summary.bytes_read += p.bytes;
                let report = self.commit(p, &mut next_index, &mut seen, opts)?;
                summary.sources.push(report);
            }
            self.save_manifest()?;
        }
        let _ = fs_err::remove_dir_all(&staging);
        summary.seconds = t0.elapsed().as_secs_f64();
        Ok(summary)
    }

    /// The next free episode index of every task folder.
    fn scan_indices(&self, tasks: &TaskSet) -> Result<HashMap<String, usize>> {
        let mut next = HashMap::new();
        for e in fs_err::read_dir(&self.root)
            .map_err(io_err("list", &self.root))?
            .flatten()
        {
            let Some(task) = e.file_name().to_str().map(str::to_owned) else {
                continue;
            };
            if !tasks.contains(&task) || !e.path().is_dir() {
                continue;
            }
            let mut max = 0;
            for ep in fs_err::read_dir(e.path()).into_iter().flatten().flatten() {
                if let Some(n) = ep
                    .file_name()
                    .to_str()
                    .and_then(|n| n.strip_prefix("episode_"))
                    .and_then(|n| n.parse::<usize>().ok())
                {
                    max = max.max(n + 1);
                }
            }
            next.insert(task, max);
        }
        Ok(next)
    }

    /// Reads, checks and stages `source` in `slot` (a staging folder of its own).
    fn prepare(&self, source: &Source, opts: &IngestOptions, slot: &Path) -> Prepared {
        let (hash, bytes, content) = match hash_source(source) {
            Ok(x) => x,
            Err(e) => {
                // Unreadable: the id comes from the path, so a re-run finds the same entry.
                let id = hex16(&Sha256::digest(source.path.to_string_lossy().as_bytes()));
                if let Some(prev) = self.manifest.get(&id).filter(|_| !opts.force) {
                    return Prepared {
                        source: source.clone(),
                        entry: prev.clone(),
                        staged: None,
                        outcome: Outcome::Quarantined,
                        bytes: 0,
                        fatal: None,
                    };
                }
                let entry = ManifestEntry {
                    id: id.clone(),
                    task: None,
                    source: source.path.clone(),
                    source_kind: source.kind,
                    source_hash: String::new(),
                    length: 0,
                    status: Status::Quarantined,
                    path: Path::new(QUARANTINE).join(&id),
                    problems: name_problems(e.problems(), &source.path, &id),
                    notes: Vec::new(),
                };
                return self.quarantine(source, entry, slot, 0);
            }
        };
        let id = hash[..16].to_owned();
        if let Some(prev) = self.manifest.get(&id) {
            let present = self.root.join(&prev.path).is_dir();
            if present && !opts.force {
                return Prepared {
                    source: source.clone(),
                    entry: prev.clone(),
                    staged: None,
                    outcome: match prev.status {
                        Status::Ok => Outcome::AlreadyPresent,
                        Status::Quarantined => Outcome::Quarantined,
                    },
                    bytes,
                    fatal: None,
                };
            }
        }
        let mut entry = ManifestEntry {
            id: id.clone(),
            task: None,
            source: source.path.clone(),
            source_kind: source.kind,
            source_hash: format!("sha256:{hash}"),
            length: 0,
            status: Status::Ok,
            path: PathBuf::new(),
            problems: Vec::new(),
            notes: Vec::new(),
        };
        match self.read_and_stage(source, content, opts, slot, &mut entry) {
            Ok(staged) => Prepared {
                source: source.clone(),
                entry,
                staged: Some(staged),
                outcome: Outcome::Landed,
                bytes,
                fatal: None,
            },
            Err(StageFailure::Store(e)) => Prepared {
                source: source.clone(),
                entry,
                staged: None,
                outcome: Outcome::Landed,
                bytes,
                fatal: Some(e),
            },
            Err(StageFailure::Input(e)) => {
                entry.problems = name_problems(e.problems(), &source.path, &id);
                entry.status = Status::Quarantined;
                entry.path = Path::new(QUARANTINE).join(&id);
                self.quarantine(source, entry, slot, bytes)
            }
        }
    }

    fn read_and_stage(
        &self,
        source: &Source,
        content: Option<Vec<u8>>,
        opts: &IngestOptions,
        slot: &Path,
        entry: &mut ManifestEntry,
    ) -> std::result::Result<PathBuf, StageFailure> {
        let read = source.read_with(
            &opts.tasks,
            ReadOptions {
                task: opts.task.as_deref(),
                bytes: content.as_deref(),
            },
        )?;
        let (mut ep, videos) = (read.episode, read.videos);
        ep.id = entry.id.clone();
        entry.task = Some(ep.task.clone());
        entry.length = ep.len();
        entry.notes = read.notes;
        let task = opts.tasks.get(&ep.task).ok_or_else(|| {
            IngestError::input(
                ProblemCode::UnknownTask,
                &Location::default().path(&source.path),
                format!("unknown task '{}'", ep.task),
            )
        })?;
        let problems = validate(&ep, task, &source.path, &opts.validation);
        if !problems.is_empty() {
            return Err(StageFailure::Input(IngestError::Invalid(problems)));
        }
        let dir = slot.join(&entry.id);
        if dir.exists() {
            fs_err::remove_dir_all(&dir)
                .map_err(io_err("remove", &dir))
                .map_err(store_failure)?;
        }
        raw::write_raw_episode(&dir, &ep, task).map_err(store_failure)?;
        for v in &videos {
            let to = dir.join(v);
            if let Some(parent) = to.parent() {
                fs_err::create_dir_all(parent).map_err(io_err("create", parent))?;
            }
            fs_err::copy(source.path.join(v), &to).map_err(io_err("copy", source.path.join(v)))?;
        }
        Ok(dir)
    }

    /// Copies a rejected input and its reason into its staging `slot`, to be renamed under
    /// `quarantine/<id>/` on commit.
    fn quarantine(
        &self,
        source: &Source,
        mut entry: ManifestEntry,
        slot: &Path,
        bytes: u64,
    ) -> Prepared {
        tracing::warn!(
            source = %source.path.display(),
            "rejected: {}",
            entry.problems.first().map(ToString::to_string).unwrap_or_default()
        );
        let dir = slot.join(format!("q-{}", entry.id));
        let _ = fs_err::remove_dir_all(&dir);
        let copied = (|| -> dexjoco_formats::Result<()> {
            let dest = dir.join("source");
            fs_err::create_dir_all(&dest).map_err(io_err("create", &dest))?;
            let name = source
                .path
                .file_name()
                .map_or_else(|| "input".into(), |n| n.to_owned());
            copy_tree(&source.path, &dest.join(name))
        })();
        if let Err(e) = copied {
            entry.notes.push(format!(
                "the input could not be copied into quarantine: {e}"
            ));
        }
        let staged = match write_atomic(
            &dir.join(REASON_FILE),
            &serde_json::to_vec_pretty(&entry).expect("entry serializes"),
        ) {
            Ok(()) => Some(dir),
            Err(e) => {
                entry
                    .notes
                    .push(format!("the quarantine folder could not be written: {e}"));
                None
            }
        };
        Prepared {
            source: source.clone(),
            entry,
            staged,
            outcome: Outcome::Quarantined,
            bytes,
            fatal: None,
        }
    }

    /// Moves a prepared source into the store (or reports why not) and records it in
    /// the manifest.
    fn commit(
        &mut self,
        p: Prepared,
        next_index: &mut HashMap<String, usize>,
        seen: &mut HashMap<String, PathBuf>,
        opts: &IngestOptions,
    ) -> Result<SourceReport> {
        let Prepared {
            source,
            mut entry,
            staged,
            mut outcome,
            bytes: _,
            fatal,
        } = p;
        if let Some(e) = fatal {
            return Err(e);
        }
        if let Some(first) = seen.get(&entry.id) {
            return Ok(duplicate_report(source, entry, staged.as_deref(), first));
        }
        seen.insert(entry.id.clone(), source.path.clone());
        let previous = self.manifest.get(&entry.id).cloned();
        if let Some(prev) = previous.as_ref().filter(|prev| {
            prev.status == Status::Ok
                && entry.status == Status::Quarantined
                && self.root.join(&prev.path).is_dir()
        }) {
            return Ok(recheck_failed_report(
                source,
                entry,
                staged.as_deref(),
                prev,
            ));
        }
        let replaced = match staged {
            Some(staged) => {
                self.move_into_place(&staged, &mut entry, previous, next_index, opts.force)?
            }
            None => false,
        };
        if replaced {
            outcome = Outcome::Replaced;
        }
        self.manifest.upsert(entry.clone());
        Ok(SourceReport {
            source: source.path,
            id: entry.id,
            outcome,
            path: entry.path,
            problems: entry.problems,
            notes: entry.notes,
        })
    }

    /// Renames a staged folder into place: a landed episode at its folder (the one it had
    /// under `force`, else its task's next index), a rejected input under quarantine.
    /// Returns whether a stored episode was replaced.
    fn move_into_place(
        &self,
        staged: &Path,
        entry: &mut ManifestEntry,
        previous: Option<ManifestEntry>,
        next_index: &mut HashMap<String, usize>,
        force: bool,
    ) -> Result<bool> {
        let mut replaced = false;
        if entry.status == Status::Ok {
            // Force re-uses the episode's folder; otherwise the task's next index.
            let reuse = previous
                .as_ref()
                .filter(|prev| prev.status == Status::Ok && force)
                .map(|prev| prev.path.clone());
            replaced = reuse.is_some();
            let task = entry.task.clone().unwrap_or_default();
            entry.path = reuse.unwrap_or_else(|| {
                let n = next_index.entry(task.clone()).or_insert(0);
                let path = Path::new(&task).join(format!("episode_{:06}", *n));
                *n += 1;
                path
            });
            write_atomic(
                &staged.join(ENTRY_FILE),
                &serde_json::to_vec_pretty(&entry).expect("entry serializes"),
            )?;
        }
        if entry.status == Status::Quarantined {
            keep_quarantined_copy(staged, &self.root.join(&entry.path))?;
        }
        if let Some(prev) = previous.filter(|prev| prev.path != entry.path) {
            // A quarantined input that now passes (or the reverse, under force).
            let old = self.root.join(&prev.path);
            if old.exists() {
                fs_err::remove_dir_all(&old).map_err(io_err("remove", &old))?;
            }
        }
        replace_dir(staged, &self.root.join(&entry.path))?;
        Ok(replaced)
    }
}
