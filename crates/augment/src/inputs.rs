//! Reading the inputs of an augment run: every episode with its task spec, the ones that
//! cannot be replayed named and skipped.

use std::path::{Path, PathBuf};

use dexjoco_core::{Episode, FrameArray, TaskSet, TaskSpec};
use serde::{Deserialize, Serialize};

use crate::error::AugmentError;

/// An episode to replay.
pub(crate) struct Source {
    pub(crate) episode: Episode,
    pub(crate) spec: TaskSpec,
    pub(crate) path: PathBuf,
}

impl Source {
    /// `<task>/<episode>`: what a replay's seed is derived from.
    pub(crate) fn key(&self) -> String {
        format!("{}/{}", self.spec.id, self.episode.id)
    }
}

/// An input that could not be replayed, and why; the rest of the batch goes on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SkippedInput {
    /// The file or folder.
    pub source: String,
    /// What is wrong with it (episode, field and frame where known).
    pub reason: String,
}

impl SkippedInput {
    pub(crate) fn new(path: &Path, reason: String) -> Self {
        tracing::warn!(input = %path.display(), "skipped: {reason}");
        Self {
            source: path.display().to_string(),
            reason,
        }
    }
}

/// Reads every input episode and its task spec, through the one episode reader
/// ([`dexjoco_formats::episodes`]). A path that cannot be listed, an episode that cannot
/// be read, an unknown task or a missing field skips that input or episode only.
pub(crate) fn read_sources(
    inputs: &[PathBuf],
    tasks: &TaskSet,
) -> Result<(Vec<Source>, Vec<SkippedInput>), AugmentError> {
    let mut out = Vec::new();
    let mut skipped = Vec::new();
    let mut skip = |path: &Path, reason: String| skipped.push(SkippedInput::new(path, reason));
    for input in inputs {
        let found = match dexjoco_formats::discover_input(input, None) {
            Ok(found) => found,
            Err(e) => {
                skip(input, e.to_string());
                continue;
            }
        };
        'episodes: for found in found {
            let episode = match found.read(tasks) {
                Ok(r) => r.episode,
                Err(e) => {
                    skip(&found.path, e.to_string());
                    continue;
                }
            };
            let path = found.path;
            let Some(spec) = tasks.get(&episode.task).cloned() else {
                skip(
                    &path,
                    format!("episode '{}': unknown task '{}'", episode.id, episode.task),
                );
                continue;
            };
            for field in [Episode::ACTION, Episode::STATE] {
                if episode.array(field).is_none_or(FrameArray::is_empty) {
                    skip(
                        &path,
                        format!(
                            "episode '{}': field '{field}' is missing or empty (frame 0)",
                            episode.id
                        ),
                    );
                    continue 'episodes;
                }
            }
            out.push(Source {
                episode,
                spec,
                path,
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
