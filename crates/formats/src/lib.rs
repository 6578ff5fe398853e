//! Every on-disk format of dexjoco-data, and the file-system primitives its writers use.
//! Stage crates (`ingest`, `augment`, `convert`, `stats`) read and write files only
//! through this crate, so "where is the MCAP reader" has one answer:
//!
//! - [`episodes`]: **the** episode discovery and reader every command uses (raw
//!   folders, episode stores, MCAP files, in folders or given directly; one rule).
//! - [`container`]: [`EpisodeContainer`], the one trait (probe, read, write) of the
//!   containers of one episode: the raw folder ([`raw::RawFolder`]) and the MCAP log
//!   ([`mcap::McapLog`]).
//! - [`raw`]: the DexJoCo raw layout (`replay.zarr` + `videos/`), read and written with
//!   `zarrs` exactly as the reference recorder (zarr-python 2) lays it out.
//! - [`dataset`]: the training datasets `convert` writes (LeRobot v3.0, LeRobot v2.1,
//!   Diffusion Policy's replay buffer) behind one trait, [`dataset::DatasetWriter`]
//!   (check compatible / write episode / finish), with typed LeRobot metadata and
//!   statistics as lerobot computes them.
//! - [`zarr_v2`]: Zarr v2 metadata and groups as zarr-python 2 writes them (the raw layout
//!   and the Diffusion Policy replay buffer).
//! - [`mcap`]: our MCAP schema for teleop episodes (`schemas/mcap-teleop.md`).
//! - [`npz`]: numpy `.npz` depth archives (`videos/<camera>_depth.npz`), streamed.
//! - [`openpi`]: openpi's `norm_stats.json`, the one implementation of normalization
//!   statistics (convert and stats both use it).
//! - [`validate`]: the checks of an episode against its task: the integrity checks every
//!   reader applies whichever door the episode comes in by, and `ingest`'s full check.
//! - [`augment_report`]: augment's report and replay record, the one definition its
//!   writer and its readers share.
//! - [`manifest`]: the episode store's `manifest.json` and per-episode entries.
//! - [`fs`]: atomic file writes, whole-folder replacement, tree copies; [`lock`]: one
//!   writer per output folder.
//! - [`error`]: [`FormatError`] and the [`Problem`] records (code, file, episode, field,
//!   frame) that manifests and reports keep; [`DatasetError`] of the dataset writers.

pub mod augment_report;
pub mod container;
pub mod dataset;
pub mod episodes;
pub mod error;
pub mod fs;
pub mod lock;
pub mod manifest;
pub mod mcap;
pub mod npz;
pub mod openpi;
pub mod raw;
pub mod validate;
pub mod zarr_v2;

pub use container::{EpisodeContainer, EpisodeMeta, ReadEpisode, ReadOptions};
pub use episodes::{Source, discover, discover_input, read_episode};
pub use error::{DatasetError, FormatError, Problem, ProblemCode, Result};
pub use fs::write_atomic;
pub use lock::{DirLock, LOCK_FILE, LockOwner};
pub use manifest::{ENTRY_FILE, MANIFEST, Manifest, ManifestEntry, SourceKind, Status};
pub use validate::ValidationOptions;
