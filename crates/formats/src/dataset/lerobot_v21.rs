//! The LeRobot v2.1 writer (what openpi's pinned lerobot reads): one parquet and one mp4
//! per camera for each episode, jsonl metadata with per-episode statistics.
//!
//! ```text
//! meta/info.json              codebase_version "v2.1", total_chunks, total_videos
//! meta/episodes.jsonl         {"episode_index", "tasks", "length"}
//! meta/tasks.jsonl            {"task_index", "task"}
//! meta/episodes_stats.jsonl   {"episode_index", "stats": {feature: {min, max, mean, std, count, q01..q99}}}
//! meta/stats.json             the statistics aggregated over episodes
//! data/chunk-{chunk:03}/episode_{episode:06}.parquet   (with `huggingface` schema metadata)
//! videos/chunk-{chunk:03}/{video_key}/episode_{episode:06}.mp4   (timestamps from 0)
//! ```

use std::collections::{BTreeMap, HashMap};
use std::io::Write;
use std::path::{Path, PathBuf};

use serde_json::{Value, json};

use super::episode_labels::label_columns;
use super::language::{SUBTASK_INDEX, SubtaskTexts};
use super::lerobot_info::{
    CameraSpec, Features, Info, InfoVersion, Tasks, VideoMeta, VideoMetaV21, check_episode,
    stats_json, train_split,
};
use super::lerobot_v3::{CHUNKS_SIZE, data_columns, index_stats};
use super::parquet as pq;
use super::stats::column_stats;
use super::stats::{FeatureStats, aggregate};
use super::{DatasetWriter, PreparedEpisode, place_video, write_json};
use crate::error::DatasetError;
use crate::raw::ReplayLabel;

/// Writes a LeRobot v2.1 dataset into `root` (a fresh folder).
pub struct V21Writer {
    root: PathBuf,
    robot_type: Option<String>,
    fps: u32,
    action_names: Vec<String>,
    state_names: Vec<String>,
    /// The vector features' keys and column names (`--environment-state`, ...).
    vectors: Vec<(String, Vec<String>)>,
    cameras: Vec<CameraSpec>,
    episodes: fs_err::File,
    episodes_stats: fs_err::File,
    /// Per episode, its statistics (kept for stats.json; a few hundred numbers each).
    stats: Vec<BTreeMap<String, FeatureStats>>,
    /// Per episode, its `episodes.jsonl` line and replay record (the labels are added
    /// to the lines at the end, when some episode has a record).
    lines: Vec<(Value, Option<ReplayLabel>)>,
    tasks: Tasks,
    frames: usize,
    /// The subtask texts `subtask_index` indexes, when the episodes carry subtasks (as
    /// the first one does).
    subtasks: Option<SubtaskTexts>,
}

impl std::fmt::Debug for V21Writer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("V21Writer")
            .field("root", &self.root)
            .field("episodes", &self.stats.len())
            .finish_non_exhaustive()
    }
}

fn jsonl_line(file: &mut fs_err::File, value: &Value) -> Result<(), DatasetError> {
    let mut line = serde_json::to_string(value).expect("JSON values serialize");
    line.push('\n');
    file.write_all(line.as_bytes())?;
    Ok(())
}

/// The `huggingface` schema metadata the v2.1 loader builds its features from.
fn hf_metadata(
    action: usize,
    state: usize,
    vectors: &[(String, Vec<String>)],
    subtasks: bool,
) -> String {
    let seq = |n: usize| json!({"feature": {"dtype": "float32", "_type": "Value"}, "length": n, "_type": "Sequence"});
    let value = |t: &str| json!({"dtype": t, "_type": "Value"});
    // serde_json keeps insertion order (its `preserve_order`, which zarrs turns on).
    let mut features = serde_json::Map::new();
    features.insert("action".into(), seq(action));
    features.insert("observation.state".into(), seq(state));
    for (key, names) in vectors {
        features.insert(key.clone(), seq(names.len()));
    }
    features.insert("timestamp".into(), value("float32"));
    for k in ["frame_index", "episode_index", "index", "task_index"] {
        features.insert(k.into(), value("int64"));
    }
    if subtasks {
        features.insert(SUBTASK_INDEX.into(), value("int64"));
    }
    serde_json::to_string(&json!({"info": {"features": features}})).expect("serializes")
}

impl V21Writer {
    /// Starts a dataset whose features are those of `first`.
    pub fn try_new(
        root: impl Into<PathBuf>,
        first: &PreparedEpisode,
        robot_type: Option<String>,
    ) -> Result<Self, DatasetError> {
        let root = root.into();
        let meta = root.join("meta");
        fs_err::create_dir_all(&meta)?;
        let open = |name: &str| -> Result<fs_err::File, DatasetError> {
            Ok(fs_err::File::create(meta.join(name))?)
        };
        Ok(Self {
            episodes: open("episodes.jsonl")?,
            episodes_stats: open("episodes_stats.jsonl")?,
            robot_type,
            fps: first.fps,
            action_names: first.action_names.clone(),
            state_names: first.state_names.clone(),
            vectors: first.vector_layout(),
            cameras: CameraSpec::of(first),
            root,
            stats: Vec::new(),
            lines: Vec::new(),
            tasks: Tasks::default(),
            frames: 0,
            subtasks: (!first.subtasks.is_empty()).then(SubtaskTexts::default),
        })
    }

    fn info(&self) -> Info {
        let features =
            Features::lerobot(&self.action_names, &self.state_names, &self.cameras, |c| {
                VideoMeta::V21(VideoMetaV21 {
                    fps: f64::from(self.fps),
                    height: c.height,
                    width: c.width,
                    channels: 3,
                    codec: c.codec.clone(),
                    pix_fmt: c.pix_fmt.clone(),
                    video_is_depth_map: false,
                    has_audio: false,
                })
            })
            .with_vectors(&self.vectors)
            .with_subtask_index(self.subtasks.is_some());
        let episodes = self.stats.len();
        Info {
            version: InfoVersion::V21 {
                total_videos: episodes * self.cameras.len(),
                total_chunks: episodes.div_ceil(CHUNKS_SIZE),
            },
            robot_type: self.robot_type.clone(),
            fps: self.fps,
            features,
            total_episodes: episodes,
            total_frames: self.frames,
            total_tasks: self.tasks.list().len(),
            chunks_size: CHUNKS_SIZE,
            splits: train_split(episodes),
            data_path: "data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}.parquet",
            video_path: (!self.cameras.is_empty()).then_some(
                "videos/chunk-{episode_chunk:03d}/{video_key}/episode_{episode_index:06d}.mp4",
            ),
        }
    }
}

impl V21Writer {
    /// Rewrites `episodes.jsonl` with the label columns ([`label_columns`]) in every line
    /// when some episode has a replay record (lerobot 0.6.1's v2.1 -> v3.0 script carries
    /// a line's keys into the v3.0 episode metadata).
    fn add_labels(&mut self, meta: &Path) -> Result<(), DatasetError> {
        let labels: Vec<Option<&ReplayLabel>> =
            self.lines.iter().map(|(_, l)| l.as_ref()).collect();
        let columns = label_columns(&labels);
        if columns.is_empty() {
            return Ok(());
        }
        let mut file = fs_err::File::create(meta.join("episodes.jsonl"))?;
        for (i, (line, _)) in self.lines.iter().enumerate() {
            let mut line = line.clone();
            let obj = line.as_object_mut().expect("an object");
            for (name, values) in &columns {
                obj.insert(name.clone(), values.json(i));
            }
            jsonl_line(&mut file, &line)?;
        }
        file.flush()?;
        Ok(())
    }
}

impl DatasetWriter for V21Writer {
    /// Checks that `ep` can join this dataset (layout, video size, codec and pixel format).
    fn check_compatible(&self, ep: &PreparedEpisode) -> Result<(), DatasetError> {
        ep.check_vectors(&self.vectors)?;
        check_episode(
            ep,
            self.fps,
            (self.action_names.len(), self.state_names.len()),
            &self.cameras,
            |c, v| {
                // v2.1 encodes every video alike, so the pixel formats agree in practice.
                let (ours, theirs) = if v.pix_fmt == c.pix_fmt {
                    (v.codec.clone(), c.codec.clone())
                } else {
                    (
                        format!("{} {}", v.codec, v.pix_fmt),
                        format!("{} {}", c.codec, c.pix_fmt),
                    )
                };
                format!(
                    "camera '{}': {}x{} {ours} differs from the dataset's {}x{} {theirs}",
                    c.name, v.width, v.height, c.width, c.height
                )
            },
        )
    }

    /// Writes one episode's parquet and videos and its metadata lines.
    fn write_episode(&mut self, ep: PreparedEpisode) -> Result<(), DatasetError> {
        self.check_compatible(&ep)?;
        let n = ep.len();
        let index = self.stats.len();
        let chunk = index / CHUNKS_SIZE;
        let task_index = self.tasks.index_of(&ep.instruction);
        let mut stats = ep.stats.clone();
        let timestamps = index_stats(&mut stats, n, self.fps, index, self.frames, task_index);
        let mut columns = data_columns(&ep, &timestamps, index, self.frames, task_index);
        if let Some(texts) = &mut self.subtasks {
            let idx = texts.frame_indices(&ep.subtasks, n);
            let values: Vec<f64> = idx.iter().map(|&i| i as f64).collect();
            stats.insert(SUBTASK_INDEX.into(), column_stats(&values, 1));
            columns.push((SUBTASK_INDEX.to_owned(), pq::i64_column(idx)));
        }
        let batch = pq::batch(
            columns,
            HashMap::from([(
                "huggingface".to_owned(),
                hf_metadata(
                    self.action_names.len(),
                    self.state_names.len(),
                    &self.vectors,
                    self.subtasks.is_some(),
                ),
            )]),
        );
        let path = self
            .root
            .join(format!("data/chunk-{chunk:03}/episode_{index:06}.parquet"));
        fs_err::create_dir_all(path.parent().expect("has parent"))?;
        pq::write_file(&path, &batch)?;

        for (part, cam) in ep.videos.iter().zip(&self.cameras) {
            let dst = self.root.join(format!(
                "videos/chunk-{chunk:03}/{}/episode_{index:06}.mp4",
                cam.key
            ));
            place_video(part, &dst)?;
        }

        let line = json!({"episode_index": index, "tasks": [ep.instruction], "length": n});
        jsonl_line(&mut self.episodes, &line)?;
        self.lines.push((line, ep.label.clone()));
        let mut st = serde_json::Map::new();
        for (key, s) in &stats {
            st.insert(
                key.clone(),
                stats_json(s, key.starts_with("observation.images.")),
            );
        }
        jsonl_line(
            &mut self.episodes_stats,
            &json!({"episode_index": index, "stats": st}),
        )?;
        self.stats.push(stats);
        self.frames += n;
        Ok(())
    }

    fn episodes(&self) -> usize {
        self.stats.len()
    }

    fn frames(&self) -> usize {
        self.frames
    }

    /// Writes tasks.jsonl, stats.json and info.json.
    fn finish(mut self: Box<Self>) -> Result<(), DatasetError> {
        self.episodes.flush()?;
        self.episodes_stats.flush()?;
        let meta = self.root.join("meta");
        self.add_labels(&meta)?;
        let mut tasks = fs_err::File::create(meta.join("tasks.jsonl"))?;
        for (i, t) in self.tasks.list().iter().enumerate() {
            jsonl_line(&mut tasks, &json!({"task_index": i, "task": t}))?;
        }
        if let Some(texts) = &self.subtasks {
            let mut file = fs_err::File::create(meta.join("subtasks.jsonl"))?;
            for (i, t) in texts.list().iter().enumerate() {
                jsonl_line(&mut file, &json!({"subtask_index": i, "subtask": t}))?;
            }
        }
        let mut agg = serde_json::Map::new();
        if let Some(first) = self.stats.first() {
            for key in first.keys() {
                let per: Vec<&FeatureStats> = self.stats.iter().map(|s| &s[key]).collect();
                let a = aggregate(&per).expect("at least one episode");
                agg.insert(
                    key.clone(),
                    stats_json(&a, key.starts_with("observation.images.")),
                );
            }
        }
        write_json(&meta.join("stats.json"), &Value::Object(agg))?;
        write_json(&meta.join("info.json"), &self.info())?;
        Ok(())
    }
}
