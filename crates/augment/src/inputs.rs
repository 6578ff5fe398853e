//! Reading the inputs of an augment run: every episode with its task spec, the ones that
//! cannot be replayed named and skipped.

use std::path::{Path, PathBuf};

use dexjoco_core::{Episode, FrameArray, TaskSet, TaskSpec};
use dexjoco_formats::SourceKind;

use crate::error::AugmentError;

/// An episode to replay.
pub(crate) struct Source {
    pub(crate) episode: Episode,
    pub(crate) spec: TaskSpec,
    pub(crate) path: PathBuf,
    /// Its kind (a worker reads it again).
    pub(crate) kind: SourceKind,
    /// Content hash of the episode (recorded in each replay; see `fingerprint`).
    pub(crate) hash: String,
}

impl Source {
    /// `<task>/<episode>`: what a replay's seed is derived from.
    pub(crate) fn key(&self) -> String {
        format!("{}/{}", self.spec.id, self.episode.id)
    }
}

pub use dexjoco_formats::augment_report::SkippedInput;

/// An input left out, and why (logged as a warning).
pub(crate) fn skipped_input(path: &Path, reason: String) -> SkippedInput {
    tracing::warn!(input = %path.display(), "skipped: {reason}");
    SkippedInput {
        source: path.display().to_string(),
        reason,
    }
}

/// The fields a replay needs: `action` and `state`, each with at least one frame, of one
/// length.
pub(crate) fn check_fields(episode: &Episode) -> Result<(), String> {
    for field in [Episode::ACTION, Episode::STATE] {
        if episode.array(field).is_none_or(FrameArray::is_empty) {
            return Err(format!(
                "episode '{}': field '{field}' is missing or empty (frame 0)",
                episode.id
            ));
        }
    }
    let (a, s) = (
        episode.len(),
        episode.array(Episode::STATE).map_or(0, FrameArray::len),
    );
    if a != s {
        return Err(format!(
            "episode '{}': field 'state' has {s} frames but 'action' has {a} (frame {})",
            episode.id,
            a.min(s)
        ));
    }
    Ok(())
}

/// Reads every input episode and its task spec, through the one episode reader
/// ([`dexjoco_formats::episodes`]) with the checks every door applies (names, shapes,
/// finite values, frame rate, timestamps: `Source::read_checked`). A path that cannot be
/// listed, an episode that cannot be read or fails a check, an unknown task or a missing
/// field skips that input or episode only.
/// Nothing under `exclude` (the run's own `--out`) is read as input, so an output folder
/// inside an input folder is never replayed again.
pub(crate) fn read_sources(
    inputs: &[PathBuf],
    exclude: &Path,
    tasks: &TaskSet,
) -> Result<(Vec<Source>, Vec<SkippedInput>), AugmentError> {
    let mut out = Vec::new();
    let mut skipped = Vec::new();
    let mut skip = |path: &Path, reason: String| skipped.push(skipped_input(path, reason));
    for input in inputs {
        let found = match dexjoco_formats::discover_input(input, Some(exclude)) {
            Ok(found) => found,
            Err(e) => {
                skip(input, e.to_string());
                continue;
            }
        };
        for found in found {
            let episode = match found.read_checked(tasks) {
                Ok(r) => r.episode,
                Err(e) => {
                    skip(&found.path, e.to_string());
                    continue;
                }
            };
            let Some(spec) = tasks.get(&episode.task).cloned() else {
                skip(
                    &found.path,
                    format!("episode '{}': unknown task '{}'", episode.id, episode.task),
                );
                continue;
            };
            if let Err(reason) = check_fields(&episode) {
                skip(&found.path, reason);
                continue;
            }
            out.push(Source {
                hash: crate::fingerprint::episode_hash(&episode, &spec),
                episode,
                spec,
                path: found.path,
                kind: found.kind,
            });
        }
    }
    out.sort_by(|a, b| (&a.episode.task, &a.episode.id).cmp(&(&b.episode.task, &b.episode.id)));
    for w in out.windows(2) {
        if w[0].episode.task == w[1].episode.task && w[0].episode.id == w[1].episode.id {
            return Err(AugmentError::Input(format!(
                "episode '{}/{}' is given twice ('{}' and '{}')",
                w[0].episode.task,
                w[0].episode.id,
                w[0].path.display(),
                w[1].path.display()
            )));
        }
    }
    Ok((out, skipped))
}
