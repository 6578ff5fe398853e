//! Subtask statistics over rollouts (augment's replays, eval's episodes): for each of a
//! task's subtasks, how many rollouts completed it, when, and how long it took (from the
//! end of the subtasks it waits for, as the task spec orders them, to its own end).

use std::collections::BTreeMap;

use dexjoco_core::SubtaskSpan;
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

/// Summaries of every subtask of every task, from each rollout's task and subtask spans
/// (rollouts without spans, made before subtasks existed, are not counted).
pub fn summarize<'a>(
    rollouts: impl IntoIterator<Item = (&'a str, &'a [SubtaskSpan])>,
) -> Vec<SubtaskSummary> {
    // (task, index) -> (id, text, ends, durations); rollouts per task.
    type Seen = (String, String, Vec<usize>, Vec<usize>);
    let mut seen: BTreeMap<(String, usize), Seen> = BTreeMap::new();
    let mut counted: BTreeMap<String, usize> = BTreeMap::new();
    for (task, spans) in rollouts {
        if spans.is_empty() {
            continue;
        }
        *counted.entry(task.to_owned()).or_default() += 1;
        for (i, s) in spans.iter().enumerate() {
            let entry = seen.entry((task.to_owned(), i)).or_insert_with(|| {
                let text = if s.text.is_empty() { &s.id } else { &s.text };
                (s.id.clone(), text.clone(), Vec::new(), Vec::new())
            });
            if let Some(end) = s.end {
                entry.2.push(end);
                entry.3.push(end + 1 - s.start.unwrap_or(0).min(end));
            }
        }
    }
    seen.into_iter()
        .map(|((task, _), (id, text, at, steps))| {
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

    fn span(id: &str, start: Option<usize>, end: Option<usize>) -> SubtaskSpan {
        SubtaskSpan {
            id: id.into(),
            text: format!("the text of {id}"),
            start,
            end,
        }
    }

    #[test]
    fn durations_run_from_each_start_to_its_end() {
        // bimanual_assembly: grasp_peg (right), reach_tray (left), insert_peg (both).
        let a = [
            span("grasp_peg", Some(0), Some(250)),
            span("reach_tray", Some(0), Some(100)),
            span("insert_peg", Some(251), Some(1000)),
        ];
        let b = [
            span("grasp_peg", Some(0), Some(260)),
            span("reach_tray", Some(0), Some(110)),
            span("insert_peg", Some(261), None),
        ];
        let s = summarize([("bimanual_assembly", &a[..]), ("bimanual_assembly", &b[..])]);
        assert_eq!(s.len(), 3);
        assert_eq!((s[0].completed, s[0].rollouts), (2, 2));
        assert_eq!(s[0].mean_steps, Some(256.0), "251 and 261 steps");
        assert_eq!((s[2].completed, s[2].min_steps), (1, Some(750)));
        let md = to_markdown(&s);
        assert!(
            md.contains(
                "| bimanual_assembly | the text of insert_peg | 1/2 (50 %) | 1000 | 750 (750-750) |"
            ),
            "{md}"
        );
    }
}
