//! Segmenting a rollout into its task's subtasks, step by step: a subtask ends on the
//! first step on which its end node holds once every subtask it waits for has ended (its
//! lane's previous one and those its `after` names). Read from the checker after each
//! control step, so every rollout that runs through a [`TaskEnv`](crate::TaskEnv) (augment's
//! replays, scripted plans, eval episodes) is segmented the same way.

use dexjoco_core::{SubtaskSpan, TaskSpec};

use crate::checker::SuccessChecker;

/// Follows a rollout's subtasks.
#[derive(Debug, Clone)]
pub struct SubtaskTracker {
    ids: Vec<String>,
    texts: Vec<String>,
    /// Each subtask's end node, by its name.
    ends: Vec<String>,
    before: Vec<Vec<usize>>,
    at: Vec<Option<usize>>,
    step: usize,
}

impl SubtaskTracker {
    /// A tracker of `spec`'s subtasks (none when the spec has none).
    pub fn new(spec: &TaskSpec) -> Self {
        Self {
            ids: spec.subtasks.iter().map(|s| s.id.clone()).collect(),
            texts: spec.subtasks.iter().map(|s| s.text.clone()).collect(),
            ends: spec.subtasks.iter().map(|s| s.end.clone()).collect(),
            before: spec.subtask_predecessors(),
            at: vec![None; spec.subtasks.len()],
            step: 0,
        }
    }

    /// Forgets what was seen (after a reset or restore).
    pub fn reset(&mut self) {
        self.at.iter_mut().for_each(|a| *a = None);
        self.step = 0;
    }

    /// Reads the checker after a control step.
    pub fn observe(&mut self, checker: &SuccessChecker) {
        for i in 0..self.at.len() {
            if self.at[i].is_some() || self.before[i].iter().any(|&b| self.at[b].is_none()) {
                continue;
            }
            if checker.value(&self.ends[i]) == Some(true) {
                self.at[i] = Some(self.step);
            }
        }
        self.step += 1;
    }

    /// Each subtask's span so far, in the spec's order: it starts on the frame after the
    /// last of those it waits for ended (never after its own end: one that ends on the
    /// same step as its predecessor spans that one frame).
    pub fn spans(&self) -> Vec<SubtaskSpan> {
        (0..self.ids.len())
            .map(|i| {
                let start = self.before[i]
                    .iter()
                    .map(|&b| self.at[b])
                    .collect::<Option<Vec<usize>>>()
                    .map(|ends| ends.into_iter().max().map_or(0, |e| e + 1))
                    .map(|s| self.at[i].map_or(s, |end| s.min(end)));
                SubtaskSpan {
                    id: self.ids[i].clone(),
                    text: self.texts[i].clone(),
                    start,
                    end: self.at[i],
                }
            })
            .collect()
    }
}
