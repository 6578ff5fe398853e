//! The LeRobot v3.0 writer: episodes appended in order into size-capped data files and
//! per-camera video files joined by stream copy; metadata written by `finish`.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use dexjoco_video::ConcatInput;
use parquet::arrow::ArrowWriter;
use serde_json::Value;

use super::depth::DepthVideoMeta;
use super::episode_labels::label_columns;
use super::language::{LANGUAGE_EVENTS, LANGUAGE_PERSISTENT, events_column, persistent_column};
use super::lerobot_info::{
    CameraSpec, Features, Info, InfoVersion, Tasks, VideoMeta, VideoMetaV3, check_episode,
    stats_json, train_split,
};
use super::parquet::{self as pq, parquet_err};
use super::stats::{FeatureStats, aggregate, column_stats};
use super::{DatasetWriter, PreparedEpisode, write_json};
use crate::error::DatasetError;
use crate::raw::ReplayLabel;

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
    /// Rows of every episode's `language_persistent` slice (its subtask rows, then
    /// `task_aug` rows): the most any episode of the dataset has, plus one
    /// ([`super::language::slots_for`]); 0: each episode's own count plus one.
    pub language_slots: usize,
}

impl Default for V3Options {
    fn default() -> Self {
        Self {
            robot_type: None,
            data_file_mb: DEFAULT_DATA_FILE_MB,
            video_file_mb: DEFAULT_VIDEO_FILE_MB,
            language_slots: 0,
        }
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
    let mut cols = vec![
        (
            "action".to_owned(),
            pq::f32_vectors(ep.action.as_slice(), ep.action.width()),
        ),
        (
            "observation.state".to_owned(),
            pq::f32_vectors(ep.state.as_slice(), ep.state.width()),
        ),
    ];
    for v in &ep.vectors {
        cols.push((
            v.key.clone(),
            pq::f32_vectors(v.values.as_slice(), v.values.width()),
        ));
    }
    cols.extend([
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
    ]);
    cols
}

#[derive(Debug, Default)]
struct VideoFile {
    chunk: usize,
    file: usize,
    parts: Vec<ConcatInput>,
    /// The parts' extradata (H.264 SPS/PPS): parts with other parameters start a file.
    extradata: Option<String>,
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
    label: Option<ReplayLabel>,
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
    /// The vector features' keys and column names (`--environment-state`, ...).
    vectors: Vec<(String, Vec<String>)>,
    /// The colour cameras, then the depth ones (`<camera>_depth`).
    cameras: Vec<CameraSpec>,
    /// How many of `cameras` are colour cameras.
    colour: usize,
    data: Option<DataFile>,
    data_index: (usize, usize),
    videos: Vec<VideoFile>,
    episodes: Vec<EpisodeRow>,
    tasks: Tasks,
    frames: usize,
    /// Whether the episodes carry lerobot 0.6's language columns (their subtasks): as
    /// the first episode does.
    language: bool,
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
    ) -> Result<Self, DatasetError> {
        let root = root.into();
        fs_err::create_dir_all(root.join("meta"))?;
        let mut cameras = CameraSpec::of(first);
        let colour = cameras.len();
        cameras.extend(super::lerobot_info::depth_camera_specs(first));
        Ok(Self {
            videos: cameras.iter().map(|_| VideoFile::default()).collect(),
            root,
            options,
            fps: first.fps,
            action_names: first.action_names.clone(),
            state_names: first.state_names.clone(),
            vectors: first.vector_layout(),
            cameras,
            colour,
            data: None,
            data_index: (0, 0),
            episodes: Vec::new(),
            tasks: Tasks::default(),
            frames: 0,
            language: !first.subtasks.is_empty(),
        })
    }

    /// Appends one episode's rows to the current data file (one row group), rolling the
    /// file over when it has reached its cap.
    fn write_data(&mut self, batch: &arrow_array::RecordBatch) -> Result<(), DatasetError> {
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
                .map_err(parquet_err(&path))?;
            self.data = Some(DataFile { writer, path });
        }
        let d = self.data.as_mut().expect("opened above");
        let err = parquet_err(&d.path);
        d.writer.write(batch).map_err(&err)?;
        d.writer.flush().map_err(&err)?;
        Ok(())
    }

    /// Appends one episode's video parts to each camera's current file (rolled over at
    /// its cap); returns each camera's (chunk, file, from, to timestamps).
    fn append_videos(
        &mut self,
        ep: &PreparedEpisode,
    ) -> Result<Vec<(usize, usize, f64, f64)>, DatasetError> {
        let fps = f64::from(self.fps);
        let vcap = (self.options.video_file_mb * 1e6) as u64;
        let mut videos = Vec::new();
        let depth = super::lerobot_info::encoded_depth_parts(ep, &self.cameras[self.colour..])?;
        for (i, part) in ep.videos.iter().chain(depth).enumerate() {
            let other_parameters = self.videos[i]
                .extradata
                .as_ref()
                .is_some_and(|e| *e != part.info.extradata);
            if !self.videos[i].parts.is_empty()
                && (self.videos[i].bytes + part.bytes >= vcap || other_parameters)
            {
                self.close_video(i)?;
                let (c, f) = next_index((self.videos[i].chunk, self.videos[i].file));
                self.videos[i] = VideoFile {
                    chunk: c,
                    file: f,
                    ..VideoFile::default()
                };
            }
            let v = &mut self.videos[i];
            // The part's static leading frames are cut at its keyframe `skip`.
            let kept = part.frames - part.skip;
            let (start, end) = (v.frames, v.frames + kept);
            videos.push((v.chunk, v.file, start as f64 / fps, end as f64 / fps));
            v.parts.push(ConcatInput {
                path: part.path.clone(),
                skip: part.skip,
                // Fewer frames than the file holds (an evaluated rollout's last one).
                take: (part.frames < part.info.frames as usize).then_some(kept),
            });
            v.extradata = Some(part.info.extradata.clone());
            if part.temporary {
                v.temporary.push(part.path.clone());
            }
            v.frames += kept;
            v.bytes += part.bytes;
        }
        Ok(videos)
    }

    fn close_data(&mut self) -> Result<(), DatasetError> {
        if let Some(d) = self.data.take() {
            d.writer.close().map_err(parquet_err(&d.path))?;
        }
        Ok(())
    }

    fn close_video(&mut self, i: usize) -> Result<(), DatasetError> {
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
            DatasetError::Video {
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

    /// `meta/tasks.parquet`, with the pandas index metadata the loader needs.
    fn write_tasks(&self, meta: &Path) -> Result<(), DatasetError> {
        let pandas = r#"{"index_columns":["task"],"column_indexes":[],"columns":[{"name":"task_index","field_name":"task_index","pandas_type":"int64","numpy_type":"int64","metadata":null},{"name":"task","field_name":"task","pandas_type":"unicode","numpy_type":"object","metadata":null}]}"#;
        let tasks = self.tasks.list();
        let tasks = pq::batch(
            vec![
                (
                    "task_index".into(),
                    pq::i64_column((0..tasks.len()).map(|i| i as i64)),
                ),
                ("task".into(), pq::string_column(tasks)),
            ],
            HashMap::from([("pandas".to_owned(), pandas.to_owned())]),
        );
        pq::write_file(&meta.join("tasks.parquet"), &tasks)
    }

    /// `meta/episodes/chunk-000/file-000.parquet`: per episode its task, length, data
    /// and video file indices, video time ranges and statistics.
    fn write_episodes(
        &self,
        meta: &Path,
        feature_keys: &[(String, bool)],
    ) -> Result<(), DatasetError> {
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
        cols.extend(self.video_columns());
        cols.extend(stats_columns(rows, feature_keys));
        let labels: Vec<Option<&ReplayLabel>> = rows.iter().map(|r| r.label.as_ref()).collect();
        cols.extend(
            label_columns(&labels)
                .into_iter()
                .map(|(name, values)| (name, values.to_arrow())),
        );
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
        pq::write_file(&ep_path, &pq::batch(cols, HashMap::new()))
    }

    /// Per camera, the episodes' video chunk and file indices and time ranges.
    fn video_columns(&self) -> Vec<(String, arrow_array::ArrayRef)> {
        let rows = &self.episodes;
        let mut cols: Vec<(String, arrow_array::ArrayRef)> = Vec::new();
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
        cols
    }

    /// Features with statistics, and whether each is an image.
    fn stat_features(&self) -> Vec<(String, bool)> {
        let mut v: Vec<(String, bool)> = vec![
            ("action".into(), false),
            ("observation.state".into(), false),
        ];
        v.extend(self.vectors.iter().map(|(k, _)| (k.clone(), false)));
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
        let features =
            Features::lerobot(&self.action_names, &self.state_names, &self.cameras, |c| {
                if c.pix_fmt == super::depth::DEPTH_PIX_FMT {
                    return VideoMeta::Depth(DepthVideoMeta::new(c.width, c.height, self.fps));
                }
                let encoded = !c.copied;
                VideoMeta::V3(VideoMetaV3 {
                    height: c.height,
                    width: c.width,
                    codec: c.codec.clone(),
                    pix_fmt: c.pix_fmt.clone(),
                    video_is_depth_map: false,
                    fps: self.fps,
                    channels: 3,
                    g: encoded.then_some(2),
                    crf: encoded.then_some(if c.codec == "av1" { 30 } else { 21 }),
                    preset: (encoded && c.codec == "av1").then_some(12),
                    fast_decode: 0,
                    video_backend: None,
                    extra_options: BTreeMap::new(),
                    has_audio: false,
                    is_depth_map: false,
                })
            })
            .with_vectors(&self.vectors)
            .with_language(self.language);
        Info {
            version: InfoVersion::V3 {
                data_files_size_in_mb: (self.options.data_file_mb.round() as u64).max(1),
                video_files_size_in_mb: (self.options.video_file_mb.round() as u64).max(1),
            },
            robot_type: self.options.robot_type.clone(),
            fps: self.fps,
            features,
            total_episodes: self.episodes.len(),
            total_frames: self.frames,
            total_tasks: self.tasks.list().len(),
            chunks_size: CHUNKS_SIZE,
            splits: train_split(self.episodes.len()),
            data_path: "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
            video_path: (!self.cameras.is_empty())
                .then_some("videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"),
        }
    }
}

/// Per feature, the episodes' statistics (`stats/<key>/<stat>`, then `count`).
fn stats_columns(
    rows: &[EpisodeRow],
    feature_keys: &[(String, bool)],
) -> Vec<(String, arrow_array::ArrayRef)> {
    let mut cols: Vec<(String, arrow_array::ArrayRef)> = Vec::new();
    for (key, image) in feature_keys {
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
    cols
}

impl DatasetWriter for V3Writer {
    /// Checks that `ep` can join this dataset (layout, and videos that stream-copy).
    fn check_compatible(&self, ep: &PreparedEpisode) -> Result<(), DatasetError> {
        ep.check_vectors(&self.vectors)?;
        check_episode(
            ep,
            self.fps,
            (self.action_names.len(), self.state_names.len()),
            &self.cameras[..self.colour],
            |c, v| {
                format!(
                    "camera '{}': {}x{} {} {} cannot join the dataset's {}x{} {} {} video by stream copy (use --reencode)",
                    c.name,
                    v.width,
                    v.height,
                    v.codec,
                    v.pix_fmt,
                    c.width,
                    c.height,
                    c.codec,
                    c.pix_fmt
                )
            },
        )?;
        super::lerobot_info::encoded_depth_parts(ep, &self.cameras[self.colour..]).map(drop)
    }

    /// Appends one episode: its rows to the current data file (one row group), its video
    /// parts to each camera's current file.
    fn write_episode(&mut self, ep: PreparedEpisode) -> Result<(), DatasetError> {
        self.check_compatible(&ep)?;
        let n = ep.len();
        let episode_index = self.episodes.len();
        let task_index = self.tasks.index_of(&ep.instruction);
        let from = self.frames;
        let mut index_st = BTreeMap::new();
        let timestamps = index_stats(&mut index_st, n, self.fps, episode_index, from, task_index);
        let mut columns = data_columns(&ep, &timestamps, episode_index, from, task_index);
        if self.language {
            columns.extend([
                (
                    LANGUAGE_PERSISTENT.to_owned(),
                    persistent_column(
                        &ep.subtasks,
                        &ep.task_aug,
                        self.options.language_slots,
                        self.fps,
                        n,
                    ),
                ),
                (LANGUAGE_EVENTS.to_owned(), events_column(n)),
            ]);
        }
        self.write_data(&pq::batch(columns, HashMap::new()))?;
        let videos = self.append_videos(&ep)?;
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
            label: ep.label,
        });
        self.frames += n;
        Ok(())
    }

    fn episodes(&self) -> usize {
        self.episodes.len()
    }

    fn frames(&self) -> usize {
        self.frames
    }

    /// Closes the files and writes `meta/` (info, stats, tasks, episodes).
    fn finish(mut self: Box<Self>) -> Result<(), DatasetError> {
        self.close_data()?;
        for i in 0..self.cameras.len() {
            self.close_video(i)?;
        }
        let meta = self.root.join("meta");
        self.write_tasks(&meta)?;
        let feature_keys = self.stat_features();
        self.write_episodes(&meta, &feature_keys)?;
        let mut stats = serde_json::Map::new();
        for (key, image) in &feature_keys {
            let per: Vec<&FeatureStats> = self.episodes.iter().map(|r| &r.stats[key]).collect();
            let agg = aggregate(&per).expect("at least one episode");
            stats.insert(key.clone(), stats_json(&agg, *image));
        }
        write_json(&meta.join("stats.json"), &Value::Object(stats))?;
        write_json(&meta.join("info.json"), &self.info())?;
        Ok(())
    }
}
