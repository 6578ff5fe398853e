//! Conversion of DexJoCo episodes into datasets the training stacks read unchanged.
//!
//! Built: LeRobot v3.0 (what lerobot >= 0.4 reads): data in size-capped parquet files
//! (one row group per episode), per-camera videos joined by stream copy with continuous
//! timestamps (or encoded, AV1 by default), and `meta/` (info, stats, tasks with pandas
//! metadata, episodes with per-episode stats and video time ranges).
//!
//! - [`Selection`]: what to take (action array, state slice, camera mapping, bad
//!   episodes, static leading frames, instructions), read from TOML/YAML or the DexJoCo
//!   reference converter's config folder.
//! - [`convert`]: the driver (parallel preparation in bounded batches, sequential
//!   writing, atomic finish); input is a stream of [`InputEpisode`]s.
//! - [`stats`]: normalization statistics as lerobot computes them.
//!
//! - LeRobot v2.1 (openpi's pinned lerobot): per-episode parquet (with `huggingface`
//!   schema metadata) and mp4s, jsonl metadata with per-episode statistics.
//! - Diffusion Policy: `replay_buffer.zarr` (Zarr v2) that its `ReplayBuffer` reads,
//!   images decoded into uint8 (T, H, W, 3), optionally the videos beside it.
//! - [`merge`]: several tasks in one dataset (task table from the instructions);
//!   one-arm episodes laid into the right-arm slots of the two-arm layout.
//! - openpi's `norm_stats.json` (`--norm-stats`), through the one implementation in
//!   [`dexjoco_formats::openpi`].

mod config;
mod convert;
mod diffusion_policy;
mod error;
mod lerobot_v21;
mod lerobot_v3;
pub mod merge;
mod parquet_io;
mod prepare;
pub mod stats;

pub use config::{ActionSource, ColumnSlice, Selection, TaskSelection, first_moving_frame};
pub use convert::{
    CONVERT_MARKER, ConvertOptions, FailedEpisode, OutputFormat, Summary, check_output, convert,
};
pub use diffusion_policy::{REPLAY_BUFFER, ZarrWriter};
pub use error::ConvertError;
pub use lerobot_v3::{
    CHUNKS_SIZE, DEFAULT_DATA_FILE_MB, DEFAULT_VIDEO_FILE_MB, V3Options, V3Writer,
};
pub use lerobot_v21::V21Writer;
pub use prepare::{
    InputEpisode, PreparedEpisode, VideoCodec, VideoLayout, VideoOptions, VideoPart, prepare,
};
