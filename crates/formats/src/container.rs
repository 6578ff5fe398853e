//! Episode containers: the on-disk forms that hold one episode (a DexJoCo raw folder,
//! an MCAP teleop log), each behind one trait, [`EpisodeContainer`]: probe (is this path
//! mine?), read, write. One module per format implements it ([`crate::raw::RawFolder`],
//! [`crate::mcap::McapLog`]); [`crate::episodes`] holds the list discovery asks and the
//! rule it asks by.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use dexjoco_core::{Episode, Location, TaskSet, TaskSpec};

use crate::error::{FormatError, ProblemCode, Result};
use crate::manifest::SourceKind;

/// A container of one episode on disk.
pub trait EpisodeContainer: Sync {
    /// Its name in messages (`MCAP`, `raw`).
    fn name(&self) -> &'static str;

    /// The kind manifests record for its sources.
    fn kind(&self) -> SourceKind;

    /// The extension of its episode files (`mcap`); `None` when an episode is a folder.
    fn extension(&self) -> Option<&'static str>;

    /// Whether `path`, met while searching a folder, is one episode of this container
    /// (see [`crate::episodes`] for when discovery asks).
    fn probe(&self, path: &Path) -> bool;

    /// Reads the episode at `path`; its task must be one of `tasks`.
    fn read(&self, path: &Path, tasks: &TaskSet, options: ReadOptions<'_>) -> Result<ReadEpisode>;

    /// Writes `episode` (of `task`) at `path`, with the metadata the container has a
    /// place for.
    fn write(
        &self,
        path: &Path,
        episode: &Episode,
        task: &TaskSpec,
        meta: &EpisodeMeta,
    ) -> Result<()>;
}

/// The error of an episode whose task `id` is not one of `tasks`: it names the known ones
/// and how a task of one's own becomes known (`--tasks-dir`, which every command that
/// reads episodes takes).
pub(crate) fn unknown_task(at: &Location, id: &str, tasks: &TaskSet) -> FormatError {
    FormatError::input(
        ProblemCode::UnknownTask,
        at,
        format!(
            "unknown task '{id}' (known: {}); for a task of your own, pass the folder \
             holding its spec, {id}.toml, with --tasks-dir",
            tasks.ids().join(", ")
        ),
    )
}

/// An episode read from a container, with what reading it noted.
#[derive(Debug, Clone)]
pub struct ReadEpisode {
    /// The episode.
    pub episode: Episode,
    /// Files under the raw folder's `videos/`, relative to it (none for MCAP).
    pub videos: Vec<PathBuf>,
    /// Normalisations applied and things not carried over.
    pub notes: Vec<String>,
}

/// How to read a source beyond the default rule.
#[derive(Debug, Clone, Copy, Default)]
pub struct ReadOptions<'a> {
    /// The task of raw folders, whatever their path or entry says (`ingest --task`).
    pub task: Option<&'a str>,
    /// The MCAP file's bytes, when the caller has already read them.
    pub bytes: Option<&'a [u8]>,
}

/// Episode metadata beyond the arrays and the instruction (MCAP keeps it in its
/// `dexjoco.episode` record; the raw layout has no place for it).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct EpisodeMeta {
    /// Operator, when known.
    pub operator: Option<String>,
    /// Recording date, when known.
    pub date: Option<String>,
    /// Where the episode came from.
    pub source: Option<String>,
    /// Other keys of the record, carried unchanged.
    pub extra: BTreeMap<String, String>,
}
