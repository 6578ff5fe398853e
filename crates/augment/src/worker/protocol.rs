//! What `augment` and its worker processes say to each other, inside the worker
//! protocol of `dexjoco-workers` (JSON lines): the run's configuration, a unit to render,
//! and what a rendered unit gives.

use serde::{Deserialize, Serialize};

use crate::config::AugmentConfig;
use crate::profile::StageTimes;
use crate::staging::Outcome;

/// The run's configuration, and the tasks whose scenes (and renderer) to load before the
/// first job, while the parent still loads and simulates.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct Hello {
    pub(crate) config: AugmentConfig,
    pub(crate) preload: Vec<String>,
}

/// A rendered unit: its replays' outcomes and where the time went.
#[derive(Debug, Serialize, Deserialize)]
pub(crate) struct UnitDone {
    pub(crate) outcomes: Vec<Outcome>,
    pub(crate) times: StageTimes,
}

/// The worker protocol's messages of augment.
pub(crate) type FromWorker = dexjoco_workers::FromWorker<UnitDone>;
