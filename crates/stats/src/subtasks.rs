//! Subtask statistics over rollouts (augment's replays, eval's episodes): for each of a
//! task's subtasks, how many rollouts completed it, when, and how long it took (from the
//! end of the subtasks it waits for, as the task spec orders them, to its own end).

use std::collections::BTreeMap;

use dexjoco_core::{SubtaskEnd, TaskSet};
use serde::{Deserialize, Serialize};

/// One subtask over a set of rollouts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SubtaskSummary {
    /// Task id.
    pub task: String,
    /// Subtask id.
    pub id: String,
    /// Its text (from the task spec; the id when the spec is unknown).
    pub text: String,
    /// Rollouts that completed it.
    pub completed: usize,
    /// Rollouts counted.
    pub rollouts: usize,
    /// Mean step it ended on, over those that completed it.
    pub mean_end: Option<f64>,
    /// Mean duration in steps (from the end of what it waits for, or the start), over
    /// those that completed it.
    pub mean_steps: Option<f64>,
    /// Shortest duration.
    pub min_steps: Option<usize>,
    /// Longest duration.
    pub max_steps: Option<usize>,
}

impl SubtaskSummary {
    /// Completed / rollouts (0 when there are none).
    pub fn share(&self) -> f64 {
        if self.rollouts == 0 {
            0.0
        } else {
            self.completed as f64 / self.rollouts as f64
        }
    }
}

/// Summaries of every subtask of every task, from each rollout's task and subtask ends
/// (rollouts without ends, made before subtasks existed, are not counted).
pub fn summarize<'a>(
    rollouts: impl IntoIterator<Item = (&'a str, &'a [SubtaskEnd])>,
    tasks: &TaskSet,
) -> Vec<SubtaskSummary> {
    // (task, index) -> (ends, durations); rollouts per task.
    let mut ends: BTreeMap<(String, usize), (String, Vec<usize>, Vec<usize>)> = BTreeMap::new();
    let mut counted: BTreeMap<String, usize> = BTreeMap::new();
    for (task, subtasks) in rollouts {
        if subtasks.is_empty() {
            continue;
        }
        *counted.entry(task.to_owned()).or_default() += 1;
        let before = predecessors(tasks, task, subtasks.len());
        for (i, e) in subtasks.iter().enumerate() {
            let entry = ends
                .entry((task.to_owned(), i))
                .or_insert_with(|| (e.id.clone(), Vec::new(), Vec::new()));
            let Some(end) = e.step else { continue };
            let start = before[i]
                .iter()
                .filter_map(|&b| subtasks.get(b).and_then(|s| s.step))
                .max()
                .map_or(0, |s| s + 1);
            entry.1.push(end);
            entry.2.push(end.saturating_sub(start) + 1);
        }
    }
    ends.into_iter()
        .map(|((task, i), (id, at, steps))| {
            let text = tasks
                .get(&task)
                .and_then(|s| s.subtasks.get(i))
                .map_or_else(|| id.clone(), |s| s.text.clone());
            let mean = |v: &[usize]| {
                (!v.is_empty()).then(|| v.iter().sum::<usize>() as f64 / v.len() as f64)
            };
            SubtaskSummary {
                rollouts: counted[&task],
                task,
                id,
                text,
                completed: at.len(),
                mean_end: mean(&at),
                mean_steps: mean(&steps),
                min_steps: steps.iter().min().copied(),
                max_steps: steps.iter().max().copied(),
            }
        })
        .collect()
}

/// Each subtask's predecessors in the task's spec (the previous one when the spec is
/// unknown or has other subtasks).
fn predecessors(tasks: &TaskSet, task: &str, n: usize) -> Vec<Vec<usize>> {
    match tasks.get(task) {
        Some(spec) if spec.subtasks.len() == n => spec.subtask_predecessors(),
        _ => (0..n)
            .map(|i| i.checked_sub(1).into_iter().collect())
            .collect(),
    }
}

/// A Markdown table of the summaries.
pub fn to_markdown(summaries: &[SubtaskSummary]) -> String {
    use std::fmt::Write as _;
    let mut s = String::from(
        "| Task | Subtask | Completed | Mean end step | Steps (mean, min-max) |\n|---|---|---:|---:|---:|\n",
    );
    for t in summaries {
        let f = |v: Option<f64>| v.map_or("-".into(), |x| format!("{x:.0}"));
        let range = match (t.min_steps, t.max_steps) {
            (Some(a), Some(b)) => format!("{} ({a}-{b})", f(t.mean_steps)),
            _ => "-".into(),
        };
        let _ = writeln!(
            s,
            "| {} | {} | {}/{} ({:.0} %) | {} | {range} |",
            t.task,
            t.text,
            t.completed,
            t.rollouts,
            100.0 * t.share(),
            f(t.mean_end)
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn end(id: &str, step: Option<usize>) -> SubtaskEnd {
        SubtaskEnd {
            id: id.into(),
            step,
        }
    }

    #[test]
    fn durations_run_from_what_a_subtask_waits_for() {
        let tasks = TaskSet::builtin();
        // bimanual_assembly: grasp_peg (right), reach_tray (left), insert_peg (both).
        let a = [
            end("grasp_peg", Some(250)),
            end("reach_tray", Some(100)),
            end("insert_peg", Some(1000)),
        ];
        let b = [
            end("grasp_peg", Some(260)),
            end("reach_tray", Some(110)),
            end("insert_peg", None),
        ];
        let s = summarize(
            [("bimanual_assembly", &a[..]), ("bimanual_assembly", &b[..])],
            tasks,
        );
        assert_eq!(s.len(), 3);
        assert_eq!((s[0].completed, s[0].rollouts), (2, 2));
        assert_eq!(
            s[0].mean_steps,
            Some(256.0),
            "from the start: 251 and 261 steps"
        );
        // insert_peg waits for both: from step 251 to 1000.
        assert_eq!((s[2].completed, s[2].min_steps), (1, Some(750)));
        assert_eq!(s[2].text, "insert the peg into the hole");
        let md = to_markdown(&s);
        assert!(md.contains("| bimanual_assembly | insert the peg into the hole | 1/2 (50 %) | 1000 | 750 (750-750) |"), "{md}");
    }
}
