//! The `ingest` stage: validate teleop episodes (read through `dexjoco-formats`) against
//! their task specs and land them in the episode store.
//!
//! - [`validate`]: checks of an episode against its [`TaskSpec`](dexjoco_core::TaskSpec):
//!   widths, finite values, timestamps, unit quaternions, hand ranges, dh, step cap
//!   ([`dexjoco_formats::validate`], where the integrity part every reader applies lives).
//! - [`Store`]: the canonical store (raw layout + `manifest.json`) and the pipeline that
//!   lands good episodes atomically and quarantines bad inputs with their reasons.
//!
//! Discovering and reading inputs (MCAP logs, raw folders, stores) is
//! [`dexjoco_formats::episodes`]; the store's manifest format is
//! [`dexjoco_formats::manifest`].

mod error;
mod input;
mod store;

pub use dexjoco_formats::validate::{ValidationOptions, validate};
pub use error::{IngestError, Result};
pub use store::{
    IngestOptions, IngestSummary, Outcome, QUARANTINE, REASON_FILE, STAGING, SourceReport, Store,
};
