//! The LeRobot v3.0 writer: episodes appended in order into size-capped data files and
//! per-camera video files joined by stream copy; metadata written by `finish`.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use parquet::arrow::ArrowWriter;
use serde::Serialize;
use serde_json::{Value, json};

use crate::error::ConvertError;
use crate::parquet_io::{self as pq, parquet_err};
use crate::prepare::PreparedEpisode;
use crate::stats::{FeatureStats, aggregate, column_stats};

/// Episodes per chunk folder.
pub const CHUNKS_SIZE: usize = 1000;
/// Data file size cap (MB), lerobot's default.
pub const DEFAULT_DATA_FILE_MB: f64 = 100.0;
/// Video file size cap (MB), lerobot's default.
pub const DEFAULT_VIDEO_FILE_MB: f64 = 200.0;

/// Sizes and names of a LeRobot v3.0 dataset.
#[derive(Debug, Clone)]
pub struct V3Options {
    /// `robot_type` in info.json.
    pub robot_type: Option<String>,
    /// Data file size cap in MB (info.json records it rounded, at least 1).
    pub data_file_mb: f64,
    /// Video file size cap in MB (info.json records it rounded, at least 1).
    pub video_file_mb: f64,
}

impl Default for V3Options {
    fn default() -> Self {
        Self {
            robot_type: None,
            data_file_mb: DEFAULT_DATA_FILE_MB,
            video_file_mb: DEFAULT_VIDEO_FILE_MB,
        }
    }
}

/// A camera feature of the dataset, from its first episode's video part.
#[derive(Debug, Clone)]
pub(crate) struct CameraSpec {
    pub(crate) name: String,
    pub(crate) key: String,
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) codec: String,
    pub(crate) pix_fmt: String,
    pub(crate) copied: bool,
}

impl CameraSpec {
    pub(crate) fn of(first: &PreparedEpisode) -> Vec<Self> {
        first
            .videos
            .iter()
            .map(|v| Self {
                name: v.name.clone(),
                key: format!("observation.images.{}", v.name),
                width: v.info.width,
                height: v.info.height,
                codec: v.info.codec.clone(),
                pix_fmt: v.info.pix_fmt.clone(),
                copied: v.copied,
            })
            .collect()
    }
}

/// Statistics of the default features (timestamp, frame/episode/global/task index) of
/// an episode of `n` frames, added to `stats`.
pub(crate) fn index_stats(
    stats: &mut BTreeMap<String, FeatureStats>,
    n: usize,
    fps: u32,
    episode_index: usize,
    from: usize,
    task_index: usize,
) -> Vec<f32> {
    let timestamps: Vec<f32> = (0..n).map(|k| (k as f64 / f64::from(fps)) as f32).collect();
    let ts: Vec<f64> = timestamps.iter().map(|t| f64::from(*t)).collect();
    stats.insert("timestamp".into(), column_stats(&ts, 1));
    let ints = |f: &dyn Fn(usize) -> usize| -> Vec<f64> { (0..n).map(|k| f(k) as f64).collect() };
    stats.insert("frame_index".into(), column_stats(&ints(&|k| k), 1));
    stats.insert(
        "episode_index".into(),
        column_stats(&ints(&|_| episode_index), 1),
    );
    stats.insert("index".into(), column_stats(&ints(&|k| from + k), 1));
    stats.insert("task_index".into(), column_stats(&ints(&|_| task_index), 1));
    timestamps
}

/// The data columns of one episode (features with a column, in info.json order).
pub(crate) fn data_columns(
    ep: &PreparedEpisode,
    timestamps: &[f32],
    episode_index: usize,
    from: usize,
    task_index: usize,
) -> Vec<(String, arrow_array::ArrayRef)> {
    let n = ep.len();
    vec![
        (
            "action".to_owned(),
            pq::f32_vectors(ep.action.as_slice(), ep.action.width()),
        ),
        (
            "observation.state".to_owned(),
            pq::f32_vectors(ep.state.as_slice(), ep.state.width()),
        ),
        (
            "timestamp".to_owned(),
            pq::f32_column(timestamps.iter().copied()),
        ),
        (
            "frame_index".to_owned(),
            pq::i64_column((0..n).map(|k| k as i64)),
        ),
        (
            "episode_index".to_owned(),
            pq::i64_column(std::iter::repeat_n(episode_index as i64, n)),
        ),
        (
            "index".to_owned(),
            pq::i64_column((from..from + n).map(|k| k as i64)),
        ),
        (
            "task_index".to_owned(),
            pq::i64_column(std::iter::repeat_n(task_index as i64, n)),
        ),
    ]
}

#[derive(Debug, Default)]
struct VideoFile {
    chunk: usize,
    file: usize,
    parts: Vec<PathBuf>,
    temporary: Vec<PathBuf>,
    frames: usize,
    bytes: u64,
}

#[derive(Debug)]
struct EpisodeRow {
    tasks: Vec<String>,
    length: usize,
    data: (usize, usize),
    from: usize,
    to: usize,
    videos: Vec<(usize, usize, f64, f64)>,
    stats: BTreeMap<String, FeatureStats>,
}

struct DataFile {
    writer: ArrowWriter<fs_err::File>,
    path: PathBuf,
}

/// Writes a LeRobot v3.0 dataset into `root` (which should be a fresh folder).
pub struct V3Writer {
    root: PathBuf,
    options: V3Options,
    fps: u32,
    action_names: Vec<String>,
    state_names: Vec<String>,
    cameras: Vec<CameraSpec>,
    data: Option<DataFile>,
    data_index: (usize, usize),
    videos: Vec<VideoFile>,
    episodes: Vec<EpisodeRow>,
    tasks: Vec<String>,
    task_index: HashMap<String, usize>,
    frames: usize,
}

impl std::fmt::Debug for V3Writer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("V3Writer")
            .field("root", &self.root)
            .field("episodes", &self.episodes.len())
            .finish_non_exhaustive()
    }
}

fn chunk_path(template_dir: &Path, chunk: usize, file: usize, ext: &str) -> PathBuf {
    template_dir.join(format!("chunk-{chunk:03}/file-{file:03}.{ext}"))
}

fn next_index((chunk, file): (usize, usize)) -> (usize, usize) {
    if file + 1 >= CHUNKS_SIZE {
        (chunk + 1, 0)
    } else {
        (chunk, file + 1)
    }
}

impl V3Writer {
    /// Starts a dataset whose features are those of `first` (every later episode must
    /// have the same widths and cameras).
    pub fn try_new(
        root: impl Into<PathBuf>,
        first: &PreparedEpisode,
        options: V3Options,
    ) -> Result<Self, ConvertError> {
        let root = root.into();
        fs_err::create_dir_all(root.join("meta"))?;
        let cameras = CameraSpec::of(first);
        Ok(Self {
            videos: cameras.iter().map(|_| VideoFile::default()).collect(),
            root,
            options,
            fps: first.fps,
            action_names: first.action_names.clone(),
            state_names: first.state_names.clone(),
            cameras,
            data: None,
            data_index: (0, 0),
            episodes: Vec::new(),
            tasks: Vec::new(),
            task_index: HashMap::new(),
            frames: 0,
        })
    }

    /// Episodes written so far.
    pub fn episodes(&self) -> usize {
        self.episodes.len()
    }

    /// Frames written so far.
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// Checks that `ep` can join this dataset (layout, and videos that stream-copy).
    pub(crate) fn check_compatible(&self, ep: &PreparedEpisode) -> Result<(), ConvertError> {
        let bad = |m: String| Err(ConvertError::episode(&ep.id, m));
        let want: Vec<&str> = self.cameras.iter().map(|c| c.name.as_str()).collect();
        ep.check_layout(
            self.fps,
            self.action_names.len(),
            self.state_names.len(),
            &want,
        )?;
        for (v, c) in ep.videos.iter().zip(&self.cameras) {
            if (v.info.width, v.info.height) != (c.width, c.height)
                || v.info.codec != c.codec
                || v.info.pix_fmt != c.pix_fmt
            {
                return bad(format!(
                    "camera '{}': {}x{} {} {} cannot join the dataset's {}x{} {} {} video by stream copy (use --reencode)",
                    c.name,
                    v.info.width,
                    v.info.height,
                    v.info.codec,
                    v.info.pix_fmt,
                    c.width,
                    c.height,
                    c.codec,
                    c.pix_fmt
                ));
            }
        }
        Ok(())
    }

    /// Appends one episode: its rows to the current data file (one row group), its video
    /// parts to each camera's current file.
    pub fn write_episode(&mut self, ep: PreparedEpisode) -> Result<(), ConvertError> {
        self.check_compatible(&ep)?;
        let n = ep.len();
        let episode_index = self.episodes.len();
        let task_index = match self.task_index.get(&ep.instruction) {
            Some(i) => *i,
            None => {
                self.tasks.push(ep.instruction.clone());
                self.task_index
                    .insert(ep.instruction.clone(), self.tasks.len() - 1);
                self.tasks.len() - 1
            }
        };
        let from = self.frames;
        let fps = f64::from(self.fps);
        let mut index_st = BTreeMap::new();
        let timestamps = index_stats(&mut index_st, n, self.fps, episode_index, from, task_index);
        let columns = data_columns(&ep, &timestamps, episode_index, from, task_index);
        let batch = pq::batch(columns, HashMap::new());

        // Roll the data file over when it has reached its cap.
        let cap = (self.options.data_file_mb * 1e6) as u64;
        if let Some(d) = &self.data
            && d.writer.bytes_written() as u64 >= cap
        {
            self.close_data()?;
            self.data_index = next_index(self.data_index);
        }
        if self.data.is_none() {
            let path = chunk_path(
                &self.root.join("data"),
                self.data_index.0,
                self.data_index.1,
                "parquet",
            );
            fs_err::create_dir_all(path.parent().expect("has parent"))?;
            let file = fs_err::File::create(&path)?;
            let writer = ArrowWriter::try_new(file, batch.schema(), Some(pq::props()))
                .map_err(|e| parquet_err(&path)(e.to_string()))?;
            self.data = Some(DataFile { writer, path });
        }
        {
            let d = self.data.as_mut().expect("opened above");
            let err = parquet_err(&d.path);
            d.writer.write(&batch).map_err(|e| err(e.to_string()))?;
            d.writer.flush().map_err(|e| err(e.to_string()))?;
        }

        // Videos.
        let vcap = (self.options.video_file_mb * 1e6) as u64;
        let mut videos = Vec::new();
        for (i, part) in ep.videos.iter().enumerate() {
            if !self.videos[i].parts.is_empty() && self.videos[i].bytes + part.bytes >= vcap {
                self.close_video(i)?;
                let (c, f) = next_index((self.videos[i].chunk, self.videos[i].file));
                self.videos[i] = VideoFile {
                    chunk: c,
                    file: f,
                    ..VideoFile::default()
                };
            }
            let v = &mut self.videos[i];
            let start = v.frames + part.skip;
            let end = v.frames + part.frames;
            videos.push((v.chunk, v.file, start as f64 / fps, end as f64 / fps));
            v.parts.push(part.path.clone());
            if part.temporary {
                v.temporary.push(part.path.clone());
            }
            v.frames += part.frames;
            v.bytes += part.bytes;
        }

        let mut stats = ep.stats;
        stats.extend(index_st);
        self.episodes.push(EpisodeRow {
            tasks: vec![ep.instruction],
            length: n,
            data: self.data_index,
            from,
            to: from + n,
            videos,
            stats,
        });
        self.frames += n;
        Ok(())
    }

    fn close_data(&mut self) -> Result<(), ConvertError> {
        if let Some(d) = self.data.take() {
            d.writer
                .close()
                .map_err(|e| parquet_err(&d.path)(e.to_string()))?;
        }
        Ok(())
    }

    fn close_video(&mut self, i: usize) -> Result<(), ConvertError> {
        let c = &self.cameras[i];
        let v = &mut self.videos[i];
        if v.parts.is_empty() {
            return Ok(());
        }
        let path = chunk_path(
            &self.root.join("videos").join(&c.key),
            v.chunk,
            v.file,
            "mp4",
        );
        fs_err::create_dir_all(path.parent().expect("has parent"))?;
        dexjoco_video::concat_copy(&v.parts, &path, self.fps).map_err(|source| {
            ConvertError::Video {
                at: dexjoco_core::Location::default()
                    .field(c.key.clone())
                    .path(&path)
                    .into(),
                source: source.into(),
            }
        })?;
        for t in v.temporary.drain(..) {
            let _ = fs_err::remove_file(t);
        }
        v.parts.clear();
        Ok(())
    }

    /// Closes the files and writes `meta/` (info, stats, tasks, episodes).
    pub fn finish(mut self) -> Result<(), ConvertError> {
        self.close_data()?;
        for i in 0..self.cameras.len() {
            self.close_video(i)?;
        }
        let meta = self.root.join("meta");
        // tasks.parquet, with the pandas index metadata the loader needs.
        let pandas = r#"{"index_columns":["task"],"column_indexes":[],"columns":[{"name":"task_index","field_name":"task_index","pandas_type":"int64","numpy_type":"int64","metadata":null},{"name":"task","field_name":"task","pandas_type":"unicode","numpy_type":"object","metadata":null}]}"#;
        let tasks = pq::batch(
            vec![
                (
                    "task_index".into(),
                    pq::i64_column((0..self.tasks.len()).map(|i| i as i64)),
                ),
                ("task".into(), pq::string_column(&self.tasks)),
            ],
            HashMap::from([("pandas".to_owned(), pandas.to_owned())]),
        );
        pq::write_file(&meta.join("tasks.parquet"), &tasks)?;

        // Episodes.
        let feature_keys = self.stat_features();
        let rows = &self.episodes;
        let mut cols: Vec<(String, arrow_array::ArrayRef)> = vec![
            (
                "episode_index".into(),
                pq::i64_column((0..rows.len()).map(|i| i as i64)),
            ),
            (
                "tasks".into(),
                pq::string_lists(&rows.iter().map(|r| r.tasks.clone()).collect::<Vec<_>>()),
            ),
            (
                "length".into(),
                pq::i64_column(rows.iter().map(|r| r.length as i64)),
            ),
            (
                "data/chunk_index".into(),
                pq::i64_column(rows.iter().map(|r| r.data.0 as i64)),
            ),
            (
                "data/file_index".into(),
                pq::i64_column(rows.iter().map(|r| r.data.1 as i64)),
            ),
            (
                "dataset_from_index".into(),
                pq::i64_column(rows.iter().map(|r| r.from as i64)),
            ),
            (
                "dataset_to_index".into(),
                pq::i64_column(rows.iter().map(|r| r.to as i64)),
            ),
        ];
        for (i, c) in self.cameras.iter().enumerate() {
            let k = &c.key;
            cols.push((
                format!("videos/{k}/chunk_index"),
                pq::i64_column(rows.iter().map(|r| r.videos[i].0 as i64)),
            ));
            cols.push((
                format!("videos/{k}/file_index"),
                pq::i64_column(rows.iter().map(|r| r.videos[i].1 as i64)),
            ));
            cols.push((
                format!("videos/{k}/from_timestamp"),
                std::sync::Arc::new(arrow_array::Float64Array::from_iter_values(
                    rows.iter().map(|r| r.videos[i].2),
                )),
            ));
            cols.push((
                format!("videos/{k}/to_timestamp"),
                std::sync::Arc::new(arrow_array::Float64Array::from_iter_values(
                    rows.iter().map(|r| r.videos[i].3),
                )),
            ));
        }
        for (key, image) in &feature_keys {
            let get = |r: &EpisodeRow| {
                r.stats
                    .get(key)
                    .cloned()
                    .expect("every episode has every feature's stats")
            };
            let all: Vec<FeatureStats> = rows.iter().map(get).collect();
            let names: Vec<&str> = all[0].named().iter().map(|(n, _)| *n).collect();
            for (si, stat) in names.iter().enumerate() {
                let vals: Vec<Vec<f64>> = all.iter().map(|s| s.named()[si].1.to_vec()).collect();
                let col = if *image {
                    pq::f64_channel_lists(&vals)
                } else {
                    pq::f64_lists(&vals)
                };
                cols.push((format!("stats/{key}/{stat}"), col));
            }
            cols.push((
                format!("stats/{key}/count"),
                pq::i64_lists(&all.iter().map(|s| vec![s.count as i64]).collect::<Vec<_>>()),
            ));
        }
        cols.push((
            "meta/episodes/chunk_index".into(),
            pq::i64_column(rows.iter().map(|_| 0)),
        ));
        cols.push((
            "meta/episodes/file_index".into(),
            pq::i64_column(rows.iter().map(|_| 0)),
        ));
        let ep_path = chunk_path(&meta.join("episodes"), 0, 0, "parquet");
        fs_err::create_dir_all(ep_path.parent().expect("has parent"))?;
        pq::write_file(&ep_path, &pq::batch(cols, HashMap::new()))?;

        // stats.json
        let mut stats = serde_json::Map::new();
        for (key, image) in &feature_keys {
            let per: Vec<&FeatureStats> = rows.iter().map(|r| &r.stats[key]).collect();
            let agg = aggregate(&per).expect("at least one episode");
            stats.insert(key.clone(), stats_json(&agg, *image));
        }
        write_json(&meta.join("stats.json"), &Value::Object(stats))?;
        write_json(&meta.join("info.json"), &self.info())?;
        Ok(())
    }

    /// Features with statistics, and whether each is an image.
    fn stat_features(&self) -> Vec<(String, bool)> {
        let mut v: Vec<(String, bool)> = vec![
            ("action".into(), false),
            ("observation.state".into(), false),
        ];
        v.extend(self.cameras.iter().map(|c| (c.key.clone(), true)));
        for k in [
            "timestamp",
            "frame_index",
            "episode_index",
            "index",
            "task_index",
        ] {
            v.push((k.into(), false));
        }
        v
    }

    fn info(&self) -> Info {
        let mut features = Ordered::default();
        features.push(
            "action",
            json!({"dtype": "float32", "shape": [self.action_names.len()], "names": self.action_names}),
        );
        features.push(
            "observation.state",
            json!({"dtype": "float32", "shape": [self.state_names.len()], "names": self.state_names}),
        );
        for c in &self.cameras {
            let encoded = !c.copied;
            features.push(
                &c.key,
                json!({
                    "dtype": "video",
                    "shape": [c.height, c.width, 3],
                    "names": ["height", "width", "channels"],
                    "info": {
                        "video.height": c.height,
                        "video.width": c.width,
                        "video.codec": c.codec,
                        "video.pix_fmt": c.pix_fmt,
                        "video.is_depth_map": false,
                        "video.fps": self.fps,
                        "video.channels": 3,
                        "video.g": if encoded { json!(2) } else { Value::Null },
                        "video.crf": if encoded { json!(if c.codec == "av1" { 30 } else { 21 }) } else { Value::Null },
                        "video.preset": if encoded && c.codec == "av1" { json!(12) } else { Value::Null },
                        "video.fast_decode": 0,
                        "video.video_backend": Value::Null,
                        "video.extra_options": {},
                        "has_audio": false,
                        "is_depth_map": false,
                    }
                }),
            );
        }
        features.push(
            "timestamp",
            json!({"dtype": "float32", "shape": [1], "names": null}),
        );
        for k in ["frame_index", "episode_index", "index", "task_index"] {
            features.push(k, json!({"dtype": "int64", "shape": [1], "names": null}));
        }
        Info {
            codebase_version: "v3.0",
            fps: self.fps,
            features,
            total_episodes: self.episodes.len(),
            total_frames: self.frames,
            total_tasks: self.tasks.len(),
            chunks_size: CHUNKS_SIZE,
            data_files_size_in_mb: (self.options.data_file_mb.round() as u64).max(1),
            video_files_size_in_mb: (self.options.video_file_mb.round() as u64).max(1),
            data_path: "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
            video_path: (!self.cameras.is_empty())
                .then_some("videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"),
            robot_type: self.options.robot_type.clone(),
            splits: BTreeMap::from([("train", format!("0:{}", self.episodes.len()))]),
        }
    }
}

/// A JSON object that keeps insertion order.
#[derive(Debug, Default)]
pub(crate) struct Ordered(Vec<(String, Value)>);

impl Ordered {
    pub(crate) fn push(&mut self, k: &str, v: Value) {
        self.0.push((k.to_owned(), v));
    }
}

impl Serialize for Ordered {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut m = s.serialize_map(Some(self.0.len()))?;
        for (k, v) in &self.0 {
            m.serialize_entry(k, v)?;
        }
        m.end()
    }
}

#[derive(Debug, Serialize)]
struct Info {
    codebase_version: &'static str,
    fps: u32,
    features: Ordered,
    total_episodes: usize,
    total_frames: usize,
    total_tasks: usize,
    chunks_size: usize,
    data_files_size_in_mb: u64,
    video_files_size_in_mb: u64,
    data_path: &'static str,
    video_path: Option<&'static str>,
    robot_type: Option<String>,
    splits: BTreeMap<&'static str, String>,
}

/// `{min, max, mean, std, count, q01..q99}`; images as 3x1x1 nested lists.
pub(crate) fn stats_json(s: &FeatureStats, image: bool) -> Value {
    let mut m = serde_json::Map::new();
    let shape = |v: &[f64]| -> Value {
        if image {
            Value::Array(v.iter().map(|x| json!([[x]])).collect())
        } else {
            json!(v)
        }
    };
    for (k, v) in s.named() {
        m.insert(k.to_owned(), shape(v));
    }
    m.insert("count".into(), json!([s.count]));
    Value::Object(m)
}

/// JSON with a 4-space indent, as lerobot writes it.
pub(crate) fn write_json(path: &Path, value: &impl Serialize) -> Result<(), ConvertError> {
    let mut buf = Vec::new();
    let fmt = serde_json::ser::PrettyFormatter::with_indent(b"    ");
    let mut ser = serde_json::Serializer::with_formatter(&mut buf, fmt);
    value
        .serialize(&mut ser)
        .map_err(|e| ConvertError::Parquet {
            path: path.into(),
            message: e.to_string(),
        })?;
    buf.push(b'\n');
    fs_err::write(path, buf)?;
    Ok(())
}
