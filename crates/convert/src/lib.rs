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
//! Not built yet: LeRobot v2.1, Diffusion Policy Zarr, openpi `norm_stats.json`.

mod config;
mod convert;
mod error;
mod lerobot_v3;
mod parquet_io;
mod prepare;
pub mod stats;

pub use config::{
    ActionSource, ColumnSlice, DEXJOCO_INSTRUCTIONS, Selection, TaskSelection, first_moving_frame,
};
pub use convert::{
    ConvertOptions, OutputFormat, Reporter, Silent, Summary, convert, is_non_empty_dir,
};
pub use error::ConvertError;
pub use lerobot_v3::{
    CHUNKS_SIZE, DEFAULT_DATA_FILE_MB, DEFAULT_VIDEO_FILE_MB, V3Options, V3Writer,
};
pub use prepare::{InputEpisode, PreparedEpisode, VideoCodec, VideoOptions, VideoPart, prepare};
