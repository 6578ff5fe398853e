//! The health section of `stats --dataset`: what would go wrong at training time.
//! Zero-variance and near-constant dimensions (and what normalization does with them),
//! static leading frames, the episode-length distribution per task, duplicated
//! episodes, and the success and render-check flag rates of replays; each finding that
//! needs action is also a one-line warning.
//!
//! Rules (documented in `docs/commands/stats.md`):
//! - a dimension is *constant* when every value over the scope (a task, or the whole
//!   dataset when it holds several tasks) is the same (std exactly 0), *near-constant*
//!   when not, but its population std is at most [`NEAR_CONSTANT_REL`] x max(1, |mean|);
//! - static leading frames follow the reference converter's rule
//!   ([`dexjoco_core::first_moving_frame`] on `action`, as recorded), which `convert`
//!   applies;
//! - an episode is a length outlier when it is under half or over twice its task's
//!   median length;
//! - duplicates: episodes with the same arrays (names, widths and every value, bit for
//!   bit) form a "same arrays" group; those that also have the same video bytes (or no
//!   videos) are full duplicates. augment's replays of one source share their arrays by
//!   design (only the rendering differs), so same-arrays groups of replays are listed,
//!   not warned about.

use std::collections::BTreeMap;

use dexjoco_core::{Episode, first_moving_frame};
use dexjoco_formats::raw::ReplayLabel;
use serde::{Deserialize, Serialize};

use crate::measures::quantile_sorted;

pub use crate::health_files::EpisodeFiles;

/// Relative std under which a dimension is near-constant: `std <= NEAR_CONSTANT_REL *
/// max(1, |mean|)`.
pub const NEAR_CONSTANT_REL: f64 = 1e-4;
/// lerobot 0.6.1's epsilon (`NormalizerProcessorStep.eps`): mean/std normalization is
/// `(x - mean) / (std + 1e-8)`.
pub const LEROBOT_EPS: f64 = 1e-8;
/// openpi's epsilon (`transforms.Normalize`): `(x - mean) / (std + 1e-6)`, and with
/// quantiles `(x - q01) / (q99 - q01 + 1e-6) * 2 - 1`.
pub const OPENPI_EPS: f64 = 1e-6;

/// The scope name of dataset-wide rows.
pub const ALL_TASKS: &str = "*";

/// How flat a dimension is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Flatness {
    /// Every value the same (std exactly 0).
    Constant,
    /// Not constant, but std <= [`NEAR_CONSTANT_REL`] x max(1, |mean|).
    NearConstant,
}

/// A constant or near-constant dimension and what normalization does with it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FlatDimension {
    /// The task, or [`ALL_TASKS`] for the dataset-wide statistics.
    pub scope: String,
    /// The array (`action`, `action_rotvec`, `state`...).
    pub array: String,
    /// Column index.
    pub index: usize,
    /// Column name (the task spec's state layout where known).
    pub column: String,
    /// Constant or near-constant.
    pub flatness: Flatness,
    /// Mean.
    pub mean: f64,
    /// Population std.
    pub std: f64,
    /// Smallest value.
    pub min: f64,
    /// Largest value.
    pub max: f64,
    /// lerobot mean/std: a deviation `d` from the mean becomes `d * lerobot_gain`
    /// (`1 / (std + 1e-8)`); the column trains as 0.
    pub lerobot_gain: f64,
    /// openpi z-score: `d * openpi_gain` (`1 / (std + 1e-6)`); trains as 0.
    pub openpi_gain: f64,
    /// openpi quantiles: `d * openpi_quantile_gain` (`2 / (q99 - q01 + 1e-6)`, exact
    /// quantiles); trains as -1 when constant.
    pub openpi_quantile_gain: f64,
}

/// An episode and a frame count.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct EpisodeFrames {
    /// Episode id.
    pub episode: String,
    /// Frames (static leading frames, or the episode's length).
    pub frames: usize,
    /// The episode's length.
    pub length: usize,
}

/// Static leading frames of one task's episodes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StaticLeading {
    /// Task id.
    pub task: String,
    /// Episodes of the task.
    pub episodes: usize,
    /// Static leading frames over all of them.
    pub frames: usize,
    /// Each episode with static leading frames, in dataset order.
    pub with_static: Vec<EpisodeFrames>,
    /// Episodes whose action never changes (the rule keeps all their frames).
    pub never_moving: Vec<String>,
}

/// The episode-length distribution of one task.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LengthDistribution {
    /// Task id.
    pub task: String,
    /// Episodes.
    pub count: usize,
    /// Shortest.
    pub min: usize,
    /// 10 % quantile (linear interpolation).
    pub p10: f64,
    /// Median.
    pub median: f64,
    /// 90 % quantile.
    pub p90: f64,
    /// Longest.
    pub max: usize,
    /// Episodes under half or over twice the median, in dataset order.
    pub outliers: Vec<EpisodeFrames>,
}

/// Episodes with the same content.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct DuplicateGroup {
    /// SHA-256 of the arrays (hex).
    pub arrays_sha256: String,
    /// `(task, episode id)` of each member, in dataset order.
    pub episodes: Vec<(String, String)>,
    /// Whether every member is a replay (has a replay record).
    pub replays: bool,
}

/// Duplicated episodes.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Duplicates {
    /// Same arrays and same video bytes (or no videos).
    pub full: Vec<DuplicateGroup>,
    /// Same arrays, different videos (e.g. augment's replays of one source).
    pub same_arrays: Vec<DuplicateGroup>,
}

/// Replay outcomes and render-check flags of one task.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Outcomes {
    /// Task id.
    pub task: String,
    /// Episodes without a replay record (recordings).
    pub recordings: usize,
    /// Episodes with a replay record.
    pub replays: usize,
    /// Replays whose task succeeded.
    pub succeeded: usize,
    /// Replays the render checks ran on (records with a `flags` field).
    pub checked: usize,
    /// Replays with at least one flag.
    pub flagged: usize,
    /// Replays flagged per check (`blank_frame`, `frozen_video`, `non_finite`).
    pub per_check: BTreeMap<String, usize>,
    /// Flagged replays: episode id and each flag described.
    pub flagged_episodes: Vec<(String, Vec<String>)>,
}

/// The health section of the dataset statistics.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Health {
    /// Constant and near-constant dimensions, per task then dataset-wide.
    pub flat_dimensions: Vec<FlatDimension>,
    /// Static leading frames per task.
    pub static_leading: Vec<StaticLeading>,
    /// Episode-length distribution per task.
    pub lengths: Vec<LengthDistribution>,
    /// Duplicated episodes.
    pub duplicates: Duplicates,
    /// Replay outcomes and flags per task.
    pub outcomes: Vec<Outcomes>,
    /// One line per finding that needs action, naming task, array, column or episode
    /// and what to do.
    pub warnings: Vec<String>,
}

/// Static leading frames of one task's episodes (`action`, compared as recorded).
fn static_leading(task: &str, episodes: &[&Episode]) -> StaticLeading {
    let mut s = StaticLeading {
        task: task.to_owned(),
        episodes: episodes.len(),
        frames: 0,
        with_static: Vec::new(),
        never_moving: Vec::new(),
    };
    for e in episodes {
        let Some(action) = e.array(Episode::ACTION) else {
            continue;
        };
        let n = action.len();
        if n > 1 && action.rows().all(|r| r == action.row(0)) {
            s.never_moving.push(e.id.clone());
            continue;
        }
        let k = first_moving_frame(action, false);
        if k > 0 {
            s.frames += k;
            s.with_static.push(EpisodeFrames {
                episode: e.id.clone(),
                frames: k,
                length: n,
            });
        }
    }
    s
}

/// The length distribution of one task's episodes.
fn length_distribution(task: &str, episodes: &[&Episode]) -> LengthDistribution {
    let mut sorted: Vec<f64> = episodes.iter().map(|e| e.len() as f64).collect();
    sorted.sort_by(f64::total_cmp);
    let q = |p: f64| quantile_sorted(&sorted, p).unwrap_or(0.0);
    let median = q(0.5);
    LengthDistribution {
        task: task.to_owned(),
        count: episodes.len(),
        min: episodes.iter().map(|e| e.len()).min().unwrap_or(0),
        p10: q(0.1),
        median,
        p90: q(0.9),
        max: episodes.iter().map(|e| e.len()).max().unwrap_or(0),
        outliers: episodes
            .iter()
            .filter(|e| {
                let n = e.len() as f64;
                n < median / 2.0 || n > median * 2.0
            })
            .map(|e| EpisodeFrames {
                episode: e.id.clone(),
                frames: e.len(),
                length: e.len(),
            })
            .collect(),
    }
}

/// Groups of episodes sharing a key (two or more), in order of their first member.
fn groups<K: Ord + Clone>(keys: &[Option<K>]) -> Vec<Vec<usize>> {
    let mut by_key: BTreeMap<K, Vec<usize>> = BTreeMap::new();
    for (i, k) in keys.iter().enumerate() {
        if let Some(k) = k {
            by_key.entry(k.clone()).or_default().push(i);
        }
    }
    let mut out: Vec<Vec<usize>> = by_key.into_values().filter(|g| g.len() > 1).collect();
    out.sort();
    out
}

/// Full duplicates and same-arrays groups.
fn duplicates(episodes: &[Episode], files: &[EpisodeFiles]) -> Duplicates {
    let arrays: Vec<Option<String>> = episodes
        .iter()
        .map(|e| Some(crate::health_files::arrays_sha256(e)))
        .collect();
    let full_keys: Vec<Option<(String, Option<String>)>> = arrays
        .iter()
        .zip(files)
        .map(|(a, f)| a.clone().map(|a| (a, f.videos_sha256.clone())))
        .collect();
    let group = |g: Vec<usize>| DuplicateGroup {
        arrays_sha256: arrays[g[0]].clone().unwrap_or_default(),
        episodes: g
            .iter()
            .map(|&i| (episodes[i].task.clone(), episodes[i].id.clone()))
            .collect(),
        replays: g.iter().all(|&i| files[i].label.is_some()),
    };
    let full = groups(&full_keys);
    let same_arrays = groups(&arrays)
        .into_iter()
        .filter(|g| !full.contains(g))
        .map(group)
        .collect();
    Duplicates {
        full: full.into_iter().map(group).collect(),
        same_arrays,
    }
}

/// Replay outcomes and flags of one task's episodes.
fn outcomes(task: &str, labels: &[(&str, Option<&ReplayLabel>)]) -> Outcomes {
    let mut o = Outcomes {
        task: task.to_owned(),
        recordings: 0,
        replays: 0,
        succeeded: 0,
        checked: 0,
        flagged: 0,
        per_check: ["blank_frame", "frozen_video", "non_finite"]
            .into_iter()
            .map(|c| (c.to_owned(), 0))
            .collect(),
        flagged_episodes: Vec::new(),
    };
    for (id, label) in labels {
        let Some(l) = label else {
            o.recordings += 1;
            continue;
        };
        o.replays += 1;
        o.succeeded += usize::from(l.success);
        o.checked += usize::from(l.checked);
        if l.flagged() {
            o.flagged += 1;
            let mut checks: Vec<&str> = l.flags.iter().map(|f| f.check.name()).collect();
            checks.sort_unstable();
            checks.dedup();
            for c in checks {
                *o.per_check.entry(c.to_owned()).or_default() += 1;
            }
            o.flagged_episodes.push((
                (*id).to_owned(),
                l.flags.iter().map(|f| f.describe()).collect(),
            ));
        }
    }
    o
}

impl Health {
    /// The health of `episodes` (with `files[i]` what episode `i`'s folder holds; a
    /// missing entry counts as a recording without videos), given the constant and
    /// near-constant dimensions of their statistics. The warnings are left to
    /// `health_report::warnings`.
    pub fn compute(
        flat_dimensions: Vec<FlatDimension>,
        episodes: &[Episode],
        files: &[EpisodeFiles],
    ) -> Self {
        let none = EpisodeFiles::default();
        let files: Vec<EpisodeFiles> = (0..episodes.len())
            .map(|i| files.get(i).unwrap_or(&none).clone())
            .collect();
        let mut by_task: BTreeMap<&str, Vec<usize>> = BTreeMap::new();
        for (i, e) in episodes.iter().enumerate() {
            by_task.entry(e.task.as_str()).or_default().push(i);
        }
        let mut h = Self {
            flat_dimensions,
            ..Self::default()
        };
        for (task, idx) in &by_task {
            let eps: Vec<&Episode> = idx.iter().map(|&i| &episodes[i]).collect();
            h.static_leading.push(static_leading(task, &eps));
            h.lengths.push(length_distribution(task, &eps));
            let labels: Vec<(&str, Option<&ReplayLabel>)> = idx
                .iter()
                .map(|&i| (episodes[i].id.as_str(), files[i].label.as_ref()))
                .collect();
            h.outcomes.push(outcomes(task, &labels));
        }
        h.duplicates = duplicates(episodes, &files);
        h
    }
}
