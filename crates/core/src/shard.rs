//! Shards: a run's work split deterministically over several processes or machines (a
//! Slurm job array, a Kubernetes Indexed Job), each naming its share as `I/N`.

use serde::{Deserialize, Serialize};

/// A deterministic share of a run split over several processes or machines (augment,
/// generate): shard `index` of `count` (0-based).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    /// This shard, `0..count`.
    pub index: usize,
    /// Number of shards.
    pub count: usize,
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// Why a shard could not be parsed or found in the environment.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ShardError {
    /// The text has no `/`.
    #[error("'{text}' is not I/N (e.g. 0/4)")]
    NotIOverN {
        /// The text given.
        text: String,
    },
    /// The index or the count is not a number.
    #[error("'{text}': shard {part} '{value}' is not a number")]
    NotANumber {
        /// The text given.
        text: String,
        /// `index` or `count`.
        part: &'static str,
        /// The part that is not a number.
        value: String,
    },
    /// The index is not below the count (or the count is 0).
    #[error("'{text}': the index must be in 0..{count}")]
    OutOfRange {
        /// The text given.
        text: String,
        /// The count.
        count: usize,
    },
    /// A scheduler variable is not a number.
    #[error("{name}={value} is not a number")]
    Variable {
        /// The variable.
        name: String,
        /// Its value.
        value: String,
    },
    /// A Slurm job array without its task count.
    #[error("SLURM_ARRAY_TASK_ID is set but SLURM_ARRAY_TASK_COUNT is not")]
    SlurmCountMissing,
    /// A Kubernetes Indexed Job without the shard count.
    #[error(
        "JOB_COMPLETION_INDEX is set (a Kubernetes Indexed Job): set DEXJOCO_SHARD_COUNT to the Job's completions"
    )]
    KubernetesCountMissing,
    /// `SLURM_ARRAY_TASK_ID` is below `SLURM_ARRAY_TASK_MIN`.
    #[error("SLURM_ARRAY_TASK_ID {id} < SLURM_ARRAY_TASK_MIN {min}")]
    BelowMin {
        /// The task id.
        id: usize,
        /// The array's first id.
        min: usize,
    },
    /// The Slurm array gives no valid shard.
    #[error("Slurm array ({source}): use a contiguous --array=0-{last}")]
    SlurmArray {
        /// Why.
        source: Box<ShardError>,
        /// The last task id a contiguous array would have.
        last: usize,
    },
    /// Neither scheduler's variables are set.
    #[error(
        "--shard auto: neither SLURM_ARRAY_TASK_ID (a Slurm job array) nor JOB_COMPLETION_INDEX (a Kubernetes Indexed Job) is set"
    )]
    NoScheduler,
}

impl Shard {
    /// Parses `I/N` (0 <= I < N).
    pub fn parse(text: &str) -> Result<Self, ShardError> {
        let (i, n) = text
            .split_once('/')
            .ok_or_else(|| ShardError::NotIOverN { text: text.into() })?;
        let number = |part: &'static str, value: &str| {
            value
                .trim()
                .parse::<usize>()
                .map_err(|_| ShardError::NotANumber {
                    text: text.into(),
                    part,
                    value: value.into(),
                })
        };
        let (index, count) = (number("index", i)?, number("count", n)?);
        if count == 0 || index >= count {
            return Err(ShardError::OutOfRange {
                text: text.into(),
                count,
            });
        }
        Ok(Self { index, count })
    }

    /// The shard a cluster scheduler gives this process (`--shard auto`): a Slurm job array
    /// (`SLURM_ARRAY_TASK_ID` relative to `SLURM_ARRAY_TASK_MIN`, of
    /// `SLURM_ARRAY_TASK_COUNT`), or a Kubernetes Indexed Job (`JOB_COMPLETION_INDEX`, of
    /// `DEXJOCO_SHARD_COUNT`).
    pub fn from_env(var: impl Fn(&str) -> Option<String>) -> Result<Self, ShardError> {
        let num = |name: &str| -> Result<Option<usize>, ShardError> {
            var(name)
                .map(|v| {
                    v.trim().parse::<usize>().map_err(|_| ShardError::Variable {
                        name: name.into(),
                        value: v.clone(),
                    })
                })
                .transpose()
        };
        if let Some(id) = num("SLURM_ARRAY_TASK_ID")? {
            let count = num("SLURM_ARRAY_TASK_COUNT")?.ok_or(ShardError::SlurmCountMissing)?;
            let min = num("SLURM_ARRAY_TASK_MIN")?.unwrap_or(0);
            let index = id
                .checked_sub(min)
                .ok_or(ShardError::BelowMin { id, min })?;
            return Self::parse(&format!("{index}/{count}")).map_err(|e| ShardError::SlurmArray {
                source: Box::new(e),
                last: count.max(1) - 1,
            });
        }
        if let Some(index) = num("JOB_COMPLETION_INDEX")? {
            let count = num("DEXJOCO_SHARD_COUNT")?.ok_or(ShardError::KubernetesCountMissing)?;
            return Self::parse(&format!("{index}/{count}"));
        }
        Err(ShardError::NoScheduler)
    }
}
