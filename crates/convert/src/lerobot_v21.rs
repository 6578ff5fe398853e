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
use std::path::PathBuf;

use serde_json::{Value, json};

use crate::error::ConvertError;
use crate::lerobot_v3::{
    CHUNKS_SIZE, CameraSpec, Ordered, data_columns, index_stats, stats_json, write_json,
};
use crate::parquet_io as pq;
use crate::prepare::PreparedEpisode;
use crate::stats::{FeatureStats, aggregate};

/// Writes a LeRobot v2.1 dataset into `root` (a fresh folder).
pub struct V21Writer {
    root: PathBuf,
    robot_type: Option<String>,
    fps: u32,
    action_names: Vec<String>,
    state_names: Vec<String>,
    cameras: Vec<CameraSpec>,
    episodes: fs_err::File,
    episodes_stats: fs_err::File,
    /// Per episode, its statistics (kept for stats.json; a few hundred numbers each).
    stats: Vec<BTreeMap<String, FeatureStats>>,
    tasks: Vec<String>,
    task_index: HashMap<String, usize>,
    frames: usize,
}

impl std::fmt::Debug for V21Writer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("V21Writer")
            .field("root", &self.root)
            .field("episodes", &self.stats.len())
            .finish_non_exhaustive()
    }
}

fn jsonl_line(file: &mut fs_err::File, value: &Value) -> Result<(), ConvertError> {
    let mut line = serde_json::to_string(value).expect("JSON values serialize");
    line.push('\n');
    file.write_all(line.as_bytes())?;
    Ok(())
}

/// The `huggingface` schema metadata the v2.1 loader builds its features from.
fn hf_metadata(action: usize, state: usize) -> String {
    let seq = |n: usize| json!({"feature": {"dtype": "float32", "_type": "Value"}, "length": n, "_type": "Sequence"});
    let value = |t: &str| json!({"dtype": t, "_type": "Value"});
    let mut features = Ordered::default();
    features.push("action", seq(action));
    features.push("observation.state", seq(state));
    features.push("timestamp", value("float32"));
    for k in ["frame_index", "episode_index", "index", "task_index"] {
        features.push(k, value("int64"));
    }
    serde_json::to_string(&json!({"info": {"features": features}})).expect("serializes")
}

impl V21Writer {
    /// Starts a dataset whose features are those of `first`.
    pub fn try_new(
        root: impl Into<PathBuf>,
        first: &PreparedEpisode,
        robot_type: Option<String>,
    ) -> Result<Self, ConvertError> {
        let root = root.into();
        let meta = root.join("meta");
        fs_err::create_dir_all(&meta)?;
        let open = |name: &str| -> Result<fs_err::File, ConvertError> {
            Ok(fs_err::File::create(meta.join(name))?)
        };
        Ok(Self {
            episodes: open("episodes.jsonl")?,
            episodes_stats: open("episodes_stats.jsonl")?,
            robot_type,
            fps: first.fps,
            action_names: first.action_names.clone(),
            state_names: first.state_names.clone(),
            cameras: CameraSpec::of(first),
            root,
            stats: Vec::new(),
            tasks: Vec::new(),
            task_index: HashMap::new(),
            frames: 0,
        })
    }

    /// Episodes written so far.
    pub fn episodes(&self) -> usize {
        self.stats.len()
    }

    /// Frames written so far.
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// Checks that `ep` can join this dataset (layout, video size and codec).
    pub(crate) fn check_compatible(&self, ep: &PreparedEpisode) -> Result<(), ConvertError> {
        let bad = |m: String| Err(ConvertError::episode(&ep.id, m));
        let want: Vec<&str> = self.cameras.iter().map(|c| c.name.as_str()).collect();
        ep.check_layout(
            self.fps,
            self.action_names.len(),
            self.state_names.len(),
            &want,
        )?;
        for (v, c) in ep.videos.iter().zip(&self.cameras) {
            if (v.info.width, v.info.height) != (c.width, c.height) || v.info.codec != c.codec {
                return bad(format!(
                    "camera '{}': {}x{} {} differs from the dataset's {}x{} {}",
                    c.name, v.info.width, v.info.height, v.info.codec, c.width, c.height, c.codec
                ));
            }
        }
        Ok(())
    }

    /// Writes one episode's parquet and videos and its metadata lines.
    pub fn write_episode(&mut self, ep: PreparedEpisode) -> Result<(), ConvertError> {
        self.check_compatible(&ep)?;
        let n = ep.len();
        let index = self.stats.len();
        let chunk = index / CHUNKS_SIZE;
        let task_index = match self.task_index.get(&ep.instruction) {
            Some(i) => *i,
            None => {
                self.tasks.push(ep.instruction.clone());
                self.task_index
                    .insert(ep.instruction.clone(), self.tasks.len() - 1);
                self.tasks.len() - 1
            }
        };
        let mut stats = ep.stats.clone();
        let timestamps = index_stats(&mut stats, n, self.fps, index, self.frames, task_index);
        let columns = data_columns(&ep, &timestamps, index, self.frames, task_index);
        let batch = pq::batch(
            columns,
            HashMap::from([(
                "huggingface".to_owned(),
                hf_metadata(self.action_names.len(), self.state_names.len()),
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
            fs_err::create_dir_all(dst.parent().expect("has parent"))?;
            if part.temporary {
                fs_err::rename(&part.path, &dst)?;
            } else {
                fs_err::copy(&part.path, &dst)?;
            }
        }

        jsonl_line(
            &mut self.episodes,
            &json!({"episode_index": index, "tasks": [ep.instruction], "length": n}),
        )?;
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

    /// Writes tasks.jsonl, stats.json and info.json.
    pub fn finish(mut self) -> Result<(), ConvertError> {
        self.episodes.flush()?;
        self.episodes_stats.flush()?;
        let meta = self.root.join("meta");
        let mut tasks = fs_err::File::create(meta.join("tasks.jsonl"))?;
        for (i, t) in self.tasks.iter().enumerate() {
            jsonl_line(&mut tasks, &json!({"task_index": i, "task": t}))?;
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

    fn info(&self) -> InfoV21 {
        let mut features = Ordered::default();
        features.push(
            "action",
            json!({"dtype": "float32", "shape": [self.action_names.len()], "names": self.action_names}),
        );
        features.push(
            "observation.state",
            json!({"dtype": "float32", "shape": [self.state_names.len()], "names": self.state_names}),
        );
        for c in &self.cameras {
            features.push(
                &c.key,
                json!({
                    "dtype": "video",
                    "shape": [c.height, c.width, 3],
                    "names": ["height", "width", "channels"],
                    "info": {
                        "video.fps": f64::from(self.fps),
                        "video.height": c.height,
                        "video.width": c.width,
                        "video.channels": 3,
                        "video.codec": c.codec,
                        "video.pix_fmt": c.pix_fmt,
                        "video.is_depth_map": false,
                        "has_audio": false,
                    }
                }),
            );
        }
        features.push(
            "timestamp",
            json!({"dtype": "float32", "shape": [1], "names": null}),
        );
        for k in ["frame_index", "episode_index", "index", "task_index"] {
            features.push(k, json!({"dtype": "int64", "shape": [1], "names": null}));
        }
        let episodes = self.stats.len();
        InfoV21 {
            codebase_version: "v2.1",
            robot_type: self.robot_type.clone(),
            total_episodes: episodes,
            total_frames: self.frames,
            total_tasks: self.tasks.len(),
            total_videos: episodes * self.cameras.len(),
            total_chunks: episodes.div_ceil(CHUNKS_SIZE),
            chunks_size: CHUNKS_SIZE,
            fps: self.fps,
            splits: BTreeMap::from([("train", format!("0:{episodes}"))]),
            data_path: "data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}.parquet",
            video_path: (!self.cameras.is_empty()).then_some(
                "videos/chunk-{episode_chunk:03d}/{video_key}/episode_{episode_index:06d}.mp4",
            ),
            features,
        }
    }
}

#[derive(Debug, serde::Serialize)]
struct InfoV21 {
    codebase_version: &'static str,
    robot_type: Option<String>,
    total_episodes: usize,
    total_frames: usize,
    total_tasks: usize,
    total_videos: usize,
    total_chunks: usize,
    chunks_size: usize,
    fps: u32,
    splits: BTreeMap<&'static str, String>,
    data_path: &'static str,
    video_path: Option<&'static str>,
    features: Ordered,
}
