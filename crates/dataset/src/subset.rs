//! A dataset made of some of another's episodes, in the source's order: frames streamed
//! file by file with `episode_index`, `index` and `task_index` renumbered and every
//! other column as stored; episode rows with every column kept (custom labels too) and
//! only their placement rewritten; the tasks used; videos copied or cut by stream copy;
//! statistics recomputed; info.json updated.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use arrow_array::{Array, ArrayRef, Float64Array, Int64Array, RecordBatch, UInt32Array};
use arrow_schema::{DataType, SchemaRef};
use dexjoco_core::Progress;
use dexjoco_formats::dataset::lerobot_read::LeRobotDataset;
use dexjoco_formats::dataset::parquet::{props, write_file};
use dexjoco_formats::fs::StagedDir;
use parquet::arrow::ArrowWriter;
use serde::Serialize;
use serde_json::{Value, json};

use crate::data_file::DataFile;
use crate::videos::{VideoPlace, write_videos};
use crate::{EditError, Selection, stats};

/// What a filter (or one split) wrote.
#[derive(Debug, Clone, Default, Serialize, PartialEq, Eq)]
pub struct SubsetReport {
    /// Episodes written.
    pub episodes: usize,
    /// Frames written.
    pub frames: u64,
    /// Tasks the written episodes use.
    pub tasks: usize,
    /// Data files written.
    pub data_files: usize,
    /// Video files copied whole.
    pub videos_copied: usize,
    /// Video files made by cutting episodes out by stream copy.
    pub videos_cut: usize,
    /// Video frames re-encoded by smart cuts (where a trimmed episode's first or last
    /// kept frame falls where no stream copy can start or end).
    pub frames_reencoded: usize,
    /// Video files re-encoded whole (where no encoder setting reproduced the source's
    /// stream headers, so a smart cut could not join it).
    pub videos_reencoded: usize,
}

/// Writes the episodes of `source` that `selection` keeps as a new dataset at `out`
/// (staged and renamed; an existing `out` is replaced only with `overwrite`).
pub fn filter(
    source: &Path,
    selection: &Selection,
    out: &Path,
    overwrite: bool,
    progress: &dyn Progress,
) -> Result<SubsetReport, EditError> {
    let ds = LeRobotDataset::open(source)?;
    let rows = selection.apply(&ds)?;
    if rows.is_empty() {
        return Err(EditError::Selection(format!(
            "the selection keeps no episode of '{}' ({} episodes): nothing to write",
            source.display(),
            ds.len()
        )));
    }
    check_output(source, out, overwrite)?;
    let staged = StagedDir::begin(out)?;
    let report = write_subset(&ds, &rows, None, staged.path(), None, progress)?;
    staged.commit()?;
    Ok(report)
}

/// Refuses an output that is the source, lies inside it or holds it, or exists
/// without `overwrite`.
pub(crate) fn check_output(source: &Path, out: &Path, overwrite: bool) -> Result<(), EditError> {
    let refuse = |message: String| EditError::Refused {
        path: out.to_path_buf(),
        message,
    };
    if dexjoco_formats::fs::overlaps(source, out) {
        return Err(refuse(format!(
            "it overlaps the source '{}'; the source is never changed: write beside it",
            source.display()
        )));
    }
    if out.exists() && !overwrite {
        return Err(refuse(
            "it exists; pass --overwrite to replace it, or choose another output".into(),
        ));
    }
    Ok(())
}

/// Writes the source `rows` (ascending source indices) of `ds` as a dataset into the
/// empty folder `dir`: each whole, or with `frames`, only frames `from..to` (frame
/// indices, end excluded) of each; `splits` replaces info.json's (default `train: 0:N`).
pub fn write_subset(
    ds: &LeRobotDataset,
    rows: &[usize],
    frames: Option<&[(i64, i64)]>,
    dir: &Path,
    splits: Option<BTreeMap<String, String>>,
    progress: &dyn Progress,
) -> Result<SubsetReport, EditError> {
    let (task_names, task_map) = used_tasks(ds, rows)?;
    let lengths = ds.lengths()?;
    let whole: Vec<(i64, i64)> = rows.iter().map(|r| (0, lengths[*r])).collect();
    let trimmed = frames.is_some_and(|f| f != whole);
    let frames = frames.unwrap_or(&whole);
    let data = write_data(ds, rows, frames, dir, &task_map, progress)?;
    let mut report = SubsetReport {
        episodes: rows.len(),
        frames: data.places.last().map_or(0, |p| p.to as u64),
        tasks: task_names.len(),
        data_files: data.files.len(),
        ..SubsetReport::default()
    };
    let mut video_places = BTreeMap::new();
    for key in ds.video_keys() {
        let (places, counts) = write_videos(ds, &key, rows, frames, dir, progress)?;
        report.videos_copied += counts.copied;
        report.videos_cut += counts.cut;
        report.frames_reencoded += counts.frames_reencoded;
        report.videos_reencoded += counts.reencoded;
        video_places.insert(key, places);
    }
    let episodes = episode_rows(ds, rows, &data.places, &video_places)?;
    let episodes = if trimmed {
        // Every numeric feature's per-episode statistics describe fewer frames now.
        let features = ds.features();
        let numeric: Vec<&str> = features
            .iter()
            .filter(|(_, f)| !matches!(f["dtype"].as_str(), Some("video" | "image" | "string")))
            .map(|(k, _)| k.as_str())
            .collect();
        let trimmed: Vec<bool> = frames.iter().zip(&whole).map(|(a, b)| a != b).collect();
        let episodes = stats::restat_renumbered(&episodes, &data.files)?;
        stats::restat_episode_columns(&episodes, &data.files, &numeric, Some(&trimmed))?
    } else {
        stats::restat_renumbered(&episodes, &data.files)?
    };
    let meta = dir.join("meta");
    fs_err::create_dir_all(meta.join("episodes/chunk-000"))?;
    write_file(&meta.join("episodes/chunk-000/file-000.parquet"), &episodes)?;
    write_tasks(ds, &task_names, &meta)?;
    stats::write_stats(ds, &data.files, &episodes, dir)?;
    let had = ds.root.join(dexjoco_formats::openpi::NORM_STATS).exists();
    crate::restat::carry_norm_stats(had, &ds.meta, &data.files, dir)?;
    let mut info = ds.info.clone();
    info.insert("total_episodes".into(), json!(rows.len()));
    info.insert("total_frames".into(), json!(report.frames));
    info.insert("total_tasks".into(), json!(task_names.len()));
    let splits =
        splits.unwrap_or_else(|| BTreeMap::from([("train".into(), format!("0:{}", rows.len()))]));
    info.insert("splits".into(), json!(splits));
    let text = serde_json::to_string_pretty(&Value::Object(info)).expect("json");
    fs_err::write(meta.join("info.json"), text + "\n")?;
    Ok(report)
}

/// The tasks the kept episodes use, in the source's task order, and the map from
/// source to new task index.
fn used_tasks(
    ds: &LeRobotDataset,
    rows: &[usize],
) -> Result<(Vec<String>, HashMap<i64, i64>), EditError> {
    let names = ds.task_names()?;
    let episode_tasks = ds.episode_tasks()?;
    let used: HashSet<&String> = rows.iter().flat_map(|r| &episode_tasks[*r]).collect();
    let mut kept = Vec::new();
    let mut map = HashMap::new();
    for (old, name) in names.iter().enumerate() {
        if used.contains(name) {
            map.insert(old as i64, kept.len() as i64);
            kept.push(name.clone());
        }
    }
    Ok((kept, map))
}

/// Where a kept episode's frames are in the output.
#[derive(Debug, Clone, Copy)]
pub(crate) struct DataPlace {
    pub chunk: i64,
    pub file: i64,
    pub from: i64,
    pub to: i64,
}

struct WrittenData {
    places: Vec<DataPlace>,
    files: Vec<PathBuf>,
}

/// Streams the kept episodes' frames into the output's data files: one output file per
/// run of kept episodes that share a source file.
fn write_data(
    ds: &LeRobotDataset,
    rows: &[usize],
    frames: &[(i64, i64)],
    dir: &Path,
    task_map: &HashMap<i64, i64>,
    progress: &dyn Progress,
) -> Result<WrittenData, EditError> {
    let chunk = ds.int_column("data/chunk_index")?;
    let file = ds.int_column("data/file_index")?;
    let ranges: HashMap<i64, (i64, i64)> = rows
        .iter()
        .zip(frames)
        .map(|(r, f)| (*r as i64, *f))
        .collect();
    let copy = CopyRows {
        new_index: rows
            .iter()
            .enumerate()
            .map(|(new, old)| (*old as i64, new as i64))
            .collect(),
        ranges,
        task_map,
        fps: ds.fps,
    };
    let mut written = WrittenData {
        places: Vec::with_capacity(rows.len()),
        files: Vec::new(),
    };
    let mut next_index = 0i64;
    let same_file = |a: &usize, b: &usize| (chunk[*a], file[*a]) == (chunk[*b], file[*b]);
    progress.phase("data", rows.chunk_by(same_file).count() as u64);
    for (k, group) in rows.chunk_by(same_file).enumerate() {
        let (out_chunk, out_file) = ds.placement(k);
        let out = dir.join(ds.data_rel(out_chunk, out_file));
        fs_err::create_dir_all(out.parent().unwrap_or(dir))?;
        let src = ds.data_file(chunk[group[0]], file[group[0]]);
        let wanted: HashSet<i64> = group.iter().map(|r| *r as i64).collect();
        let counts = copy.rows(&src, &out, &wanted, &mut next_index)?;
        for r in group {
            let n = counts.get(&(*r as i64)).copied().unwrap_or(0);
            let (from, to) = copy.ranges[&(*r as i64)];
            if n != to - from {
                return Err(EditError::Selection(format!(
                    "data file '{}': episode {r} has {n} frames {from}..{to} there, not {}",
                    src.display(),
                    to - from
                )));
            }
            let from = written.places.last().map_or(0, |p| p.to);
            written.places.push(DataPlace {
                chunk: out_chunk,
                file: out_file,
                from,
                to: from + n,
            });
        }
        progress.advance(1, &src.display().to_string());
        written.files.push(out);
    }
    Ok(written)
}

/// How source rows become output rows: episode renumbering, the frames kept of each
/// episode, task renumbering, and the frame rate (for trimmed episodes' timestamps).
struct CopyRows<'a> {
    new_index: HashMap<i64, i64>,
    ranges: HashMap<i64, (i64, i64)>,
    task_map: &'a HashMap<i64, i64>,
    fps: f64,
}

impl CopyRows<'_> {
    /// Copies the kept frames of episodes `wanted` from `src` to `out`, renumbered;
    /// returns the frames copied per source episode.
    fn rows(
        &self,
        src: &Path,
        out: &Path,
        wanted: &HashSet<i64>,
        next_index: &mut i64,
    ) -> Result<HashMap<i64, i64>, EditError> {
        let f = DataFile(src);
        let err = |e: &dyn std::fmt::Display| f.error(e);
        let reader = f.batches()?;
        let schema = arrow_array::RecordBatchReader::schema(&reader);
        let mut writer = ArrowWriter::try_new(
            fs_err::File::create(out)?.into_parts().0,
            schema.clone(),
            Some(props()),
        )
        .map_err(|e| err(&e))?;
        let mut counts = HashMap::new();
        for batch in reader {
            let batch = batch.map_err(|e| err(&e))?;
            let Some(kept) = self.batch(&batch, &schema, wanted, next_index, &mut counts)? else {
                continue;
            };
            writer.write(&kept).map_err(|e| err(&e))?;
        }
        writer.close().map_err(|e| err(&e))?;
        Ok(counts)
    }

    /// The kept rows of `batch`, renumbered (`None`: none kept).
    fn batch(
        &self,
        batch: &RecordBatch,
        schema: &SchemaRef,
        wanted: &HashSet<i64>,
        next_index: &mut i64,
        counts: &mut HashMap<i64, i64>,
    ) -> Result<Option<RecordBatch>, EditError> {
        let err = |e: &dyn std::fmt::Display| EditError::Selection(e.to_string());
        let episode =
            ints(batch, "episode_index").ok_or_else(|| err(&"no episode_index column"))?;
        let frame = ints(batch, "frame_index").ok_or_else(|| err(&"no frame_index column"))?;
        let keep: Vec<u32> = (0..batch.num_rows())
            .filter(|i| {
                wanted.contains(&episode[*i])
                    && self
                        .ranges
                        .get(&episode[*i])
                        .is_some_and(|(from, to)| (*from..*to).contains(&frame[*i]))
            })
            .map(|i| i as u32)
            .collect();
        if keep.is_empty() {
            return Ok(None);
        }
        let kept = arrow_select::take::take_record_batch(batch, &UInt32Array::from(keep.clone()))
            .map_err(|e| err(&e))?;
        let old: Vec<i64> = keep.iter().map(|i| episode[*i as usize]).collect();
        for e in &old {
            *counts.entry(*e).or_insert(0) += 1;
        }
        let n = old.len() as i64;
        let mut replace: Vec<(&str, Vec<i64>)> = vec![
            (
                "episode_index",
                old.iter().map(|e| self.new_index[e]).collect(),
            ),
            ("index", (*next_index..*next_index + n).collect()),
        ];
        if let Some(tasks) = ints(&kept, "task_index") {
            let map = |t: &i64| self.task_map.get(t).copied().unwrap_or(*t);
            replace.push(("task_index", tasks.iter().map(map).collect()));
        }
        *next_index += n;
        // Trimmed episodes start at frame 0 and time 0 again.
        let shift: Vec<i64> = old.iter().map(|e| self.ranges[e].0).collect();
        let mut kept = kept;
        if shift.iter().any(|s| *s > 0) {
            let frames: Vec<i64> = keep
                .iter()
                .zip(&shift)
                .map(|(i, s)| frame[*i as usize] - s)
                .collect();
            let times: Vec<f64> = frames.iter().map(|f| *f as f64 / self.fps).collect();
            kept = with_float_column(&kept, schema, "timestamp", times).map_err(|e| err(&e))?;
            replace.push(("frame_index", frames));
        }
        with_columns(&kept, schema, &replace)
            .map(Some)
            .map_err(|e| err(&e))
    }
}

/// The episode rows of the kept episodes, every column kept, their placement rewritten.
fn episode_rows(
    ds: &LeRobotDataset,
    rows: &[usize],
    data: &[DataPlace],
    videos: &BTreeMap<String, Vec<VideoPlace>>,
) -> Result<RecordBatch, EditError> {
    let take = UInt32Array::from(rows.iter().map(|r| *r as u32).collect::<Vec<_>>());
    let kept = arrow_select::take::take_record_batch(&ds.episodes, &take)
        .map_err(|e| EditError::Selection(format!("episode rows: {e}")))?;
    placed(&kept, data, videos)
}

/// Episode rows `kept` (in output order) with their placement columns rewritten to
/// `data` and `videos`, every other column as it is.
pub(crate) fn placed(
    kept: &RecordBatch,
    data: &[DataPlace],
    videos: &BTreeMap<String, Vec<VideoPlace>>,
) -> Result<RecordBatch, EditError> {
    let n = kept.num_rows() as i64;
    let mut ints: Vec<(String, Vec<i64>)> = vec![
        ("episode_index".into(), (0..n).collect()),
        (
            "length".into(),
            data.iter().map(|p| p.to - p.from).collect(),
        ),
        (
            "data/chunk_index".into(),
            data.iter().map(|p| p.chunk).collect(),
        ),
        (
            "data/file_index".into(),
            data.iter().map(|p| p.file).collect(),
        ),
        (
            "dataset_from_index".into(),
            data.iter().map(|p| p.from).collect(),
        ),
        (
            "dataset_to_index".into(),
            data.iter().map(|p| p.to).collect(),
        ),
        ("meta/episodes/chunk_index".into(), vec![0; n as usize]),
        ("meta/episodes/file_index".into(), vec![0; n as usize]),
    ];
    let mut floats: Vec<(String, Vec<f64>)> = Vec::new();
    for (key, places) in videos {
        ints.push((
            format!("videos/{key}/chunk_index"),
            places.iter().map(|p| p.chunk).collect(),
        ));
        ints.push((
            format!("videos/{key}/file_index"),
            places.iter().map(|p| p.file).collect(),
        ));
        floats.push((
            format!("videos/{key}/from_timestamp"),
            places.iter().map(|p| p.from).collect(),
        ));
        floats.push((
            format!("videos/{key}/to_timestamp"),
            places.iter().map(|p| p.to).collect(),
        ));
    }
    let schema = kept.schema();
    let mut columns: Vec<ArrayRef> = kept.columns().to_vec();
    for (i, field) in schema.fields().iter().enumerate() {
        let new: Option<ArrayRef> =
            if let Some((_, v)) = ints.iter().find(|(k, _)| k == field.name()) {
                Some(Arc::new(Int64Array::from(v.clone())))
            } else {
                floats
                    .iter()
                    .find(|(k, _)| k == field.name())
                    .map(|(_, v)| Arc::new(Float64Array::from(v.clone())) as ArrayRef)
            };
        if let Some(new) = new {
            columns[i] = arrow_cast::cast(&new, field.data_type()).map_err(|e| {
                EditError::Selection(format!("episode column {}: {e}", field.name()))
            })?;
        }
    }
    RecordBatch::try_new(schema, columns)
        .map_err(|e| EditError::Selection(format!("episode rows: {e}")))
}

/// `meta/tasks.parquet` with only `names`, renumbered, in the source's schema.
fn write_tasks(ds: &LeRobotDataset, names: &[String], meta: &Path) -> Result<(), EditError> {
    let all = ds.task_names()?;
    let index = ints(&ds.tasks, "task_index").unwrap_or_default();
    // Rows of the source table holding the kept names, in the kept order.
    let rows: Vec<u32> = names
        .iter()
        .filter_map(|n| {
            let old = all.iter().position(|a| a == n)? as i64;
            index.iter().position(|i| *i == old).map(|r| r as u32)
        })
        .collect();
    let kept = arrow_select::take::take_record_batch(&ds.tasks, &UInt32Array::from(rows))
        .map_err(|e| EditError::Selection(format!("tasks: {e}")))?;
    let replace = [("task_index", (0..names.len() as i64).collect::<Vec<_>>())];
    let kept = with_columns(&kept, &ds.tasks.schema(), &replace)
        .map_err(|e| EditError::Selection(format!("tasks: {e}")))?;
    Ok(write_file(&meta.join("tasks.parquet"), &kept)?)
}

/// `batch` with the integer columns named in `replace` swapped for new values (in each
/// column's own type).
pub(crate) fn with_columns(
    batch: &RecordBatch,
    schema: &SchemaRef,
    replace: &[(&str, Vec<i64>)],
) -> Result<RecordBatch, arrow_schema::ArrowError> {
    let mut columns = batch.columns().to_vec();
    for (name, values) in replace {
        if let Ok(i) = schema.index_of(name) {
            let new: ArrayRef = Arc::new(Int64Array::from(values.clone()));
            columns[i] = arrow_cast::cast(&new, schema.field(i).data_type())?;
        }
    }
    RecordBatch::try_new(schema.clone(), columns)
}

/// `batch` with the float column `name` (where it exists) holding `values` instead, in
/// the column's own type.
fn with_float_column(
    batch: &RecordBatch,
    schema: &SchemaRef,
    name: &str,
    values: Vec<f64>,
) -> Result<RecordBatch, arrow_schema::ArrowError> {
    let Ok(i) = schema.index_of(name) else {
        return Ok(batch.clone());
    };
    let mut columns = batch.columns().to_vec();
    let new: ArrayRef = Arc::new(Float64Array::from(values));
    columns[i] = arrow_cast::cast(&new, schema.field(i).data_type())?;
    RecordBatch::try_new(schema.clone(), columns)
}

/// An integer column of `batch` as i64.
pub(crate) fn ints(batch: &RecordBatch, name: &str) -> Option<Vec<i64>> {
    let col = batch.column_by_name(name)?;
    let col = arrow_cast::cast(col, &DataType::Int64).ok()?;
    let col = col.as_any().downcast_ref::<Int64Array>()?;
    Some((0..col.len()).map(|i| col.value(i)).collect())
}
