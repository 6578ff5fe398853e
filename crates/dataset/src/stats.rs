//! `meta/stats.json` of an edited dataset: numeric features exactly from every frame of
//! its data files (quantiles included, as convert computes them), video and image
//! features combined from the kept episodes' own statistics (the per-episode
//! `stats/<feature>/...` columns, which were sampled from decoded frames).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use arrow_array::{Array, ArrayRef, FixedSizeListArray, ListArray, RecordBatch};
use arrow_schema::DataType;
use dexjoco_formats::dataset::lerobot_info::stats_json;
use dexjoco_formats::dataset::lerobot_read::LeRobotDataset;
use dexjoco_formats::dataset::stats::{FeatureStats, QUANTILES, aggregate, column_stats};
use dexjoco_formats::openpi::{NormStats, NormStatsOptions};
use serde_json::{Map, Value};

use crate::EditError;
use crate::data_file::DataFile;

/// A feature's values gathered row by row.
struct Column {
    width: usize,
    values: Vec<f64>,
}

/// Writes `meta/stats.json` under `dir` for the data files `data` of the edited
/// dataset, whose episode rows are `episodes` (output order).
pub(crate) fn write_stats(
    ds: &LeRobotDataset,
    data: &[PathBuf],
    episodes: &RecordBatch,
    dir: &Path,
) -> Result<(), EditError> {
    let doc = stats_document(ds, data, episodes)?;
    let text = serde_json::to_string_pretty(&doc).expect("json");
    fs_err::write(dir.join("meta/stats.json"), text)?;
    Ok(())
}

/// The `meta/stats.json` document of a dataset described by `ds` (its features) whose
/// data files are `data` and episode rows `episodes`.
pub(crate) fn stats_document(
    ds: &LeRobotDataset,
    data: &[PathBuf],
    episodes: &RecordBatch,
) -> Result<Value, EditError> {
    let mut numeric: BTreeMap<String, Column> = ds
        .meta
        .features
        .iter()
        .filter(|(_, f)| f.is_numeric())
        .map(|(k, f)| {
            let column = Column {
                width: f.width,
                values: Vec::new(),
            };
            (k.clone(), column)
        })
        .collect();
    for file in data {
        gather(file, &mut numeric)?;
    }
    let mut out = Map::new();
    for (key, f) in &ds.meta.features {
        let stats = match numeric.get(key) {
            Some(c) if !c.values.is_empty() => Some(column_stats(&c.values, c.width)),
            Some(_) => None,
            None => per_episode(episodes, key)?,
        };
        if let Some(s) = stats {
            out.insert(key.clone(), stats_json(&s, f.is_visual()));
        }
    }
    Ok(Value::Object(out))
}

/// openpi's `norm_stats.json` statistics of the data files `data` (their
/// `observation.state` and `action`, episode by episode, fed as `options` say).
pub(crate) fn norm_stats_of(
    data: &[PathBuf],
    options: NormStatsOptions,
) -> Result<NormStats, EditError> {
    let mut norm = NormStats::new(options);
    // The episode being gathered: its index, state rows and action rows.
    let mut current: Option<(f64, Vec<f64>, Vec<f64>)> = None;
    let mut widths = (0, 0);
    let mut flush = |ep: Option<(f64, Vec<f64>, Vec<f64>)>, widths: (usize, usize)| {
        if let Some((_, state, action)) = ep
            && !action.is_empty()
        {
            norm.add_episode(&state, widths.0, &action, widths.1);
        }
    };
    for file in data {
        let f = DataFile(file);
        let err = |e: &dyn std::fmt::Display| f.error(e);
        for batch in f.batches()? {
            let batch = batch.map_err(|e| err(&e))?;
            let column = |name: &str| -> Result<(Vec<f64>, usize), EditError> {
                let col = batch.column_by_name(name).ok_or_else(|| {
                    err(&format!(
                        "no {name} column: openpi's statistics need observation.state and action"
                    ))
                })?;
                let values = flat_f64(col).ok_or_else(|| err(&format!("{name} is not numeric")))?;
                let width = values.len() / batch.num_rows().max(1);
                Ok((values, width))
            };
            let (episode, _) = column("episode_index")?;
            let (state, sw) = column("observation.state")?;
            let (action, aw) = column("action")?;
            widths = (sw, aw);
            for (row, e) in episode.iter().enumerate() {
                if current.as_ref().is_none_or(|c| c.0 != *e) {
                    flush(current.take(), widths);
                    current = Some((*e, Vec::new(), Vec::new()));
                }
                let c = current.as_mut().expect("set");
                c.1.extend_from_slice(&state[row * sw..(row + 1) * sw]);
                c.2.extend_from_slice(&action[row * aw..(row + 1) * aw]);
            }
        }
    }
    flush(current.take(), widths);
    Ok(norm)
}

/// Appends every numeric feature's values of the data file `file`.
fn gather(file: &Path, columns: &mut BTreeMap<String, Column>) -> Result<(), EditError> {
    let f = DataFile(file);
    for batch in f.batches()? {
        let batch = batch.map_err(|e| f.error(&e))?;
        for (key, c) in columns.iter_mut() {
            if let Some(col) = batch.column_by_name(key)
                && let Some(values) = flat_f64(col)
            {
                if values.len() != batch.num_rows() * c.width {
                    return Err(f.error(&format!(
                        "column {key:?} holds {} values in {} rows, but info.json's shape \
                         says {} per frame: the dataset's metadata does not describe its data",
                        values.len(),
                        batch.num_rows(),
                        c.width
                    )));
                }
                c.values.extend(values);
            }
        }
    }
    Ok(())
}

/// Every leaf value of a numeric column, nested lists flattened in row order.
pub(crate) fn flat_f64(col: &ArrayRef) -> Option<Vec<f64>> {
    match col.data_type() {
        DataType::FixedSizeList(_, size) => {
            let l = col.as_any().downcast_ref::<FixedSizeListArray>()?;
            let size = *size as usize;
            let inner = l.values().slice(l.offset() * size, l.len() * size);
            flat_f64(&inner)
        }
        DataType::List(_) => {
            let l = col.as_any().downcast_ref::<ListArray>()?;
            let mut all = Vec::new();
            for i in 0..l.len() {
                all.extend(flat_f64(&l.value(i))?);
            }
            Some(all)
        }
        DataType::Boolean | DataType::Utf8 | DataType::LargeUtf8 => None,
        _ => {
            let f = arrow_cast::cast(col, &DataType::Float64).ok()?;
            let f = f.as_any().downcast_ref::<arrow_array::Float64Array>()?;
            Some(f.values().to_vec())
        }
    }
}

/// A video or image feature's statistics combined from the kept episodes' own
/// (`stats/<key>/min`, ...), as lerobot combines them; `None` where they are absent.
fn per_episode(episodes: &RecordBatch, key: &str) -> Result<Option<FeatureStats>, EditError> {
    let column = |stat: &str| -> Option<Vec<Vec<f64>>> {
        let col = episodes.column_by_name(&format!("stats/{key}/{stat}"))?;
        (0..col.len()).map(|i| flat_f64(&col.slice(i, 1))).collect()
    };
    let (Some(min), Some(max), Some(mean), Some(std), Some(count)) = (
        column("min"),
        column("max"),
        column("mean"),
        column("std"),
        column("count"),
    ) else {
        return Ok(None);
    };
    let quantiles: Vec<Option<Vec<Vec<f64>>>> =
        QUANTILES.iter().map(|(_, name)| column(name)).collect();
    let each: Vec<FeatureStats> = (0..min.len())
        .map(|i| FeatureStats {
            min: min[i].clone(),
            max: max[i].clone(),
            mean: mean[i].clone(),
            std: std[i].clone(),
            count: count[i].first().copied().unwrap_or(0.0) as u64,
            quantiles: std::array::from_fn(|q| {
                quantiles[q]
                    .as_ref()
                    .map_or_else(|| mean[i].clone(), |v| v[i].clone())
            }),
        })
        .collect();
    Ok(aggregate(&each.iter().collect::<Vec<_>>()))
}

/// The per-episode columns whose values an edit renumbers.
const RENUMBERED: [&str; 3] = ["episode_index", "index", "task_index"];

/// `episodes` with the per-episode statistics of the renumbered columns
/// (`stats/episode_index/...`, `stats/index/...`, `stats/task_index/...`) recomputed
/// from the written data files `data`, where those columns exist.
pub(crate) fn restat_renumbered(
    episodes: &RecordBatch,
    data: &[PathBuf],
) -> Result<RecordBatch, EditError> {
    restat_episode_columns(episodes, data, &RENUMBERED, None)
}

/// `episodes` with the per-episode statistics (`stats/<column>/...`) of each of
/// `columns` that has them recomputed from the written data files `data` (rows found
/// by their `episode_index`, the row number in `episodes`); with `only`, in the rows
/// it marks, the others keeping their values.
pub(crate) fn restat_episode_columns(
    episodes: &RecordBatch,
    data: &[PathBuf],
    columns: &[&str],
    only: Option<&[bool]>,
) -> Result<RecordBatch, EditError> {
    let present: Vec<&str> = columns
        .iter()
        .copied()
        .filter(|c| episodes.column_by_name(&format!("stats/{c}/min")).is_some())
        .collect();
    if present.is_empty() {
        return Ok(episodes.clone());
    }
    let values = per_episode_values(episodes.num_rows(), data, &present)?;
    let schema = episodes.schema();
    let mut out = episodes.columns().to_vec();
    for c in present {
        let (values, rows) = &values[c];
        let stats: Vec<Option<FeatureStats>> = values
            .iter()
            .zip(rows)
            .map(|(v, n)| (*n > 0).then(|| column_stats(v, v.len() / n)))
            .collect();
        for (i, field) in schema.fields().iter().enumerate() {
            let Some(stat) = field.name().strip_prefix(&format!("stats/{c}/")) else {
                continue;
            };
            let rows: Option<Vec<Vec<f64>>> = stats
                .iter()
                .map(|s| s.as_ref().and_then(|s| pick(s, stat)))
                .collect();
            let Some(rows) = rows else { continue };
            let mut b =
                arrow_array::builder::ListBuilder::new(arrow_array::builder::Float64Builder::new());
            for r in rows {
                b.values().append_slice(&r);
                b.append(true);
            }
            let new: ArrayRef = std::sync::Arc::new(b.finish());
            let Ok(new) = arrow_cast::cast(&new, field.data_type()) else {
                continue;
            };
            out[i] = match only {
                None => new,
                Some(rows) => {
                    let mask = arrow_array::BooleanArray::from(rows.to_vec());
                    arrow_select::zip::zip(&mask, &new, &out[i])
                        .map_err(|e| EditError::Selection(format!("episode rows: {e}")))?
                }
            };
        }
    }
    RecordBatch::try_new(schema, out)
        .map_err(|e| EditError::Selection(format!("episode rows: {e}")))
}

/// One statistic (`min`, `count`, `q01`, ...) of `s`, as its per-episode column holds it.
fn pick(s: &FeatureStats, stat: &str) -> Option<Vec<f64>> {
    match stat {
        "min" => Some(s.min.clone()),
        "max" => Some(s.max.clone()),
        "mean" => Some(s.mean.clone()),
        "std" => Some(s.std.clone()),
        "count" => Some(vec![s.count as f64]),
        q => QUANTILES
            .iter()
            .position(|(_, name)| *name == q)
            .map(|k| s.quantiles[k].clone()),
    }
}

/// Per column of `columns`: each episode's values (flattened rows) and row count, read
/// from the data files `data`.
pub(crate) type EpisodeValues<'a> = BTreeMap<&'a str, (Vec<Vec<f64>>, Vec<usize>)>;

pub(crate) fn per_episode_values<'a>(
    n: usize,
    data: &[PathBuf],
    columns: &[&'a str],
) -> Result<EpisodeValues<'a>, EditError> {
    let mut values: EpisodeValues = columns
        .iter()
        .map(|c| (*c, (vec![Vec::new(); n], vec![0; n])))
        .collect();
    for file in data {
        let f = DataFile(file);
        let err = |e: &dyn std::fmt::Display| f.error(e);
        for batch in f.batches()? {
            let batch = batch.map_err(|e| err(&e))?;
            let Some(episode) = batch.column_by_name("episode_index").and_then(flat_f64) else {
                continue;
            };
            for c in columns {
                let Some(v) = batch.column_by_name(c).and_then(flat_f64) else {
                    continue;
                };
                let width = v.len() / episode.len().max(1);
                let (per, rows) = values.get_mut(c).expect("present");
                for (row, e) in episode.iter().enumerate() {
                    if let Some(slot) = per.get_mut(*e as usize) {
                        slot.extend_from_slice(&v[row * width..(row + 1) * width]);
                        rows[*e as usize] += 1;
                    }
                }
            }
        }
    }
    Ok(values)
}
