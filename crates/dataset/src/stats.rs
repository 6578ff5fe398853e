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
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use serde_json::{Map, Value};

use crate::EditError;

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
    let features = ds.features();
    let mut numeric: BTreeMap<String, Column> = features
        .iter()
        .filter(|(_, f)| !matches!(f["dtype"].as_str(), Some("video" | "image" | "string")))
        .map(|(k, f)| {
            let width = f["shape"].as_array().map_or(1, |s| {
                s.iter().filter_map(Value::as_u64).product::<u64>() as usize
            });
            (
                k.clone(),
                Column {
                    width: width.max(1),
                    values: Vec::new(),
                },
            )
        })
        .collect();
    for file in data {
        gather(file, &mut numeric)?;
    }
    let mut out = Map::new();
    for (key, f) in &features {
        let stats = match numeric.get(key) {
            Some(c) if !c.values.is_empty() && c.values.len() % c.width == 0 => {
                Some(column_stats(&c.values, c.width))
            }
            Some(_) => None,
            None => per_episode(episodes, key)?,
        };
        if let Some(s) = stats {
            let image = matches!(f["dtype"].as_str(), Some("video" | "image"));
            out.insert(key.clone(), stats_json(&s, image));
        }
    }
    let path = dir.join("meta/stats.json");
    let text = serde_json::to_string_pretty(&Value::Object(out)).expect("json");
    fs_err::write(&path, text)?;
    Ok(())
}

/// Appends every numeric feature's values of the data file `file`.
fn gather(file: &Path, columns: &mut BTreeMap<String, Column>) -> Result<(), EditError> {
    let err = |e: &dyn std::fmt::Display| {
        EditError::Selection(format!("data file '{}': {e}", file.display()))
    };
    let reader = ParquetRecordBatchReaderBuilder::try_new(fs_err::File::open(file)?.into_parts().0)
        .map_err(|e| err(&e))?
        .build()
        .map_err(|e| err(&e))?;
    for batch in reader {
        let batch = batch.map_err(|e| err(&e))?;
        for (key, c) in columns.iter_mut() {
            if let Some(col) = batch.column_by_name(key)
                && let Some(values) = flat_f64(col)
            {
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
