//! `dataset to-v21`: a LeRobot v3.0 dataset written as v2.1, the version openpi's pinned
//! lerobot reads: one parquet and one mp4 per camera for each episode (each cut out of
//! the v3.0 files by stream copy, bit-exact), jsonl metadata with per-episode
//! statistics and every per-episode column that has a JSON form. lerobot 0.6's
//! `language` features have no v2.1 form and are left out (named).
//!
//! ```text
//! meta/info.json  meta/episodes.jsonl  meta/tasks.jsonl  meta/episodes_stats.jsonl  meta/stats.json
//! data/chunk-{c:03}/episode_{e:06}.parquet
//! videos/chunk-{c:03}/{video_key}/episode_{e:06}.mp4
//! ```

use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;

use arrow_array::{Array, ArrayRef, BooleanArray, ListArray, RecordBatch};
use arrow_schema::{DataType, SchemaRef};
use dexjoco_core::Progress;
use dexjoco_formats::dataset::lerobot_read::{LeRobotDataset, strings};
use dexjoco_formats::fs::StagedDir;
use dexjoco_video::{ConcatInput, concat_copy};
use parquet::arrow::ArrowWriter;
use serde_json::{Map, Value, json};

use crate::data_file::DataFile;
use crate::info::is_format_column;
use crate::subset::check_output;
use crate::videos::Placement;
use crate::{EditError, SubsetReport};
use dexjoco_formats::dataset::parquet::props;

/// v2.1's file layout.
const DATA_PATH: &str = "data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}.parquet";
const VIDEO_PATH: &str =
    "videos/chunk-{episode_chunk:03d}/{video_key}/episode_{episode_index:06d}.mp4";

/// Writes the v3.0 dataset at `source` as a v2.1 dataset at `out`.
pub fn to_v21(
    source: &Path,
    out: &Path,
    overwrite: bool,
    progress: &dyn Progress,
) -> Result<SubsetReport, EditError> {
    let ds = LeRobotDataset::open(source)?;
    check_output(source, out, overwrite)?;
    let staged = StagedDir::begin(out)?;
    let dir = staged.path();
    let chunks_size = ds.meta.chunks_size as i64;
    let dropped: Vec<String> = ds
        .features()
        .iter()
        .filter(|(_, f)| f["dtype"] == "language")
        .map(|(k, _)| k.clone())
        .collect();
    if !dropped.is_empty() {
        tracing::warn!(
            "LeRobot v2.1 has no language features: {} left out",
            dropped.join(", ")
        );
    }
    progress.phase("episodes", ds.len() as u64);
    let frames = write_episode_data(&ds, dir, chunks_size, &dropped, progress)?;
    let videos = write_episode_videos(&ds, dir, chunks_size)?;
    write_meta(&ds, dir, chunks_size, &dropped, videos)?;
    staged.commit()?;
    Ok(SubsetReport {
        episodes: ds.len(),
        frames,
        tasks: ds.task_names()?.len(),
        data_files: ds.len(),
        videos_cut: videos,
        ..SubsetReport::default()
    })
}

/// The chunk folder of episode `e`.
fn chunk_of(e: usize, chunks_size: i64) -> i64 {
    e as i64 / chunks_size
}

/// One parquet per episode, the source's columns but `dropped`.
fn write_episode_data(
    ds: &LeRobotDataset,
    dir: &Path,
    chunks_size: i64,
    dropped: &[String],
    progress: &dyn Progress,
) -> Result<u64, EditError> {
    let mut open: Option<(i64, ArrowWriter<std::fs::File>)> = None;
    let mut frames = 0u64;
    for file in ds.data_files()? {
        let f = DataFile(&file);
        let err = |e: &dyn std::fmt::Display| f.error(e);
        for batch in f.batches()? {
            let batch = without(&batch.map_err(|e| err(&e))?, dropped).map_err(|e| err(&e))?;
            let episodes = crate::subset::ints(&batch, "episode_index").unwrap_or_default();
            let mut start = 0;
            while start < episodes.len() {
                let e = episodes[start];
                let end = episodes[start..]
                    .iter()
                    .position(|x| *x != e)
                    .map_or(episodes.len(), |p| start + p);
                if open.as_ref().is_none_or(|(at, _)| *at != e) {
                    if let Some((done, w)) = open.take() {
                        w.close().map_err(|e| err(&e))?;
                        progress.advance(1, &format!("episode {done}"));
                    }
                    let path = dir.join(format!(
                        "data/chunk-{:03}/episode_{e:06}.parquet",
                        chunk_of(e as usize, chunks_size)
                    ));
                    fs_err::create_dir_all(path.parent().unwrap_or(dir))?;
                    let f = fs_err::File::create(&path)?.into_parts().0;
                    let schema = with_hf_metadata(&batch.schema(), &ds.features());
                    let w = ArrowWriter::try_new(f, schema, Some(props())).map_err(|e| err(&e))?;
                    open = Some((e, w));
                }
                let part = batch.slice(start, end - start);
                let part = RecordBatch::try_new(
                    with_hf_metadata(&part.schema(), &ds.features()),
                    part.columns().to_vec(),
                )
                .map_err(|e| err(&e))?;
                open.as_mut()
                    .expect("opened")
                    .1
                    .write(&part)
                    .map_err(|e| err(&e))?;
                frames += (end - start) as u64;
                start = end;
            }
        }
    }
    if let Some((done, w)) = open {
        w.close()
            .map_err(|e| EditError::Selection(format!("episode {done}: {e}")))?;
        progress.advance(1, &format!("episode {done}"));
    }
    Ok(frames)
}

/// `schema` with the `huggingface` metadata the v2.1 loader (and lerobot's v2.1 to v3.0
/// converter) builds its features from, made from info.json's `features` for the columns
/// present: vectors as `Sequence`s of `Value`s, scalars as `Value`s.
fn with_hf_metadata(schema: &SchemaRef, features: &Map<String, Value>) -> SchemaRef {
    let mut hf = Map::new();
    for field in schema.fields() {
        let Some(f) = features.get(field.name()) else {
            continue;
        };
        let dtype = f["dtype"].as_str().unwrap_or("float32");
        let shape: Vec<u64> = f["shape"]
            .as_array()
            .map(|s| s.iter().filter_map(Value::as_u64).collect())
            .unwrap_or_default();
        let value = json!({"dtype": dtype, "_type": "Value"});
        let entry = match shape.as_slice() {
            [1] | [] => value,
            [n] => json!({"feature": value, "length": n, "_type": "Sequence"}),
            _ => continue,
        };
        hf.insert(field.name().clone(), entry);
    }
    let text = serde_json::to_string(&json!({"info": {"features": hf}})).expect("json");
    let mut metadata = schema.metadata().clone();
    metadata.insert("huggingface", text);
    std::sync::Arc::new(schema.as_ref().clone().with_metadata(metadata))
}

/// `batch` without the columns `dropped` (its schema metadata kept).
fn without(
    batch: &RecordBatch,
    dropped: &[String],
) -> Result<RecordBatch, arrow_schema::ArrowError> {
    if dropped.is_empty() {
        return Ok(batch.clone());
    }
    let keep: Vec<usize> = (0..batch.num_columns())
        .filter(|i| !dropped.contains(batch.schema().field(*i).name()))
        .collect();
    batch.project(&keep)
}

/// One mp4 per camera for each episode, cut out of the v3.0 files by stream copy;
/// returns how many were written.
fn write_episode_videos(
    ds: &LeRobotDataset,
    dir: &Path,
    chunks_size: i64,
) -> Result<usize, EditError> {
    let mut written = 0;
    for key in ds.video_keys() {
        let place = Placement::checked(ds, &key)?;
        for e in 0..ds.len() {
            let (chunk, file) = place.source(e);
            let src = ds.video_file(&key, chunk, file);
            let context = |r: usize| format!("video '{}' of episode {r} ({key})", src.display());
            let (start, frames) = place.span(e, ds.fps, &context)?;
            let out = dir.join(format!(
                "videos/chunk-{:03}/{key}/episode_{e:06}.mp4",
                chunk_of(e, chunks_size)
            ));
            fs_err::create_dir_all(out.parent().unwrap_or(dir))?;
            let input = ConcatInput {
                path: src.clone(),
                skip: start as usize,
                take: Some(frames as usize),
            };
            concat_copy(&[input], &out, ds.fps.round() as u32).map_err(|source| {
                EditError::Video {
                    context: format!("video '{}' of episode {e} ({key})", src.display()),
                    source,
                }
            })?;
            written += 1;
        }
    }
    Ok(written)
}

/// info.json, episodes.jsonl, tasks.jsonl, episodes_stats.jsonl and stats.json.
fn write_meta(
    ds: &LeRobotDataset,
    dir: &Path,
    chunks_size: i64,
    dropped: &[String],
    videos: usize,
) -> Result<(), EditError> {
    let meta = dir.join("meta");
    fs_err::create_dir_all(&meta)?;
    let n = ds.len();
    let mut info = ds.info.clone();
    for k in ["data_files_size_in_mb", "video_files_size_in_mb"] {
        info.remove(k);
    }
    let mut features = ds.features();
    features.retain(|k, _| !dropped.contains(k));
    info.insert("codebase_version".into(), json!("v2.1"));
    info.insert("features".into(), Value::Object(features));
    info.insert(
        "total_chunks".into(),
        json!((n as i64 + chunks_size - 1) / chunks_size),
    );
    info.insert("total_videos".into(), json!(videos));
    info.insert("data_path".into(), json!(DATA_PATH));
    info.insert("video_path".into(), json!(VIDEO_PATH));
    let text = serde_json::to_string_pretty(&Value::Object(info)).expect("json");
    fs_err::write(meta.join("info.json"), text + "\n")?;
    let names = ds.task_names()?;
    jsonl(
        &meta.join("tasks.jsonl"),
        names
            .iter()
            .enumerate()
            .map(|(i, t)| json!({"task_index": i, "task": t})),
    )?;
    let tasks = ds.episode_tasks()?;
    let lengths = ds.lengths()?;
    let schema = ds.episodes.schema();
    let custom: Vec<usize> = (0..schema.fields().len())
        .filter(|i| !is_format_column(schema.field(*i).name()))
        .collect();
    jsonl(
        &meta.join("episodes.jsonl"),
        (0..n).map(|e| {
            let mut line = Map::new();
            line.insert("episode_index".into(), json!(e));
            line.insert("tasks".into(), json!(tasks[e]));
            line.insert("length".into(), json!(lengths[e]));
            for &i in &custom {
                if let Some(v) = cell_json(ds.episodes.column(i), e) {
                    line.insert(schema.field(i).name().clone(), v);
                }
            }
            Value::Object(line)
        }),
    )?;
    jsonl(
        &meta.join("episodes_stats.jsonl"),
        (0..n).map(|e| json!({"episode_index": e, "stats": episode_stats(&ds.episodes, &schema, e, dropped)})),
    )?;
    // The same frames: the statistics and openpi's norm_stats.json carry over as they are.
    for file in ["meta/stats.json", dexjoco_formats::openpi::NORM_STATS] {
        if ds.root.join(file).exists() {
            fs_err::copy(ds.root.join(file), dir.join(file))?;
        }
    }
    Ok(())
}

/// Episode `e`'s `{feature: {stat: value}}` from the `stats/<feature>/<stat>` columns.
fn episode_stats(
    episodes: &RecordBatch,
    schema: &SchemaRef,
    e: usize,
    dropped: &[String],
) -> Value {
    let mut out: BTreeMap<String, Map<String, Value>> = BTreeMap::new();
    for (i, f) in schema.fields().iter().enumerate() {
        let Some(rest) = f.name().strip_prefix("stats/") else {
            continue;
        };
        let Some((feature, stat)) = rest.rsplit_once('/') else {
            continue;
        };
        if dropped.iter().any(|d| d == feature) {
            continue;
        }
        if let Some(v) = cell_json(episodes.column(i), e) {
            out.entry(feature.to_owned())
                .or_default()
                .insert(stat.to_owned(), v);
        }
    }
    json!(out)
}

/// Row `row` of `col` as JSON: booleans, numbers, text and (nested) lists of them;
/// `None` for nulls and other types.
fn cell_json(col: &ArrayRef, row: usize) -> Option<Value> {
    if col.is_null(row) {
        return None;
    }
    match col.data_type() {
        DataType::Boolean => {
            let b = col.as_any().downcast_ref::<BooleanArray>()?;
            Some(json!(b.value(row)))
        }
        DataType::Utf8 | DataType::LargeUtf8 => Some(json!(strings(&col.slice(row, 1))[0])),
        DataType::List(_) => {
            let l = col.as_any().downcast_ref::<ListArray>()?;
            let inner = l.value(row);
            Some(Value::Array(
                (0..inner.len())
                    .filter_map(|i| cell_json(&inner, i))
                    .collect(),
            ))
        }
        DataType::Int8
        | DataType::Int16
        | DataType::Int32
        | DataType::Int64
        | DataType::UInt8
        | DataType::UInt16
        | DataType::UInt32
        | DataType::UInt64 => {
            let v = arrow_cast::cast(&col.slice(row, 1), &DataType::Int64).ok()?;
            let v = v.as_any().downcast_ref::<arrow_array::Int64Array>()?;
            Some(json!(v.value(0)))
        }
        DataType::Float16 | DataType::Float32 | DataType::Float64 => {
            let v = arrow_cast::cast(&col.slice(row, 1), &DataType::Float64).ok()?;
            let v = v.as_any().downcast_ref::<arrow_array::Float64Array>()?;
            serde_json::Number::from_f64(v.value(0)).map(Value::Number)
        }
        _ => None,
    }
}

fn jsonl(path: &Path, lines: impl Iterator<Item = Value>) -> Result<(), EditError> {
    let mut f = std::io::BufWriter::new(fs_err::File::create(path)?);
    for line in lines {
        writeln!(f, "{}", serde_json::to_string(&line).expect("json"))?;
    }
    f.flush()?;
    Ok(())
}
