//! LeRobot metadata shared by v3.0 and v2.1: the typed `meta/info.json` ([`Info`], its
//! [`Feature`]s and their [`DType`]s), the camera features of a dataset and the check
//! that an episode's videos fit them, and statistics as `stats.json` writes them.
//!
//! Keys are written in declaration order, which is the order lerobot writes them; the
//! two versions differ in the order of `info.json`'s top-level keys and in the keys of a
//! video feature's `info`.

use std::collections::{BTreeMap, HashMap};

use dexjoco_video::VideoInfo;
use serde::Serialize;
use serde_json::{Value, json};

use super::depth::{DEPTH_CODEC, DEPTH_PIX_FMT, DepthVideoMeta, depth_key};
use super::stats::FeatureStats;
use super::{PreparedEpisode, VideoPart};
use crate::error::DatasetError;

/// A camera feature of the dataset, from its first episode's video part.
#[derive(Debug, Clone)]
pub struct CameraSpec {
    /// Output camera name.
    pub name: String,
    /// Feature key, `observation.images.<name>`.
    pub key: String,
    /// Frame width.
    pub width: u32,
    /// Frame height.
    pub height: u32,
    /// Codec as ffprobe names it.
    pub codec: String,
    /// Pixel format as ffprobe names it.
    pub pix_fmt: String,
    /// Whether the first episode's video is the source, stream-copied (else encoded).
    pub copied: bool,
}

impl CameraSpec {
    /// The camera features of a dataset whose first episode is `first`.
    pub fn of(first: &PreparedEpisode) -> Vec<Self> {
        first
            .videos
            .iter()
            .map(|v| Self {
                name: v.name.clone(),
                key: format!("observation.images.{}", v.name),
                width: v.info.width,
                height: v.info.height,
                codec: v.info.codec.clone(),
                pix_fmt: v.info.pix_fmt.clone(),
                copied: v.copied,
            })
            .collect()
    }

    /// Whether a video of this size, codec and pixel format is this camera's.
    fn fits(&self, v: &VideoInfo) -> bool {
        (v.width, v.height) == (self.width, self.height)
            && v.codec == self.codec
            && v.pix_fmt == self.pix_fmt
    }
}

/// Checks that `ep` fits a LeRobot dataset of `fps`, these widths and `cameras` (layout,
/// and each video's size, codec and pixel format); `mismatch` words a video that does
/// not fit its camera.
pub(crate) fn check_episode(
    ep: &PreparedEpisode,
    fps: u32,
    widths: (usize, usize),
    cameras: &[CameraSpec],
    mismatch: impl Fn(&CameraSpec, &VideoInfo) -> String,
) -> Result<(), DatasetError> {
    let want: Vec<&str> = cameras.iter().map(|c| c.name.as_str()).collect();
    ep.check_layout(fps, widths.0, widths.1, &want)?;
    for (v, c) in ep.videos.iter().zip(cameras) {
        if !c.fits(&v.info) {
            return Err(DatasetError::episode(&ep.id, mismatch(c, &v.info)));
        }
    }
    Ok(())
}

/// A feature's data type.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum DType {
    /// 32-bit float values.
    Float32,
    /// 64-bit integers.
    Int64,
    /// Frames of a video file.
    Video,
    /// lerobot 0.6's language rows (lists of row structs).
    Language,
}

/// One feature of `info.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Feature {
    /// Data type.
    pub dtype: DType,
    /// Shape of one frame's value.
    pub shape: Vec<u64>,
    /// Column names (height, width, channels for videos); null for the index features.
    pub names: Option<Vec<String>>,
    /// Video stream details (videos only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub info: Option<VideoMeta>,
}

/// A video feature's `info`, as each version writes it.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum VideoMeta {
    /// LeRobot v3.0, with the encoder settings.
    V3(VideoMetaV3),
    /// LeRobot v2.1.
    V21(VideoMetaV21),
    /// A depth map (LeRobot v3.0), as lerobot 0.6.1 describes it.
    Depth(DepthVideoMeta),
}

/// A LeRobot v3.0 video feature's `info`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VideoMetaV3 {
    /// Frame height.
    #[serde(rename = "video.height")]
    pub height: u32,
    /// Frame width.
    #[serde(rename = "video.width")]
    pub width: u32,
    /// Codec.
    #[serde(rename = "video.codec")]
    pub codec: String,
    /// Pixel format.
    #[serde(rename = "video.pix_fmt")]
    pub pix_fmt: String,
    /// Always false.
    #[serde(rename = "video.is_depth_map")]
    pub video_is_depth_map: bool,
    /// Frames per second.
    #[serde(rename = "video.fps")]
    pub fps: u32,
    /// Always 3.
    #[serde(rename = "video.channels")]
    pub channels: u32,
    /// GOP size of encoded videos (null for stream-copied sources).
    #[serde(rename = "video.g")]
    pub g: Option<u32>,
    /// CRF of encoded videos.
    #[serde(rename = "video.crf")]
    pub crf: Option<u32>,
    /// Encoder preset of AV1-encoded videos.
    #[serde(rename = "video.preset")]
    pub preset: Option<u32>,
    /// Always 0.
    #[serde(rename = "video.fast_decode")]
    pub fast_decode: u32,
    /// Always null.
    #[serde(rename = "video.video_backend")]
    pub video_backend: Option<String>,
    /// Always empty.
    #[serde(rename = "video.extra_options")]
    pub extra_options: BTreeMap<String, String>,
    /// Always false.
    pub has_audio: bool,
    /// Always false.
    pub is_depth_map: bool,
}

/// A LeRobot v2.1 video feature's `info`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VideoMetaV21 {
    /// Frames per second (written as a float).
    #[serde(rename = "video.fps")]
    pub fps: f64,
    /// Frame height.
    #[serde(rename = "video.height")]
    pub height: u32,
    /// Frame width.
    #[serde(rename = "video.width")]
    pub width: u32,
    /// Always 3.
    #[serde(rename = "video.channels")]
    pub channels: u32,
    /// Codec.
    #[serde(rename = "video.codec")]
    pub codec: String,
    /// Pixel format.
    #[serde(rename = "video.pix_fmt")]
    pub pix_fmt: String,
    /// Always false.
    #[serde(rename = "video.is_depth_map")]
    pub video_is_depth_map: bool,
    /// Always false.
    pub has_audio: bool,
}

/// Features by key, in the order they are written.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Features(pub Vec<(String, Feature)>);

impl Serialize for Features {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_map(self.0.iter().map(|(k, v)| (k, v)))
    }
}

impl Features {
    /// The features of a LeRobot dataset: action, state, the cameras (each with its
    /// `video` info), timestamp and the four indices.
    pub fn lerobot(
        action_names: &[String],
        state_names: &[String],
        cameras: &[CameraSpec],
        video: impl Fn(&CameraSpec) -> VideoMeta,
    ) -> Self {
        let vector = |names: &[String]| Feature {
            dtype: DType::Float32,
            shape: vec![names.len() as u64],
            names: Some(names.to_vec()),
            info: None,
        };
        let scalar = |dtype| Feature {
            dtype,
            shape: vec![1],
            names: None,
            info: None,
        };
        let mut features = vec![
            ("action".to_owned(), vector(action_names)),
            ("observation.state".to_owned(), vector(state_names)),
        ];
        for c in cameras {
            let feature = Feature {
                dtype: DType::Video,
                // Depth maps (gray) have one channel.
                shape: vec![
                    u64::from(c.height),
                    u64::from(c.width),
                    if c.pix_fmt.starts_with("gray") { 1 } else { 3 },
                ],
                names: Some(["height", "width", "channels"].map(String::from).to_vec()),
                info: Some(video(c)),
            };
            features.push((c.key.clone(), feature));
        }
        features.push(("timestamp".to_owned(), scalar(DType::Float32)));
        for k in ["frame_index", "episode_index", "index", "task_index"] {
            features.push((k.to_owned(), scalar(DType::Int64)));
        }
        Self(features)
    }
}

impl Features {
    /// With lerobot 0.6's two language columns (when `language`), after the others.
    #[must_use]
    pub fn with_language(mut self, language: bool) -> Self {
        if language {
            for key in [
                super::language::LANGUAGE_PERSISTENT,
                super::language::LANGUAGE_EVENTS,
            ] {
                let feature = Feature {
                    dtype: DType::Language,
                    shape: vec![1],
                    names: None,
                    info: None,
                };
                self.0.push((key.to_owned(), feature));
            }
        }
        self
    }

    /// With a per-frame `subtask_index` (LeRobot v2.1), after `task_index`.
    #[must_use]
    pub fn with_subtask_index(mut self, subtasks: bool) -> Self {
        if subtasks {
            let at = self
                .0
                .iter()
                .position(|(k, _)| k == "task_index")
                .map_or(self.0.len(), |i| i + 1);
            let feature = Feature {
                dtype: DType::Int64,
                shape: vec![1],
                names: None,
                info: None,
            };
            self.0
                .insert(at, (super::language::SUBTASK_INDEX.to_owned(), feature));
        }
        self
    }

    /// These features with the vector features `layout` (`--environment-state`,
    /// `--privileged-state`: float32 with one name per column) after `observation.state`,
    /// in order.
    #[must_use]
    pub fn with_vectors(mut self, layout: &[(String, Vec<String>)]) -> Self {
        let at = self
            .0
            .iter()
            .position(|(k, _)| k == "observation.state")
            .map_or(self.0.len(), |i| i + 1);
        let added = layout.iter().map(|(key, names)| {
            let feature = Feature {
                dtype: DType::Float32,
                shape: vec![names.len() as u64],
                names: Some(names.clone()),
                info: None,
            };
            (key.clone(), feature)
        });
        self.0.splice(at..at, added);
        self
    }
}

/// `meta/info.json` of a LeRobot dataset.
#[derive(Debug, Clone, PartialEq)]
pub struct Info {
    /// What only one version records (and the version itself).
    pub version: InfoVersion,
    /// `robot_type`.
    pub robot_type: Option<String>,
    /// Frames per second.
    pub fps: u32,
    /// Every feature.
    pub features: Features,
    /// Episodes.
    pub total_episodes: usize,
    /// Frames.
    pub total_frames: usize,
    /// Tasks (instructions).
    pub total_tasks: usize,
    /// Episodes (v2.1) or files (v3.0) per chunk folder.
    pub chunks_size: usize,
    /// `{"train": "0:<episodes>"}`.
    pub splits: BTreeMap<String, String>,
    /// Data file path template.
    pub data_path: &'static str,
    /// Video file path template; null without cameras.
    pub video_path: Option<&'static str>,
}

/// The `info.json` keys of one LeRobot version.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InfoVersion {
    /// `codebase_version` "v3.0".
    V3 {
        /// Data file size cap in MB.
        data_files_size_in_mb: u64,
        /// Video file size cap in MB.
        video_files_size_in_mb: u64,
    },
    /// `codebase_version` "v2.1".
    V21 {
        /// Video files (episodes x cameras).
        total_videos: usize,
        /// Chunk folders.
        total_chunks: usize,
    },
}

/// `info.json` of v3.0, in its key order.
#[derive(Serialize)]
struct InfoV3<'a> {
    codebase_version: &'static str,
    fps: u32,
    features: &'a Features,
    total_episodes: usize,
    total_frames: usize,
    total_tasks: usize,
    chunks_size: usize,
    data_files_size_in_mb: u64,
    video_files_size_in_mb: u64,
    data_path: &'static str,
    video_path: Option<&'static str>,
    robot_type: &'a Option<String>,
    splits: &'a BTreeMap<String, String>,
}

/// `info.json` of v2.1, in its key order.
#[derive(Serialize)]
struct InfoV21<'a> {
    codebase_version: &'static str,
    robot_type: &'a Option<String>,
    total_episodes: usize,
    total_frames: usize,
    total_tasks: usize,
    total_videos: usize,
    total_chunks: usize,
    chunks_size: usize,
    fps: u32,
    splits: &'a BTreeMap<String, String>,
    data_path: &'static str,
    video_path: Option<&'static str>,
    features: &'a Features,
}

impl Serialize for Info {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self.version {
            InfoVersion::V3 {
                data_files_size_in_mb,
                video_files_size_in_mb,
            } => InfoV3 {
                codebase_version: "v3.0",
                fps: self.fps,
                features: &self.features,
                total_episodes: self.total_episodes,
                total_frames: self.total_frames,
                total_tasks: self.total_tasks,
                chunks_size: self.chunks_size,
                data_files_size_in_mb,
                video_files_size_in_mb,
                data_path: self.data_path,
                video_path: self.video_path,
                robot_type: &self.robot_type,
                splits: &self.splits,
            }
            .serialize(s),
            InfoVersion::V21 {
                total_videos,
                total_chunks,
            } => InfoV21 {
                codebase_version: "v2.1",
                robot_type: &self.robot_type,
                total_episodes: self.total_episodes,
                total_frames: self.total_frames,
                total_tasks: self.total_tasks,
                total_videos,
                total_chunks,
                chunks_size: self.chunks_size,
                fps: self.fps,
                splits: &self.splits,
                data_path: self.data_path,
                video_path: self.video_path,
                features: &self.features,
            }
            .serialize(s),
        }
    }
}

/// The task table: instructions in the order they first appear.
#[derive(Debug, Default)]
pub(crate) struct Tasks {
    list: Vec<String>,
    index: HashMap<String, usize>,
}

impl Tasks {
    /// The task index of `instruction`, added to the table when new.
    pub(crate) fn index_of(&mut self, instruction: &str) -> usize {
        match self.index.get(instruction) {
            Some(i) => *i,
            None => {
                self.list.push(instruction.to_owned());
                self.index
                    .insert(instruction.to_owned(), self.list.len() - 1);
                self.list.len() - 1
            }
        }
    }

    /// The instructions by task index.
    pub(crate) fn list(&self) -> &[String] {
        &self.list
    }
}

/// `{"train": "0:<episodes>"}`.
pub(crate) fn train_split(episodes: usize) -> BTreeMap<String, String> {
    BTreeMap::from([("train".to_owned(), format!("0:{episodes}"))])
}

/// `{min, max, mean, std, count, q01..q99}`; images as 3x1x1 nested lists.
pub fn stats_json(s: &FeatureStats, image: bool) -> Value {
    let mut m = serde_json::Map::new();
    let shape = |v: &[f64]| -> Value {
        if image {
            Value::Array(v.iter().map(|x| json!([[x]])).collect())
        } else {
            json!(v)
        }
    };
    for (k, v) in s.named() {
        m.insert(k.to_owned(), shape(v));
    }
    m.insert("count".into(), json!([s.count]));
    Value::Object(m)
}

/// The depth camera features of a dataset whose first episode is `first` (from its depth
/// parts' encoded videos), named `<camera>_depth`.
pub(crate) fn depth_camera_specs(first: &PreparedEpisode) -> Vec<CameraSpec> {
    first
        .depth
        .iter()
        .map(|d| CameraSpec {
            name: format!("{}_depth", d.name),
            key: depth_key(&d.name),
            width: d.width as u32,
            height: d.height as u32,
            codec: DEPTH_CODEC.into(),
            pix_fmt: DEPTH_PIX_FMT.into(),
            copied: false,
        })
        .collect()
}

/// The encoded depth videos of `ep`, checked against the dataset's depth features.
pub(crate) fn encoded_depth_parts<'a>(
    ep: &'a PreparedEpisode,
    specs: &[CameraSpec],
) -> Result<Vec<&'a VideoPart>, DatasetError> {
    let names: Vec<&str> = ep.depth.iter().map(|d| d.name.as_str()).collect();
    let want: Vec<&str> = specs
        .iter()
        .map(|s| s.name.trim_end_matches("_depth"))
        .collect();
    if names != want {
        return Err(DatasetError::episode(
            &ep.id,
            format!("depth of cameras {names:?} differs from the dataset's {want:?}"),
        ));
    }
    let mut parts = Vec::new();
    for (d, s) in ep.depth.iter().zip(specs) {
        let Some(v) = d.video.as_ref() else {
            return Err(DatasetError::episode(
                &ep.id,
                format!("the depth of camera '{}' was not encoded", d.name),
            ));
        };
        if (d.width as u32, d.height as u32) != (s.width, s.height) {
            return Err(DatasetError::episode(
                &ep.id,
                format!(
                    "depth of camera '{}' ('{}'): {}x{} differs from the dataset's {}x{}",
                    d.name,
                    d.path.display(),
                    d.width,
                    d.height,
                    s.width,
                    s.height
                ),
            ));
        }
        parts.push(v);
    }
    Ok(parts)
}
