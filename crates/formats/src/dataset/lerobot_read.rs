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
    /// `meta/info.json`, every key kept.
    pub info: Map<String, Value>,
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
        let text = fs_err::read_to_string(&info_path).map_err(|e| {
            DatasetError::Layout(format!(
                "'{}' is no LeRobot dataset: {e} (a dataset folder holds meta/info.json)",
                root.display()
            ))
        })?;
        let info: Map<String, Value> =
            serde_json::from_str(&text).map_err(|source| DatasetError::Json {
                path: info_path.clone(),
                source,
            })?;
        let version = info["codebase_version"].as_str().unwrap_or("?");
        if version != V3_VERSION {
            return Err(bad(
                &info_path,
                &format!(
                    "codebase_version is {version}; these commands read {V3_VERSION} \
                     (convert a v2.1 dataset with lerobot's convert_dataset_v21_to_v30)"
                ),
            ));
        }
        let fps = info
            .get("fps")
            .and_then(Value::as_f64)
            .ok_or_else(|| bad(&info_path, "no fps"))?;
        check_paths(&info, &info_path)?;
        let episodes = read_episodes(root)?;
        let tasks = read_all(&root.join("meta/tasks.parquet"))?;
        let ds = Self {
            root: root.to_path_buf(),
            info,
            fps,
            episodes,
            tasks,
        };
        ds.check_numbering()?;
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
        self.features()
            .iter()
            .filter(|(_, f)| f["dtype"] == "video")
            .map(|(k, _)| k.clone())
            .collect()
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
            by_index[at] = name;
        }
        Ok(by_index)
    }

    /// A path of the dataset from one of info.json's templates (`data_path`,
    /// `video_path`), its `{name}` / `{name:03d}` fields filled in.
    pub fn path_of(&self, template: &str, fields: &[(&str, &str, i64)]) -> PathBuf {
        let t = self
            .info
            .get(template)
            .and_then(Value::as_str)
            .unwrap_or("");
        self.root.join(fill_template(t, fields))
    }

    /// The data file of chunk/file indices.
    pub fn data_file(&self, chunk: i64, file: i64) -> PathBuf {
        self.path_of(
            "data_path",
            &[("chunk_index", "", chunk), ("file_index", "", file)],
        )
    }

    /// The data files of the episodes, in the order of the episodes (each once).
    pub fn data_files(&self) -> Result<Vec<PathBuf>, DatasetError> {
        let chunk = self.int_column("data/chunk_index")?;
        let file = self.int_column("data/file_index")?;
        let mut out: Vec<PathBuf> = Vec::new();
        for (c, f) in chunk.into_iter().zip(file) {
            let p = self.data_file(c, f);
            if !out.contains(&p) {
                out.push(p);
            }
        }
        Ok(out)
    }

    /// The video file of `key` at chunk/file indices.
    pub fn video_file(&self, key: &str, chunk: i64, file: i64) -> PathBuf {
        let t = self
            .info
            .get("video_path")
            .and_then(Value::as_str)
            .unwrap_or("");
        self.root.join(fill_template(
            t,
            &[
                ("video_key", key, 0),
                ("chunk_index", "", chunk),
                ("file_index", "", file),
            ],
        ))
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

/// Refuses a dataset whose path templates or video keys would place files outside its
/// folder (an absolute path, a `..`, a key with a path separator): the files of a
/// downloaded dataset are untrusted, and edits write the same layout.
fn check_paths(info: &Map<String, Value>, info_path: &Path) -> Result<(), DatasetError> {
    let escapes = |p: &str| {
        let path = Path::new(p);
        path.is_absolute()
            || p.starts_with(['/', '\\'])
            || path
                .components()
                .any(|c| !matches!(c, std::path::Component::Normal(_)))
    };
    for key in ["data_path", "video_path"] {
        if let Some(t) = info.get(key).and_then(Value::as_str)
            && escapes(t)
        {
            return Err(bad(
                info_path,
                &format!("{key} {t:?} leaves the dataset folder (absolute, or with ..)"),
            ));
        }
    }
    let features = info.get("features").and_then(Value::as_object);
    for (k, f) in features.into_iter().flatten() {
        if f["dtype"] == "video"
            && (k.contains(['/', '\\']) || k == "." || k == ".." || k.is_empty())
        {
            return Err(bad(
                info_path,
                &format!(
                    "video feature {k:?} is no folder name (it names the feature's video folder)"
                ),
            ));
        }
    }
    Ok(())
}

/// Fills a Python format template's `{name}` and `{name:0Nd}` fields: a field with a
/// non-empty text takes the text, else the number (zero-padded to N where asked).
pub fn fill_template(template: &str, fields: &[(&str, &str, i64)]) -> String {
    let mut out = String::new();
    let mut rest = template;
    while let Some(open) = rest.find('{') {
        out.push_str(&rest[..open]);
        let Some(close) = rest[open..].find('}') else {
            break;
        };
        let spec = &rest[open + 1..open + close];
        let (name, format) = spec.split_once(':').unwrap_or((spec, ""));
        match fields.iter().find(|(n, _, _)| *n == name) {
            Some((_, text, _)) if !text.is_empty() => out.push_str(text),
            Some((_, _, number)) => {
                let width: usize = format
                    .trim_start_matches('0')
                    .trim_end_matches('d')
                    .parse()
                    .unwrap_or(0);
                out.push_str(&format!("{number:0width$}"));
            }
            None => out.push_str(&rest[open..=open + close]),
        }
        rest = &rest[open + close + 1..];
    }
    out.push_str(rest);
    out
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
    collect_parquet(&dir, &mut files)?;
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

fn collect_parquet(dir: &Path, out: &mut Vec<PathBuf>) -> Result<(), DatasetError> {
    let Ok(entries) = fs_err::read_dir(dir) else {
        return Ok(());
    };
    for entry in entries {
        let path = entry?.path();
        if path.is_dir() {
            collect_parquet(&path, out)?;
        } else if path.extension().is_some_and(|e| e == "parquet") {
            out.push(path);
        }
    }
    Ok(())
}

/// A [`DatasetError::Layout`] naming the file.
fn bad(path: &Path, message: &str) -> DatasetError {
    DatasetError::Layout(format!("file '{}': {message}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::fill_template;

    #[test]
    fn templates_leaving_the_folder_are_refused() {
        let info = |data: &str, key: &str| -> serde_json::Map<String, serde_json::Value> {
            serde_json::from_value(serde_json::json!({
                "data_path": data,
                "video_path": "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4",
                "features": {key: {"dtype": "video"}}
            }))
            .unwrap()
        };
        let p = std::path::Path::new("meta/info.json");
        let ok = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet";
        assert!(super::check_paths(&info(ok, "observation.images.top"), p).is_ok());
        for bad in [
            "../x/{file_index}.parquet",
            "/etc/{file_index}",
            "data/../../x",
        ] {
            let e = super::check_paths(&info(bad, "top"), p).unwrap_err();
            assert!(e.to_string().contains("leaves the dataset folder"), "{e}");
        }
        for key in ["../top", "a/b", ".."] {
            assert!(super::check_paths(&info(ok, key), p).is_err(), "{key}");
        }
    }

    #[test]
    fn templates_fill_like_python_format() {
        let f = [
            ("video_key", "observation.images.top", 0),
            ("chunk_index", "", 1),
            ("file_index", "", 12),
        ];
        assert_eq!(
            fill_template(
                "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4",
                &f
            ),
            "videos/observation.images.top/chunk-001/file-012.mp4"
        );
        assert_eq!(
            fill_template("a/{file_index}.x{unknown}", &f),
            "a/12.x{unknown}"
        );
    }
}
