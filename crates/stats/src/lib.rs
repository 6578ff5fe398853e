//! Language-generalization statistics, success-rate tables and dataset summaries: the
//! `stats` stage of dexjoco-data.
//!
//! - [`LanguageInput`] reads a language study (the reference evaluator's episode folders,
//!   or a tidy CSV/JSON) and [`LanguageReport`] analyses it as the DexJoCo paper's
//!   appendix A: the instruction x output distribution, precision over seeds, a
//!   chi-square test of independence, normalized mutual information and Jensen-Shannon
//!   divergences, with a verdict, a heatmap and JSON.
//! - [`SuccessTable`] aggregates evaluation runs into mean ± std over seeds per task x
//!   regime x policy, as Markdown, LaTeX (the paper's Table 2 layout) and CSV.
//! - [`DatasetStats`] summarizes episodes: counts, lengths, per-dimension distributions
//!   and openpi-style normalization statistics.
//! - [`Health`] (part of [`DatasetStats`]) finds what would go wrong at training time:
//!   flat dimensions, static leading frames, length outliers, duplicates, failed and
//!   flagged replays.
//! - [`ReplayStats`] reads an augment report: replay success rates per task, and the
//!   subtasks of the kept replays ([`subtasks`]: completed, when, how long).
//! - [`ReplayProvenance`] reads where a dataset's replays were made (CPU and program
//!   versions, from each `replay.json`) and warns when it mixes places.
//!
//! The measures in [`measures`] follow SciPy and scikit-learn; the tests compare them.
//! Standard deviations over seeds are sample standard deviations (divisor n - 1), as
//! the paper reports them.

mod dataset;
mod error;
pub mod evaltree;
mod health;
mod health_files;
mod health_report;
mod language;
pub mod measures;
mod output;
pub mod plot;
mod provenance;
mod replays;
pub mod subtasks;
mod success;

pub use dataset::{
    ArrayStats, DatasetStats, HISTOGRAM_BINS, LengthStats, TaskStats, column_names,
    flat_dimensions, width_outliers,
};
pub use error::StatsError;
pub use health::{
    ALL_TASKS, DuplicateGroup, Duplicates, EpisodeFiles, EpisodeFrames, FlatDimension, Flatness,
    Health, LEROBOT_EPS, LengthDistribution, NEAR_CONSTANT_REL, OPENPI_EPS, Outcomes,
    StaticLeading,
};
pub use health_files::arrays_sha256;
pub use language::{
    EXAMPLE_MARKER, Instruction, JsPair, LanguageInput, LanguageOptions, LanguageReport,
    MANIFEST_FILE, NONE_OUTPUT, Precision, Trial, format_p, infer_expected,
};
pub use measures::{ChiSquare, LogBase, MeanStd, quantile_sorted};
pub use output::{SOURCE_NORM_STATS, SOURCE_NORM_STATS_DIR};
pub use provenance::{MadeOn, ReplayProvenance};
pub use replays::{AUGMENT_REPORT, ReplayStats, TaskReplays};
pub use success::{AverageCell, SuccessCell, SuccessTable, latex_escape, regime_name, task_name};
