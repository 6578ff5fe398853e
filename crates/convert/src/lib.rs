//! Conversion of DexJoCo episodes into datasets the training stacks read unchanged:
//! LeRobot v3.0, LeRobot v2.1 and Diffusion Policy's Zarr replay buffer. The formats
//! themselves (files, metadata, statistics as lerobot computes them) live in
//! [`dexjoco_formats::dataset`], behind one trait ([`DatasetWriter`]); this crate
//! chooses what goes into them:
//!
//! - [`Selection`]: what to take (action array, state slice, camera mapping, bad
//!   episodes, static leading frames, instructions), read from TOML/YAML or the DexJoCo
//!   reference converter's config folder.
//! - [`prepare`]: one episode made ready for writing (selected arrays, trimmed start,
//!   per-camera video parts stream-copied or encoded, statistics), in parallel.
//! - `vectors`: `--environment-state` and `--privileged-state`, the state features
//!   (objects' poses, `dh`) named after the task spec's layout; each replay's record
//!   (`replay.json`) is carried into the episode as its label.
//! - [`merge`]: several tasks in one dataset (task table from the instructions);
//!   one-arm episodes laid into the right-arm slots of the two-arm layout.
//! - [`convert`]: the driver (parallel preparation in bounded batches, sequential
//!   writing through the chosen [`DatasetWriter`], atomic finish); input is a stream
//!   of [`InputEpisode`]s.
//!
//! [`DatasetWriter`]: dexjoco_formats::dataset::DatasetWriter
//! - openpi's `norm_stats.json` (`--norm-stats`), through the one implementation in
//!   [`dexjoco_formats::openpi`].

mod config;
mod convert;
mod depth;
mod error;
pub mod merge;
mod prepare;
mod vectors;

pub use config::{ActionSource, ColumnSlice, Selection, TaskSelection, first_moving_frame};
pub use convert::{
    CONVERT_MARKER, ConvertOptions, FailedEpisode, OutputFormat, Summary, check_output, convert,
    language_slots,
};
// The dataset types of this crate's API (the writers' input and options).
pub use dexjoco_formats::dataset::{PreparedEpisode, V3Options};
pub use dexjoco_formats::openpi::NormStatsOptions;
pub use error::ConvertError;
pub use prepare::{InputEpisode, VideoCodec, VideoOptions, prepare};
pub use vectors::StateFeatures;
