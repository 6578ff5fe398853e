//! Reading any LeRobot v3.0 dataset (ours, lerobot's own writer's, one from the Hub)
//! through the format's own files: `meta/info.json` kept whole, every
//! `meta/episodes/*.parquet` row with all its columns (custom ones included),
//! `meta/tasks.parquet`, and the path templates that place data and video files.

use std::fs::File;
use std::path::{Path, PathBuf};

use arrow_array::{Array, ArrayRef, Float64Array, Int64Array, RecordBatch, StringArray};
use arrow_schema::DataType;
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use serde_json::{Map, Value};

use super::lerobot_meta::{InfoMeta, MAX_INDEX};
use super::parquet::parquet_err;
use crate::error::DatasetError;

/// The LeRobot format version this reader takes.
pub const V3_VERSION: &str = "v3.0";

/// A LeRobot v3.0 dataset opened for reading: its metadata in memory, its frames and
/// videos left on disk.
#[derive(Debug, Clone)]
pub struct LeRobotDataset {
    /// The dataset folder (holding `meta/`, `data/`, `videos/`).
    pub root: PathBuf,
    /// `meta/info.json`, every key kept, completed with the format's defaults (what an
    /// edited copy writes).
    pub info: Map<String, Value>,
    /// `meta/info.json`, checked and typed: what the commands read of it.
    pub meta: InfoMeta,
    /// Frames per second.
    pub fps: f64,
    /// Every episode's row of `meta/episodes/`, sorted by `episode_index`, all columns.
    pub episodes: RecordBatch,
    /// `meta/tasks.parquet` as stored.
    pub tasks: RecordBatch,
}

impl LeRobotDataset {
    /// Opens the dataset at `root`, checking its version and that its episode rows are
    /// numbered 0..N without gaps and cover `total_episodes`.
    pub fn open(root: &Path) -> Result<Self, DatasetError> {
        let info_path = root.join("meta/info.json");
        let text = read_bounded(&info_path, MAX_INFO_BYTES).map_err(|e| {
            DatasetError::Layout(format!(
                "'{}' is no LeRobot dataset: {e} (a dataset folder holds meta/info.json)",
                root.display()
            ))
        })?;
        let mut info: Map<String, Value> =
            serde_json::from_slice(&text).map_err(|source| DatasetError::Json {
                path: info_path.clone(),
                source,
            })?;
        let meta = InfoMeta::parse(&mut info, &info_path)?;
        if meta.codebase_version != V3_VERSION {
            return Err(bad(
                &info_path,
                &format!(
                    "codebase_version is {}; these commands read {V3_VERSION} \
                     (convert a v2.1 dataset with lerobot's convert_dataset_v21_to_v30)",
                    meta.codebase_version
                ),
            ));
        }
        let episodes = read_episodes(root)?;
        let tasks = read_all(&root.join("meta/tasks.parquet"))?;
        let ds = Self {
            root: root.to_path_buf(),
            info,
            fps: meta.fps,
            meta,
            episodes,
            tasks,
        };
        ds.check_numbering()?;
        ds.check_rows()?;
        Ok(ds)
    }

    /// Number of episodes.
    pub fn len(&self) -> usize {
        self.episodes.num_rows()
    }

    /// Whether it has no episodes.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// `info.json`'s `features`.
    pub fn features(&self) -> Map<String, Value> {
        self.info
            .get("features")
            .and_then(Value::as_object)
            .cloned()
            .unwrap_or_default()
    }

    /// The features stored as videos, in `info.json`'s order.
    pub fn video_keys(&self) -> Vec<String> {
        self.meta.video_keys()
    }

    /// The episodes-metadata column `name`.
    pub fn column(&self, name: &str) -> Option<&ArrayRef> {
        self.episodes.column_by_name(name)
    }

    /// The integer column `name` of the episode rows (any integer type).
    pub fn int_column(&self, name: &str) -> Result<Vec<i64>, DatasetError> {
        let col = self.required(name)?;
        let cast = arrow_cast::cast(col, &DataType::Int64).map_err(|e| self.column_err(name, e))?;
        let ints = cast
            .as_any()
            .downcast_ref::<Int64Array>()
            .expect("cast to int64");
        self.no_nulls(name, &cast)?;
        Ok((0..ints.len()).map(|i| ints.value(i)).collect())
    }

    /// The float column `name` of the episode rows (any numeric type).
    pub fn float_column(&self, name: &str) -> Result<Vec<f64>, DatasetError> {
        let col = self.required(name)?;
        let cast =
            arrow_cast::cast(col, &DataType::Float64).map_err(|e| self.column_err(name, e))?;
        let floats = cast
            .as_any()
            .downcast_ref::<Float64Array>()
            .expect("cast to float64");
        self.no_nulls(name, &cast)?;
        Ok((0..floats.len()).map(|i| floats.value(i)).collect())
    }

    /// Every episode's frame count (`length`).
    pub fn lengths(&self) -> Result<Vec<i64>, DatasetError> {
        self.int_column("length")
    }

    /// Every episode's task strings (`tasks`, a list of strings per episode).
    pub fn episode_tasks(&self) -> Result<Vec<Vec<String>>, DatasetError> {
        let col = self.required("tasks")?;
        let lists = arrow_cast::cast(
            col,
            &DataType::List(std::sync::Arc::new(arrow_schema::Field::new(
                "item",
                DataType::Utf8,
                true,
            ))),
        )
        .map_err(|e| self.column_err("tasks", e))?;
        let lists = lists
            .as_any()
            .downcast_ref::<arrow_array::ListArray>()
            .expect("cast to list");
        Ok((0..lists.len())
            .map(|i| strings(&lists.value(i)))
            .collect::<Vec<_>>())
    }

    /// The task strings of `meta/tasks.parquet` by task index.
    pub fn task_names(&self) -> Result<Vec<String>, DatasetError> {
        let path = self.root.join("meta/tasks.parquet");
        let index = self
            .tasks
            .column_by_name("task_index")
            .ok_or_else(|| bad(&path, "no task_index column"))?;
        let index = arrow_cast::cast(index, &DataType::Int64)
            .map_err(|e| bad(&path, &format!("task_index: {e}")))?;
        if index.null_count() > 0 {
            return Err(bad(&path, "task_index has a null"));
        }
        let index = index.as_any().downcast_ref::<Int64Array>().expect("int64");
        // pandas writes the index (the task string) as `task` or `__index_level_0__`.
        let names = ["task", "__index_level_0__"]
            .iter()
            .find_map(|n| self.tasks.column_by_name(n))
            .ok_or_else(|| bad(&path, "no task column"))?;
        let names = strings(names);
        let mut by_index = vec![String::new(); names.len()];
        for (i, name) in names.into_iter().enumerate() {
            let at = usize::try_from(index.value(i))
                .ok()
                .filter(|at| *at < by_index.len())
                .ok_or_else(|| {
                    bad(
                        &path,
                        &format!("task_index {} out of range", index.value(i)),
                    )
                })?;
            if !by_index[at].is_empty() {
                return Err(bad(&path, &format!("task_index {at} is given twice")));
            }
            by_index[at] = name;
        }
        Ok(by_index)
    }

    /// Chunk and file indices of the `k`-th file an edited copy of this dataset writes
    /// (`chunks_size` files per chunk folder).
    pub fn placement(&self, k: usize) -> (i64, i64) {
        let per = self.meta.chunks_size as i64;
        (k as i64 / per, k as i64 % per)
    }

    /// The data file of chunk/file indices, relative to a dataset's folder.
    pub fn data_rel(&self, chunk: i64, file: i64) -> String {
        self.meta.data_path.fill("", index(chunk), index(file))
    }

    /// The video file of `key` at chunk/file indices, relative to a dataset's folder.
    pub fn video_rel(&self, key: &str, chunk: i64, file: i64) -> String {
        let template = self
            .meta
            .video_path
            .as_ref()
            .expect("a dataset with video features has a video_path");
        template.fill(key, index(chunk), index(file))
    }

    /// The data file of chunk/file indices (checked non-negative by [`Self::open`]).
    pub fn data_file(&self, chunk: i64, file: i64) -> PathBuf {
        self.root.join(self.data_rel(chunk, file))
    }

    /// The data files of the episodes, in the order of the episodes (each once).
    pub fn data_files(&self) -> Result<Vec<PathBuf>, DatasetError> {
        let chunk = self.int_column("data/chunk_index")?;
        let file = self.int_column("data/file_index")?;
        let mut seen = std::collections::HashSet::new();
        let mut out: Vec<PathBuf> = Vec::new();
        for (c, f) in chunk.into_iter().zip(file) {
            if seen.insert((c, f)) {
                out.push(self.data_file(c, f));
            }
        }
        Ok(out)
    }

    /// The video file of `key` (a video feature) at chunk/file indices.
    pub fn video_file(&self, key: &str, chunk: i64, file: i64) -> PathBuf {
        self.root.join(self.video_rel(key, chunk, file))
    }

    fn required(&self, name: &str) -> Result<&ArrayRef, DatasetError> {
        self.column(name).ok_or_else(|| {
            bad(
                &self.root.join("meta/episodes"),
                &format!("no column {name:?} in the episode rows"),
            )
        })
    }

    fn column_err(&self, name: &str, e: arrow_schema::ArrowError) -> DatasetError {
        bad(
            &self.root.join("meta/episodes"),
            &format!("column {name:?}: {e}"),
        )
    }

    /// Refuses a null in column `name` (cast `values`), naming the first row.
    fn no_nulls(&self, name: &str, values: &ArrayRef) -> Result<(), DatasetError> {
        match (0..values.len()).find(|i| values.is_null(*i)) {
            Some(row) => Err(self.row_err(name, row, "is null".into())),
            None => Ok(()),
        }
    }

    fn row_err(&self, name: &str, row: usize, message: String) -> DatasetError {
        DatasetError::Metadata {
            path: self.root.join("meta/episodes"),
            field: name.to_owned(),
            message: format!("episode {row} {message}"),
        }
    }

    /// Checks the episode rows' placement columns: lengths, chunk and file indices in
    /// range, the data span of each episode its length, video spans finite and ordered,
    /// task lists of text. Nothing read from them later can overflow or index out of range.
    fn check_rows(&self) -> Result<(), DatasetError> {
        let in_range = |name: &str| -> Result<Vec<i64>, DatasetError> {
            let v = self.int_column(name)?;
            match v.iter().position(|x| !(0..=MAX_INDEX).contains(x)) {
                Some(row) => Err(self.row_err(
                    name,
                    row,
                    format!("has {}, outside 0..={MAX_INDEX}", v[row]),
                )),
                None => Ok(v),
            }
        };
        let lengths = in_range("length")?;
        in_range("data/chunk_index")?;
        in_range("data/file_index")?;
        if self.column("dataset_from_index").is_some() && self.column("dataset_to_index").is_some()
        {
            let from = in_range("dataset_from_index")?;
            let to = in_range("dataset_to_index")?;
            if let Some(row) = (0..lengths.len()).find(|r| to[*r] - from[*r] != lengths[*r]) {
                return Err(self.row_err(
                    "dataset_to_index",
                    row,
                    format!(
                        "spans frames {}..{} of its data file, but its length is {}",
                        from[row], to[row], lengths[row]
                    ),
                ));
            }
        }
        for key in self.video_keys() {
            let col = |s: &str| format!("videos/{key}/{s}");
            if self.column(&col("chunk_index")).is_none() {
                continue;
            }
            in_range(&col("chunk_index"))?;
            in_range(&col("file_index"))?;
            let from = self.float_column(&col("from_timestamp"))?;
            let to = self.float_column(&col("to_timestamp"))?;
            let bad = |r: usize| {
                !(from[r].is_finite() && to[r].is_finite() && 0.0 <= from[r] && from[r] <= to[r])
                    || to[r] > MAX_INDEX as f64
            };
            if let Some(row) = (0..from.len()).find(|r| bad(*r)) {
                return Err(self.row_err(
                    &col("to_timestamp"),
                    row,
                    format!(
                        "spans {}..{} s of its video: not a finite, ordered span",
                        from[row], to[row]
                    ),
                ));
            }
        }
        self.episode_tasks()?;
        Ok(())
    }

    fn check_numbering(&self) -> Result<(), DatasetError> {
        let index = self.int_column("episode_index")?;
        if let Some((row, got)) = index
            .iter()
            .enumerate()
            .find(|(row, got)| **got != *row as i64)
        {
            return Err(bad(
                &self.root.join("meta/episodes"),
                &format!("episode rows are not numbered 0..N: row {row} is episode {got}"),
            ));
        }
        let total = self.info.get("total_episodes").and_then(Value::as_u64);
        if total.is_some_and(|t| t != index.len() as u64) {
            return Err(bad(
                &self.root.join("meta/info.json"),
                &format!(
                    "total_episodes is {} but meta/episodes holds {} rows",
                    total.unwrap_or(0),
                    index.len()
                ),
            ));
        }
        Ok(())
    }
}

/// The strings of a string column (`Utf8` or `LargeUtf8`; nulls as "").
pub fn strings(col: &ArrayRef) -> Vec<String> {
    let cast = arrow_cast::cast(col, &DataType::Utf8).unwrap_or_else(|_| col.clone());
    match cast.as_any().downcast_ref::<StringArray>() {
        Some(s) => (0..s.len())
            .map(|i| {
                if s.is_null(i) {
                    String::new()
                } else {
                    s.value(i).to_owned()
                }
            })
            .collect(),
        None => vec![String::new(); col.len()],
    }
}

/// Every row of the parquet file at `path`, as one batch.
pub fn read_all(path: &Path) -> Result<RecordBatch, DatasetError> {
    let err = parquet_err(path);
    let file = File::open(path)
        .map_err(|e| DatasetError::Layout(format!("file '{}': {e}", path.display())))?;
    let builder = ParquetRecordBatchReaderBuilder::try_new(file).map_err(&err)?;
    let schema = builder.schema().clone();
    let batches = builder
        .build()
        .map_err(&err)?
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| bad(path, &e.to_string()))?;
    arrow_select::concat::concat_batches(&schema, &batches).map_err(|e| bad(path, &e.to_string()))
}

/// Every `meta/episodes/**/*.parquet` row, sorted by `episode_index`.
fn read_episodes(root: &Path) -> Result<RecordBatch, DatasetError> {
    let dir = root.join("meta/episodes");
    let mut files = Vec::new();
    collect_parquet(&dir, &mut files, 0)?;
    files.sort();
    if files.is_empty() {
        return Err(bad(&dir, "no episode metadata files"));
    }
    let mut batches = Vec::new();
    for f in &files {
        batches.push(read_all(f)?);
    }
    let schema = batches[0].schema();
    if let Some((f, _)) = files
        .iter()
        .zip(&batches)
        .find(|(_, b)| b.schema().fields() != schema.fields())
    {
        return Err(bad(
            f,
            &format!(
                "its columns differ from '{}''s; the episode files of one dataset share one schema",
                files[0].display()
            ),
        ));
    }
    let all = arrow_select::concat::concat_batches(&schema, &batches)
        .map_err(|e| bad(&dir, &e.to_string()))?;
    sort_by_episode(all, &dir)
}

fn sort_by_episode(all: RecordBatch, dir: &Path) -> Result<RecordBatch, DatasetError> {
    let col = all
        .column_by_name("episode_index")
        .ok_or_else(|| bad(dir, "no episode_index column"))?;
    let col = arrow_cast::cast(col, &DataType::Int64).map_err(|e| bad(dir, &e.to_string()))?;
    let index = col.as_any().downcast_ref::<Int64Array>().expect("int64");
    let mut order: Vec<u32> = (0..all.num_rows() as u32).collect();
    order.sort_by_key(|i| index.value(*i as usize));
    let order = arrow_array::UInt32Array::from(order);
    arrow_select::take::take_record_batch(&all, &order).map_err(|e| bad(dir, &e.to_string()))
}

/// How deep episode metadata files are looked for (`chunk-000/file-000.parquet` is 1):
/// a folder linked into itself is not followed forever.
const MAX_EPISODES_DEPTH: usize = 4;

fn collect_parquet(dir: &Path, out: &mut Vec<PathBuf>, depth: usize) -> Result<(), DatasetError> {
    let Ok(entries) = fs_err::read_dir(dir) else {
        return Ok(());
    };
    for entry in entries {
        let path = entry?.path();
        if path.is_dir() {
            if depth < MAX_EPISODES_DEPTH {
                collect_parquet(&path, out, depth + 1)?;
            }
        } else if path.extension().is_some_and(|e| e == "parquet") {
            out.push(path);
        }
    }
    Ok(())
}

/// A checked index as a number for a path (non-negative once [`LeRobotDataset::open`]
/// has checked the rows).
fn index(i: i64) -> u64 {
    u64::try_from(i).unwrap_or(0)
}

/// The largest `meta/info.json` read (its features and templates are small; a file
/// larger than this is no dataset's).
const MAX_INFO_BYTES: u64 = 64 << 20;

/// The bytes of `path`, refused past `limit`.
fn read_bounded(path: &Path, limit: u64) -> std::io::Result<Vec<u8>> {
    use std::io::Read;
    let mut bytes = Vec::new();
    fs_err::File::open(path)?
        .take(limit + 1)
        .read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(std::io::Error::other(format!(
            "'{}' is larger than {} MB",
            path.display(),
            limit >> 20
        )));
    }
    Ok(bytes)
}

/// A [`DatasetError::Layout`] naming the file.
fn bad(path: &Path, message: &str) -> DatasetError {
    DatasetError::Layout(format!("file '{}': {message}", path.display()))
}
