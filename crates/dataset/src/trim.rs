//! `dataset trim`: fewer frames per episode, every episode kept. Idle frames at the start
//! and end of each episode go (a frame is idle while the action does not change by more
//! than a threshold from one frame to the next, LIBERO's no-op rule for absolute
//! actions), or explicit frame ranges are kept. Frames are renumbered from 0 in each
//! episode (frame_index, timestamp), per-episode statistics recomputed, videos cut with
//! smart cuts so almost every frame stays bit-exact.

use std::collections::BTreeMap;
use std::path::Path;

use dexjoco_core::Progress;
use dexjoco_formats::dataset::lerobot_read::LeRobotDataset;
use dexjoco_formats::fs::StagedDir;
use serde::Serialize;

use crate::subset::{check_output, write_subset};
use crate::{EditError, SubsetReport};

/// Which frames of each episode a trim keeps.
#[derive(Debug, Clone, PartialEq)]
pub enum TrimRule {
    /// Leading and trailing idle frames removed: the frames before the first whose
    /// `column` differs from the frame before by more than `threshold` (largest
    /// absolute difference of any element), and after the last such, keeping `margin`
    /// idle frames on each side. An episode that never moves is kept whole.
    Idle {
        /// The per-frame column compared (usually `action`).
        column: String,
        /// Largest change still counted as idle.
        threshold: f64,
        /// Idle frames kept before the first and after the last movement.
        margin: usize,
    },
    /// Frames `from..to` (end excluded) of the named episodes; others kept whole.
    Ranges(BTreeMap<usize, (i64, i64)>),
}

/// What a trim did.
#[derive(Debug, Clone, Default, Serialize, PartialEq, Eq)]
pub struct TrimReport {
    /// The dataset written.
    #[serde(flatten)]
    pub written: SubsetReport,
    /// Frames removed in all.
    pub frames_removed: u64,
    /// Episodes that lost frames.
    pub episodes_trimmed: usize,
    /// Episodes the idle rule found no movement in (kept whole).
    pub still_episodes: Vec<usize>,
}

/// Writes `source` with each episode trimmed by `rule` to `out` (staged and renamed; an
/// existing `out` is replaced only with `overwrite`).
pub fn trim(
    source: &Path,
    rule: &TrimRule,
    out: &Path,
    overwrite: bool,
    progress: &dyn Progress,
) -> Result<TrimReport, EditError> {
    let ds = LeRobotDataset::open(source)?;
    let lengths = ds.lengths()?;
    let (frames, still_episodes) = match rule {
        TrimRule::Idle {
            column,
            threshold,
            margin,
        } => idle_ranges(&ds, column, *threshold, *margin)?,
        TrimRule::Ranges(ranges) => (explicit_ranges(ranges, &lengths)?, Vec::new()),
    };
    let whole: Vec<(i64, i64)> = lengths.iter().map(|n| (0, *n)).collect();
    let episodes_trimmed = frames.iter().zip(&whole).filter(|(a, b)| a != b).count();
    if episodes_trimmed == 0 {
        return Err(EditError::Selection(format!(
            "no episode of '{}' loses a frame by this rule: nothing to write",
            source.display()
        )));
    }
    check_output(source, out, overwrite)?;
    let staged = StagedDir::begin(out)?;
    let rows: Vec<usize> = (0..ds.len()).collect();
    let written = write_subset(&ds, &rows, Some(&frames), staged.path(), None, progress)?;
    staged.commit()?;
    let before: i64 = lengths.iter().sum();
    Ok(TrimReport {
        frames_removed: (before as u64).saturating_sub(written.frames),
        written,
        episodes_trimmed,
        still_episodes,
    })
}

/// Frames `from..to` of an episode (end excluded).
type FrameRange = (i64, i64);

/// Each episode's kept frames by the idle rule, and the episodes with no movement.
fn idle_ranges(
    ds: &LeRobotDataset,
    column: &str,
    threshold: f64,
    margin: usize,
) -> Result<(Vec<FrameRange>, Vec<usize>), EditError> {
    let features = ds.features();
    if !features.contains_key(column) {
        let names: Vec<&String> = features.keys().collect();
        return Err(EditError::Selection(format!(
            "no feature '{column}' to find idle frames by (features: {names:?})"
        )));
    }
    let data = ds.data_files()?;
    let values = crate::stats::per_episode_values(ds.len(), &data, &[column])?;
    let (values, rows) = &values[column];
    let mut ranges = Vec::with_capacity(ds.len());
    let mut still = Vec::new();
    for (episode, (v, n)) in values.iter().zip(rows).enumerate() {
        match moving_span(v, *n, threshold) {
            Some((first, last)) => {
                let from = first.saturating_sub(margin);
                let to = (last + 1 + margin).min(*n);
                ranges.push((from as i64, to as i64));
            }
            None => {
                still.push(episode);
                ranges.push((0, *n as i64));
            }
        }
    }
    Ok((ranges, still))
}

/// The first and last frame of the movement in `n` frames of `values` (rows of equal
/// width): the first and last frame whose value differs from the frame before by more
/// than `threshold` (as LIBERO drops no-op actions, and lerobot-doctor's trim). `None`
/// where nothing changes.
fn moving_span(values: &[f64], n: usize, threshold: f64) -> Option<(usize, usize)> {
    if n < 2 {
        return None;
    }
    let width = values.len() / n;
    let changes = |t: usize| {
        let (a, b) = (
            &values[t * width..(t + 1) * width],
            &values[(t + 1) * width..(t + 2) * width],
        );
        a.iter().zip(b).any(|(x, y)| (x - y).abs() > threshold)
    };
    let first = (0..n - 1).find(|t| changes(*t))?;
    let last = (0..n - 1).rev().find(|t| changes(*t))?;
    Some((first + 1, last + 1))
}

/// Explicit ranges checked against the episodes' lengths; unnamed episodes whole.
fn explicit_ranges(
    ranges: &BTreeMap<usize, (i64, i64)>,
    lengths: &[i64],
) -> Result<Vec<(i64, i64)>, EditError> {
    if let Some((episode, _)) = ranges.iter().find(|(e, _)| **e >= lengths.len()) {
        return Err(EditError::Selection(format!(
            "episode {episode} is out of range: the dataset has {} episodes (0..{})",
            lengths.len(),
            lengths.len()
        )));
    }
    let mut out: Vec<(i64, i64)> = lengths.iter().map(|n| (0, *n)).collect();
    for (episode, (from, to)) in ranges {
        let n = lengths[*episode];
        if *from < 0 || to <= from || *to > n {
            return Err(EditError::Selection(format!(
                "episode {episode}: frames {from}..{to} are not a non-empty range within its \
                 {n} frames (0..{n}, end excluded)"
            )));
        }
        out[*episode] = (*from, *to);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_moving_span_runs_from_the_last_still_frame_to_the_first_still_one() {
        // Still for frames 0-2, new values in frames 3-5, still after 5.
        let v = [0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 3.0, 3.0];
        assert_eq!(moving_span(&v, 8, 1e-6), Some((3, 5)));
        assert_eq!(moving_span(&[1.0; 5], 5, 1e-6), None);
        // Two columns: movement in either counts; a change at the threshold does not.
        let v = [0.0, 0.0, 0.0, 0.5, 0.0, 0.5, 0.0, 0.5];
        assert_eq!(moving_span(&v, 4, 1e-6), Some((1, 1)));
        assert_eq!(moving_span(&v, 4, 0.5), None);
    }

    #[test]
    fn ranges_outside_an_episode_are_named() {
        let lengths = [10, 20];
        let ok = explicit_ranges(&BTreeMap::from([(1, (5, 20))]), &lengths).unwrap();
        assert_eq!(ok, vec![(0, 10), (5, 20)]);
        for bad in [(1, (5, 21)), (0, (4, 4)), (2, (0, 1))] {
            let err = explicit_ranges(&BTreeMap::from([bad]), &lengths).unwrap_err();
            assert!(
                err.to_string().contains(&format!("episode {}", bad.0)),
                "{err}"
            );
        }
    }
}
