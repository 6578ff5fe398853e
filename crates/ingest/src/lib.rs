//! Reading, validating and storing teleop episodes: the `ingest` stage.
//!
//! - [`raw`]: the DexJoCo raw layout (`replay.zarr` Zarr v2 + `videos/`), read and written
//!   with `zarrs` as the reference recorder lays it out (zarr-python 2 reads ours).
//! - [`teleop`]: our MCAP schema for teleop episodes (`schemas/mcap-teleop.md`).
//! - [`validate`]: checks against the task table of `dexjoco-core`.
//! - [`Store`]: the canonical store (raw layout + `manifest.json`) and the pipeline that
//!   lands good episodes atomically and quarantines bad inputs with their reasons.
//! - [`synth`]: valid synthetic episodes for tests and benchmarks.

pub mod depth;
mod error;
pub mod raw;
mod store;
pub mod synth;
pub mod teleop;
mod validate;
pub mod zarr_v2;

pub use error::{IngestError, Problem, ProblemCode, Result};
pub use store::{
    ENTRY_FILE, IngestOptions, IngestSummary, LOCK_FILE, MANIFEST, Manifest, ManifestEntry,
    NoReporter, Outcome, QUARANTINE, REASON_FILE, Reporter, STAGING, Source, SourceKind,
    SourceReport, Status, Store, discover, episode_dirs, landed_by_task, read_stored_episode,
    stored_episode_dirs, write_atomic,
};
pub use validate::{ValidationOptions, validate};
