//! Where the replays of a dataset were made, from each replay's record (`replay.json`,
//! written by `dexjoco-data augment`): its `made_on`, the CPU model and flags and the
//! versions of the programs that decide the bytes. MuJoCo's floating point depends on the
//! CPU, so a dataset whose replays were made in more than one place is not what one
//! machine would make; [`ReplayProvenance::warning`] says so.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::StatsError;

use dexjoco_formats::raw::REPLAY_RECORD;

/// One place replays were made, and how many.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub struct MadeOn {
    /// The CPU model (`/proc/cpuinfo`).
    pub cpu_model: String,
    /// The CPU's feature flags.
    pub cpu_flags: String,
    /// The programs' versions (`dexjoco_data`, `mujoco`, `ffmpeg`, `x264`).
    pub versions: BTreeMap<String, String>,
    /// Replays made there.
    #[serde(default)]
    pub replays: usize,
}

/// The replay record's field read here.
#[derive(Deserialize)]
struct RecordFile {
    made_on: Option<MadeOn>,
}

/// Where the replays below a folder were made.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ReplayProvenance {
    /// Each distinct place, sorted.
    pub made_on: Vec<MadeOn>,
    /// Replays whose record says nothing of it (made before it was recorded, or a record
    /// that cannot be read).
    pub not_recorded: usize,
}

impl ReplayProvenance {
    /// Reads the replay records below `root` (every folder holding a `replay.json`,
    /// hidden and linked folders passed over). `Ok(None)` when there is none.
    pub fn read(root: &Path) -> Result<Option<Self>, StatsError> {
        let mut counts: BTreeMap<MadeOn, usize> = BTreeMap::new();
        let mut not_recorded = 0;
        let mut stack = vec![root.to_path_buf()];
        while let Some(dir) = stack.pop() {
            let record = dir.join(REPLAY_RECORD);
            if record.is_file() {
                let made_on = fs_err::read(&record)
                    .ok()
                    .and_then(|b| serde_json::from_slice::<RecordFile>(&b).ok())
                    .and_then(|r| r.made_on);
                match made_on {
                    Some(m) => *counts.entry(m).or_default() += 1,
                    None => not_recorded += 1,
                }
                continue;
            }
            for entry in fs_err::read_dir(&dir)? {
                let entry = entry?;
                let hidden = entry.file_name().to_string_lossy().starts_with('.');
                // Linked folders are not followed (a link loop would never end).
                if entry.file_type()?.is_dir() && !hidden {
                    stack.push(entry.path());
                }
            }
        }
        if counts.is_empty() && not_recorded == 0 {
            return Ok(None);
        }
        let made_on = counts
            .into_iter()
            .map(|(m, replays)| MadeOn { replays, ..m })
            .collect();
        Ok(Some(Self {
            made_on,
            not_recorded,
        }))
    }

    /// Places counted, the unrecorded as one.
    fn places(&self) -> usize {
        self.made_on.len() + usize::from(self.not_recorded > 0)
    }

    /// A warning when the replays were made in more than one place.
    pub fn warning(&self) -> Option<String> {
        (self.places() > 1).then(|| {
            format!(
                "the replays were made in {} different places (CPU model and flags, or program \
                 versions{}): MuJoCo's floating point depends on the CPU and the bytes on the \
                 versions, so this dataset is not what one machine would make",
                self.places(),
                if self.not_recorded > 0 {
                    ", counting replays that do not record it as one"
                } else {
                    ""
                }
            )
        })
    }

    /// A Markdown table of the places, with the warning when there is one.
    pub fn to_markdown(&self) -> String {
        let mut s = String::from(
            "| CPU | dexjoco-data | MuJoCo | ffmpeg | x264 | replays |\n|---|---|---|---|---|---:|\n",
        );
        let v = |m: &MadeOn, k: &str| m.versions.get(k).cloned().unwrap_or_else(|| "-".into());
        for m in &self.made_on {
            s.push_str(&format!(
                "| {} | {} | {} | {} | {} | {} |\n",
                m.cpu_model,
                v(m, "dexjoco_data"),
                v(m, "mujoco"),
                v(m, "ffmpeg"),
                v(m, "x264"),
                m.replays
            ));
        }
        if self.not_recorded > 0 {
            s.push_str(&format!(
                "| not recorded | - | - | - | - | {} |\n",
                self.not_recorded
            ));
        }
        if let Some(w) = self.warning() {
            s.push_str(&format!("\n**Warning:** {w}.\n"));
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(dir: &Path, cpu: &str) {
        fs_err::create_dir_all(dir).unwrap();
        let json = serde_json::json!({
            "name": "episode_000000__r00",
            "made_on": {
                "cpu_model": cpu,
                "cpu_flags": "fpu sse2",
                "versions": {"dexjoco_data": "0.1.0", "mujoco": "3.17.0",
                             "ffmpeg": "5.1.9", "x264": "x264 - core 164"}
            }
        });
        fs_err::write(dir.join(REPLAY_RECORD), json.to_string()).unwrap();
    }

    #[test]
    fn replays_made_on_two_cpu_models_are_listed_and_warned_of() {
        let tmp = tempfile::tempdir().unwrap();
        let root = tmp.path();
        record(&root.join("t/episode_000000__r00"), "AMD EPYC 7B13");
        record(&root.join("t/episode_000000__r01"), "AMD EPYC 7B13");
        // A staged replay is not part of the dataset.
        record(&root.join(".staging/t__episode_000000__r02"), "Other");
        let one = ReplayProvenance::read(root).unwrap().unwrap();
        assert_eq!(one.made_on.len(), 1);
        assert_eq!(one.made_on[0].replays, 2);
        assert_eq!(one.warning(), None);

        record(
            &root.join("t/episode_000001__r00"),
            "Intel Xeon Platinum 8480+",
        );
        let two = ReplayProvenance::read(root).unwrap().unwrap();
        let models: Vec<_> = two.made_on.iter().map(|m| m.cpu_model.as_str()).collect();
        assert_eq!(models, ["AMD EPYC 7B13", "Intel Xeon Platinum 8480+"]);
        let md = two.to_markdown();
        assert!(
            md.contains(
                "| Intel Xeon Platinum 8480+ | 0.1.0 | 3.17.0 | 5.1.9 | x264 - core 164 | 1 |"
            ) && md.contains("**Warning:** the replays were made in 2 different places"),
            "{md}"
        );
        let empty = tempfile::tempdir().unwrap();
        assert_eq!(ReplayProvenance::read(empty.path()).unwrap(), None);
    }
}
