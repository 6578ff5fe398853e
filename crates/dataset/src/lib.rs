//! Dataset management after a dataset is made: commands that take any LeRobot v3.0
//! dataset (ours, or one written by lerobot itself) and write a new one beside it,
//! the source never changed. [`info`] describes a dataset; [`filter`] keeps the episodes
//! a [`Selection`] picks; [`split`] deals them into seeded, per-task stratified splits;
//! [`merge`] joins several datasets, reconciling feature names and widths;
//! [`edit_features`] renames and removes features; [`restat`] recomputes statistics;
//! [`reencode`] encodes the videos again; [`trim`] cuts idle frames or keeps frame ranges; [`to_v21`] writes LeRobot v2.1 for
//! openpi.
//! Every output is written whole into a staging folder and renamed into place, episodes
//! re-indexed, every per-episode column kept, videos cut by stream copy (bit-exact) and
//! statistics recomputed.

mod data_file;
mod error;
mod info;
mod merge;
mod reencode;
mod restat;
mod select;
mod split;
mod stats;
mod subset;
mod to_v21;
mod trim;
mod videos;

pub use error::EditError;
pub use info::{DatasetSummary, FeatureSummary, info};
pub use merge::{MergeOptions, edit_features, merge};
pub use reencode::{ReencodeOptions, ReencodeReport, reencode};
pub use restat::{RestatReport, restat};
pub use select::{Comparison, Predicate, Selection};
pub use split::{SplitPlan, SplitSizes, plan_split, split};
pub use subset::{SubsetReport, filter, write_subset};
pub use to_v21::to_v21;
pub use trim::{TrimReport, TrimRule, trim};
