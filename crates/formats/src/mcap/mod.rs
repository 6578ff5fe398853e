//! Our MCAP schema for teleop episodes (documented in `schemas/mcap-teleop.md`), read and
//! written with the `mcap` crate. One episode per file; JSON message encoding with
//! JSON Schemas, so a file opens in Foxglove. [`McapLog`] is its [`EpisodeContainer`].
//!
//! Per-frame channels hold one message per control step, in order; the i-th message
//! of each is frame i. Values are JSON numbers, written in shortest round-trip form and
//! parsed exactly, so f64 data survives raw -> MCAP -> raw bit for bit.
//!
//! `write.rs` lays an episode out as channels and messages; `read.rs` checks a file and
//! reads it back.

use std::collections::{BTreeMap, HashMap};
use std::io::{BufWriter, Write};
use std::path::Path;

use dexjoco_core::{ArmSetup, Episode, FrameArray, HAND_DOF, Location, TaskSet, TaskSpec};
use mcap::records::{MessageHeader, Metadata, Record};
use serde_json::{Value, json};

use crate::container::{EpisodeContainer, EpisodeMeta, ReadEpisode, ReadOptions, unknown_task};
use crate::error::{FormatError, ProblemCode, Result, io_err};
use crate::manifest::SourceKind;

/// Version of the schema this crate writes and reads.
pub const SCHEMA_VERSION: &str = "1";
/// Name of the MCAP Metadata record describing the episode.
pub const EPISODE_METADATA: &str = "dexjoco.episode";
/// Topic of the state channel.
pub const STATE_TOPIC: &str = "/state";
/// Topic of the optional rotation-vector action channel.
pub const ACTION_ROTVEC_TOPIC: &str = "/action_rotvec";

const POSE_SCHEMA: &str = include_str!("../../../../schemas/mcap/foxglove.PoseInFrame.json");
const HAND_SCHEMA: &str = include_str!("../../../../schemas/mcap/dexjoco.HandJointTargets.json");
const STATE_SCHEMA: &str = include_str!("../../../../schemas/mcap/dexjoco.State.json");
const ROTVEC_SCHEMA: &str = include_str!("../../../../schemas/mcap/dexjoco.ActionRotvec.json");

/// Topic of an arm's pose commands (`arm` is `arm`, `right` or `left`).
pub fn pose_topic(arm: &str) -> String {
    format!("/{arm}/pose_command")
}

/// Topic of an arm's hand joint targets.
pub fn hand_topic(arm: &str) -> String {
    format!("/{arm}/hand_target")
}

/// The joint order of a hand's targets (the left hand's is reversed by finger).
pub fn joint_order(arm: &str) -> String {
    let fingers: [&str; 4] = if arm == "left" {
        ["rf", "mf", "ff", "th"]
    } else {
        ["ff", "mf", "rf", "th"]
    };
    fingers
        .iter()
        .flat_map(|f| (0..4).map(move |j| format!("{f}{j}")))
        .collect::<Vec<_>>()
        .join(",")
}

/// An episode read from an MCAP file, with what was not carried into the arrays.
#[derive(Debug, Clone)]
pub struct TeleopEpisode {
    /// The episode (`id` from the file's `episode_id` when present, else empty).
    pub episode: Episode,
    /// The metadata record's other keys.
    pub meta: EpisodeMeta,
    /// Notes: computed arrays, streams the raw layout has no place for.
    pub notes: Vec<String>,
}

mod read;
mod write;

pub use read::read_episode_mcap;
pub use write::write_episode_mcap;

/// MCAP teleop logs as an [`EpisodeContainer`]: one file per episode, found by its
/// `.mcap` extension (any case).
#[derive(Debug, Clone, Copy, Default)]
pub struct McapLog;

impl EpisodeContainer for McapLog {
    fn name(&self) -> &'static str {
        "MCAP"
    }

    fn kind(&self) -> SourceKind {
        SourceKind::Mcap
    }

    fn extension(&self) -> Option<&'static str> {
        Some("mcap")
    }

    fn probe(&self, path: &Path) -> bool {
        !path.is_dir()
            && path
                .extension()
                .is_some_and(|x| x.eq_ignore_ascii_case("mcap"))
    }

    /// Reads the file (or `options.bytes`); the episode's id is the recorded one, else
    /// the file stem.
    fn read(&self, path: &Path, tasks: &TaskSet, options: ReadOptions<'_>) -> Result<ReadEpisode> {
        let owned;
        let bytes = match options.bytes {
            Some(b) => b,
            None => {
                owned = fs_err::read(path).map_err(io_err("read", path))?;
                &owned
            }
        };
        let t = read_episode_mcap(path, bytes, tasks)?;
        let mut episode = t.episode;
        if episode.id.is_empty() {
            episode.id = path
                .file_stem()
                .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        }
        Ok(ReadEpisode {
            episode,
            videos: Vec::new(),
            notes: t.notes,
        })
    }

    fn write(
        &self,
        path: &Path,
        episode: &Episode,
        task: &TaskSpec,
        meta: &EpisodeMeta,
    ) -> Result<()> {
        write_episode_mcap(path, episode, task, meta)
    }
}
