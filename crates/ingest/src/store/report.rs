//! What an ingest run says of each source: its outcome, and the reports of the sources
//! that land nowhere (a duplicate of an earlier input, a stored episode failing its
//! re-check).

use std::path::{Path, PathBuf};

use dexjoco_core::Location;
use dexjoco_formats::manifest::{ManifestEntry, Status};
use dexjoco_formats::{Problem, ProblemCode, Source};
use serde::Serialize;

/// What happened to one source.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Stored.
    Landed,
    /// Stored again over the previous copy (`force`).
    Replaced,
    /// Already in the store; nothing done.
    AlreadyPresent,
    /// The same content appeared earlier in this run; nothing done.
    Duplicate,
    /// Rejected and quarantined (now or in an earlier run).
    Quarantined,
    /// Already stored, redone under `force`, and failed its re-check (e.g. under tighter
    /// tolerances): the stored episode is kept as it was, the problems are reported.
    RecheckFailed,
}

/// The result for one source.
#[derive(Debug, Clone, Serialize)]
pub struct SourceReport {
    /// The input.
    pub source: PathBuf,
    /// Its id.
    pub id: String,
    /// What happened.
    pub outcome: Outcome,
    /// The episode or quarantine folder, relative to the store.
    pub path: PathBuf,
    /// Why it was rejected.
    pub problems: Vec<Problem>,
    /// Notes from reading.
    pub notes: Vec<String>,
}

/// The result of a run.
#[derive(Debug, Clone, Default, Serialize)]
pub struct IngestSummary {
    /// One report per source, in input order.
    pub sources: Vec<SourceReport>,
    /// Bytes of input read.
    pub bytes_read: u64,
    /// Wall-clock seconds.
    pub seconds: f64,
}

impl IngestSummary {
    /// Sources with this outcome.
    pub fn count(&self, outcome: Outcome) -> usize {
        self.sources.iter().filter(|s| s.outcome == outcome).count()
    }

    /// Sources rejected (now or before), and stored episodes that failed their re-check.
    pub fn rejected(&self) -> usize {
        self.count(Outcome::Quarantined) + self.count(Outcome::RecheckFailed)
    }
}

/// The report of a source with the same content as `first`, met earlier in this run:
/// its staged copy is dropped.
pub(super) fn duplicate_report(
    source: Source,
    entry: ManifestEntry,
    staged: Option<&Path>,
    first: &Path,
) -> SourceReport {
    if let Some(dir) = staged {
        let _ = fs_err::remove_dir_all(dir);
    }
    let problem = Problem::new(
        ProblemCode::Duplicate,
        &Location::episode(&entry.id).path(&source.path),
        format!("same content as '{}', ingested once", first.display()),
    );
    tracing::info!("{problem}");
    // A copy of a rejected input is rejected too (and counted so).
    let rejected = entry.status == Status::Quarantined;
    let mut problems = if rejected { entry.problems } else { Vec::new() };
    problems.push(problem);
    SourceReport {
        source: source.path,
        id: entry.id,
        outcome: if rejected {
            Outcome::Quarantined
        } else {
            Outcome::Duplicate
        },
        path: entry.path,
        problems,
        notes: Vec::new(),
    }
}

/// The report of a stored episode redone under force that fails its re-check: it is
/// never removed, it stays as it was (`prev`), and the problems are reported.
pub(super) fn recheck_failed_report(
    source: Source,
    entry: ManifestEntry,
    staged: Option<&Path>,
    prev: &ManifestEntry,
) -> SourceReport {
    if let Some(dir) = staged {
        let _ = fs_err::remove_dir_all(dir);
    }
    tracing::warn!(
        "{}: the stored episode failed its re-check and is kept as it was: {}",
        prev.path.display(),
        entry
            .problems
            .first()
            .map(ToString::to_string)
            .unwrap_or_default()
    );
    SourceReport {
        source: source.path,
        id: entry.id,
        outcome: Outcome::RecheckFailed,
        path: prev.path.clone(),
        problems: entry.problems,
        notes: entry.notes,
    }
}
