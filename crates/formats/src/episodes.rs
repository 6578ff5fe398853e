//! Finding and reading episodes: the one rule every command uses (`ingest`, `augment`,
//! `convert`, `stats --dataset`, `export`). Discovery asks each container of
//! [`CONTAINERS`] whether a path is its own ([`EpisodeContainer::probe`]: a raw episode
//! folder holds `replay.zarr`; an MCAP log is a file named `*.mcap`, any case) and reads
//! an episode with the container of its [`SourceKind`].
//!
//! An input path is, checked in this order:
//!
//! 1. a file: an MCAP teleop log (one episode), whatever its extension;
//! 2. a folder named `replay.zarr`: its parent, a DexJoCo raw episode folder;
//! 3. a folder a container probes as its own: one episode;
//! 4. a folder holding `manifest.json` (an episode store made by `ingest`): its landed
//!    episodes, in manifest order (its quarantine is not read);
//! 5. any other folder: searched recursively, entries in name order, by rules 3-4 for
//!    folders and the containers' probes for files. Folders whose name starts with `.`
//!    (work in progress such as `.staging/` or `.dropped/`) are not entered, linked
//!    folders are followed once, and the `exclude` folder (an output being written) is
//!    never entered.
//!
//! The same path found twice is read once. Reading an episode takes its task from, in
//! order: the caller's override, the episode folder's store entry
//! (`.dexjoco-ingest.json`), its path ([`crate::raw::task_from_path`]); an MCAP log
//! names its task in its metadata. Its id is the store entry's id, else the folder name;
//! for MCAP, the recorded id, else the file stem. Its prompt is its own instruction (a
//! raw folder's `replay.zarr/.zattrs` attribute `instruction`, an MCAP log's `prompt`),
//! else its task's.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use dexjoco_core::{Episode, Location, TaskSet};

use crate::container::{EpisodeContainer, ReadEpisode, ReadOptions};
use crate::error::{FormatError, ProblemCode, Result, io_err};
use crate::manifest::{MANIFEST, Manifest, SourceKind};
use crate::mcap::McapLog;
use crate::raw::{REPLAY_ZARR, RawFolder};

/// Every episode container, in the order discovery asks them.
pub const CONTAINERS: [&dyn EpisodeContainer; 2] = [&RawFolder, &McapLog];

/// The container a path belongs to, when one probes it as its own.
fn probe(path: &Path) -> Option<&'static dyn EpisodeContainer> {
    CONTAINERS.into_iter().find(|c| c.probe(path))
}

impl SourceKind {
    /// The container of sources of this kind.
    pub fn container(self) -> &'static dyn EpisodeContainer {
        match self {
            Self::Raw => &RawFolder,
            Self::Mcap => &McapLog,
        }
    }
}

/// One episode to read: a raw episode folder or an MCAP file.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Source {
    /// The file or folder.
    pub path: PathBuf,
    /// Its kind.
    pub kind: SourceKind,
}

/// The sources under every input (see the module documentation for the rule), in input
/// order, each path once. The first input that cannot be listed fails the call.
pub fn discover(inputs: &[PathBuf], exclude: Option<&Path>) -> Result<Vec<Source>> {
    let mut out = Vec::new();
    for input in inputs {
        out.extend(discover_input(input, exclude)?);
    }
    let mut seen = HashSet::new();
    out.retain(|s| seen.insert(s.path.clone()));
    Ok(out)
}

/// The sources under one input path.
pub fn discover_input(input: &Path, exclude: Option<&Path>) -> Result<Vec<Source>> {
    let meta = fs_err::metadata(input).map_err(io_err("read", input))?;
    if !meta.is_dir() {
        return Ok(vec![Source {
            path: input.to_owned(),
            kind: SourceKind::Mcap,
        }]);
    }
    if input.file_name().is_some_and(|n| n == REPLAY_ZARR) {
        let parent = input
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .map_or_else(|| PathBuf::from("."), Path::to_path_buf);
        return Ok(vec![raw_source(parent)]);
    }
    let exclude = exclude.and_then(|e| e.canonicalize().ok());
    let mut out = Vec::new();
    walk(input, exclude.as_deref(), &mut HashSet::new(), &mut out)?;
    Ok(out)
}

fn raw_source(path: PathBuf) -> Source {
    Source {
        path,
        kind: SourceKind::Raw,
    }
}

fn walk(
    dir: &Path,
    exclude: Option<&Path>,
    visited: &mut HashSet<PathBuf>,
    out: &mut Vec<Source>,
) -> Result<()> {
    let real = dir.canonicalize().map_err(io_err("resolve", dir))?;
    if exclude == Some(real.as_path()) || !visited.insert(real) {
        return Ok(());
    }
    if let Some(container) = probe(dir) {
        out.push(Source {
            path: dir.to_owned(),
            kind: container.kind(),
        });
        return Ok(());
    }
    if dir.join(MANIFEST).is_file() {
        let manifest = Manifest::read(dir)?;
        out.extend(manifest.landed_dirs(dir).into_iter().map(raw_source));
        return Ok(());
    }
    let mut entries: Vec<_> = fs_err::read_dir(dir)
        .map_err(io_err("list", dir))?
        .collect::<std::io::Result<_>>()
        .map_err(io_err("list", dir))?;
    entries.sort_by_key(fs_err::DirEntry::file_name);
    for e in entries {
        let p = e.path();
        let hidden = e.file_name().to_string_lossy().starts_with('.');
        if p.is_dir() {
            if !hidden {
                walk(&p, exclude, visited, out)?;
            }
        } else if let Some(container) = probe(&p) {
            out.push(Source {
                path: p,
                kind: container.kind(),
            });
        }
    }
    Ok(())
}

impl Source {
    /// The source at `path`: a raw episode folder when it is a folder, else an MCAP file.
    pub fn at(path: impl Into<PathBuf>) -> Self {
        let path = path.into();
        let kind = if path.is_dir() {
            SourceKind::Raw
        } else {
            SourceKind::Mcap
        };
        Self { path, kind }
    }

    /// Reads the episode by the default rule (tasks from `tasks`).
    pub fn read(&self, tasks: &TaskSet) -> Result<ReadEpisode> {
        self.read_with(tasks, ReadOptions::default())
    }

    /// Reads the episode with its container; `options` can fix the task of raw folders
    /// and hand over an MCAP file's bytes. The names the episode brings (its id, task and
    /// camera names) are checked to be names, never paths ([`dexjoco_core::safe_name`]):
    /// they become folder and file names downstream.
    pub fn read_with(&self, tasks: &TaskSet, options: ReadOptions<'_>) -> Result<ReadEpisode> {
        let read = self.kind.container().read(&self.path, tasks, options)?;
        check_names(&self.path, &read.episode)?;
        Ok(read)
    }

    /// Reads the episode ([`Self::read`]) and applies the checks every command applies
    /// whichever door an episode comes in by ([`crate::validate::integrity`]: shapes
    /// against its task, finite values, frame rate, timestamps; tolerances as `ingest`'s
    /// defaults). A bad episode is an error naming file, episode, field and frame, with
    /// the count of further problems.
    pub fn read_checked(&self, tasks: &TaskSet) -> Result<ReadEpisode> {
        let read = self.read(tasks)?;
        let task = tasks.get(&read.episode.task).ok_or_else(|| {
            crate::container::unknown_task(
                &Location::default().path(&self.path).field("task"),
                &read.episode.task,
                tasks,
            )
        })?;
        let mut problems = crate::validate::integrity(
            &read.episode,
            task,
            &self.path,
            &crate::ValidationOptions::default(),
        );
        if problems.is_empty() {
            return Ok(read);
        }
        let more = problems.len() - 1;
        let mut first = problems.swap_remove(0);
        if more > 0 {
            first
                .message
                .push_str(&format!(" (and {more} more problem(s))"));
        }
        Err(FormatError::Input(Box::new(first)))
    }
}

/// The names an episode brings, each a safe file name ([`dexjoco_core::safe_name`]).
fn check_names(path: &Path, ep: &Episode) -> Result<()> {
    let at = Location::default().path(path);
    let names = [
        ("episode id", "id", ep.id.as_str()),
        ("task id", "task", &ep.task),
    ]
    .into_iter()
    .chain(
        ep.cameras
            .iter()
            .map(|c| ("camera name", "cameras", c.name.as_str())),
    );
    for (what, field, name) in names {
        dexjoco_core::safe_name(what, name).map_err(|e| {
            let mut at = at.clone().field(field);
            at.episode = (what != "episode id").then(|| ep.id.clone());
            FormatError::input(ProblemCode::UnsafeName, &at, e.to_string())
        })?;
    }
    Ok(())
}

/// Reads the one episode at `path` (a raw episode folder or an MCAP file) by the default
/// rule.
pub fn read_episode(path: &Path, tasks: &TaskSet) -> Result<Episode> {
    Ok(Source::at(path).read(tasks)?.episode)
}

/// Reads every episode under `inputs` by the default rule: (source, result) pairs in
/// discovery order, so one bad episode never hides the others.
pub fn read_all(inputs: &[PathBuf], tasks: &TaskSet) -> Result<Vec<(Source, Result<ReadEpisode>)>> {
    Ok(discover(inputs, None)?
        .into_iter()
        .map(|s| {
            let r = s.read(tasks);
            (s, r)
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::manifest::ManifestEntry;

    fn touch_raw(dir: &Path) {
        fs_err::create_dir_all(dir.join(REPLAY_ZARR)).unwrap();
    }

    #[test]
    fn one_rule_for_folders_stores_and_files() {
        let tmp = tempfile::tempdir().unwrap();
        let root = tmp.path();
        touch_raw(&root.join("b/click_mouse/episode_000001"));
        touch_raw(&root.join("b/click_mouse/episode_000000"));
        touch_raw(&root.join("b/.staging/click_mouse/episode_000002"));
        fs_err::write(root.join("a.MCAP"), b"x").unwrap();
        fs_err::write(root.join("notes.txt"), b"x").unwrap();
        // A store: only its landed episodes (not the quarantined copy) are read.
        let store = root.join("c");
        touch_raw(&store.join("quarantine/q1/source/x"));
        touch_raw(&store.join("pinch_tongs/episode_000000"));
        let mut m = Manifest::default();
        m.upsert(ManifestEntry {
            id: "0123".into(),
            task: Some("pinch_tongs".into()),
            source: "s".into(),
            source_kind: SourceKind::Raw,
            source_hash: String::new(),
            length: 1,
            status: crate::manifest::Status::Ok,
            path: "pinch_tongs/episode_000000".into(),
            problems: Vec::new(),
            notes: Vec::new(),
        });
        fs_err::write(store.join(MANIFEST), serde_json::to_vec(&m).unwrap()).unwrap();
        let found = discover(&[root.to_owned(), root.join("a.MCAP")], None).unwrap();
        let rel: Vec<_> = found
            .iter()
            .map(|s| (s.path.strip_prefix(root).unwrap().to_owned(), s.kind))
            .collect();
        assert_eq!(
            rel,
            [
                (PathBuf::from("a.MCAP"), SourceKind::Mcap),
                ("b/click_mouse/episode_000000".into(), SourceKind::Raw),
                ("b/click_mouse/episode_000001".into(), SourceKind::Raw),
                ("c/pinch_tongs/episode_000000".into(), SourceKind::Raw),
            ]
        );
        // A replay.zarr given directly is its episode folder; an excluded folder is skipped.
        let direct =
            discover_input(&root.join("b/click_mouse/episode_000000/replay.zarr"), None).unwrap();
        assert_eq!(direct[0].path, root.join("b/click_mouse/episode_000000"));
        let excl = discover(&[root.to_owned()], Some(&root.join("b"))).unwrap();
        assert_eq!(excl.len(), 2, "{excl:?}");
        assert!(discover(&[root.join("missing")], None).is_err());
    }
}
