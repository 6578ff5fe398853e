//! Dataset statistics over episodes: counts, episode lengths, per-dimension
//! distributions and openpi-style normalization statistics.

use std::collections::BTreeMap;

use dexjoco_core::{ArmSetup, ArrayLayout, Episode, TaskSet, TaskSpec};
use serde::{Deserialize, Serialize};

use dexjoco_formats::openpi::{RunningStats, norm_stats_document};

use crate::error::StatsError;
use crate::health::{
    ALL_TASKS, EpisodeFiles, FlatDimension, Flatness, Health, LEROBOT_EPS, NEAR_CONSTANT_REL,
    OPENPI_EPS,
};
use crate::health_report::warnings;
use crate::measures::{mean_std, quantile_sorted};

/// Bins of the per-dimension histograms.
pub const HISTOGRAM_BINS: usize = 40;

/// Arrays that are not distributions worth summarizing.
const SKIPPED_ARRAYS: [&str; 1] = [Episode::TIMESTAMP];

/// Summary of episode lengths in frames.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LengthStats {
    /// Shortest.
    pub min: usize,
    /// Longest.
    pub max: usize,
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation (n - 1); `None` for one episode.
    pub std: Option<f64>,
    /// Median.
    pub median: f64,
    /// Every length, in episode order.
    pub lengths: Vec<usize>,
}

impl LengthStats {
    fn from_lengths(lengths: Vec<usize>) -> Option<Self> {
        let values: Vec<f64> = lengths.iter().map(|&n| n as f64).collect();
        let ms = mean_std(&values)?;
        let mut sorted = values;
        sorted.sort_by(f64::total_cmp);
        Some(Self {
            min: *lengths.iter().min()?,
            max: *lengths.iter().max()?,
            mean: ms.mean,
            std: ms.std,
            median: quantile_sorted(&sorted, 0.5)?,
            lengths,
        })
    }
}

/// Per-dimension statistics of one array over every frame of a set of episodes.
///
/// `mean`, `std`, `q01` and `q99` are openpi's normalization statistics; `std` is the
/// population standard deviation (divisor n), as openpi computes it, and the quantiles
/// are exact (linear interpolation, `numpy.quantile`) where openpi approximates them
/// from a histogram.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ArrayStats {
    /// Values per frame.
    pub width: usize,
    /// Frames counted.
    pub frames: usize,
    /// Column names (from the DexJoCo layouts when the width matches one).
    pub columns: Vec<String>,
    /// Mean per dimension.
    pub mean: Vec<f64>,
    /// Population standard deviation per dimension.
    pub std: Vec<f64>,
    /// Minimum per dimension.
    pub min: Vec<f64>,
    /// Maximum per dimension.
    pub max: Vec<f64>,
    /// 1 % quantile per dimension.
    pub q01: Vec<f64>,
    /// 99 % quantile per dimension.
    pub q99: Vec<f64>,
    /// Histogram per dimension: [`HISTOGRAM_BINS`] equal bins from min to max.
    pub histogram: Vec<Vec<u64>>,
}

/// Column names of an array, from the DexJoCo layouts when its width fits one. `state`
/// takes its task's state layout (`mouse.pose[3]`, as ingest, the simulator and MCAP name
/// it) when `task` gives one of its width; without one (a dataset of several tasks) the
/// columns past proprioception are `privileged[i]`.
pub fn column_names(
    array: &str,
    width: usize,
    setup: Option<ArmSetup>,
    task: Option<&ArrayLayout>,
) -> Vec<String> {
    if array == Episode::STATE
        && let Some(l) = task.filter(|l| l.width() == width)
    {
        return (0..width).map(|i| l.column_name(i)).collect();
    }
    let layout = match (array, setup) {
        (Episode::ACTION, _) if width == 23 => Some(ArmSetup::SingleArm.action_layout()),
        (Episode::ACTION, _) if width == 46 => Some(ArmSetup::Bimanual.action_layout()),
        (Episode::ACTION_ROTVEC, _) if width == 22 => {
            Some(ArmSetup::SingleArm.action_rotvec_layout())
        }
        (Episode::ACTION_ROTVEC, _) if width == 44 => {
            Some(ArmSetup::Bimanual.action_rotvec_layout())
        }
        (Episode::STATE, Some(s)) if width >= s.proprio_dim() => Some(s.proprio_layout()),
        _ => None,
    };
    (0..width)
        .map(|i| match &layout {
            Some(l) if i < l.width() => l.column_name(i),
            Some(l) if array == Episode::STATE => format!("privileged[{}]", i - l.width()),
            _ => format!("{array}[{i}]"),
        })
        .collect()
}

fn array_stats(
    episodes: &[&Episode],
    name: &str,
    setup: Option<ArmSetup>,
    task: Option<&ArrayLayout>,
) -> Option<ArrayStats> {
    let arrays: Vec<_> = episodes.iter().filter_map(|e| e.array(name)).collect();
    let width = arrays.first()?.width();
    let frames: usize = arrays.iter().map(|a| a.len()).sum();
    if frames == 0 {
        return None;
    }
    let mut s = ArrayStats {
        width,
        frames,
        columns: column_names(name, width, setup, task),
        mean: Vec::with_capacity(width),
        std: Vec::with_capacity(width),
        min: Vec::with_capacity(width),
        max: Vec::with_capacity(width),
        q01: Vec::with_capacity(width),
        q99: Vec::with_capacity(width),
        histogram: Vec::with_capacity(width),
    };
    let mut column = Vec::with_capacity(frames);
    for d in 0..width {
        column.clear();
        column.extend(arrays.iter().flat_map(|a| a.rows().map(move |r| r[d])));
        let mean = column.iter().sum::<f64>() / frames as f64;
        let var = column.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / frames as f64;
        column.sort_by(f64::total_cmp);
        let (lo, hi) = (column[0], column[frames - 1]);
        let mut bins = vec![0u64; HISTOGRAM_BINS];
        for &v in &column {
            let k = if hi > lo {
                (((v - lo) / (hi - lo)) * HISTOGRAM_BINS as f64) as usize
            } else {
                0
            };
            bins[k.min(HISTOGRAM_BINS - 1)] += 1;
        }
        s.mean.push(mean);
        s.std.push(var.sqrt());
        s.min.push(lo);
        s.max.push(hi);
        s.q01
            .push(quantile_sorted(&column, 0.01).expect("non-empty"));
        s.q99
            .push(quantile_sorted(&column, 0.99).expect("non-empty"));
        s.histogram.push(bins);
    }
    Some(s)
}

/// openpi's normalization statistics of `names` over `episodes`, fed episode by episode
/// (the one implementation, [`dexjoco_formats::openpi`]).
fn norm_stats<'a>(
    episodes: &[&Episode],
    names: impl Iterator<Item = &'a str>,
) -> serde_json::Value {
    let mut arrays = BTreeMap::new();
    for name in names {
        let mut running = RunningStats::default();
        for a in episodes.iter().filter_map(|e| e.array(name)) {
            running.update(a.as_slice(), a.width());
        }
        arrays.insert(name.to_owned(), running);
    }
    norm_stats_document(&arrays)
}

/// Statistics of one task's episodes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TaskStats {
    /// Task id.
    pub task: String,
    /// Episodes.
    pub episodes: usize,
    /// Frames over all episodes.
    pub frames: usize,
    /// Episode lengths.
    pub lengths: LengthStats,
    /// Per-dimension statistics per array (every array but `timestamp`).
    pub arrays: BTreeMap<String, ArrayStats>,
    /// Each language instruction of the task's episodes (an episode's own, else its
    /// task's prompt) with its number of episodes.
    #[serde(default)]
    pub instructions: BTreeMap<String, usize>,
    /// openpi's `norm_stats.json` document of the same arrays (written beside, not into,
    /// `dataset_stats.json`).
    #[serde(skip)]
    pub norm_stats: serde_json::Value,
}

/// Statistics of a dataset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DatasetStats {
    /// Episodes.
    pub episodes: usize,
    /// Frames over all episodes.
    pub frames: usize,
    /// Frame rates found (30 for DexJoCo).
    pub fps: Vec<f64>,
    /// Episode lengths over the whole dataset.
    pub lengths: LengthStats,
    /// Per task, sorted by task id.
    pub tasks: Vec<TaskStats>,
    /// Per-dimension statistics over the whole dataset, for arrays of one width in every
    /// episode.
    pub arrays: BTreeMap<String, ArrayStats>,
    /// Arrays left out of the dataset-wide statistics because their width differs
    /// between tasks (e.g. `state`, whose privileged part is per task).
    pub mixed_width_arrays: Vec<String>,
    /// openpi's `norm_stats.json` document of the dataset-wide arrays.
    #[serde(skip)]
    pub norm_stats: serde_json::Value,
    /// What would go wrong at training time (flat dimensions, static leading frames,
    /// length outliers, duplicates, replay outcomes and flags).
    #[serde(default)]
    pub health: Health,
    /// Each task's subtasks over the episodes whose folders record them (augment's
    /// replays, scripted plans, eval episodes): completed, when, how long.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub subtasks: Vec<crate::subtasks::SubtaskSummary>,
}

/// The episodes that do not fit their task's layout: per task and array, the width most
/// episodes of the task have (among equals, that of the first) is the task's; each
/// episode with another width is returned (its index and a [`StatsError::Width`] naming
/// task, episode, field and both widths), so it can be left out and named while the
/// rest is described.
pub fn width_outliers(episodes: &[Episode]) -> Vec<(usize, StatsError)> {
    let mut by_task: BTreeMap<&str, Vec<usize>> = BTreeMap::new();
    for (i, e) in episodes.iter().enumerate() {
        by_task.entry(e.task.as_str()).or_default().push(i);
    }
    let mut out: Vec<(usize, StatsError)> = Vec::new();
    for (task, idx) in by_task {
        // Array name -> (width -> (count, first index)).
        let mut counts: BTreeMap<&str, BTreeMap<usize, (usize, usize)>> = BTreeMap::new();
        for &i in &idx {
            for (name, a) in &episodes[i].arrays {
                if SKIPPED_ARRAYS.contains(&name.as_str()) {
                    continue;
                }
                let c = counts
                    .entry(name)
                    .or_default()
                    .entry(a.width())
                    .or_insert((0, i));
                c.0 += 1;
            }
        }
        let chosen: BTreeMap<&str, usize> = counts
            .iter()
            .filter_map(|(name, widths)| {
                widths
                    .iter()
                    .max_by_key(|(_, (n, first))| (*n, std::cmp::Reverse(*first)))
                    .map(|(w, _)| (*name, *w))
            })
            .collect();
        for &i in &idx {
            let e = &episodes[i];
            let odd = e
                .arrays
                .iter()
                .find(|(name, a)| chosen.get(name.as_str()).is_some_and(|w| *w != a.width()));
            if let Some((name, a)) = odd {
                out.push((
                    i,
                    StatsError::Width {
                        task: task.to_owned(),
                        episode: e.id.clone(),
                        array: name.clone(),
                        expected: chosen[name.as_str()],
                        found: a.width(),
                    },
                ));
            }
        }
    }
    out.sort_by_key(|(i, _)| *i);
    out
}

impl DatasetStats {
    /// Computes the statistics of episodes of the built-in tasks
    /// ([`Self::compute_with_tasks`]).
    pub fn compute(episodes: &[Episode]) -> Result<Self, StatsError> {
        Self::compute_with_tasks(episodes, TaskSet::builtin())
    }

    /// Computes the statistics, naming each task's state columns after its spec in
    /// `specs` (generic names for a task not there). Fails when there are no episodes,
    /// or when an array's width differs between episodes of one task. The health
    /// section counts every episode as a recording without videos
    /// ([`Self::compute_with_files`] reads what their folders hold).
    pub fn compute_with_tasks(episodes: &[Episode], specs: &TaskSet) -> Result<Self, StatsError> {
        Self::compute_with_files(episodes, &[], specs)
    }

    /// [`Self::compute_with_tasks`], with `files[i]` what episode `i`'s folder holds
    /// (its replay record and videos, for the health section).
    pub fn compute_with_files(
        episodes: &[Episode],
        files: &[EpisodeFiles],
        specs: &TaskSet,
    ) -> Result<Self, StatsError> {
        let mut stats = Self::compute_arrays(episodes, specs)?;
        stats.subtasks = crate::subtasks::summarize(
            episodes
                .iter()
                .zip(files)
                .filter_map(|(e, f)| Some((e.task.as_str(), f.subtasks.as_deref()?))),
        );
        stats.health = Health::compute(stats.flat_dimensions(), episodes, files);
        stats.health.warnings = warnings(&stats.health);
        Ok(stats)
    }

    fn compute_arrays(episodes: &[Episode], specs: &TaskSet) -> Result<Self, StatsError> {
        let Some(lengths) = LengthStats::from_lengths(episodes.iter().map(Episode::len).collect())
        else {
            return Err(StatsError::Empty {
                path: "<episodes>".into(),
                message: "no episodes".into(),
            });
        };
        let mut by_task: BTreeMap<&str, Vec<&Episode>> = BTreeMap::new();
        for e in episodes {
            by_task.entry(e.task.as_str()).or_default().push(e);
        }
        let setup_of = |eps: &[&Episode]| {
            eps.iter()
                .find_map(|e| e.array(Episode::ACTION))
                .and_then(|a| match a.width() {
                    23 => Some(ArmSetup::SingleArm),
                    46 => Some(ArmSetup::Bimanual),
                    _ => None,
                })
        };
        let mut widths: BTreeMap<&str, Option<usize>> = BTreeMap::new();
        let mut tasks = Vec::new();
        for (task, eps) in &by_task {
            let mut task_widths: BTreeMap<&str, (usize, &str)> = BTreeMap::new();
            for e in eps {
                for (name, a) in &e.arrays {
                    if SKIPPED_ARRAYS.contains(&name.as_str()) {
                        continue;
                    }
                    let (w, _) = *task_widths.entry(name).or_insert((a.width(), &e.id));
                    if w != a.width() {
                        return Err(StatsError::Width {
                            task: (*task).to_string(),
                            episode: e.id.clone(),
                            array: name.clone(),
                            expected: w,
                            found: a.width(),
                        });
                    }
                }
            }
            for (name, (w, _)) in &task_widths {
                let entry = widths.entry(name).or_insert(Some(*w));
                if *entry != Some(*w) {
                    *entry = None;
                }
            }
            let setup = setup_of(eps);
            let layout = specs.get(task).map(TaskSpec::state_layout);
            tasks.push(TaskStats {
                task: (*task).to_string(),
                episodes: eps.len(),
                frames: eps.iter().map(|e| e.len()).sum(),
                lengths: LengthStats::from_lengths(eps.iter().map(|e| e.len()).collect())
                    .expect("a task has episodes"),
                arrays: task_widths
                    .keys()
                    .filter_map(|name| {
                        let s = array_stats(eps, name, setup, layout.as_ref())?;
                        Some(((*name).to_string(), s))
                    })
                    .collect(),
                instructions: eps.iter().fold(BTreeMap::new(), |mut m, e| {
                    *m.entry(e.prompt.clone()).or_default() += 1;
                    m
                }),
                norm_stats: norm_stats(eps, task_widths.keys().copied()),
            });
        }
        let all: Vec<&Episode> = episodes.iter().collect();
        let setup = setup_of(&all);
        let mut arrays = BTreeMap::new();
        let mut mixed_width_arrays = Vec::new();
        for (name, w) in &widths {
            match w {
                Some(_) => {
                    if let Some(s) = array_stats(&all, name, setup, None) {
                        arrays.insert((*name).to_string(), s);
                    }
                }
                None => mixed_width_arrays.push((*name).to_string()),
            }
        }
        let norm_stats = norm_stats(&all, arrays.keys().map(String::as_str));
        let mut fps: Vec<f64> = episodes.iter().map(|e| e.fps).collect();
        fps.sort_by(f64::total_cmp);
        fps.dedup();
        Ok(Self {
            episodes: episodes.len(),
            frames: episodes.iter().map(Episode::len).sum(),
            fps,
            lengths,
            tasks,
            arrays,
            mixed_width_arrays,
            norm_stats,
            health: Health::default(),
            subtasks: Vec::new(),
        })
    }

    /// A short Markdown summary: totals, per-task counts and lengths, the instructions
    /// per task, then the health section.
    pub fn to_markdown(&self) -> String {
        use std::fmt::Write as _;
        let fmt_std = |s: Option<f64>| s.map_or_else(|| "n/a".into(), |s| format!("{s:.1}"));
        let mut s = format!(
            "{} episodes, {} frames ({:.1} min at {} fps); episode length {:.1} ± {} frames (min {}, median {:.0}, max {})\n\n",
            self.episodes,
            self.frames,
            self.frames as f64 / self.fps.first().copied().unwrap_or(30.0) / 60.0,
            self.fps
                .iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join("/"),
            self.lengths.mean,
            fmt_std(self.lengths.std),
            self.lengths.min,
            self.lengths.median,
            self.lengths.max
        );
        s.push_str("| Task | Episodes | Frames | Length mean ± std | Min | Max |\n|---|---:|---:|---:|---:|---:|\n");
        for t in &self.tasks {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {:.1} ± {} | {} | {} |",
                t.task,
                t.episodes,
                t.frames,
                t.lengths.mean,
                fmt_std(t.lengths.std),
                t.lengths.min,
                t.lengths.max
            );
        }
        s.push_str("\n| Task | Instruction | Episodes |\n|---|---|---:|\n");
        for t in &self.tasks {
            for (instruction, n) in &t.instructions {
                let cell = instruction.replace('|', "\\|").replace('\n', " ");
                let _ = writeln!(s, "| {} | {cell} | {n} |", t.task);
            }
        }
        s.push('\n');
        if !self.subtasks.is_empty() {
            s.push_str(
                "Subtasks (from the episodes' replay, plan or eval records; steps from the end of \
                 what each waits for to its own end):\n\n",
            );
            s.push_str(&crate::subtasks::to_markdown(&self.subtasks));
            s.push('\n');
        }
        s.push_str(&self.health.to_markdown());
        s
    }
}

/// The constant and near-constant dimensions of one array's statistics.
pub fn flat_dimensions(scope: &str, array: &str, s: &ArrayStats) -> Vec<FlatDimension> {
    (0..s.width)
        .filter_map(|d| {
            let flatness = if s.min[d] == s.max[d] {
                Flatness::Constant
            } else if s.std[d] <= NEAR_CONSTANT_REL * s.mean[d].abs().max(1.0) {
                Flatness::NearConstant
            } else {
                return None;
            };
            let std = if flatness == Flatness::Constant {
                0.0
            } else {
                s.std[d]
            };
            Some(FlatDimension {
                scope: scope.to_owned(),
                array: array.to_owned(),
                index: d,
                column: s.columns[d].clone(),
                flatness,
                mean: s.mean[d],
                std,
                min: s.min[d],
                max: s.max[d],
                lerobot_gain: 1.0 / (std + LEROBOT_EPS),
                openpi_gain: 1.0 / (std + OPENPI_EPS),
                openpi_quantile_gain: 2.0 / (s.q99[d] - s.q01[d] + OPENPI_EPS),
            })
        })
        .collect()
}

impl DatasetStats {
    /// The constant and near-constant dimensions of every task's arrays, and of the
    /// whole dataset's when it holds several tasks.
    fn flat_dimensions(&self) -> Vec<FlatDimension> {
        let mut out = Vec::new();
        for t in &self.tasks {
            for (name, s) in &t.arrays {
                out.extend(flat_dimensions(&t.task, name, s));
            }
        }
        if self.tasks.len() > 1 {
            for (name, s) in &self.arrays {
                out.extend(flat_dimensions(ALL_TASKS, name, s));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_interpolate_linearly() {
        let v = [1.0, 2.0, 3.0, 4.0, 5.0];
        assert_eq!(quantile_sorted(&v, 0.5), Some(3.0));
        assert_eq!(quantile_sorted(&v, 0.0), Some(1.0));
        assert_eq!(quantile_sorted(&v, 1.0), Some(5.0));
        assert!((quantile_sorted(&v, 0.01).unwrap() - 1.04).abs() < 1e-12);
        assert_eq!(quantile_sorted(&[], 0.5), None);
    }

    #[test]
    fn column_names_follow_the_layouts() {
        let n = column_names(Episode::STATE, 31, Some(ArmSetup::SingleArm), None);
        assert_eq!(n[0], "arm.tcp_pos[0]");
        assert_eq!(n[7], "arm.hand_qpos[0]");
        assert_eq!(n[23], "privileged[0]");
        let mouse = TaskSpec::builtin("click_mouse").unwrap().state_layout();
        let n = column_names(Episode::STATE, mouse.width(), None, Some(&mouse));
        assert_eq!(n[7], "arm.hand_qpos[0]");
        assert_eq!(
            n[23], "mouse.pose[0]",
            "the spec's name, as ingest gives it"
        );
        assert_eq!(n[mouse.width() - 1], "dh[0]");
        let other = column_names(Episode::STATE, 30, Some(ArmSetup::SingleArm), Some(&mouse));
        assert_eq!(
            other[23], "privileged[0]",
            "a layout of another width is not used"
        );
        assert_eq!(
            column_names(Episode::ACTION, 46, None, None)[23],
            "left.pos[0]"
        );
        assert_eq!(
            column_names("other", 2, None, None),
            ["other[0]", "other[1]"]
        );
    }
}
