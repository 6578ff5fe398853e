//! `dataset stats`: a dataset's `meta/stats.json` recomputed exactly from all its frames
//! (numeric features; video features combined from the episodes' own statistics), in
//! place: the new file written atomically, the previous one kept as
//! `meta/stats.json.bak`; with openpi's `norm_stats.json` beside it on request. Says how
//! far the previous statistics were from the exact ones.

use std::path::{Path, PathBuf};

use dexjoco_formats::dataset::lerobot_read::LeRobotDataset;
use dexjoco_formats::openpi::{NORM_STATS, NormStatsOptions};
use serde::Serialize;
use serde_json::Value;

use crate::{EditError, stats};

/// What `dataset stats` did.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct RestatReport {
    /// Features with statistics.
    pub features: usize,
    /// Per feature, the largest absolute difference of any statistic between the
    /// previous `stats.json` and the exact one (absent: the feature was not there).
    pub previous_off_by: Vec<(String, f64)>,
    /// Where the previous `stats.json` was kept (none when it was the same or absent).
    pub backup: Option<PathBuf>,
    /// openpi's `norm_stats.json`, when written.
    pub norm_stats: Option<PathBuf>,
}

/// Recomputes the statistics of the dataset at `root` in place (and openpi's
/// `norm_stats.json` with `norm`).
pub fn restat(root: &Path, norm: Option<NormStatsOptions>) -> Result<RestatReport, EditError> {
    let ds = LeRobotDataset::open(root)?;
    let path = root.join("meta/stats.json");
    // In place: the files written replace links, never write through them, and no folder
    // on the way may be a link (it would lead the writes out of the dataset).
    dexjoco_formats::fs::check_no_linked_folders(root, &path)?;
    let data = ds.data_files()?;
    let doc = stats::stats_document(&ds, &data, &ds.episodes)?;
    let previous_bytes = fs_err::read(&path).ok();
    let previous: Option<Value> = previous_bytes
        .as_deref()
        .and_then(|t| serde_json::from_slice(t).ok());
    let previous_off_by = doc
        .as_object()
        .into_iter()
        .flatten()
        .filter_map(|(k, new)| {
            let old = previous.as_ref()?.get(k)?;
            Some((k.clone(), largest_difference(old, new)))
        })
        .collect();
    let text = serde_json::to_string_pretty(&doc).expect("json");
    let backup = match (&previous, &previous_bytes) {
        (Some(old), Some(bytes)) if *old != doc => {
            let bak = root.join("meta/stats.json.bak");
            dexjoco_formats::fs::write_atomic(&bak, bytes)?;
            Some(bak)
        }
        _ => None,
    };
    dexjoco_formats::fs::write_atomic(&path, text.as_bytes())?;
    let norm_stats = match norm {
        Some(options) => {
            stats::norm_stats_of(&data, options)?.write(root)?;
            Some(root.join(NORM_STATS))
        }
        None => None,
    };
    Ok(RestatReport {
        features: doc.as_object().map_or(0, |m| m.len()),
        previous_off_by,
        backup,
        norm_stats,
    })
}

/// The largest absolute difference between the numbers of two statistics documents of
/// one feature, position by position (infinite where their shapes differ).
fn largest_difference(old: &Value, new: &Value) -> f64 {
    fn numbers(v: &Value, out: &mut Vec<f64>) {
        match v {
            Value::Number(n) => out.extend(n.as_f64()),
            Value::Array(a) => a.iter().for_each(|x| numbers(x, out)),
            _ => {}
        }
    }
    let mut worst: f64 = 0.0;
    for (k, n) in new.as_object().into_iter().flatten() {
        if k == "count" {
            continue;
        }
        let (mut a, mut b) = (Vec::new(), Vec::new());
        numbers(&old[k], &mut a);
        numbers(n, &mut b);
        if a.len() != b.len() {
            return f64::INFINITY;
        }
        for (x, y) in a.iter().zip(&b) {
            worst = worst.max((x - y).abs());
        }
    }
    worst
}

/// Writes openpi's `norm_stats.json` (openpi's defaults) into the edited dataset `dir`
/// whose data files are `data`, when the source had one: an edit keeps it true.
pub(crate) fn carry_norm_stats(
    source_had: bool,
    meta: &dexjoco_formats::dataset::lerobot_meta::InfoMeta,
    data: &[PathBuf],
    dir: &Path,
) -> Result<(), EditError> {
    if !source_had {
        return Ok(());
    }
    if let Some(gone) = ["observation.state", "action"]
        .into_iter()
        .find(|k| meta.feature(k).is_none())
    {
        tracing::warn!(
            "'{}' has no {gone} feature: openpi's norm_stats.json (of observation.state and \
             action) is not written",
            dir.display()
        );
        return Ok(());
    }
    let norm = stats::norm_stats_of(data, NormStatsOptions::default())?;
    if norm.document().is_some() {
        norm.write(dir)?;
    } else {
        tracing::warn!(
            "'{}': too few frames for openpi's norm_stats.json (batches of {}): not written",
            dir.display(),
            NormStatsOptions::default().batch_size
        );
    }
    Ok(())
}
