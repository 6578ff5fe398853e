//! Replay success rates from an augment report (`augment_report.json`, written by
//! `dexjoco-data augment` beside its replay folders), read through the report's one
//! definition (`dexjoco_formats::augment_report`) without the renderer's parts.

use std::collections::BTreeMap;
use std::path::Path;

use dexjoco_formats::augment_report::{ReportSummary, read_report};
use serde::{Deserialize, Serialize};

use crate::StatsError;

pub use dexjoco_formats::augment_report::AUGMENT_REPORT;

/// One task's replay outcome.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TaskReplays {
    /// Task id.
    pub task: String,
    /// Source episodes replayed.
    pub source_episodes: usize,
    /// Source episodes whose replay succeeded.
    pub source_successes: usize,
    /// Replays asked for: source episodes x replays per episode.
    pub replays_asked: usize,
    /// Replays on disk (successful ones, plus failures kept with `--keep-failed`).
    pub replays_kept: usize,
    /// Replays on disk whose task succeeded.
    pub replays_successful: usize,
    /// Replays that failed under their `--dynamics` draw and were not kept.
    #[serde(default)]
    pub replays_dropped: usize,
    /// Largest state deviation from the recording over the kept replays.
    pub max_state_deviation: f64,
    /// Kept replays that reached their success only after the recording ended (the last
    /// action repeated, `augment --extend-steps`).
    #[serde(default)]
    pub replays_extended: usize,
}

impl TaskReplays {
    fn empty(task: &str) -> Self {
        Self {
            task: task.to_owned(),
            source_episodes: 0,
            source_successes: 0,
            replays_asked: 0,
            replays_kept: 0,
            replays_successful: 0,
            replays_dropped: 0,
            max_state_deviation: 0.0,
            replays_extended: 0,
        }
    }

    /// Source episodes whose replay succeeded, as a fraction (0 when there are none).
    pub fn source_success_rate(&self) -> f64 {
        ratio(self.source_successes, self.source_episodes)
    }

    /// Successful replays on disk / replays asked for.
    pub fn yield_rate(&self) -> f64 {
        ratio(self.replays_successful, self.replays_asked)
    }
}

fn ratio(a: usize, b: usize) -> f64 {
    if b == 0 { 0.0 } else { a as f64 / b as f64 }
}

/// Replay success rates per task, from an augment report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReplayStats {
    /// Replays asked per source episode.
    pub replays_per_episode: usize,
    /// Per task, sorted by task id.
    pub tasks: Vec<TaskReplays>,
    /// Each task's subtasks over the kept replays: completed, when, how long.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub subtasks: Vec<crate::subtasks::SubtaskSummary>,
}

impl ReplayStats {
    /// Reads `augment_report.json` (the file itself, or the augment output folder holding
    /// it). `Ok(None)` when a folder holds no report.
    pub fn read(path: &Path) -> Result<Option<Self>, StatsError> {
        let file = if path.is_dir() {
            let f = path.join(AUGMENT_REPORT);
            if !f.is_file() {
                return Ok(None);
            }
            f
        } else {
            path.to_path_buf()
        };
        let report: ReportSummary = read_report(&file)?;
        Ok(Some(Self::from_report(&report)))
    }

    fn from_report(report: &ReportSummary) -> Self {
        let mut tasks: BTreeMap<String, TaskReplays> = BTreeMap::new();
        fn entry<'a>(
            tasks: &'a mut BTreeMap<String, TaskReplays>,
            task: &str,
        ) -> &'a mut TaskReplays {
            tasks
                .entry(task.to_owned())
                .or_insert_with(|| TaskReplays::empty(task))
        }
        for e in &report.episodes {
            let t = entry(&mut tasks, &e.task);
            t.source_episodes += 1;
            t.source_successes += usize::from(e.success);
            t.replays_asked += report.replays_per_episode;
        }
        for r in &report.replays {
            let t = entry(&mut tasks, &r.task);
            t.replays_kept += 1;
            t.replays_successful += usize::from(r.success);
            t.max_state_deviation = t.max_state_deviation.max(r.max_state_deviation);
            t.replays_extended += usize::from(r.extended);
        }
        for r in &report.dropped {
            entry(&mut tasks, &r.task).replays_dropped += 1;
        }
        let subtasks = crate::subtasks::summarize(
            report
                .replays
                .iter()
                .map(|r| (r.task.as_str(), r.subtasks.as_slice())),
        );
        Self {
            replays_per_episode: report.replays_per_episode,
            tasks: tasks.into_values().collect(),
            subtasks,
        }
    }

    /// A Markdown table: per task, source episodes replayed to success and the yield of
    /// successful replays, plus a total row.
    pub fn to_markdown(&self) -> String {
        use std::fmt::Write as _;
        let mut s = String::from(
            "| Task | Source episodes | Replayed to success | Replays asked | Kept | Successful | Dropped (dynamics) | Yield | Max state deviation | Extended |\n\
             |---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
        );
        let mut total = TaskReplays::empty("**all**");
        for t in &self.tasks {
            total.source_episodes += t.source_episodes;
            total.source_successes += t.source_successes;
            total.replays_asked += t.replays_asked;
            total.replays_kept += t.replays_kept;
            total.replays_successful += t.replays_successful;
            total.replays_dropped += t.replays_dropped;
            total.max_state_deviation = total.max_state_deviation.max(t.max_state_deviation);
            total.replays_extended += t.replays_extended;
        }
        for t in self.tasks.iter().chain(std::iter::once(&total)) {
            let _ = writeln!(
                s,
                "| {} | {} | {} ({:.0} %) | {} | {} | {} | {} | {:.0} % | {:e} | {} |",
                t.task,
                t.source_episodes,
                t.source_successes,
                100.0 * t.source_success_rate(),
                t.replays_asked,
                t.replays_kept,
                t.replays_successful,
                t.replays_dropped,
                100.0 * t.yield_rate(),
                t.max_state_deviation,
                t.replays_extended
            );
        }
        if !self.subtasks.is_empty() {
            s.push_str(
                "\nSubtasks of the kept replays (steps: from the end of what each waits for):\n\n",
            );
            s.push_str(&crate::subtasks::to_markdown(&self.subtasks));
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use dexjoco_formats::augment_report::{EpisodeOutcome, ReplayRecord};
    use serde::de::IgnoredAny;

    fn episode(task: &str, success: bool) -> EpisodeOutcome {
        EpisodeOutcome {
            task: task.into(),
            episode: "e".into(),
            source: "s".into(),
            success,
            first_success: None,
            steps: 1,
            recorded_steps: 1,
            success_shift: None,
            extended: false,
            max_state_deviation: 0.0,
            replays_kept: 0,
            subtasks: Vec::new(),
        }
    }

    fn replay(task: &str, success: bool, deviation: f64) -> ReplayRecord<IgnoredAny, IgnoredAny> {
        ReplayRecord {
            name: "r".into(),
            task: task.into(),
            episode: "e".into(),
            replay: 0,
            sample: IgnoredAny,
            success,
            first_success: None,
            steps: 1,
            recorded_steps: 1,
            extended: false,
            max_state_deviation: deviation,
            deviation_at: None,
            subtasks: Vec::new(),
            flags: Vec::new(),
            videos: Vec::new(),
            depth: Vec::new(),
            dynamics: None,
            source_hash: String::new(),
            renderer: String::new(),
            made_on: None,
        }
    }

    #[test]
    fn counts_per_task_and_in_total() {
        let mut replays: Vec<_> = (0..3).map(|_| replay("a", true, 0.0)).collect();
        replays.push(ReplayRecord {
            extended: true,
            ..replay("a", false, 0.25)
        });
        replays.extend((0..3).map(|_| replay("b", true, 0.0)));
        let report = ReportSummary {
            seed: 0,
            replays_per_episode: 3,
            settings: IgnoredAny,
            camera_pools: BTreeMap::new(),
            table_library: BTreeMap::new(),
            instructions: BTreeMap::new(),
            episodes: vec![episode("a", true), episode("a", false), episode("b", true)],
            replays,
            dropped: vec![replay("b", false, 0.0)],
            flagged: Vec::new(),
            skipped: Vec::new(),
            failed_units: Vec::new(),
            made_on: Vec::new(),
        };
        let r = ReplayStats::from_report(&report);
        assert_eq!(r.tasks.len(), 2);
        let a = &r.tasks[0];
        assert_eq!((a.source_episodes, a.source_successes), (2, 1));
        assert_eq!(
            (a.replays_asked, a.replays_kept, a.replays_successful),
            (6, 4, 3)
        );
        assert!((a.yield_rate() - 0.5).abs() < 1e-12);
        assert_eq!(a.max_state_deviation, 0.25);
        let md = r.to_markdown();
        assert!(
            md.contains("| a | 2 | 1 (50 %) | 6 | 4 | 3 | 0 | 50 % | 2.5e-1 |"),
            "{md}"
        );
        assert!(
            md.contains("| **all** | 3 | 2 (67 %) | 9 | 7 | 6 | 1 | 67 % | 2.5e-1 | 1 |"),
            "{md}"
        );
        assert_eq!(a.replays_extended, 1);
    }
}
