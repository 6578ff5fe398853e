//! `dataset info`: what a LeRobot v3.0 dataset holds, from its own metadata.

use std::collections::BTreeMap;
use std::path::Path;

use dexjoco_formats::dataset::lerobot_read::LeRobotDataset;
use serde::Serialize;
use serde_json::Value;

use crate::EditError;
use crate::select::column_names;

/// One feature of a dataset.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct FeatureSummary {
    /// Its key (`action`, `observation.images.wrist`).
    pub key: String,
    /// `float32`, `video`, `int64`...
    pub dtype: String,
    /// Its shape.
    pub shape: Vec<u64>,
    /// Videos: codec, pixel format and size as info.json records them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub video: Option<String>,
}

/// What `dataset info` reports.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct DatasetSummary {
    /// The folder.
    pub root: String,
    /// `codebase_version`.
    pub version: String,
    /// `robot_type`.
    pub robot_type: Option<String>,
    /// Frames per second.
    pub fps: f64,
    /// Episodes.
    pub episodes: usize,
    /// Frames.
    pub frames: u64,
    /// Shortest, mean and longest episode (frames).
    pub length_min: i64,
    /// Mean episode length (frames).
    pub length_mean: f64,
    /// Longest episode (frames).
    pub length_max: i64,
    /// Episodes per task.
    pub tasks: BTreeMap<String, usize>,
    /// Every feature.
    pub features: Vec<FeatureSummary>,
    /// Per-episode columns beyond the format's own (labels, randomization, provenance).
    pub custom_columns: Vec<String>,
    /// `splits` of info.json.
    pub splits: BTreeMap<String, String>,
    /// Bytes on disk (data, videos, metadata).
    pub bytes: u64,
}

/// The per-episode columns every LeRobot v3.0 dataset has (and `videos/...`,
/// `stats/...`): the rest are a writer's own.
pub(crate) fn is_format_column(name: &str) -> bool {
    const OWN: [&str; 9] = [
        "episode_index",
        "tasks",
        "length",
        "data/chunk_index",
        "data/file_index",
        "dataset_from_index",
        "dataset_to_index",
        "meta/episodes/chunk_index",
        "meta/episodes/file_index",
    ];
    OWN.contains(&name) || name.starts_with("videos/") || name.starts_with("stats/")
}

/// Describes the dataset at `root`.
pub fn info(root: &Path) -> Result<DatasetSummary, EditError> {
    let ds = LeRobotDataset::open(root)?;
    let lengths = ds.lengths()?;
    let mut tasks = BTreeMap::new();
    for t in ds.episode_tasks()? {
        for name in t {
            *tasks.entry(name).or_insert(0) += 1;
        }
    }
    let raw = ds.features();
    let features = ds
        .meta
        .features
        .iter()
        .map(|(key, f)| FeatureSummary {
            key: key.clone(),
            dtype: f.dtype.clone(),
            shape: f.shape.clone(),
            video: f
                .is_video()
                .then(|| video_text(raw.get(key).map_or(&Value::Null, |f| &f["info"]))),
        })
        .collect();
    let frames: u64 = lengths.iter().map(|l| *l as u64).sum();
    Ok(DatasetSummary {
        root: root.display().to_string(),
        version: ds.meta.codebase_version.clone(),
        robot_type: ds.meta.robot_type.clone(),
        fps: ds.fps,
        episodes: ds.len(),
        frames,
        length_min: lengths.iter().copied().min().unwrap_or(0),
        length_mean: frames as f64 / ds.len().max(1) as f64,
        length_max: lengths.iter().copied().max().unwrap_or(0),
        tasks,
        features,
        custom_columns: column_names(&ds)
            .into_iter()
            .filter(|c| !is_format_column(c))
            .collect(),
        splits: ds.meta.splits.clone(),
        bytes: tree_bytes(root),
    })
}

/// `h264 yuv420p 224x224` from a video feature's `info`.
fn video_text(info: &Value) -> String {
    let s = |k: &str| info[k].as_str().map(str::to_owned);
    let n = |k: &str| info[k].as_u64().map(|v| v.to_string());
    let size = match (n("video.width"), n("video.height")) {
        (Some(w), Some(h)) => Some(format!("{w}x{h}")),
        _ => None,
    };
    [s("video.codec"), s("video.pix_fmt"), size]
        .into_iter()
        .flatten()
        .collect::<Vec<_>>()
        .join(" ")
}

/// Bytes of the files under `dir`: linked files count as their targets (a Hugging Face
/// cache holds links), linked folders are not followed (a link may loop).
fn tree_bytes(dir: &Path) -> u64 {
    let Ok(entries) = fs_err::read_dir(dir) else {
        return 0;
    };
    entries
        .flatten()
        .map(|e| match e.file_type() {
            Ok(t) if t.is_dir() => tree_bytes(&e.path()),
            Ok(t) if t.is_symlink() => fs_err::metadata(e.path())
                .ok()
                .filter(std::fs::Metadata::is_file)
                .map_or(0, |m| m.len()),
            _ => e.metadata().map(|m| m.len()).unwrap_or(0),
        })
        .sum()
}

impl DatasetSummary {
    /// The summary as text for a terminal.
    pub fn text(&self) -> String {
        let mut t = format!(
            "{} (LeRobot {}, {} fps{})\n  {} episodes, {} frames (length {}..{}, mean {:.1}), {:.1} MB\n",
            self.root,
            self.version,
            self.fps,
            self.robot_type
                .as_ref()
                .map_or(String::new(), |r| format!(", robot {r}")),
            self.episodes,
            self.frames,
            self.length_min,
            self.length_max,
            self.length_mean,
            self.bytes as f64 / 1e6
        );
        t.push_str("  tasks:\n");
        for (task, n) in &self.tasks {
            t.push_str(&format!("    {n:>6}  {task}\n"));
        }
        t.push_str("  features:\n");
        for f in &self.features {
            let shape = f.shape.iter().map(u64::to_string).collect::<Vec<_>>();
            t.push_str(&format!(
                "    {:<40} {:<8} [{}]{}\n",
                f.key,
                f.dtype,
                shape.join(", "),
                f.video.as_ref().map_or(String::new(), |v| format!("  {v}"))
            ));
        }
        if !self.custom_columns.is_empty() {
            t.push_str(&format!(
                "  per-episode columns: {}\n",
                self.custom_columns.join(", ")
            ));
        }
        let splits: Vec<String> = self
            .splits
            .iter()
            .map(|(k, v)| format!("{k} {v}"))
            .collect();
        t.push_str(&format!("  splits: {}\n", splits.join(", ")));
        t
    }
}
