//! `dataset merge`: several LeRobot v3.0 datasets into one, reconciling what can be
//! reconciled and naming what cannot. Features renamed by a mapping (`--rename
//! observation.images.cam_high=observation.images.top`), 1-D float features of different
//! widths zero-padded to the widest (`--pad`, as `convert --merge-bimanual` pads one-arm
//! tasks), the same fps and video codec required, tasks and per-episode columns unioned
//! (a column one dataset lacks is null for its episodes). Frames are streamed and
//! renumbered, video files copied whole (bit-exact), statistics recomputed.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use arrow_array::{Array, ArrayRef, FixedSizeListArray, Float64Array, RecordBatch, new_null_array};
use arrow_schema::{DataType, Field, Schema, SchemaRef};
use dexjoco_core::Progress;
use dexjoco_formats::dataset::lerobot_meta::InfoMeta;
use dexjoco_formats::dataset::lerobot_read::LeRobotDataset;
use dexjoco_formats::fs::StagedDir;
use parquet::arrow::ArrowWriter;
use serde_json::{Map, Value, json};

use crate::data_file::DataFile;
use crate::subset::{DataPlace, check_output, ints, placed, with_columns};
use crate::videos::VideoPlace;
use crate::{EditError, SubsetReport, stats};
use dexjoco_formats::dataset::parquet::{props, write_file};

/// How datasets are reconciled when merged.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MergeOptions {
    /// Feature keys renamed in every source before merging (`old`, `new`).
    pub rename: Vec<(String, String)>,
    /// Zero-pad 1-D float features of different widths to the widest.
    pub pad: bool,
    /// Features left out (by their name after `rename`): data columns, videos and their
    /// per-episode columns.
    pub remove: Vec<String>,
}

/// Columns every LeRobot dataset needs, never removed.
const REQUIRED: [&str; 5] = [
    "timestamp",
    "frame_index",
    "episode_index",
    "index",
    "task_index",
];

/// A source prepared for merging: its features under their merged names.
struct Part {
    ds: LeRobotDataset,
    /// Merged name of each source feature key.
    names: BTreeMap<String, String>,
    /// Merged names of the features left out.
    removed: Vec<String>,
}

impl Part {
    /// Opens `source` with `options`' renames and removals.
    fn open(source: &Path, options: &MergeOptions) -> Result<Self, EditError> {
        let ds = LeRobotDataset::open(source)?;
        // A new name is a data column, a per-episode column prefix and, for a video, a
        // folder of the output: one name, checked as every name that becomes a path is.
        for (_, new) in &options.rename {
            dexjoco_core::safe_name("feature name", new)
                .map_err(|e| EditError::Selection(format!("--rename: {e}")))?;
        }
        let names = ds
            .features()
            .keys()
            .map(|k| {
                let new = options
                    .rename
                    .iter()
                    .find(|(o, _)| o == k)
                    .map_or(k, |(_, n)| n);
                (k.clone(), new.clone())
            })
            .collect();
        Ok(Self {
            ds,
            names,
            removed: options.remove.clone(),
        })
    }

    /// Whether the source feature (or data column) `key` is kept.
    fn keeps(&self, key: &str) -> bool {
        !self.removed.iter().any(|r| r == self.name(key))
    }

    /// Whether the per-episode column `column` (merged name) belongs to a removed feature.
    fn drops_column(&self, column: &str) -> bool {
        self.removed.iter().any(|r| {
            column.starts_with(&format!("videos/{r}/"))
                || column.starts_with(&format!("stats/{r}/"))
        })
    }

    fn name<'a>(&'a self, key: &'a str) -> &'a str {
        self.names.get(key).map_or(key, String::as_str)
    }

    /// A per-episode column's merged name (`videos/<key>/...`, `stats/<key>/...`).
    fn column_name(&self, column: &str) -> String {
        for prefix in ["videos/", "stats/"] {
            if let Some(rest) = column.strip_prefix(prefix) {
                for (old, new) in &self.names {
                    if let Some(tail) = rest.strip_prefix(old.as_str())
                        && tail.starts_with('/')
                    {
                        return format!("{prefix}{new}{tail}");
                    }
                }
            }
        }
        column.to_owned()
    }
}

/// Merges the datasets at `sources` (in order) into a new dataset at `out`.
pub fn merge(
    sources: &[PathBuf],
    options: &MergeOptions,
    out: &Path,
    overwrite: bool,
    progress: &dyn Progress,
) -> Result<SubsetReport, EditError> {
    if sources.len() < 2 {
        return Err(EditError::Selection(
            "merge needs two or more datasets".into(),
        ));
    }
    let mut parts = Vec::new();
    for s in sources {
        check_output(s, out, overwrite)?;
        parts.push(Part::open(s, options)?);
    }
    let features = merged_features(&parts, options.pad)?;
    let staged = StagedDir::begin(out)?;
    let report = write_merged(&parts, &features, staged.path(), progress)?;
    staged.commit()?;
    Ok(report)
}

/// Writes `source` with features renamed and removed (`options.rename`,
/// `options.remove`) as a new dataset at `out`; everything else as `merge` writes it.
pub fn edit_features(
    source: &Path,
    options: &MergeOptions,
    out: &Path,
    overwrite: bool,
    progress: &dyn Progress,
) -> Result<SubsetReport, EditError> {
    check_output(source, out, overwrite)?;
    let part = Part::open(source, options)?;
    let features = part.ds.features();
    for key in options.rename.iter().map(|(o, _)| o).chain(&options.remove) {
        let known = features.contains_key(key) || part.names.values().any(|n| n == key);
        if !known {
            return Err(EditError::Selection(format!(
                "no feature {key:?} in '{}' (its features: {})",
                source.display(),
                features.keys().cloned().collect::<Vec<_>>().join(", ")
            )));
        }
    }
    if let Some(r) = options
        .remove
        .iter()
        .find(|r| REQUIRED.contains(&r.as_str()))
    {
        return Err(EditError::Selection(format!(
            "{r} cannot be removed: every LeRobot dataset has {}",
            REQUIRED.join(", ")
        )));
    }
    let parts = [part];
    let merged = merged_features(&parts, false)?;
    let staged = StagedDir::begin(out)?;
    let report = write_merged(&parts, &merged, staged.path(), progress)?;
    staged.commit()?;
    Ok(report)
}

/// The merged `features` of info.json: every source must have the same features (under
/// their merged names) with the same dtype, shape (1-D floats padded with `pad`) and
/// video codec; fps must agree.
fn merged_features(parts: &[Part], pad: bool) -> Result<Map<String, Value>, EditError> {
    let first = &parts[0];
    let mut merged = Map::new();
    for (k, f) in first.ds.features() {
        if first.keeps(&k) {
            merged.insert(first.name(&k).to_owned(), f);
        }
    }
    for p in &parts[1..] {
        if (p.ds.fps - first.ds.fps).abs() > 1e-9 {
            return Err(mismatch(
                first,
                p,
                &format!("fps {} vs {}", first.ds.fps, p.ds.fps),
            ));
        }
        let theirs: Map<String, Value> =
            p.ds.features()
                .into_iter()
                .map(|(k, f)| (p.name(&k).to_owned(), f))
                .collect();
        let (a, b): (Vec<_>, Vec<_>) = (merged.keys().collect(), theirs.keys().collect());
        if a != b {
            return Err(mismatch(
                first,
                p,
                &format!(
                    "features {a:?} vs {b:?} (--rename OLD=NEW maps a feature's key, as a \
                     camera named differently)"
                ),
            ));
        }
        for (key, f) in &theirs {
            reconcile(merged.get_mut(key).expect("same keys"), f, key, pad)
                .map_err(|why| mismatch(first, p, &why))?;
        }
    }
    Ok(merged)
}

/// Makes `mine` the merged description of one feature given another source's `theirs`.
fn reconcile(mine: &mut Value, theirs: &Value, key: &str, pad: bool) -> Result<(), String> {
    if mine["dtype"] != theirs["dtype"] {
        return Err(format!(
            "{key}: dtype {} vs {}",
            mine["dtype"], theirs["dtype"]
        ));
    }
    if mine["dtype"] == "video" && mine["info"]["video.codec"] != theirs["info"]["video.codec"] {
        return Err(format!(
            "{key}: video codec {} vs {} (one dataset's files cannot be described by one info.json)",
            mine["info"]["video.codec"], theirs["info"]["video.codec"]
        ));
    }
    if mine["shape"] == theirs["shape"] {
        return Ok(());
    }
    let width = |f: &Value| -> Option<u64> {
        let s = f["shape"].as_array()?;
        (s.len() == 1).then(|| s[0].as_u64()).flatten()
    };
    let float = matches!(mine["dtype"].as_str(), Some("float32" | "float64"));
    match (width(mine), width(theirs)) {
        (Some(a), Some(b)) if pad && float => {
            mine["shape"] = json!([a.max(b)]);
            // Names no longer describe every column once padded.
            if mine["names"].is_array() && a < b {
                mine["names"] = theirs["names"].clone();
            }
            Ok(())
        }
        _ => Err(format!(
            "{key}: shape {} vs {}{}",
            mine["shape"],
            theirs["shape"],
            if float {
                " (--pad zero-pads 1-D float features to the widest)"
            } else {
                ""
            }
        )),
    }
}

fn mismatch(a: &Part, b: &Part, why: &str) -> EditError {
    EditError::Selection(format!(
        "'{}' and '{}' cannot be merged: {why}",
        a.ds.root.display(),
        b.ds.root.display()
    ))
}

/// Writes the merged dataset into `dir`.
fn write_merged(
    parts: &[Part],
    features: &Map<String, Value>,
    dir: &Path,
    progress: &dyn Progress,
) -> Result<SubsetReport, EditError> {
    let first = &parts[0].ds;
    let (tasks, task_maps) = merged_tasks(parts)?;
    let (places, files) = write_data(parts, features, dir, &task_maps, progress)?;
    let mut report = SubsetReport {
        episodes: places.len(),
        frames: places.last().map_or(0, |p| p.to as u64),
        tasks: tasks.len(),
        data_files: files.len(),
        ..SubsetReport::default()
    };
    let mut video_places = BTreeMap::new();
    for (key, f) in features {
        if f["dtype"] == "video" {
            let (p, copied) = copy_videos(parts, key, dir)?;
            report.videos_copied += copied;
            video_places.insert(key.clone(), p);
        }
    }
    let episodes = placed(&merged_episode_rows(parts)?, &places, &video_places)?;
    let episodes = stats::restat_renumbered(&episodes, &files)?;
    let meta = dir.join("meta");
    fs_err::create_dir_all(meta.join("episodes/chunk-000"))?;
    write_file(&meta.join("episodes/chunk-000/file-000.parquet"), &episodes)?;
    write_tasks(first, &tasks, &meta)?;
    let mut info = first.info.clone();
    info.insert("features".into(), Value::Object(features.clone()));
    info.insert("total_episodes".into(), json!(report.episodes));
    info.insert("total_frames".into(), json!(report.frames));
    info.insert("total_tasks".into(), json!(tasks.len()));
    info.insert(
        "splits".into(),
        json!({"train": format!("0:{}", report.episodes)}),
    );
    let mut merged = first.clone();
    merged.info = info.clone();
    merged.meta = InfoMeta::parse(&mut merged.info, &meta.join("info.json"))?;
    stats::write_stats(&merged, &files, &episodes, dir)?;
    let had = parts
        .iter()
        .any(|p| p.ds.root.join(dexjoco_formats::openpi::NORM_STATS).exists());
    crate::restat::carry_norm_stats(had, &merged.meta, &files, dir)?;
    let text = serde_json::to_string_pretty(&Value::Object(info)).expect("json");
    fs_err::write(meta.join("info.json"), text + "\n")?;
    Ok(report)
}

/// A source's task indices to the merged ones.
type TaskMap = HashMap<i64, i64>;

/// The tasks of all sources in order of first appearance, and each source's map from
/// its task index to the merged one.
fn merged_tasks(parts: &[Part]) -> Result<(Vec<String>, Vec<TaskMap>), EditError> {
    let mut names: Vec<String> = Vec::new();
    let mut maps = Vec::new();
    for p in parts {
        let mut map = HashMap::new();
        for (old, name) in p.ds.task_names()?.into_iter().enumerate() {
            let new = names.iter().position(|n| *n == name).unwrap_or_else(|| {
                names.push(name);
                names.len() - 1
            });
            map.insert(old as i64, new as i64);
        }
        maps.push(map);
    }
    Ok((names, maps))
}

/// Streams every source's data files into the output, one output file per source file.
fn write_data(
    parts: &[Part],
    features: &Map<String, Value>,
    dir: &Path,
    task_maps: &[TaskMap],
    progress: &dyn Progress,
) -> Result<(Vec<DataPlace>, Vec<PathBuf>), EditError> {
    let first = &parts[0].ds;
    let total: usize = parts
        .iter()
        .map(|p| p.ds.data_files().map_or(0, |f| f.len()))
        .sum();
    progress.phase("data", total as u64);
    let (mut places, mut files) = (Vec::new(), Vec::new());
    let (mut schema, mut next_index, mut episode_offset) = (None::<SchemaRef>, 0i64, 0i64);
    for (p, task_map) in parts.iter().zip(task_maps) {
        let lengths = p.ds.lengths()?;
        for src in p.ds.data_files()? {
            let (out_chunk, out_file) = first.placement(files.len());
            let out = dir.join(first.data_rel(out_chunk, out_file));
            fs_err::create_dir_all(out.parent().unwrap_or(dir))?;
            let f = DataFile(&src);
            let err = |e: &dyn std::fmt::Display| f.error(e);
            let reader = f.batches()?;
            let mut writer: Option<ArrowWriter<std::fs::File>> = None;
            let mut counts: BTreeMap<i64, i64> = BTreeMap::new();
            for batch in reader {
                let batch =
                    conform(p, &batch.map_err(|e| err(&e))?, features).map_err(|e| err(&e))?;
                let target = schema.get_or_insert_with(|| batch.schema()).clone();
                let batch = project(&batch, &target).map_err(|e| err(&e))?;
                let episodes = ints(&batch, "episode_index").unwrap_or_default();
                for e in &episodes {
                    *counts.entry(*e).or_insert(0) += 1;
                }
                let n = episodes.len() as i64;
                let tasks = ints(&batch, "task_index").unwrap_or_default();
                let replace = [
                    (
                        "episode_index",
                        episodes.iter().map(|e| e + episode_offset).collect(),
                    ),
                    ("index", (next_index..next_index + n).collect()),
                    (
                        "task_index",
                        tasks
                            .iter()
                            .map(|t| task_map.get(t).copied().unwrap_or(*t))
                            .collect(),
                    ),
                ];
                next_index += n;
                let batch = with_columns(&batch, &target, &replace).map_err(|e| err(&e))?;
                if writer.is_none() {
                    let f = fs_err::File::create(&out)?.into_parts().0;
                    writer = Some(
                        ArrowWriter::try_new(f, target.clone(), Some(props()))
                            .map_err(|e| err(&e))?,
                    );
                }
                writer
                    .as_mut()
                    .expect("opened")
                    .write(&batch)
                    .map_err(|e| err(&e))?;
            }
            if let Some(w) = writer {
                w.close().map_err(|e| err(&e))?;
            }
            for (e, n) in counts {
                if lengths.get(e as usize) != Some(&n) {
                    return Err(err(&format!(
                        "episode {e} has {n} frames here but its length is {:?}",
                        lengths.get(e as usize)
                    )));
                }
                let from = places.last().map_or(0, |p: &DataPlace| p.to);
                places.push(DataPlace {
                    chunk: out_chunk,
                    file: out_file,
                    from,
                    to: from + n,
                });
            }
            files.push(out);
            progress.advance(1, &src.display().to_string());
        }
        episode_offset += p.ds.len() as i64;
    }
    Ok((places, files))
}

/// A data batch of `p` with its columns renamed and padded to the merged `features`;
/// the schema's Hugging Face metadata dropped where a column changed.
fn conform(
    p: &Part,
    batch: &RecordBatch,
    features: &Map<String, Value>,
) -> Result<RecordBatch, arrow_schema::ArrowError> {
    let mut changed = false;
    let mut fields = Vec::new();
    let mut columns = Vec::new();
    for (field, col) in batch.schema().fields().iter().zip(batch.columns()) {
        if !p.keeps(field.name()) {
            changed = true;
            continue;
        }
        let name = p.name(field.name()).to_owned();
        changed |= name != *field.name();
        let width = features.get(&name).and_then(|f| f["shape"][0].as_u64());
        let col = match (col.data_type(), width) {
            (DataType::FixedSizeList(inner, w), Some(want)) if (*w as u64) < want => {
                changed = true;
                pad_list(col, inner, *w as usize, want as usize)?
            }
            _ => col.clone(),
        };
        fields.push(Field::new(
            name,
            col.data_type().clone(),
            field.is_nullable(),
        ));
        columns.push(col);
    }
    let mut schema = Schema::new(fields);
    if !changed {
        schema = schema.with_metadata(batch.schema().metadata().clone());
    }
    RecordBatch::try_new(Arc::new(schema), columns)
}

/// A fixed-size list column of width `w` zero-padded to `want`.
fn pad_list(
    col: &ArrayRef,
    inner: &Arc<Field>,
    w: usize,
    want: usize,
) -> Result<ArrayRef, arrow_schema::ArrowError> {
    let list = col
        .as_any()
        .downcast_ref::<FixedSizeListArray>()
        .expect("fixed-size list");
    let values = list.values().slice(list.offset() * w, list.len() * w);
    let values = arrow_cast::cast(&values, &DataType::Float64)?;
    let values = values
        .as_any()
        .downcast_ref::<Float64Array>()
        .expect("float64");
    let mut padded = Vec::with_capacity(list.len() * want);
    for row in values.values().chunks(w) {
        padded.extend_from_slice(row);
        padded.resize(padded.len() + want - w, 0.0);
    }
    let padded: ArrayRef = Arc::new(Float64Array::from(padded));
    let padded = arrow_cast::cast(&padded, inner.data_type())?;
    Ok(Arc::new(FixedSizeListArray::try_new(
        inner.clone(),
        want as i32,
        padded,
        None,
    )?))
}

/// `batch` with its columns in `target`'s order and types.
fn project(
    batch: &RecordBatch,
    target: &SchemaRef,
) -> Result<RecordBatch, arrow_schema::ArrowError> {
    let columns = target
        .fields()
        .iter()
        .map(|f| {
            let col = batch.column_by_name(f.name()).ok_or_else(|| {
                arrow_schema::ArrowError::SchemaError(format!("no column {:?}", f.name()))
            })?;
            if col.data_type() == f.data_type() {
                Ok(col.clone())
            } else {
                arrow_cast::cast(col, f.data_type())
            }
        })
        .collect::<Result<Vec<_>, _>>()?;
    RecordBatch::try_new(target.clone(), columns)
}

/// Every source's video files of merged feature `key`, copied whole in order.
fn copy_videos(
    parts: &[Part],
    key: &str,
    dir: &Path,
) -> Result<(Vec<VideoPlace>, usize), EditError> {
    let first = &parts[0].ds;
    let (mut places, mut files) = (Vec::new(), 0usize);
    for p in parts {
        let source_key = p
            .names
            .iter()
            .find(|(_, n)| *n == key)
            .map_or(key, |(o, _)| o.as_str());
        // Copied whole, but the placements carried over must describe the files.
        crate::videos::Placement::checked(&p.ds, source_key)?;
        let col = |s: &str| format!("videos/{source_key}/{s}");
        let (chunk, file) = (
            p.ds.int_column(&col("chunk_index"))?,
            p.ds.int_column(&col("file_index"))?,
        );
        let (from, to) = (
            p.ds.float_column(&col("from_timestamp"))?,
            p.ds.float_column(&col("to_timestamp"))?,
        );
        let mut copied: HashMap<(i64, i64), (i64, i64)> = HashMap::new();
        for e in 0..p.ds.len() {
            let (out_chunk, out_file) = match copied.get(&(chunk[e], file[e])) {
                Some(at) => *at,
                None => {
                    let at = first.placement(files);
                    let out = dir.join(first.video_rel(key, at.0, at.1));
                    fs_err::create_dir_all(out.parent().unwrap_or(dir))?;
                    fs_err::copy(p.ds.video_file(source_key, chunk[e], file[e]), &out)?;
                    copied.insert((chunk[e], file[e]), at);
                    files += 1;
                    at
                }
            };
            places.push(VideoPlace {
                chunk: out_chunk,
                file: out_file,
                from: from[e],
                to: to[e],
            });
        }
    }
    Ok((places, files))
}

/// Every source's episode rows, renamed, under the union of their columns (a column a
/// source lacks is null for its episodes).
fn merged_episode_rows(parts: &[Part]) -> Result<RecordBatch, EditError> {
    let err = |e: arrow_schema::ArrowError| EditError::Selection(format!("episode rows: {e}"));
    let mut fields: Vec<Field> = Vec::new();
    let mut renamed = Vec::new();
    for p in parts {
        let schema = p.ds.episodes.schema();
        let named: Vec<(String, ArrayRef)> = schema
            .fields()
            .iter()
            .zip(p.ds.episodes.columns())
            .map(|(f, c)| (p.column_name(f.name()), c.clone()))
            .filter(|(name, _)| !p.drops_column(name))
            .collect();
        for (name, col) in &named {
            if !fields.iter().any(|f| f.name() == name) {
                fields.push(Field::new(name, col.data_type().clone(), true));
            }
        }
        renamed.push(named);
    }
    let schema = Arc::new(Schema::new(fields));
    let mut batches = Vec::new();
    for (p, named) in parts.iter().zip(&renamed) {
        let n = p.ds.len();
        let columns = schema
            .fields()
            .iter()
            .map(|f| match named.iter().find(|(name, _)| name == f.name()) {
                Some((_, c)) if c.data_type() == f.data_type() => Ok(c.clone()),
                Some((_, c)) => arrow_cast::cast(c, f.data_type()),
                None => Ok(new_null_array(f.data_type(), n)),
            })
            .collect::<Result<Vec<_>, _>>()
            .map_err(err)?;
        batches.push(RecordBatch::try_new(schema.clone(), columns).map_err(err)?);
    }
    arrow_select::concat::concat_batches(&schema, &batches).map_err(err)
}

/// `meta/tasks.parquet` of the merged task list, in the first source's table layout.
fn write_tasks(first: &LeRobotDataset, names: &[String], meta: &Path) -> Result<(), EditError> {
    let schema = first.tasks.schema();
    let n = names.len();
    let columns = schema
        .fields()
        .iter()
        .map(|f| -> Result<ArrayRef, arrow_schema::ArrowError> {
            let col: ArrayRef = match f.name().as_str() {
                "task_index" => Arc::new(arrow_array::Int64Array::from_iter_values(0..n as i64)),
                "task" | "__index_level_0__" => {
                    Arc::new(arrow_array::StringArray::from_iter_values(names))
                }
                _ => return Ok(new_null_array(f.data_type(), n)),
            };
            arrow_cast::cast(&col, f.data_type())
        })
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| EditError::Selection(format!("tasks: {e}")))?;
    let batch = RecordBatch::try_new(schema, columns)
        .map_err(|e| EditError::Selection(format!("tasks: {e}")))?;
    Ok(write_file(&meta.join("tasks.parquet"), &batch)?)
}
