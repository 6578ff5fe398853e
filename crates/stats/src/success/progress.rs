//! How far each cell's episodes got through their task's subtasks (from the episodes'
//! records), beside the success table.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::{SuccessCell, policy_of};
use crate::evaltree::Run;

/// How far one cell's episodes got through their task's subtasks.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SubtaskProgress {
    /// Policy.
    pub policy: String,
    /// Regime.
    pub regime: String,
    /// Task id.
    pub task: String,
    /// Episodes whose record gives their subtasks (counted).
    pub episodes: usize,
    /// Episodes without such a record (a reference-made folder has none): not counted.
    pub without_record: usize,
    /// Per subtask, in the task spec's order: id, text and the episodes that completed it.
    pub subtasks: Vec<SubtaskShare>,
    /// Subtasks completed per counted episode, on average.
    pub mean_completed: f64,
}

/// One subtask's completion over a cell's episodes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SubtaskShare {
    /// Subtask id.
    pub id: String,
    /// Its text (as the records give it; the id when they give none).
    pub text: String,
    /// Episodes that completed it.
    pub completed: usize,
}

impl SubtaskProgress {
    /// Progress per (policy, regime, task) over `runs`, in the order of `cells`; cells
    /// without any episode folder are left out.
    pub(super) fn of_runs(root: &Path, runs: &[Run], cells: &[SuccessCell]) -> Vec<Self> {
        cells
            .iter()
            .filter_map(|c| {
                let episodes: Vec<&crate::evaltree::EpisodeFolder> = runs
                    .iter()
                    .filter(|r| {
                        policy_of(root, r) == c.policy
                            && r.name.regime == c.regime
                            && r.name.task == c.task
                    })
                    .flat_map(|r| &r.episodes)
                    .collect();
                if episodes.is_empty() {
                    return None;
                }
                let recorded: Vec<&Vec<dexjoco_core::SubtaskSpan>> = episodes
                    .iter()
                    .filter_map(|e| e.subtasks.as_ref())
                    .collect();
                let ids: Vec<String> = recorded
                    .iter()
                    .max_by_key(|s| s.len())
                    .map(|s| s.iter().map(|e| e.id.clone()).collect())
                    .unwrap_or_default();
                let text = |id: &str| {
                    recorded
                        .iter()
                        .flat_map(|s| s.iter())
                        .find(|e| e.id == id && !e.text.is_empty())
                        .map_or_else(|| id.to_owned(), |e| e.text.clone())
                };
                let subtasks: Vec<SubtaskShare> = ids
                    .iter()
                    .map(|id| SubtaskShare {
                        id: id.clone(),
                        text: text(id),
                        completed: recorded
                            .iter()
                            .filter(|s| s.iter().any(|e| &e.id == id && e.completed()))
                            .count(),
                    })
                    .collect();
                let total: usize = subtasks.iter().map(|s| s.completed).sum();
                Some(Self {
                    policy: c.policy.clone(),
                    regime: c.regime.clone(),
                    task: c.task.clone(),
                    episodes: recorded.len(),
                    without_record: episodes.len() - recorded.len(),
                    mean_completed: if recorded.is_empty() {
                        0.0
                    } else {
                        total as f64 / recorded.len() as f64
                    },
                    subtasks,
                })
            })
            .collect()
    }
}
