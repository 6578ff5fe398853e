//! Training datasets, written episode by episode behind one trait, [`DatasetWriter`]:
//!
//! - [`lerobot_v3`]: LeRobot v3.0 (what lerobot >= 0.4 reads): size-capped parquet data
//!   files (one row group per episode), per-camera videos joined by stream copy, `meta/`.
//! - [`lerobot_v21`]: LeRobot v2.1 (openpi's pinned lerobot): per-episode parquet and
//!   mp4s, jsonl metadata with per-episode statistics.
//! - [`diffusion_policy`]: Diffusion Policy's `replay_buffer.zarr` (Zarr v2), images
//!   decoded into uint8 (T, H, W, 3), optionally the videos beside it.
//!
//! A writer takes its layout (fps, widths, cameras) from the first episode it is made
//! with and appends [`PreparedEpisode`]s of that layout; selecting, trimming, encoding
//! and measuring episodes is the caller's (`dexjoco-convert`). [`lerobot_info`] holds the
//! typed `info.json` both LeRobot versions write, [`stats`] the statistics as lerobot
//! computes them, `parquet` the column builders, [`episode_labels`] the replays' outcome and
//! randomization columns.

pub mod depth;
pub mod diffusion_policy;
pub mod episode_labels;
pub mod language;
pub mod lerobot_info;
pub mod lerobot_meta;
pub mod lerobot_read;
pub mod lerobot_v21;
pub mod lerobot_v3;
pub mod parquet;
pub mod stats;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use dexjoco_core::FrameArray;
use dexjoco_video::VideoInfo;
use serde::Serialize;

use crate::error::DatasetError;
use crate::raw::ReplayLabel;
use stats::FeatureStats;

pub use diffusion_policy::{REPLAY_BUFFER, ZarrWriter};
pub use lerobot_v3::{
    CHUNKS_SIZE, DEFAULT_DATA_FILE_MB, DEFAULT_VIDEO_FILE_MB, V3Options, V3Writer,
};
pub use lerobot_v21::V21Writer;

/// The LeRobot feature key of the privileged state (`--privileged-state`): outside
/// `observation.*`, so lerobot's policies do not take it as an input.
pub const PRIVILEGED_KEY: &str = "privileged.state";

/// The LeRobot feature key of the environment state (`--environment-state`): LeRobot's own
/// key, which its ACT and Diffusion Policy take as an input.
pub const ENVIRONMENT_STATE_KEY: &str = "observation.environment_state";

/// A float feature of an episode beyond its action and state, one row per kept frame and
/// one name per column: the environment state ([`ENVIRONMENT_STATE_KEY`]), the
/// privileged state ([`PRIVILEGED_KEY`]). Every writer stores them the same way (float32
/// columns in LeRobot, float64 arrays in Diffusion Policy's store).
#[derive(Debug, Clone, PartialEq)]
pub struct VectorFeature {
    /// The LeRobot feature key.
    pub key: String,
    /// Column names (`mouse.pose[0]` ... `dh[0]`).
    pub names: Vec<String>,
    /// The rows.
    pub values: FrameArray,
}

impl VectorFeature {
    /// The array name in Diffusion Policy's store: the key without `observation.`, dots
    /// as underscores (`environment_state`, `privileged_state`).
    pub fn zarr_name(key: &str) -> String {
        key.trim_start_matches("observation.").replace('.', "_")
    }
}

/// A dataset being written: episodes of one layout appended in order, then finished.
pub trait DatasetWriter: std::fmt::Debug {
    /// Checks that `ep` can join this dataset (fps, widths, cameras and their videos).
    fn check_compatible(&self, ep: &PreparedEpisode) -> Result<(), DatasetError>;

    /// Appends one episode (checked with [`Self::check_compatible`] first).
    fn write_episode(&mut self, ep: PreparedEpisode) -> Result<(), DatasetError>;

    /// Episodes written so far.
    fn episodes(&self) -> usize;

    /// Frames written so far.
    fn frames(&self) -> usize;

    /// Closes the files and writes the dataset's metadata.
    fn finish(self: Box<Self>) -> Result<(), DatasetError>;
}

/// How a format lays its videos out; decides when a source video is encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum VideoLayout {
    /// Episodes joined into shared files by stream copy (LeRobot v3.0): the source is
    /// used as it is (trimmed by timestamps) when its codec fits.
    #[default]
    Joined,
    /// One file per episode starting at its first kept frame (Diffusion Policy
    /// `--videos`): the source is copied when nothing is trimmed and its codec is the
    /// chosen one.
    PerEpisode,
    /// One file per episode, every one encoded with the same settings (LeRobot v2.1:
    /// lerobot's v2.1 -> v3.0 script joins them by stream copy, which needs files from
    /// one encoder configuration).
    Encoded,
    /// No video output, only decoded frames (Diffusion Policy images): never encoded.
    Frames,
}

/// A camera's frames for one episode, as a part of the dataset's video file.
#[derive(Debug, Clone)]
pub struct VideoPart {
    /// Output camera name (the feature key is `observation.images.<name>`).
    pub name: String,
    /// The mp4 to join (the source, or an encoded file in the work folder).
    pub path: PathBuf,
    /// Whether `path` is a temporary file of ours.
    pub temporary: bool,
    /// Frames of `path` before the episode's first kept frame.
    pub skip: usize,
    /// Frames of `path` up to the episode's last (an evaluated rollout's video holds one
    /// more after it).
    pub frames: usize,
    /// Size of `path` in bytes.
    pub bytes: u64,
    /// Codec, size and pixel format of `path`.
    pub info: VideoInfo,
    /// Whether the part is the source, stream-copied (or smart-cut from it).
    pub copied: bool,
    /// Frames a smart cut re-encoded (the source's frames before its first keyframe at or
    /// after the cut); 0 for a plain stream copy or an encoded part.
    pub reencoded_frames: usize,
    /// The source video (all frames, before trimming).
    pub source: PathBuf,
}

/// An episode ready to be written.
#[derive(Debug, Clone)]
pub struct PreparedEpisode {
    /// Episode id.
    pub id: String,
    /// Task id.
    pub task: String,
    /// Language instruction.
    pub instruction: String,
    /// Frames per second (integer).
    pub fps: u32,
    /// Selected action, from the first kept frame.
    pub action: FrameArray,
    /// Selected state columns, from the first kept frame.
    pub state: FrameArray,
    /// Column names of the action.
    pub action_names: Vec<String>,
    /// Column names of the state.
    pub state_names: Vec<String>,
    /// Leading frames skipped.
    pub skipped: usize,
    /// Per output camera, in name order.
    pub videos: Vec<VideoPart>,
    /// Statistics of action, state and each camera (`observation.images.<name>`).
    pub stats: BTreeMap<String, FeatureStats>,
    /// The replay's record (outcome, render flags, randomization draw) for a replay
    /// made by augment; `None` for a recording.
    pub label: Option<ReplayLabel>,
    /// Float features beyond action and state, in the order they are written: the
    /// environment state (`--environment-state`), then the privileged state
    /// (`--privileged-state`: the task spec's non-proprioceptive state columns, objects'
    /// reset-time poses and `dh`).
    pub vectors: Vec<VectorFeature>,
    /// With `--depth`: per output camera, in name order, its depth archive.
    pub depth: Vec<DepthPart>,
    /// Where the running subtasks change (from the replay's subtask spans); empty for an
    /// episode without them.
    pub subtasks: Vec<language::SubtaskRow>,
    /// The episode's prompt variants (`task_aug` rows in LeRobot v3.0): the instruction
    /// first, then its paraphrases from the task spec or an instructions file.
    pub task_aug: Vec<String>,
}

/// A camera's depth for one episode: augment's `videos/<camera>_depth.npz` (key
/// `depth`, float32 (T, H, W), metres).
#[derive(Debug, Clone)]
pub struct DepthPart {
    /// Output camera name (the same as its colour video's).
    pub name: String,
    /// The archive.
    pub path: PathBuf,
    /// Frames of the archive before the episode's first kept frame.
    pub skip: usize,
    /// All frames of the archive.
    pub frames: usize,
    /// Frame width in pixels.
    pub width: usize,
    /// Frame height in pixels.
    pub height: usize,
    /// For LeRobot v3.0: the kept frames quantized and encoded as lerobot stores depth
    /// (a temporary file, see [`depth::encode_part`]); None for formats that read the
    /// archive itself.
    pub video: Option<VideoPart>,
}

impl PreparedEpisode {
    /// Checks that this episode fits a dataset of `fps`, action/state widths and camera
    /// names (in order): every writer appends episodes of one layout.
    pub fn check_layout(
        &self,
        fps: u32,
        action_width: usize,
        state_width: usize,
        cameras: &[&str],
    ) -> Result<(), DatasetError> {
        let bad = |m: String| Err(DatasetError::episode(&self.id, m));
        if self.fps != fps {
            return bad(format!("fps {} differs from the dataset's {fps}", self.fps));
        }
        if self.action.width() != action_width || self.state.width() != state_width {
            return bad(format!(
                "action/state widths {}/{} differ from the dataset's {action_width}/{state_width} (select the same arrays for every task)",
                self.action.width(),
                self.state.width(),
            ));
        }
        let names: Vec<&str> = self.videos.iter().map(|v| v.name.as_str()).collect();
        if names != cameras {
            return bad(format!(
                "cameras {names:?} differ from the dataset's {cameras:?} (map cameras to shared names)"
            ));
        }
        Ok(())
    }

    /// The key and column names of each of its vector features, in order.
    pub fn vector_layout(&self) -> Vec<(String, Vec<String>)> {
        self.vectors
            .iter()
            .map(|v| (v.key.clone(), v.names.clone()))
            .collect()
    }

    /// Checks that this episode's vector features (`--environment-state`,
    /// `--privileged-state`) have the dataset's keys and columns `layout`.
    pub fn check_vectors(&self, layout: &[(String, Vec<String>)]) -> Result<(), DatasetError> {
        let mine = self.vector_layout();
        if mine == layout {
            return Ok(());
        }
        let (key, _) = layout
            .iter()
            .chain(&mine)
            .find(|x| !(layout.contains(x) && mine.contains(x)))
            .expect("the layouts differ");
        let names =
            |l: &[(String, Vec<String>)]| l.iter().find(|(k, _)| k == key).map(|(_, n)| n.clone());
        Err(DatasetError::episode(
            &self.id,
            format!(
                "{key}: columns {:?} differ from the dataset's {:?} (the episodes of one \
                 dataset need tasks with the same state objects)",
                names(&mine),
                names(layout)
            ),
        ))
    }

    /// Frames kept.
    pub fn len(&self) -> usize {
        self.action.len()
    }

    /// True when no frame is kept.
    pub fn is_empty(&self) -> bool {
        self.action.is_empty()
    }
}

/// Moves a temporary video part to `dst`, or copies the source there.
fn place_video(part: &VideoPart, dst: &Path) -> Result<(), DatasetError> {
    fs_err::create_dir_all(dst.parent().expect("has parent"))?;
    if part.temporary {
        fs_err::rename(&part.path, dst)?;
    } else {
        fs_err::copy(&part.path, dst)?;
    }
    Ok(())
}

/// JSON with a 4-space indent, as lerobot writes it.
pub(crate) fn write_json(path: &Path, value: &impl Serialize) -> Result<(), DatasetError> {
    let mut buf = Vec::new();
    let fmt = serde_json::ser::PrettyFormatter::with_indent(b"    ");
    let mut ser = serde_json::Serializer::with_formatter(&mut buf, fmt);
    value
        .serialize(&mut ser)
        .map_err(|source| DatasetError::Json {
            path: path.into(),
            source,
        })?;
    buf.push(b'\n');
    fs_err::write(path, buf)?;
    Ok(())
}
